"""The compliant profile mount: a spring-damper along the mount's normal, checked against its analytic
behaviour (static deflection, period, logarithmic decrement, end stops) in both engines, and used end to end
(trials, launches, a URDF robot, the parameter files)."""
import math

import numpy as np
import pytest

pybullet = pytest.importorskip("pybullet")
mujoco = pytest.importorskip("mujoco")

from rollability_ros.core.config import ConfigError, from_mapping  # noqa: E402
from rollability_ros.core.robots.robot import ChassisModel, ChassisSpec, ProfileBody, ProfileMountSpec  # noqa: E402
from rollability_ros.core.sim import world  # noqa: E402
from rollability_ros.core.sim.mujoco_trials import MujocoTrialWorld  # noqa: E402
from rollability_ros.core.sim.trials import TrialSettings, TrialWorld, place_on_ground  # noqa: E402

PROFILE_KG = 0.1
GRAVITY = 9.81
#: A box-shaped profile, 100 x 80 x 30 mm, its centre of mass at its middle.
PROFILE = ProfileBody(hull_vertices_m=np.array([[x, y, z] for x in (-0.05, 0.05) for y in (-0.04, 0.04)
                                                for z in (0.0, 0.03)]),
                      mass_kg=PROFILE_KG, com_m=np.array([0.0, 0.0, 0.015]),
                      inertia_kgm2=np.diag([PROFILE_KG / 12 * (b * b + c * c) for b, c in
                                            ((0.08, 0.03), (0.1, 0.03), (0.1, 0.08))]))


def chassis(stiffness, damping=0.0, travel=0.01):
    return ChassisModel(ChassisSpec(profile_mount=ProfileMountSpec(stiffness_npm=stiffness, damping_nspm=damping,
                                                                   travel_m=travel)))


def mount_trace(engine, model, steps=480):
    """The profile's displacement along the mount normal (m) after each step, the chassis set upright on the
    ground at rest with its spring unloaded."""
    physics = world.PhysicsParams()
    if engine == "pybullet":
        client = world.connect()
        try:
            world.reset_world(client, physics)
            robot = model.spawn(client, PROFILE, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 1.0), time_step_s=physics.time_step_s)
            place_on_ground(client, robot.body_id, (0.0, 0.0, 0.0, 1.0), 0.0)
            trace = []
            for _ in range(steps):
                robot.before_step()
                pybullet.stepSimulation(physicsClientId=client)
                trace.append(robot.mount_spring.position_m())
            return np.array(trace)
        finally:
            world.disconnect(client)
    trials = MujocoTrialWorld(model, PROFILE, TrialSettings(), physics)
    trials.place((0.0, 0.0, 0.0, 1.0), 0.0)
    address = trials.model.jnt_qposadr[trials.model.joint(model.profile_joint).id]
    trace = []
    for _ in range(steps):
        mujoco.mj_step(trials.model, trials.data)
        trace.append(float(trials.data.qpos[address]))
    return np.array(trace)


def upward_crossings(values):
    """Fractional step indices where ``values`` crosses zero upwards (linear interpolation)."""
    below = np.where((values[:-1] < 0) & (values[1:] >= 0))[0]
    return below + values[below] / (values[below] - values[below + 1])


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_loaded_spring_deflects_by_weight_over_stiffness(engine):
    stiffness = 2000.0
    trace = mount_trace(engine, chassis(stiffness, damping=5.0))
    expected = -PROFILE_KG * GRAVITY / stiffness  # -0.49 mm
    assert trace[-60:].mean() == pytest.approx(expected, rel=0.02)
    assert np.ptp(trace[-60:]) < 0.02 * abs(expected)  # at rest


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_the_free_oscillation_has_the_spring_mass_period(engine):
    stiffness = 500.0
    trace = mount_trace(engine, chassis(stiffness))
    crossings = upward_crossings(trace + PROFILE_KG * GRAVITY / stiffness)
    period_s = np.diff(crossings).mean() / 240.0
    # between the profile on a chassis held still and the two-body (reduced mass) period
    robot_kg = ChassisSpec().body_mass_kg + 4 * ChassisSpec().wheel_mass_kg
    reduced_kg = PROFILE_KG * robot_kg / (PROFILE_KG + robot_kg)
    assert 0.97 * 2 * math.pi * math.sqrt(reduced_kg / stiffness) < period_s \
        < 1.03 * 2 * math.pi * math.sqrt(PROFILE_KG / stiffness)
    assert len(crossings) >= 8


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_the_damper_gives_the_logarithmic_decrement(engine):
    stiffness, damping = 500.0, 0.5
    offset = trace = mount_trace(engine, chassis(stiffness, damping)) + PROFILE_KG * GRAVITY / stiffness
    peaks = [offset[i] for i in range(1, len(offset) - 1) if offset[i - 1] < offset[i] >= offset[i + 1] and
             offset[i] > 0]
    zeta = damping / (2 * math.sqrt(stiffness * PROFILE_KG))
    expected = math.exp(-2 * math.pi * zeta / math.sqrt(1 - zeta * zeta))  # amplitude ratio per period, 0.80
    measured = (peaks[5] / peaks[1]) ** (1 / 4)
    assert measured == pytest.approx(expected, abs=0.04)
    assert len(trace) == 480


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_the_end_stop_holds_a_spring_too_soft_for_the_load(engine):
    travel = 0.002
    trace = mount_trace(engine, chassis(100.0, damping=1.0, travel=travel))  # 9.8 mm of free deflection
    assert trace[-60:].mean() == pytest.approx(-travel, abs=0.0005)
    assert trace.min() > -travel - 0.001


def test_a_rigid_mount_is_a_fixed_joint_and_a_compliant_one_prismatic():
    rigid, compliant = ChassisModel(ChassisSpec()), chassis(2000.0, 5.0)
    assert 'type="fixed"' in rigid.simulator_urdf(PROFILE, "profile.obj")
    text = compliant.simulator_urdf(PROFILE, "profile.obj")
    assert 'name="profile_joint" type="prismatic"' in text and '<limit lower="-0.01" upper="0.01"' in text
    assert 'type="fixed"' in compliant.to_urdf("profile.stl", PROFILE)  # the exported design stays bolted on
    client = world.connect()
    try:
        physics = world.PhysicsParams()
        world.reset_world(client, physics)
        step = physics.time_step_s
        assert rigid.spawn(client, PROFILE, (0, 0, 1), (0, 0, 0, 1), time_step_s=step).mount_spring is None
        spawned = compliant.spawn(client, PROFILE, (0, 2, 1), (0, 0, 0, 1), time_step_s=step)
        info = pybullet.getJointInfo(spawned.body_id, spawned.mount_spring.joint, physicsClientId=client)
        assert info[2] == pybullet.JOINT_PRISMATIC and tuple(info[13]) == (0.0, 0.0, 1.0)  # along the normal
    finally:
        world.disconnect(client)


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_mount_too_stiff_for_the_time_step_is_refused_by_name(engine):
    model = chassis(1.0e6)  # 3,162 rad/s: 13 rad per 1/240 s step
    with pytest.raises(ValueError, match=r"profile_mount: stiffness 1e\+06 N/m .* lower them or sim.time_step_s"):
        mount_trace(engine, model, steps=1)


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_trials_on_a_compliant_mount_run_to_rest_without_the_early_decision(engine):
    settings = TrialSettings()
    physics = world.PhysicsParams(engine=engine)
    model = chassis(2000.0, 5.0)
    if engine == "mujoco":
        trials = MujocoTrialWorld(model, PROFILE, settings, physics)
        outcomes = [trials.run(i, 1000 + i) for i in range(6)]
    else:
        client = world.connect()
        try:
            trials = TrialWorld(client, model, PROFILE, settings, physics)
            outcomes = [trials.run(i, 1000 + i) for i in range(6)]
        finally:
            world.disconnect(client)
    assert trials.energy is None
    assert not any(outcome.decided for outcome in outcomes)
    assert all(outcome.settled for outcome in outcomes)


def test_the_mount_is_read_from_the_robot_parameters_and_checked():
    spec = from_mapping(ChassisSpec, {"profile_mount": {"stiffness_npm": 3000.0, "damping_nspm": 4.0}}, "robot")
    assert spec.profile_mount.compliant and spec.profile_mount.travel_m == 0.005
    assert not ChassisSpec().profile_mount.compliant
    with pytest.raises(ConfigError, match=r"^robot.profile_mount.stiffness_npm out of range: -1.0 is not in \[0.0, "):
        from_mapping(ChassisSpec, {"profile_mount": {"stiffness_npm": -1.0}}, "robot")
    with pytest.raises(ConfigError, match=r"^robot.profile_mount.travel_m out of range: 0.0 is not in \(0.0, 1.0\]$"):
        from_mapping(ChassisSpec, {"profile_mount": {"travel_m": 0.0}}, "robot")


def test_a_launch_on_a_compliant_mount_is_a_valid_launch_that_differs_from_the_rigid_one():
    import dataclasses

    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.sim.launch.settings import load_launch_twin_settings
    from rollability_ros.core.sim.launch.twin import simulate_launch

    rigid = load_launch_twin_settings(overrides={"twin.speed_sigma_fraction": 0.0, "twin.angle_sigma_deg": 0.0})
    compliant = dataclasses.replace(rigid, robot=dataclasses.replace(rigid.robot, profile_mount=ProfileMountSpec(
        stiffness_npm=2000.0, damping_nspm=5.0, travel_m=0.01)))
    condition = LaunchCondition("candidate", 1.3, 1.5, 30.0)
    results = [simulate_launch(condition, settings, 7, profile=PROFILE, use_profile=True)
               for settings in (rigid, compliant)]
    assert all(result.valid for result in results), [result.invalid_reason for result in results]
    assert results[0].final_orientation_xyzw != results[1].final_orientation_xyzw
    assert results[1].edge_speed_mps == pytest.approx(1.5, rel=0.05)  # the plate still launches at the target


def test_the_spawn_checks_the_mount_against_the_time_step_it_is_given_not_the_engines():
    """The step flows down from the settings (issue 29): the stiff mount that 1/240 s refuses passes at 10 us,
    in the same world, and a world never stepped (geometry only, ``None``) checks nothing."""
    model = chassis(1.0e6)
    client = world.connect()
    try:
        physics = world.PhysicsParams()
        world.reset_world(client, physics)
        with pytest.raises(ValueError, match="lower them or sim.time_step_s"):
            model.spawn(client, PROFILE, (0, 0, 1), (0, 0, 0, 1), time_step_s=physics.time_step_s)
        assert model.spawn(client, PROFILE, (0, 2, 1), (0, 0, 0, 1), time_step_s=1e-5).mount_spring is not None
        assert model.spawn(client, PROFILE, (0, 4, 1), (0, 0, 0, 1), time_step_s=None).mount_spring is not None
    finally:
        world.disconnect(client)
