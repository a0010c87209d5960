"""The launch twin's two engines model the same rig: analytic cases on the foam, and the bare robot's upright rate.

Each case puts the bare chassis on the twin's foam pad with a set velocity, in both engines, and compares what
happens with what physics says (docs/optimization.md, "The engines' disagreement on the bare robot").
"""
import math

import numpy as np
import pytest

pytest.importorskip("pybullet")
pytest.importorskip("mujoco")

from rollability_ros.core.sim.launch.placement import sized_for_robot  # noqa: E402
from rollability_ros.core.sim.launch.settings import load_launch_twin_settings  # noqa: E402

#: A simulated second of the chassis on the foam: its base velocity (m/s, world) per twin step.
ENGINES = ("pybullet", "mujoco")


def _settings(engine, **overrides):
    return sized_for_robot(load_launch_twin_settings(overrides={"physics.engine": engine, **overrides}))[0]


def _on_foam(engine, roll_deg, velocity, seconds, on_ledge=False, **overrides):
    """The bare chassis put on the foam pad at x = 1 m (``on_ledge``: on the launcher's base plate, 0.75 m above the
    foam, at x = -0.7 m) with its lowest point 0.5 mm above it, rolled by ``roll_deg``, given base ``velocity`` (3,)
    m/s and run for ``seconds``: its base velocity after every twin step, (n, 3)."""
    settings = _settings(engine, **overrides)
    foam_top = settings.twin.foam.thickness_m + (0.75 if on_ledge else 0.0)
    x_m = -0.7 if on_ledge else 1.0
    half = math.radians(roll_deg) / 2
    orientation = (math.sin(half), 0.0, 0.0, math.cos(half))
    steps = round(seconds / settings.physics.time_step_s)
    if engine == "pybullet":
        import pybullet

        from rollability_ros.core.sim.launch import pybullet_twin
        from rollability_ros.core.sim.world import connect, disconnect, set_contact

        client = connect()
        try:
            pybullet_twin.build_launch_world(client, settings, 0.75)
            robot = settings.robot_model().spawn(client, None, (1.0, 0.0, 1.0), orientation,
                                                 time_step_s=settings.physics.time_step_s, exact_cylinders=True)
            set_contact(client, robot.body_id, settings.physics.body_contact())
            pybullet_twin.apply_wheel_model(pybullet, client, robot, settings)
            pybullet_twin._place_on_plate(pybullet, client, robot, orientation, 0.0005, (x_m, 0.0), foam_top)
            pybullet.resetBaseVelocity(robot.body_id, list(velocity), [0.0, 0.0, 0.0], physicsClientId=client)
            out = []
            for _ in range(steps):
                robot.before_step()
                pybullet.stepSimulation(physicsClientId=client)
                out.append(pybullet.getBaseVelocity(robot.body_id, physicsClientId=client)[0])
        finally:
            disconnect(client)
        return np.asarray(out)
    import mujoco

    from rollability_ros.core.sim.launch import mujoco_twin

    twin = mujoco_twin.MujocoLaunchTwin(settings, None)
    twin.place(orientation, 0.0005, (x_m, 0.0), foam_top)
    if on_ledge:   # the ledge where a launch puts it (place() parks it out of the way)
        twin.data.mocap_pos[twin.ledge_mocap] = [-settings.twin.launcher.ledge_depth_m / 2, 0.0,
                                                 foam_top - mujoco_twin.LEDGE_HALF_HEIGHT_M]
        mujoco.mj_forward(twin.model, twin.data)
    twin.data.qvel[0:3] = velocity
    out = []
    for _ in range(steps):
        for _ in range(twin.substeps):
            mujoco.mj_step(twin.model, twin.data)
        out.append(twin.data.qvel[0:3].tolist())
    return np.asarray(out)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_chassis_landing_flat_on_the_foam_barely_rebounds(engine):
    """Memory foam barely rebounds (config/launch_twin.yaml: restitution 0.1 x the robot's 0.3): a chassis landing
    flat on its wheels at 4 m/s (a 0.8 m fall) leaves the foam at most 0.25 x its impact speed in either engine.
    MuJoCo's foam at one step of 1/240 s threw it back at 0.45 x (an under-resolved spring), PyBullet's at 0.05."""
    velocity = _on_foam(engine, 0.0, (0.0, 0.0, -4.0), 0.3)
    assert velocity[:, 2].max() / 4.0 < 0.25


def test_the_mujoco_twin_resolves_the_foam_spring_in_substeps():
    """The shipped foam on the chassis (omega dt 0.56 at 1/240 s) takes 2 substeps; a 4 x stiffer draw 4, a far
    stiffer one no more than FOAM_MAX_SUBSTEPS."""
    from rollability_ros.core.sim.launch import mujoco_twin

    dt = 1.0 / 240.0
    assert mujoco_twin.foam_substeps(2.0e4 / 1.1, dt) == 2
    assert mujoco_twin.foam_substeps(8.0e4 / 1.1, dt) == 4
    assert mujoco_twin.foam_substeps(1.0e7, dt) == mujoco_twin.FOAM_MAX_SUBSTEPS
    assert mujoco_twin.foam_substeps(100.0, dt) == 1


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("direction_deg", [0.0, 45.0])
def test_an_upside_down_chassis_slides_on_the_foam_at_its_friction_in_every_direction(engine, direction_deg):
    """An upside-down chassis sliding at 1 m/s on the foam decelerates at mu g, mu = the robot's 0.35 x the foam's
    1.0 (Bullet's product; the MuJoCo twin's foam carries it), within 10%, in both engines and whichever way it
    slides: Coulomb friction is isotropic (MuJoCo's default pyramidal cone gave 0.70 x mu g at 45 deg)."""
    settings = _settings(engine)
    mu = settings.physics.lateral_friction * settings.twin.foam.lateral_friction
    turn = math.radians(direction_deg)
    velocity = _on_foam(engine, 180.0, (math.cos(turn), math.sin(turn), 0.0), 0.25)
    dt = settings.physics.time_step_s
    speed = np.hypot(velocity[:, 0], velocity[:, 1])
    sliding = speed[(speed > 0.3) & (speed < 0.8)]   # settled on the foam, still sliding
    deceleration = -np.polyfit(np.arange(len(sliding)) * dt, sliding, 1)[0]
    assert deceleration == pytest.approx(mu * 9.81, rel=0.10)


@pytest.mark.parametrize("engine", ENGINES)
def test_the_chassis_coasts_on_the_launcher_at_its_wheels_resistance(engine):
    """After the stroke the chassis coasts on its unpowered Mecanum wheels: rolling friction (force
    ``wheel_rolling_friction`` / r x load) and each motor's drag torque / r slow it, against its mass plus the wheels'
    spin inertia (4 I / r^2); at 1.5 m/s the deceleration is within 10% of that in both engines (measured 0.1155
    and 0.1159 of 0.1155 m/s^2). Bullet's default
    damping of every multibody (zeroed on the twin's robot) made it 0.4 m/s^2 more."""
    settings = _settings(engine)
    robot, twin = settings.robot, settings.twin
    radius, mass = robot.wheel_radius_m, robot.body_mass_kg + 4 * robot.wheel_mass_kg
    spin_mass = 4 * (robot.wheel_mass_kg * radius ** 2 / 2) / radius ** 2
    expected = (twin.wheel_rolling_friction / radius * mass * 9.81 + 4 * twin.wheel_drag_torque_nm / radius) / \
        (mass + spin_mass)
    velocity = _on_foam(engine, 0.0, (1.5, 0.0, 0.0), 0.35, on_ledge=True)
    dt = settings.physics.time_step_s
    coasting = velocity[round(0.05 / dt):, 0]   # the wheels spun up
    deceleration = -np.polyfit(np.arange(len(coasting)) * dt, coasting, 1)[0]
    assert deceleration == pytest.approx(expected, rel=0.10)


@pytest.mark.parametrize("engine", ENGINES)
def test_the_chassis_rolls_on_the_foam_at_the_wheels_combined_rolling_friction(engine):
    """Rolling upright on the foam, each wheel meets Bullet's combination of its own values with the foam's:
    rolling friction wheel.rolling x foam.friction + foam.rolling x wheel.friction (0.0037 m shipped), plus the
    motors' drag; the deceleration is within 15% of that in both engines (measured 1.25 and 1.12 of 1.17 m/s^2).
    MuJoCo's foam geom gave the wheels the body's 0.0135 m (2.72 m/s^2) before each wheel had its own pair."""
    settings = _settings(engine)
    robot, twin, physics = settings.robot, settings.twin, settings.physics
    radius, mass = robot.wheel_radius_m, robot.body_mass_kg + 4 * robot.wheel_mass_kg
    rolling = twin.wheel_rolling_friction * twin.foam.lateral_friction + \
        twin.foam.rolling_friction * physics.lateral_friction
    expected = (rolling / radius * mass * 9.81 + 4 * twin.wheel_drag_torque_nm / radius) / \
        (mass + 4 * robot.wheel_mass_kg / 2)
    velocity = _on_foam(engine, 0.0, (0.7, 0.0, 0.0), 0.25)
    dt = physics.time_step_s
    rolling_on = velocity[round(0.05 / dt):, 0]
    deceleration = -np.polyfit(np.arange(len(rolling_on)) * dt, rolling_on, 1)[0]
    assert deceleration == pytest.approx(expected, rel=0.15)


@pytest.mark.slow
def test_both_engines_right_the_bare_robot_at_rates_within_tolerance():
    """The bare robot on the campaign's 20 conditions x 5 seeds (100 launches each engine, the same seeds): upright
    rates within 0.15 of each other (measured 400 launches: PyBullet 0.20, MuJoCo 0.27; before the fixes 0.18 vs
    0.49 on 100). The remaining difference is the robot-ledge restitution MuJoCo cannot represent."""
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.sim.launch.twin import simulate_valid_launch

    rates = {}
    for engine in ENGINES:
        settings = load_launch_twin_settings(overrides={"physics.engine": engine})
        upright = 0
        for height in (0.75, 1.30):
            for speed in (0.8, 1.5):
                for angle in (-60.0, -30.0, 0.0, 30.0, 60.0):
                    for k in range(5):
                        result = simulate_valid_launch(LaunchCondition("baseline", height, speed, angle), settings,
                                                       777021 + k)
                        upright += bool(result.valid and result.upright)
        rates[engine] = upright / 100
    assert abs(rates["pybullet"] - rates["mujoco"]) <= 0.15, rates
