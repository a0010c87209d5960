"""The launch twin with a URDF robot from config alone: the Husky inside the pybullet wheel launched off the ledge,
its wheel radius from its collision geometry, a launcher too small for it refused, the rig's sim backend on it."""
import dataclasses
import math

import numpy as np
import pytest

from rollability_ros.core.sim.launch.settings import load_launch_twin_settings
from rollability_ros.core.sim.launch.twin import simulate_launch
from rollability_ros.core.records import LaunchCondition
from rollability_ros.core.rig.launch_backend import RigSettings
from rollability_ros.core.rig.rig_session import SimulatedLaunch, simulated_outcome, launch_seed
from rollability_ros.core.robots.robot import ChassisModel, ChassisSpec
from rollability_ros.core.rig.speed_gate import SpeedGateConfig
from rollability_ros.core.robots.urdf_robot import UrdfRobotModel, UrdfRobotSpec, half_width_across_m

pytest.importorskip("pybullet")

#: ``front_left_wheel_link`` collision cylinder of pybullet_data/husky/husky.urdf (m).
HUSKY_WHEEL_RADIUS_M = 0.17775
@pytest.fixture(scope="module")
def twin_config():
    """The rig's default twin files and the Husky's config: the launcher is sized for the Husky from its collision
    geometry (a 1.7 m ledge, a 0.4 m tall plate pushing with 8 kN)."""
    return ["sim", "robot", "launch_twin", "husky"]


@pytest.fixture(scope="module")
def husky_twin(twin_config):
    return load_launch_twin_settings(twin_config)


def test_husky_config_makes_a_husky_twin_with_its_wheels_and_density(husky_twin):
    model = husky_twin.robot_model()
    assert isinstance(model, UrdfRobotModel) and model.spec.mount_link == "top_plate_link"
    assert model.wheel_radii_m() == pytest.approx((HUSKY_WHEEL_RADIUS_M,) * 4, rel=1e-5)
    assert husky_twin.urdf_robot.profile_print.model == "solid"
    assert husky_twin.urdf_robot.profile_print.solid_density_kgpm3 == 20.0
    chassis = load_launch_twin_settings()
    assert isinstance(chassis.robot_model(), ChassisModel)
    assert chassis.robot_model().wheel_radii_m() == (ChassisSpec().wheel_radius_m,) * 4


def test_wheel_radius_of_any_urdf_wheel_from_its_collision_shape():
    """The chassis's own URDF export, its wheel cylinders turned about their axles: still their radius."""
    chassis = ChassisSpec(wheel_radius_m=0.041)
    text = ChassisModel(chassis).to_urdf()
    turned = text.replace('rpy="1.5708 0 0"', 'rpy="1.5708 0.4 0"')   # 23 deg about the axle (link y)
    assert turned != text
    for description in (text, turned):
        spec = UrdfRobotSpec(robot_description=description, mount_link="base_link", wheel_link_regex=".*_wheel",
                             min_wheels_in_contact=3, footprint_offset_m=(0.0, 0.0, chassis.body_height_m / 2))
        spec.validate()
        assert UrdfRobotModel(spec).wheel_radii_m() == pytest.approx((0.041,) * 4, rel=1e-5)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * [0.2, 0.2, 0.05]
    assert half_width_across_m(corners, (0, 0, 1)) == pytest.approx(0.2)   # not the corner distance 0.28
    assert half_width_across_m(corners, (1, 0, 0)) == pytest.approx(0.05)


def test_one_husky_launch_runs_is_deterministic_and_classifies(husky_twin):
    condition = LaunchCondition("baseline", 0.75, 1.5, 0.0)
    phases = []
    result = simulate_launch(condition, husky_twin, 7, on_phase=phases.append)
    assert repr(simulate_launch(condition, husky_twin, 7)) == repr(result)
    assert phases == ["fired", "in_flight", "settling", "classifying"] and result.settled
    assert result.landing_position_m[0] > 0   # it went over the edge onto the foam
    # config/husky.yaml picks the push-through launcher (the paper's 0.15 m stroke leaves the 1 m long robot on the
    # ledge): the plate pushes the 44 kg robot with its 0.178 m wheels and 2 N m motor drag to the edge at the
    # launch speed
    assert husky_twin.twin.launcher.model == "push_through"
    assert result.edge_speed_mps == pytest.approx(result.launch_speed_mps, rel=0.05)
    assert 1.0 < result.travel_time_s / (0.34 / result.launch_speed_mps) < 1.1
    # classified from its final pose: it pitches over the edge and lands on its back (tilt = angle of its z axis)
    tilt_deg = math.degrees(2 * math.acos(min(1.0, math.hypot(*result.final_orientation[2:]))))
    assert result.tilt_deg == pytest.approx(tilt_deg, abs=1e-3)
    assert result.tilt_deg > 150 and result.upright is False


def test_a_launcher_too_small_for_the_robot_is_refused():
    settings = load_launch_twin_settings(["sim", "robot", "launch_twin", "husky"],
                                         overrides={"twin.launcher.ledge_depth_m": 0.8})   # the chassis's ledge
    with pytest.raises(ValueError, match="does not fit on the launcher.*ledge_depth_m = 0.8 m"):
        simulate_launch(LaunchCondition("baseline", 0.75, 0.8, 0.0), settings, 1)


def test_the_rig_sim_backend_launches_the_husky_from_its_twin_config(twin_config, husky_twin):
    rig = RigSettings(twin_config=twin_config)
    speed_config = SpeedGateConfig()
    condition = LaunchCondition("baseline", 0.75, 0.8, 0.0)
    outcome = SimulatedLaunch(rig, speed_config, load_launch_twin_settings(twin_config)).launch("run", "h0", condition)
    expected = simulate_launch(condition, husky_twin, launch_seed(rig.seed, "h0"))
    direct = simulated_outcome("run", "h0", condition, expected, speed_config)
    assert outcome == dataclasses.replace(direct, stamp_s=outcome.stamp_s)
    assert outcome.backend == "sim" and outcome.travel_time_s == expected.travel_time_s


def test_the_husky_launches_on_the_mujoco_twin_too(husky_twin):
    """The MuJoCo twin takes the same derived launcher and the Husky's own wheels; its plate servo is looser than
    Bullet's velocity constraint (docs/engines.md), so the edge speed is checked within 25%, not 5%."""
    pytest.importorskip("mujoco")
    settings = dataclasses.replace(husky_twin, physics=dataclasses.replace(husky_twin.physics, engine="mujoco"))
    condition = LaunchCondition("baseline", 0.75, 0.8, 0.0)
    phases = []
    result = simulate_launch(condition, settings, 7, on_phase=phases.append)
    assert repr(simulate_launch(condition, settings, 7)) == repr(result)      # the cached model, reset per launch
    assert phases == ["fired", "in_flight", "settling", "classifying"] and result.settled and result.valid
    assert result.edge_speed_mps == pytest.approx(result.launch_speed_mps, rel=0.25)
    pybullet = simulate_launch(condition, husky_twin, 7)
    assert result.steps != pybullet.steps                                       # another engine ran it
    assert result.flight_time_s == pytest.approx(pybullet.flight_time_s, rel=0.2)
