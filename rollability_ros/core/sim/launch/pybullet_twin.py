"""The launch twin in PyBullet (``sim.engine: pybullet``, the paper's engine): each launch in a fresh PyBullet
DIRECT world built as :mod:`rollability_ros.core.sim.launch` describes ("World", "Contact", "Wheels"), run through
the engine-neutral :func:`~rollability_ros.core.sim.launch.loop.step_launch`."""
import hashlib
import math
import pickle
import types
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core.optional import require
from rollability_ros.core.records import LaunchCondition
from rollability_ros.core.robots import ProfileBody, RobotModel, SpawnedRobot
from rollability_ros.core.sim.launch.contract import LaunchDrive, LaunchEngine, LaunchWorld
from rollability_ros.core.sim.launch.decision import decided_on_foam, foam_sink_m, hopeless_to_decide
from rollability_ros.core.sim.launch.drive import launch_drive
from rollability_ros.core.sim.launch.loop import LaunchTracker, PhaseReporter, launch_result, rig_verdict, step_launch
from rollability_ros.core.sim.launch.placement import check_fits_launcher, launch_plan, launcher_start_xy, plate_placement
from rollability_ros.core.sim.launch.results import LaunchResult, PhaseCallback, PoseCallback
from rollability_ros.core.sim.launch.settings import (LaunchTwinSettings, PushPlateSpec, mecanum_wheels,
                                                      wheel_rolling_friction_m)
from rollability_ros.core.sim.trials import EnergyMonitor, RestDetector, place_on_ground
from rollability_ros.core.sim.world import connect, disconnect, reset_world, set_contact


def _static_box(pybullet, client, half_extents, centre, contact):
    shape = pybullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=list(half_extents), physicsClientId=client)
    body = pybullet.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=shape, basePosition=list(centre),
                                    physicsClientId=client)
    set_contact(client, body, contact)
    return body

def build_launch_world(client: int, settings: LaunchTwinSettings, height_m: float) -> typing.Tuple[int, int, int]:
    """Empty ``client``'s world and build floor, foam and ledge (package docstring); return
    ``(foam_id, ledge_id, floor_id)``."""
    pybullet = require("pybullet", feature="the launch twin")
    physics, foam, launcher = settings.physics, settings.twin.foam, settings.twin.launcher
    floor_id = reset_world(client, physics)
    foam_id = _static_box(pybullet, client, (foam.length_m / 2, foam.width_m / 2, foam.thickness_m / 2),
                          (foam.length_m / 2, 0.0, foam.thickness_m / 2), foam.contact(physics.ground_contact()))
    top = foam.thickness_m + height_m
    ledge_id = _static_box(pybullet, client, (launcher.ledge_depth_m / 2, launcher.ledge_width_m / 2, top / 2),
                           (-launcher.ledge_depth_m / 2, 0.0, top / 2), ledge_contact(settings))
    return foam_id, ledge_id, floor_id

def ledge_contact(settings: LaunchTwinSettings) -> typing.Dict[str, float]:
    """The launcher base plate's ``changeDynamics`` keywords: the ground contact of ``config/sim.yaml`` with
    ``launcher.ledge_rolling_friction`` added to its own rolling friction (the coast's unknown resistance). Under a
    robot's own wheels the ground's own rolling friction (``per_body``: ``sim.rolling_friction``) is left out: their
    rolling resistance is ``wheel_rolling_resistance`` (:func:`~.settings.wheel_rolling_friction_m`)."""
    contact = dict(settings.physics.ground_contact())
    ground = contact.get("rollingFriction", 0.0) if mecanum_wheels(settings) else 0.0
    contact["rollingFriction"] = ground + settings.twin.launcher.ledge_rolling_friction
    return contact

def wheel_side_m(pybullet: types.ModuleType, client: int, robot: SpawnedRobot, link: int) -> float:
    """Where wheel ``link`` sits across the robot: its y in the base frame (m; + = left)."""
    base_position, base_orientation = pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)
    link_position = pybullet.getLinkState(robot.body_id, link, physicsClientId=client)[4]
    inverse_position, inverse_orientation = pybullet.invertTransform(base_position, base_orientation)
    return pybullet.multiplyTransforms(inverse_position, inverse_orientation, link_position, (0, 0, 0, 1))[0][1]

def _set_wheels(pybullet, client, robot, options, lateral_friction, mecanum, rolling_m):
    """Give the wheel links the left / right friction factors (of the robot's ``lateral_friction``), each its own
    rolling friction ``rolling_m`` (m, one per wheel: :func:`~.settings.wheel_rolling_friction_m`) and, with
    ``mecanum``, the twin's Mecanum side friction and motor drag; without it the wheels keep the robot's own joint
    drag (the trials')."""
    for link, rolling in zip(robot.wheel_links, rolling_m):
        left = wheel_side_m(pybullet, client, robot, link) >= 0.0
        side_factor = options.wheel_friction_left_factor if left else options.wheel_friction_right_factor
        pybullet.changeDynamics(robot.body_id, link, lateralFriction=lateral_friction * side_factor,
                                rollingFriction=rolling, physicsClientId=client)
        if mecanum:
            axis = pybullet.getJointInfo(robot.body_id, link, physicsClientId=client)[13]
            factors = [1.0 - (1.0 - options.wheel_side_friction_factor) * abs(a) for a in axis]  # a link unit axis
            pybullet.changeDynamics(robot.body_id, link, anisotropicFriction=factors, physicsClientId=client)
    if not mecanum:
        return
    pybullet.setJointMotorControlArray(robot.body_id, list(robot.wheel_links), pybullet.VELOCITY_CONTROL,
                                       targetVelocities=[0.0] * len(robot.wheel_links),
                                       forces=[options.wheel_drag_torque_nm] * len(robot.wheel_links),
                                       physicsClientId=client)

def apply_wheel_model(pybullet: types.ModuleType, client: int, robot: SpawnedRobot,
                      settings: LaunchTwinSettings, model: typing.Optional[RobotModel] = None) -> None:
    """The twin's wheel contact and drag (package docstring, "Wheels") on ``robot``'s wheel links (``model``: the
    robot model that spawned it, default ``settings.robot_model()``): every PyBullet model of the twin's rig (the
    launch, the characterisation roll-out) uses this one."""
    mecanum = mecanum_wheels(settings)
    radii = (0.0,) * len(robot.wheel_links) if mecanum else (model or settings.robot_model()).wheel_radii_m()
    _set_wheels(pybullet, client, robot, settings.twin, settings.physics.lateral_friction, mecanum,
                wheel_rolling_friction_m(settings, radii))
    # Bullet damps every multibody by default (force m v (0.04 + 0.04 |v|) on each link, the same for rotation): no
    # source on the rig (air drag on the chassis is ~1e-3 of that) and not in MuJoCo; it slowed the spinning wheels
    # (4.6 x their drag torque at 1.5 m/s) and the flight's rotation (13% in 0.4 s at 10 rad/s)
    pybullet.changeDynamics(robot.body_id, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=client)

def _corners_m(pybullet, client, robot):
    """Points bounding ``robot`` (a SpawnedRobot) in the world: the corners of each link's world bounding box, and
    the profile's hull vertices placed exactly (Bullet's box of a mesh link on rotated inertial axes is up to
    twice the mesh's size); (n, 3) array (m)."""
    body_id = robot.body_id
    corners = []
    for link in range(-1, pybullet.getNumJoints(body_id, physicsClientId=client)):
        if link == robot.profile_link and robot.profile_points_m is not None:
            position, orientation = pybullet.getLinkState(body_id, link, physicsClientId=client)[4:6]
            rotation = np.asarray(pybullet.getMatrixFromQuaternion(orientation)).reshape(3, 3)
            corners.extend((np.asarray(robot.profile_points_m) @ rotation.T + position).tolist())
            continue
        low, high = pybullet.getAABB(body_id, link, physicsClientId=client)
        corners.extend([(x, y, z) for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])
    return np.asarray(corners, dtype=np.float64)

def _bounds_m(pybullet, client, robot):
    """The world bounding box of ``robot`` (a SpawnedRobot) from :func:`_corners_m`: ``(low (3,), high (3,))`` (m)."""
    corners = _corners_m(pybullet, client, robot)
    return corners.min(axis=0), corners.max(axis=0)

def _place_on_plate(pybullet, client, robot, orientation, clearance_m, xy_m, plate_z):
    """:func:`place_on_ground` on the launcher's top, then lowered so the lowest of :func:`_corners_m` (not of
    Bullet's looser box of a profile mesh) is ``clearance_m`` above it."""
    place_on_ground(client, robot.body_id, orientation, clearance_m, xy_m, plate_z)
    position = list(pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)[0])
    position[2] += plate_z + clearance_m - float(_bounds_m(pybullet, client, robot)[0][2])
    pybullet.resetBasePositionAndOrientation(robot.body_id, position, orientation, physicsClientId=client)

#: How far (m) Bullet's link boxes may overstate the robot's extent (below, ahead) before the placement uses the
#: extent Bullet's contact sees (:func:`_foremost_x`, :func:`rest_on_ledge`): the twin places to the millimetre (the
#: plate starts 1 mm behind the robot). Boxes are loose by centimetres on a compound link on turned inertial axes (a
#: URDF body merged from several links with products of inertia: 47 mm below and 34 mm ahead on the TurtleBot3
#: Waffle, 58 mm ahead on the Burger) and by a convex mesh's margin (2 mm on the Husky); the built-in chassis's
#: boxes and cylinders are within 0.4 mm (measured at 0, 30 and 60 deg), so it is placed as before.
PLACE_TOLERANCE_M = 0.001

def rest_on_ledge(pybullet: types.ModuleType, client: int, robot: SpawnedRobot, ledge_id: int,
                  clearance_m: float) -> float:
    """Move ``robot`` (placed over the ledge) straight down or up so that its nearest point is ``clearance_m`` above
    the ledge ``ledge_id`` as Bullet's contact sees it (closest points: the shapes with their collision margins),
    unless it is there within :data:`PLACE_TOLERANCE_M`; return the shift (m, + = down). A robot placed by loose
    link boxes otherwise starts in the air and falls onto the ledge as the plate moves (the TurtleBot3 Waffle,
    47 mm up, landed on the plate and was never launched)."""
    gaps = [point[8] for point in pybullet.getClosestPoints(robot.body_id, ledge_id, 1.0, physicsClientId=client)]
    shift_m = min(gaps) - clearance_m if gaps else 0.0
    if abs(shift_m) <= PLACE_TOLERANCE_M:
        return 0.0
    position, orientation = pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)
    pybullet.resetBasePositionAndOrientation(robot.body_id, [position[0], position[1], position[2] - shift_m],
                                             orientation, physicsClientId=client)
    return shift_m

def _foremost_x(pybullet, client, robot, box_front_x):
    """The largest world x of ``robot``'s collision shapes as Bullet's contact sees them (m), given the front of its
    link boxes ``box_front_x``: from the closest points to a probe shape facing it (a shape only: no body joins the
    world; it goes with the launch's world), or ``box_front_x`` when that is within :data:`PLACE_TOLERANCE_M`."""
    half_m = 0.5
    probe = pybullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=[half_m, 100.0, 100.0], physicsClientId=client)
    face_x = box_front_x + half_m
    points = pybullet.getClosestPoints(robot.body_id, -1, 2 * half_m, collisionShapeB=probe,
                                       collisionShapePositionB=[face_x + half_m, 0.0, 0.0], physicsClientId=client)
    exact_x = face_x - min(point[8] for point in points) if points else box_front_x
    return exact_x if abs(exact_x - box_front_x) > PLACE_TOLERANCE_M else box_front_x

def place_on_launcher(pybullet: types.ModuleType, client: int, robot: SpawnedRobot, orientation: typing.Sequence[float],
                      push: npt.ArrayLike, settings: LaunchTwinSettings, height_m: float, ledge_id: int) -> float:
    """Put the chassis at rest on the plate so that its foremost point (:func:`_foremost_x`) reaches the edge after
    ``run_length_m`` along ``push`` (unit (3,)); the base origin's path passes through the edge's midpoint; its
    nearest point ``start_clearance_m`` above the ledge ``ledge_id`` (:func:`rest_on_ledge`). Return the foremost
    point's offset ahead of the base origin along x (m).

    Raises ``ValueError`` when the robot placed there is not wholly over the ledge (``ledge_depth_m`` behind the
    edge, ``ledge_width_m`` along it): a robot too large for the configured launcher.
    """
    launcher = settings.twin.launcher
    plate_z = settings.twin.foam.thickness_m + height_m
    _place_on_plate(pybullet, client, robot, orientation, launcher.start_clearance_m, (0.0, 0.0), plate_z)
    base_x = pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)[0][0]
    lead_m = _foremost_x(pybullet, client, robot, float(_bounds_m(pybullet, client, robot)[1][0])) - base_x
    _place_on_plate(pybullet, client, robot, orientation, launcher.start_clearance_m,
                    launcher_start_xy(lead_m, push, launcher), plate_z)
    low, high = _bounds_m(pybullet, client, robot)
    check_fits_launcher(low, high, launcher)
    rest_on_ledge(pybullet, client, robot, ledge_id, launcher.start_clearance_m)
    return lead_m

class PushPlate:
    """The push plate on its prismatic joint: placed behind the chassis, driven at the launch speed along the push
    until the chassis goes over the edge (or the plate reaches it), then braked (package docstring, "Launch")."""

    def __init__(self, pybullet: types.ModuleType, client: int, robot: SpawnedRobot, push: npt.ArrayLike,
                 spec: PushPlateSpec, plate_z: float, ignore_bodies: typing.Iterable[int]) -> None:
        self._pybullet, self._client, self.spec = pybullet, client, spec
        self.push = np.asarray(push, dtype=np.float64)
        corners = _corners_m(pybullet, client, robot)
        base = np.asarray(pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)[0])
        placement = plate_placement(float((corners @ self.push).min()), base, self.push, spec, plate_z)
        shape = pybullet.createCollisionShape(
            pybullet.GEOM_BOX, halfExtents=[spec.thickness_m / 2, spec.width_m / 2, spec.height_m / 2],
            collisionFrameOrientation=pybullet.getQuaternionFromEuler([0.0, 0.0, placement.bias_rad]),
            physicsClientId=client)
        self.body_id = pybullet.createMultiBody(
            baseMass=0.0, basePosition=list(placement.centre_m),
            baseOrientation=pybullet.getQuaternionFromEuler([0, 0, placement.yaw_rad]),
            linkMasses=[spec.mass_kg], linkCollisionShapeIndices=[shape], linkVisualShapeIndices=[-1],
            linkPositions=[[0, 0, 0]], linkOrientations=[[0, 0, 0, 1]], linkInertialFramePositions=[[0, 0, 0]],
            linkInertialFrameOrientations=[[0, 0, 0, 1]], linkParentIndices=[0],
            linkJointTypes=[pybullet.JOINT_PRISMATIC], linkJointAxis=[[1, 0, 0]], physicsClientId=client)
        pybullet.changeDynamics(self.body_id, 0, lateralFriction=0.3, linearDamping=0.0, physicsClientId=client)
        for other in ignore_bodies:
            pybullet.setCollisionFilterPair(self.body_id, other, 0, -1, 0, physicsClientId=client)
        self.face_x_m = placement.face_x_m
        # bounding boxes of turned links overstate the rear: close the rest of the gap to 1 mm along the push
        gaps = [point[8] for point in pybullet.getClosestPoints(self.body_id, robot.body_id, 1.0, linkIndexA=0,
                                                                  physicsClientId=client)]
        self.start_m = max(0.0, min(gaps) - 0.001) if gaps else 0.0
        pybullet.resetJointState(self.body_id, 0, self.start_m, 0.0, physicsClientId=client)
        self.driving = False
        self._at_speed = False

    def drive(self, speed_mps: float, time_s: float) -> None:
        """Drive the plate along the push at ``time_s`` after the fire: its speed ramps from rest to ``speed_mps``
        over ``ramp_s``, then holds, with at most ``max_force_n``."""
        if self._at_speed:
            return
        target_mps = speed_mps * min(1.0, time_s / self.spec.ramp_s)
        self._pybullet.setJointMotorControl2(self.body_id, 0, self._pybullet.VELOCITY_CONTROL,
                                             targetVelocity=target_mps, force=self.spec.max_force_n,
                                             physicsClientId=self._client)
        self._at_speed = time_s >= self.spec.ramp_s
        self.driving = True

    def reached_edge(self) -> bool:
        """True once the plate's face has reached the edge line x = 0."""
        travel_m = self._pybullet.getJointState(self.body_id, 0, physicsClientId=self._client)[0]
        return bool(self.face_x_m + travel_m * self.push[0] >= 0.0)

    def travel_m(self) -> float:
        """How far the plate has moved along the push from its start (m)."""
        return float(self._pybullet.getJointState(self.body_id, 0, physicsClientId=self._client)[0]) - self.start_m

    def stop(self) -> None:
        """Brake the plate to rest (the cylinder at the end of its push)."""
        self._pybullet.setJointMotorControl2(self.body_id, 0, self._pybullet.VELOCITY_CONTROL, targetVelocity=0.0,
                                             force=self.spec.max_force_n * 10, physicsClientId=self._client)
        self.driving = False

class _BulletLaunchWorld(LaunchWorld):
    """:class:`LaunchWorld` of one PyBullet client holding the twin's bodies and the spawned robot."""

    def __init__(self, pybullet: types.ModuleType, client: int, robot: SpawnedRobot, foam_id: int, floor_id: int,
                 settings: LaunchTwinSettings, profile: typing.Optional[ProfileBody]) -> None:
        self._pybullet, self._client, self._robot = pybullet, client, robot
        self._body, self._foam, self._floor = robot.body_id, foam_id, floor_id
        self._rest = RestDetector(settings.trial, settings.physics.time_step_s)
        self._settings, self._profile = settings, profile
        self._energy: typing.Optional[EnergyMonitor] = None

    def pose(self) -> typing.Tuple[typing.Sequence[float], typing.Sequence[float]]:
        return self._pybullet.getBasePositionAndOrientation(self._body, physicsClientId=self._client)

    def velocity(self) -> typing.Sequence[float]:
        return self._pybullet.getBaseVelocity(self._body, physicsClientId=self._client)[0]

    def touching(self) -> typing.Tuple[bool, bool]:
        contacts, client = self._pybullet.getContactPoints, self._client
        if contacts(bodyA=self._body, bodyB=self._foam, physicsClientId=client):
            return True, False   # the tracker reads the floor only when the foam is not touched
        return False, bool(contacts(bodyA=self._body, bodyB=self._floor, physicsClientId=client))

    def step(self) -> None:
        self._robot.before_step()
        self._pybullet.stepSimulation(physicsClientId=self._client)

    def settled(self, steps: int) -> bool:
        return self._rest.settled(self._client, self._body, steps)

    def decide(self, remaining_s: float) -> typing.Optional[bool]:
        if self._energy is None:
            if not self._settings.trial.early_decision or self._robot.mount_spring is not None:
                return None   # the barriers hold for a rigid hull only, as in the trials
            self._energy = _bullet_energy_monitor(self._pybullet, self._client, self._robot, self._settings,
                                                  self._profile)
        com_xy_m = self._energy.com_xy_m()
        if hopeless_to_decide(com_xy_m, math.hypot(*self.velocity()), self._energy.radius_m, self._settings,
                              remaining_s):
            return None
        return decided_on_foam(self._energy, com_xy_m, self._settings, remaining_s)

#: Energy barriers and geometry of the early decision per robot + profile (the PyBullet twin spawns per launch).
_BASINS: typing.Dict[str, typing.Any] = {}

def _bullet_energy_monitor(pybullet, client, robot, settings, profile):
    """The early decision's :class:`~rollability_ros.core.sim.trials.EnergyMonitor` of a launched robot, its
    barriers on the foam top, lowered by :func:`foam_sink_m` (the map reused per robot + profile)."""
    model = settings.robot_model()
    key = hashlib.sha256(pickle.dumps((settings.robot, settings.urdf_robot, settings.physics, settings.trial,
                                       settings.twin.foam, profile), protocol=4)).hexdigest()
    mass_kg = sum(pybullet.getDynamicsInfo(robot.body_id, link, physicsClientId=client)[0]
                  for link in range(-1, pybullet.getNumJoints(robot.body_id, physicsClientId=client)))
    margin_m = settings.trial.early_decision_margin_m + foam_sink_m(settings, mass_kg)
    monitor = EnergyMonitor(client, model, robot, settings.physics.gravity_mps2, margin_m,
                            ground_z_m=settings.twin.foam.thickness_m, basins=_BASINS.get(key))
    _BASINS[key] = monitor.basins
    while len(_BASINS) > 8:
        del _BASINS[next(iter(_BASINS))]
    return monitor

class BulletLaunch(LaunchEngine):
    """``sim.engine: pybullet``: each launch in a fresh PyBullet world (:func:`simulate_launch`)."""

    @classmethod
    def simulate(cls, condition: LaunchCondition, settings: LaunchTwinSettings, seed: int,
                 profile: typing.Optional[ProfileBody], on_phase: typing.Optional[PhaseCallback] = None,
                 on_pose: typing.Optional[PoseCallback] = None, *,
                 drive: "typing.Optional[LaunchDrive]" = None,
                 until_edge: bool = False) -> LaunchResult:
        """One launch of the sized twin ``settings`` carrying ``profile`` with the cylinder's ``drive`` (see
        :func:`simulate_launch`; None: :func:`launch_drive` of the condition's speed); ``until_edge``: stop once the
        foremost point crosses the edge (the speed solve)."""
        options = settings.twin
        drive = drive or launch_drive(settings, condition.speed_mps)
        pybullet = require("pybullet", feature="the launch twin")
        speed_mps, angle_deg, push = launch_plan(condition, seed, options)
        angle = math.radians(angle_deg)
        model = settings.robot_model()
        client = connect()
        try:
            foam_id, ledge_id, floor_id = build_launch_world(client, settings, condition.height_m)
            orientation = pybullet.getQuaternionFromEuler([0.0, 0.0, angle])
            robot = model.spawn(client, profile, (0.0, 0.0, 5.0), orientation,
                                time_step_s=settings.physics.time_step_s, exact_cylinders=True)
            set_contact(client, robot.body_id, settings.physics.body_contact())
            apply_wheel_model(pybullet, client, robot, settings, model)
            lead_m = place_on_launcher(pybullet, client, robot, orientation, push, settings, condition.height_m,
                                       ledge_id)
            plate = PushPlate(pybullet, client, robot, push, drive.plate_spec(options.plate),
                              options.foam.thickness_m + condition.height_m, (floor_id, foam_id, ledge_id))
            world = _BulletLaunchWorld(pybullet, client, robot, foam_id, floor_id, settings, profile)
            tracker = LaunchTracker(world, lead_m, PhaseReporter(on_phase), push)
            steps, settled, decision = step_launch(world, plate, tracker, settings, on_pose,
                                                   drive.plate_speed_mps(speed_mps), drive.stroke_m, until_edge)
            tilt = model.tilt_deg(client, robot)
            if decision is None:
                upright = rig_verdict(tilt, wheels_down(pybullet, client, robot, model, (foam_id, floor_id, ledge_id)),
                                      model)
            else:
                upright = decision
            position, orientation = pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)
        finally:
            disconnect(client)
        return launch_result(tracker, settings, (steps, settled, decision), (upright, tilt, orientation),
                             (speed_mps, angle_deg), seed, position, drive.plate_speed_mps(speed_mps))

def wheels_down(pybullet: types.ModuleType, client: int, robot: SpawnedRobot, model: RobotModel,
                surfaces: typing.Iterable[int]) -> int:
    """How many of ``robot``'s wheel links are within the model's ``contact_tolerance_m`` of any of the bodies
    ``surfaces`` (the twin's pad, floor and ledge): the wheels it stands on, wherever (:func:`rig_verdict`)."""
    surfaces = tuple(surfaces)
    return sum(any(pybullet.getClosestPoints(robot.body_id, surface, model.contact_tolerance_m, linkIndexA=link,
                                             physicsClientId=client) for surface in surfaces)
               for link in robot.wheel_links)
