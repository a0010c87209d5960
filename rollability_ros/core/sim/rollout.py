"""The roll-out of the characterisation protocol (docs/characterisation.md) simulated in the launch twin's world.

The bench measurement: the bare robot stands on its wheels on a surface, is pushed straight ahead to about
``speed_mps`` and let go; the distance it rolls until it stops is read off a tape. On the foam it measures the
wheel-on-foam resistance (the foam's rolling friction together with the wheels' back-drive drag); on the hard
launcher plate or table (``surface: floor``) the drag nearly alone, because a wheel on a hard surface barely
rolls in.

Model (PyBullet, the launch twin's world of :func:`~rollability_ros.core.sim.launch.pybullet_twin.build_launch_world` at
ledge height 0 and its wheels, :func:`~rollability_ros.core.sim.launch.pybullet_twin.apply_wheel_model`): the robot is set
on its wheels on the foam (x = 0.3 m, centred) or on the floor beside it (the floor carries the ground contact
of ``config/sim.yaml``, as the launcher's plate), settles for :data:`SETTLE_S`, then gets the forward velocity
``speed_mps`` along +x with every wheel turning at ``speed_mps / radius`` (rolling, no slip: a hand push rolls
the wheels up to speed). It runs until its base moves slower than :data:`REST_SPEED_MPS` for :data:`REST_HOLD_S`
or :data:`MAX_TIME_S` pass; the distance is the base origin's travel in the plane from the moment it is let go.
The MuJoCo twin has no roll-out model: a setting asking for it is refused (:func:`rollout_distance_m`).
"""
import math

from rollability_ros.core.optional import require
from rollability_ros.core.sim.launch.pybullet_twin import apply_wheel_model, build_launch_world
from rollability_ros.core.sim.launch.settings import LaunchTwinSettings
from rollability_ros.core.sim.trials import place_on_ground
from rollability_ros.core.sim.world import connect, disconnect, set_contact

#: Surfaces of a roll-out: the foam pad, or the hard floor (the launcher's plate and table carry the same contact).
SURFACES = ("foam", "floor")
#: s the robot stands on its wheels before the push (sinks into the foam).
SETTLE_S = 0.3
#: m/s below which the base counts as stopped, held for REST_HOLD_S.
REST_SPEED_MPS = 0.005
REST_HOLD_S = 0.2
#: s, longest roll-out simulated (a robot still rolling then gives the distance so far).
MAX_TIME_S = 12.0
#: m, where the roll-out starts on the foam (x from its near edge) or beside it on the floor (y beyond its side).
START_ON_FOAM_M = 0.3
BESIDE_FOAM_M = 1.0


def rollout_distance_m(settings: LaunchTwinSettings, speed_mps: float, surface: str = "foam") -> float:
    """The distance (m) the bare robot of the twin ``settings`` rolls on ``surface`` (:data:`SURFACES`) after a
    push to ``speed_mps`` (module docstring). Deterministic (no random draw). ``ValueError`` for a bad speed or
    surface, or a twin on an engine without a roll-out model (MuJoCo)."""
    from rollability_ros.core.sim.launch.pybullet_twin import BulletLaunch
    from rollability_ros.core.sim.engines import LAUNCH_ENGINES

    if LAUNCH_ENGINES.get(settings.physics.engine) is not BulletLaunch:
        raise ValueError(f"the characterisation roll-out is modelled in the PyBullet twin only; sim.engine is "
                         f"{settings.physics.engine!r}: calibrate with sim.engine pybullet")
    if surface not in SURFACES:
        raise ValueError(f"roll-out surface must be one of {', '.join(SURFACES)}, got {surface!r}")
    if not (math.isfinite(speed_mps) and 0 < speed_mps <= 5):
        raise ValueError(f"roll-out speed must be in (0, 5] m/s, got {speed_mps}")
    pybullet = require("pybullet", feature="the characterisation roll-out")
    foam = settings.twin.foam
    model = settings.robot_model()
    client = connect()
    try:
        build_launch_world(client, settings, 0.0)
        robot = model.spawn(client, None, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0, 1.0),
                            time_step_s=settings.physics.time_step_s, exact_cylinders=True)   # as the launch twin
        set_contact(client, robot.body_id, settings.physics.body_contact())
        apply_wheel_model(pybullet, client, robot, settings)
        on_foam = surface == "foam"
        xy = (START_ON_FOAM_M, 0.0) if on_foam else (START_ON_FOAM_M, foam.width_m / 2 + BESIDE_FOAM_M)
        place_on_ground(client, robot.body_id, (0.0, 0.0, 0.0, 1.0), 0.0005, xy,
                        foam.thickness_m if on_foam else 0.0)
        dt = settings.physics.time_step_s
        for _ in range(int(round(SETTLE_S / dt))):
            pybullet.stepSimulation(physicsClientId=client)
        start = pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)[0]
        pybullet.resetBaseVelocity(robot.body_id, [speed_mps, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=client)
        for link, radius in zip(robot.wheel_links, model.wheel_radii_m()):
            axis = pybullet.getJointInfo(robot.body_id, link, physicsClientId=client)[13]
            spin = speed_mps / radius
            # forward rolling about the wheel's axle: the sign that turns +x motion into rolling about the axis
            sign = -1.0 if axis[1] < 0 else 1.0
            pybullet.resetJointState(robot.body_id, link, pybullet.getJointState(
                robot.body_id, link, physicsClientId=client)[0], targetVelocity=sign * spin, physicsClientId=client)
        still_s = 0.0
        for _ in range(int(round(MAX_TIME_S / dt))):
            pybullet.stepSimulation(physicsClientId=client)
            velocity = pybullet.getBaseVelocity(robot.body_id, physicsClientId=client)[0]
            still_s = still_s + dt if math.hypot(velocity[0], velocity[1]) < REST_SPEED_MPS else 0.0
            if still_s >= REST_HOLD_S:
                break
        end = pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)[0]
    finally:
        disconnect(client)
    return float(math.hypot(end[0] - start[0], end[1] - start[1]))
