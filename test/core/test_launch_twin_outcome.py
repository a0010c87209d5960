"""The launch twin's verdict is the rig's (issue 40): the IMU classifier's tilt rule on analytic poses, and on its
wheels wherever it rests, in both engines."""
import dataclasses
import math

import pytest

from rollability_ros.core.config import from_mapping, load_parameters, section
from rollability_ros.core.imu.upright import (ImuOutcomeConfig, ImuSample, ImuUprightClassifier, quaternion_conjugate,
                                              quaternion_from_axis_angle, rotate_vector, tilt_from_orientation_deg)
from rollability_ros.core.sim.launch.loop import rig_verdict
from rollability_ros.core.sim.launch.placement import sized_for_robot
from rollability_ros.core.sim.launch.pybullet_twin import build_launch_world, wheels_down
from rollability_ros.core.sim.launch.settings import load_launch_twin_settings
from rollability_ros.core.sim.trials import place_on_ground
from rollability_ros.core.sim.world import connect, disconnect

pybullet = pytest.importorskip("pybullet")

GRAVITY_MPS2 = 9.80665
#: Analytic poses: (axis, angle deg) of the body in the world; tilt = the angle for a horizontal axis.
POSES = [((1, 0, 0), 0.0), ((1, 0, 0), 20.0), ((0, 1, 0), 29.0), ((1, 1, 0), 31.0), ((1, 0.3, 0), 135.0),
         ((0, 1, 0), 180.0), ((0, 0, 1), 70.0)]


def rig_imu_config():
    return from_mapping(ImuOutcomeConfig, section(load_parameters("rig"), "imu_outcome"), "imu_outcome")


def imu_classification(orientation_xyzw):
    """The rig's IMU classifier (config/rig.yaml) on a chassis that moved, then lay still in ``orientation``."""
    config = rig_imu_config()
    classifier = ImuUprightClassifier.from_config(config)
    still_accel = rotate_vector(quaternion_conjugate(orientation_xyzw), (0.0, 0.0, GRAVITY_MPS2))
    classifier.update(ImuSample(0.0, orientation_xyzw, (0.0, 3.0, 0.0), still_accel))   # the launch's motion
    reading = None
    for step in range(1, 200):
        reading = classifier.update(ImuSample(step * 0.01, orientation_xyzw, (0.0, 0.0, 0.0), still_accel))
    assert reading is not None and reading.settled
    return reading.classification


def test_the_twins_tilt_threshold_is_the_rig_imu_classifiers():
    settings = load_launch_twin_settings()
    assert settings.robot_model().upright_tilt_deg == rig_imu_config().tilt_threshold_deg == 30.0


@pytest.mark.parametrize("axis,angle_deg", POSES)
def test_the_verdict_agrees_with_the_imu_classifier_on_analytic_poses(axis, angle_deg):
    """The twin's tilt of a robot held in an analytic pose equals the IMU's tilt from that orientation (both
    engines), and its verdict on its wheels equals the IMU classifier's once settled."""
    norm = math.sqrt(sum(a * a for a in axis))
    orientation = quaternion_from_axis_angle([a / norm for a in axis], math.radians(angle_deg))
    expected_tilt = tilt_from_orientation_deg(orientation)
    if axis[2] == 0:
        assert expected_tilt == pytest.approx(angle_deg, abs=1e-9)
    settings = sized_for_robot(load_launch_twin_settings(overrides={"trial.early_decision": False}))[0]
    model = settings.robot_model()
    client = connect()
    try:
        build_launch_world(client, settings, 0.75)
        robot = model.spawn(client, None, (3.0, 0.0, 1.0), orientation, time_step_s=settings.physics.time_step_s)
        tilt = model.tilt_deg(client, robot)
    finally:
        disconnect(client)
    assert tilt == pytest.approx(expected_tilt, abs=1e-4)
    on_wheels = model.min_wheels_in_contact
    assert rig_verdict(tilt, on_wheels, model) == imu_classification(orientation) == (expected_tilt <= 30.0)
    pytest.importorskip("mujoco")
    from rollability_ros.core.sim.launch.mujoco_twin import twin_for
    twin = twin_for(dataclasses.replace(settings, physics=dataclasses.replace(settings.physics, engine="mujoco")),
                    None)
    twin.place(orientation, 0.5, (3.0, 0.0), 1.0)
    assert twin.tilt_deg() == pytest.approx(expected_tilt, abs=1e-4)


def test_at_rest_on_its_wheels_is_upright_on_the_floor_beyond_the_pad_and_not_on_its_back():
    """Placed at rest on the floor 1 m beyond the pad's end (PyBullet) or on the pad's level there (MuJoCo's pad is
    a plane): level on its wheels it is upright (it was not under the old foam-contact rule); on its back, or
    level but lifted off every surface, it is not."""
    settings = sized_for_robot(load_launch_twin_settings(overrides={"trial.early_decision": False}))[0]
    model = settings.robot_model()
    far = (settings.twin.foam.length_m + 1.0, 0.0)
    level, inverted = (0.0, 0.0, 0.0, 1.0), quaternion_from_axis_angle((1.0, 0.0, 0.0), math.pi)
    client = connect()
    try:
        foam_id, ledge_id, floor_id = build_launch_world(client, settings, 0.75)
        verdicts = {}
        for name, orientation, clearance in (("level", level, 0.0), ("inverted", inverted, 0.0),
                                             ("lifted", level, 0.05)):
            robot = model.spawn(client, None, (*far, 1.0), orientation, time_step_s=settings.physics.time_step_s)
            place_on_ground(client, robot.body_id, orientation, clearance, far, 0.0)
            down = wheels_down(pybullet, client, robot, model, (foam_id, floor_id, ledge_id))
            verdicts[name] = (rig_verdict(model.tilt_deg(client, robot), down, model),
                              down, model.wheels_in_contact(client, robot, foam_id))
            pybullet.removeBody(robot.body_id, physicsClientId=client)
    finally:
        disconnect(client)
    assert verdicts["level"] == (True, 4, 0)      # four wheels on the floor, none on the foam
    assert verdicts["inverted"][0] is False and verdicts["lifted"][0] is False
    pytest.importorskip("mujoco")
    from rollability_ros.core.sim.launch.mujoco_twin import twin_for
    twin = twin_for(dataclasses.replace(settings, physics=dataclasses.replace(settings.physics, engine="mujoco")),
                    None)
    foam_top = settings.twin.foam.thickness_m
    results = {}
    for name, orientation, clearance in (("level", level, 0.0), ("inverted", inverted, 0.0), ("lifted", level, 0.05)):
        twin.place(orientation, clearance, far, foam_top)
        results[name] = rig_verdict(twin.tilt_deg(), twin.wheels_down(), model)
    assert results == {"level": True, "inverted": False, "lifted": False}
