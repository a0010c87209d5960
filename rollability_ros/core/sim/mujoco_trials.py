"""The disturbance trial of :mod:`rollability_ros.core.sim.trials` in MuJoCo (``sim.engine: mujoco``).

Same trial semantics as the PyBullet :class:`~rollability_ros.core.sim.pybullet_trials.TrialWorld`, behind the same
interface (``run(index, seed) -> TrialOutcome``): start state and disturbance from
:func:`~rollability_ros.core.sim.trials.sample_conditions`, placement with the lowest point ``drop_height_m``
above the ground, the push as a world-frame force and torque at the base's centre of mass, the rest rule of
:class:`~rollability_ros.core.sim.trials.RestDetector` (speeds of the root body), the upright test (tilt of the
root frame's up axis, wheels within ``contact_tolerance_m`` of the ground) and the early decision. The rest rule
reads the root's mean speeds over each check interval from its poses (see :func:`pose_speeds`).

The robot is the URDF PyBullet loads too (:meth:`RobotModel.simulator_urdf`, profile hull as an OBJ mesh geom), compiled by
MuJoCo (fixed links fused into their parent) with a free joint on its root link.

Contact values (how ``config/sim.yaml``'s numbers map; MuJoCo combines two geoms by taking the larger value)
    the robot's geoms get the *effective* robot-ground values under ``contact_model`` (per_contact: as
    configured; per_body: Bullet's products, friction mu^2, rolling and spinning 2 r mu, restitution e^2) as
    MuJoCo's (sliding, torsional, rolling) friction with ``condim`` 6, and the ground gets zeros, so the
    contact has exactly those values. MuJoCo has no restitution coefficient: a contact is a damped spring.
    Restitution is NOT represented: the spring is critically damped (see ``CONTACT_SOLREF``; an underdamped
    spring that would bounce back with e = 0.3 never came to rest), so MuJoCo trials do not bounce. This is a
    known difference between the engines, which ``rollability evaluate --engines`` measures.
    An unpowered wheel drive's drag torque becomes the joint's ``frictionloss`` (N m).
"""
import math
import types
import typing

import numpy as np

from rollability_ros.core.optional import require
from rollability_ros.core.sim.trial_engine import TrialEngine, TrialOutcome
from rollability_ros.core.sim.trials import RestDetector, TrialSettings, sample_conditions
from rollability_ros.core.sim.world import PhysicsParams

if typing.TYPE_CHECKING:  # annotations only
    from rollability_ros.core.robots import ProfileBody, RobotModel


#: MuJoCo's contact spring (solref): time constant (s, MuJoCo's default; 2 steps blew up with the profile meshes)
#: and damping ratio 1 (critical). A damping ratio below 1 (what a restitution of 0.3 would map to, 0.36) left a
#: resting body ringing in a limit cycle at 1/240 s that never passes the rest rule.
CONTACT_SOLREF = (0.02, 1.0)


class GeomSpec(typing.Protocol):
    """The contact fields of an MjSpec geom (``mujoco.MjsGeom``) that :func:`set_geom_contact` sets."""

    friction: typing.Sequence[float]
    condim: int
    solref: typing.Sequence[float]


class BodyView(typing.Protocol):
    """A body of a compiled MuJoCo model, ``model.body(i)``: its id and name."""

    id: int
    name: str


class CompiledModel(typing.Protocol):
    """What this module reads of a compiled ``mujoco.MjModel``: bodies by index and the geom and mesh arrays."""

    nbody: int
    geom_type: np.ndarray
    geom_size: np.ndarray
    geom_dataid: np.ndarray
    mesh_vertadr: np.ndarray
    mesh_vertnum: np.ndarray
    mesh_vert: np.ndarray

    def body(self, index: int) -> BodyView: ...


def effective_contact(physics: PhysicsParams) -> typing.Tuple[float, float, float, float]:
    """Robot-ground contact values (lateral, spinning, rolling friction, restitution) under ``contact_model``."""
    if physics.contact_model == "per_body":
        mu = physics.lateral_friction
        return (mu * mu, 2 * physics.spinning_friction * mu, 2 * physics.rolling_friction * mu,
                physics.restitution ** 2)
    return physics.lateral_friction, physics.spinning_friction, physics.rolling_friction, physics.restitution


def set_geom_contact(geom: GeomSpec, physics: PhysicsParams, ground: bool = False) -> None:
    """Give an MjSpec ``geom`` the contact values of ``physics`` (module docstring): a simulated object gets the
    effective robot-ground values, the ground zeros (MuJoCo takes the larger of two geoms' values)."""
    lateral, spinning, rolling, _ = effective_contact(physics)
    geom.friction = [0.0, 0.0, 0.0] if ground else [lateral, spinning, rolling]
    geom.condim = 6
    geom.solref = [max(CONTACT_SOLREF[0], 4 * physics.time_step_s), CONTACT_SOLREF[1]]


def robot_spec(robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]",
               physics: PhysicsParams) -> typing.Tuple[typing.Any, typing.Any]:
    """The MjSpec of ``robot_model`` with ``profile`` (or None): contacts, joint drag, profile mount and a free
    joint on the root link, nothing else in the world. Returns ``(spec, root body spec)``."""
    mujoco = require("mujoco", feature="the MuJoCo trial engine")
    assets = {}
    mesh_file = None
    if profile is not None:
        from rollability_ros.core.robots import obj_text, profile_inertia
        _, hull = profile_inertia(profile)
        mesh_file = "profile.obj"
        assets[mesh_file] = obj_text(hull).encode()
    from rollability_ros.core.robots import mujoco_mesh_assets
    urdf, mesh_assets = mujoco_mesh_assets(robot_model.simulator_urdf(profile, mesh_file))   # .dae -> OBJ hulls
    spec = mujoco.MjSpec.from_string(urdf, assets={**assets, **mesh_assets})
    spec.option.timestep = physics.time_step_s
    spec.option.gravity = [0.0, 0.0, physics.gravity_mps2]
    for geom in spec.geoms:
        set_geom_contact(geom, physics)
    drag = robot_model.joint_drag_torque_nm()
    mount = robot_model.profile_mount
    for joint in spec.joints:
        if profile is not None and mount.compliant and joint.name == robot_model.profile_joint:
            # the compliant mount (ProfileMountSpec): MuJoCo's joint spring and damper, end stops at +-travel
            mount.check_time_step(profile.mass_kg, physics.time_step_s)
            joint.stiffness, joint.damping = _coefficients(joint.stiffness, mount.stiffness_npm), \
                _coefficients(joint.damping, mount.damping_nspm)
            joint.springref = 0.0
            joint.range = [-mount.travel_m, mount.travel_m]
            joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            joint.solref_limit = [2 * physics.time_step_s, 1.0]  # stiffest stable stop (default 0.02 s: soft)
            joint.frictionloss = 0.0
            continue
        joint.frictionloss = drag
    if profile is not None and mount.compliant:
        # Euler left an upside-down chassis bouncing on the spring in a limit cycle (+-3.6 mm at 2,000 N/m and
        # 5 N s/m, never at rest); RK4 settles it at its static deflection
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
    root = spec.worldbody.first_body()
    root.add_freejoint()
    return spec, root


def wheel_bodies(model: CompiledModel, robot_model: "RobotModel") -> typing.Set[int]:
    """The body ids of ``robot_model``'s wheel links in compiled ``model``."""
    wheel_names = set(robot_model.wheel_link_names())
    return {model.body(i).id for i in range(model.nbody) if model.body(i).name in wheel_names}


def build_model(robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]",
                physics: PhysicsParams) -> typing.Tuple[typing.Any, int, typing.Set[int]]:
    """Compile the MuJoCo model of ``robot_model`` with ``profile`` (or None) on a ground plane.

    Returns ``(model, root body id, {wheel body id, ...})``.
    """
    mujoco = require("mujoco", feature="the MuJoCo trial engine")
    spec, root = robot_spec(robot_model, profile, physics)
    ground = spec.worldbody.add_geom()
    ground.name = "ground"
    ground.type = mujoco.mjtGeom.mjGEOM_PLANE
    ground.size = [0.0, 0.0, 1.0]
    set_geom_contact(ground, physics, ground=True)
    model = spec.compile()
    return model, model.body(root.name).id, wheel_bodies(model, robot_model)


def _coefficients(current, linear):
    """A joint's spring or damper coefficient in the form this MuJoCo takes: a number, or
    (newer MuJoCo) polynomial coefficients whose first is the linear one."""
    return linear if np.ndim(current) == 0 else [linear] + [0.0] * (len(current) - 1)


class MujocoTrialWorld(TrialEngine):
    """The ``mujoco`` trial engine: one robot + profile in a MuJoCo model; every trial starts from a reset of its
    data (no carry-over)."""

    owns_world = True              # its own model and data: several can be kept per process

    def __init__(self, robot_model, profile, settings, physics):
        self.mujoco = mujoco = require("mujoco", feature="the MuJoCo trial engine")
        self.robot_model, self.settings, self.physics = robot_model, settings, physics
        self.model, self.root, self.wheels = build_model(robot_model, profile, physics)
        self.data = mujoco.MjData(self.model)
        model = self.model
        self.ground_geom = model.geom("ground").id
        self.robot_geoms = [g for g in range(model.ngeom) if g != self.ground_geom]
        self.wheel_geoms = {body: [g for g in self.robot_geoms if model.geom_bodyid[g] == body]
                            for body in self.wheels}
        up = np.asarray(robot_model.up_axis_in_root(), dtype=np.float64)
        self.up_in_root = up / np.linalg.norm(up)
        compliant = profile is not None and robot_model.profile_mount.compliant  # barriers need a rigid hull
        self.energy = MujocoEnergyMonitor(self, settings.early_decision_margin_m) \
            if settings.early_decision and not compliant else None

    def lowest_distance_m(self, geoms: typing.Iterable[int]) -> float:
        """Smallest distance (m, negative = penetration) from ``geoms`` to the ground, at the current state."""
        mujoco, model, data = self.mujoco, self.model, self.data
        return min(mujoco.mj_geomDistance(model, data, geom, self.ground_geom, 10.0, None) for geom in geoms)

    def place(self, orientation_xyzw: typing.Sequence[float], clearance_m: float) -> None:
        """Reset the data and put the robot at rest with ``orientation_xyzw`` and its lowest point ``clearance_m``
        above the ground."""
        mujoco, model, data = self.mujoco, self.model, self.data
        mujoco.mj_resetData(model, data)
        x, y, z, w = orientation_xyzw
        data.qpos[0:7] = [0.0, 0.0, 1.0, w, x, y, z]
        mujoco.mj_forward(model, data)
        data.qpos[2] += clearance_m - self.lowest_distance_m(self.robot_geoms)
        mujoco.mj_forward(model, data)

    def tilt_deg(self) -> float:
        """Angle between the root frame's up axis and world +z, degrees."""
        return root_tilt_deg(self.data.xmat[self.root], self.up_in_root)

    def is_upright(self) -> typing.Tuple[bool, float]:
        """``(upright, tilt_deg)`` as :meth:`RobotModel.is_upright` judges it."""
        tilt = self.tilt_deg()
        tolerance = self.robot_model.contact_tolerance_m
        touching = sum(self.lowest_distance_m(geoms) <= tolerance for geoms in self.wheel_geoms.values() if geoms)
        return tilt <= self.robot_model.upright_tilt_deg and touching >= self.robot_model.min_wheels_in_contact, tilt

    def run(self, index: int, seed: int) -> TrialOutcome:
        """Run one trial (see :mod:`rollability_ros.core.sim.trials`) and return its :class:`TrialOutcome`."""
        mujoco, model, data, settings = self.mujoco, self.model, self.data, self.settings
        conditions = sample_conditions(seed, settings)
        self.place(conditions.orientation, settings.drop_height_m)
        dt = self.physics.time_step_s
        push_start = round(settings.disturbance_delay_s / dt)
        push_end = push_start + max(1, round(settings.disturbance_duration_s / dt))
        cap = round(settings.time_cap_s / dt)
        hold_steps = round(settings.rest_hold_s / dt)
        interval = settings.check_interval_steps
        linear_limit, angular_limit = settings.rest_linear_speed_mps, math.radians(settings.rest_angular_speed_dps)
        push = np.concatenate([conditions.force_n, conditions.torque_nm])
        energy = self.energy
        step = mujoco.mj_step
        settled, decision, rest_since, previous_pose, primed, steps = False, None, None, None, False, 0
        while steps < cap:
            if steps == push_start:
                data.xfrc_applied[self.root] = push
            elif steps == push_end:
                data.xfrc_applied[self.root] = 0.0
            # whole steps up to the next check or push boundary in one call (mj_step's nstep: the same steps)
            target = min(cap, (steps // interval + 1) * interval,
                         *(boundary for boundary in (push_start, push_end) if boundary > steps))
            if primed:  # mj_step1 of this step already ran for the energy check
                mujoco.mj_step2(model, data)
                primed = False
                steps += 1
            if target > steps:
                step(model, data, target - steps)
                steps = target
            if steps % interval:
                continue
            pose = data.qpos[0:7].copy()
            moved = None if previous_pose is None else pose_speeds(previous_pose, pose, interval * dt)
            previous_pose = pose
            if steps >= push_end and moved is not None:
                if energy is not None:
                    # the first half of the next step computes the position-dependent quantities (COM, mass
                    # matrix) the energy needs; mj_step1 + mj_step2 = mj_step (Euler integrator)
                    mujoco.mj_step1(model, data)
                    primed = True
                    decision = energy.decide()
                    if decision is not None:
                        settled = True
                        break
                linear_mps, angular_radps = moved
                if linear_mps < linear_limit and angular_radps < angular_limit:
                    rest_since = steps if rest_since is None else rest_since
                    if steps - rest_since >= hold_steps:
                        settled = True
                        break
                else:
                    rest_since = None
        mujoco.mj_forward(model, data)
        if decision is not None:
            return TrialOutcome(index=index, seed=seed, upright=decision, settled=True, steps=steps,
                                tilt_deg=self.tilt_deg(), decided=True)
        upright, tilt = self.is_upright()
        return TrialOutcome(index=index, seed=seed, upright=bool(upright), settled=settled, steps=steps,
                            tilt_deg=tilt)


def root_tilt_deg(root_rotation: np.ndarray, up_in_root: np.ndarray) -> float:
    """Angle (deg) between world +z and the up axis ``up_in_root`` (3,) (unit, root frame) of a body whose world
    rotation (MuJoCo's ``data.xmat`` row of it) is ``root_rotation`` (9,) (every MuJoCo world's tilt: the trials'
    and the launch twin's)."""
    up_world = np.asarray(root_rotation).reshape(3, 3) @ up_in_root
    return math.degrees(math.acos(float(np.clip(up_world[2], -1.0, 1.0))))


def pose_speeds(before: typing.Sequence[float], after: typing.Sequence[float],
                interval_s: float) -> typing.Tuple[float, float]:
    """Mean linear (m/s) and angular (rad/s) speed of a free joint between two (x, y, z, qw, qx, qy, qz) poses.

    Positions rather than ``qvel``: MuJoCo 4 may put a body at rest to sleep, which freezes its pose but keeps
    its last velocity.
    """
    linear = math.dist(before[0:3], after[0:3]) / interval_s
    dot = min(1.0, abs(float(np.dot(before[3:7], after[3:7]))))
    return linear, 2 * math.acos(dot) / interval_s


def geom_points(mujoco: types.ModuleType, model: CompiledModel, geom: int, sections: int = 24
                ) -> typing.Optional[np.ndarray]:
    """Points (k, 3) whose hull is geom ``geom`` in its own frame (m); None for a plane."""
    kind, size = model.geom_type[geom], model.geom_size[geom]
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = model.geom_dataid[geom]
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        return np.asarray(model.mesh_vert[start:start + count], dtype=np.float64)
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * size
    angles = np.linspace(0.0, 2 * math.pi, sections, endpoint=False)
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        rim = np.column_stack([size[0] * np.cos(angles), size[0] * np.sin(angles), np.zeros(sections)])
        return np.vstack([rim + [0.0, 0.0, side * size[1]] for side in (-1, 1)])
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        from rollability_ros.core.sim._body_points import sphere_points
        return sphere_points(size[0], sections)
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        from rollability_ros.core.sim._body_points import sphere_points
        ball = sphere_points(size[0], sections)
        return np.vstack([ball + [0.0, 0.0, side * size[1]] for side in (-1, 1)])
    return None


def penetration_allowance_m(physics: PhysicsParams) -> float:
    """How far (m) a resting or rocking body may sink into MuJoCo's soft ground: 3 x g x timeconst^2.

    A critically damped contact spring of time constant ``tc`` holds a body at rest ``g tc^2`` deep
    (3.9 mm at 0.02 s; 4.8 mm measured for the chassis, MuJoCo's impedance adds a little); the factor 3 covers
    the deeper sinking under the dynamic loads of a body rocking with an energy below a barrier.
    """
    time_constant = max(CONTACT_SOLREF[0], 4 * physics.time_step_s)
    return 3 * abs(physics.gravity_mps2) * time_constant ** 2


class MujocoEnergyMonitor:
    """The early decision of :mod:`rollability_ros.core.sim.early_decision` read from MuJoCo's state:
    kinetic energy ``qvel' M qvel / 2`` (exact, from the mass matrix), COM height from the subtree COM.

    MuJoCo's contacts are soft: a body sinks into the ground (see :func:`penetration_allowance_m`), which breaks
    "COM height >= h(d)" by that depth, so the barriers are lowered by it on top of ``margin_m`` (``sink_m``
    replaces it for another ground: the launch twin's foam). ``ground_z_m`` is the ground's height;
    ``radius_m`` the hull's largest distance from the centre of mass (m).

    It keeps the world's model, data and root body, never the world: a world holds its monitor, and a monitor that
    held its world made a reference cycle that only the cyclic garbage collector frees, rarely in a long search, so a
    process kept every dropped world's compiled model and data (the launch twin compiles one per robustness draw).
    """

    def __init__(self, world, margin_m, sink_m=None, ground_z_m=0.0):
        from rollability_ros.core.sim.early_decision import build_basin_map
        mujoco, model = world.mujoco, world.model
        self.mujoco, self._model, self._data, self._root = mujoco, model, world.data, world.root
        world.place((0.0, 0.0, 0.0, 1.0), 0.0)
        data = world.data
        origin, rotation = data.xpos[world.root].copy(), data.xmat[world.root].reshape(3, 3).copy()
        points: typing.Dict[int, np.ndarray] = {}
        for geom in world.robot_geoms:
            local = geom_points(mujoco, model, geom)
            if local is None:
                continue
            world_points = local @ data.geom_xmat[geom].reshape(3, 3).T + data.geom_xpos[geom]
            body = int(model.geom_bodyid[geom])
            points[body] = np.vstack([points[body], world_points]) if body in points else world_points
        in_root = {body: (p - origin) @ rotation for body, p in points.items()}
        self.mass_kg = float(model.body_subtreemass[world.root])
        com = (data.subtree_com[world.root] - origin) @ rotation
        robot = world.robot_model
        self.radius_m = max(float(np.linalg.norm(p - com, axis=1).max()) for p in in_root.values())
        self.ground_z_m = ground_z_m
        sink_m = penetration_allowance_m(world.physics) if sink_m is None else sink_m
        self.basins = build_basin_map(in_root, sorted(world.wheels), com, self.mass_kg, world.up_in_root,
                                      robot.upright_tilt_deg, robot.min_wheels_in_contact, robot.contact_tolerance_m,
                                      margin_m=margin_m + sink_m)
        self.highest_barrier_m = self.basins.highest_barrier_m()
        self.gravity_mps2 = abs(world.physics.gravity_mps2)
        self._momentum = np.zeros(model.nv)

    def decide(self) -> typing.Optional[bool]:
        """True / False once the trial's outcome is fixed (upright / not), else None; call after ``mj_step1``."""
        mujoco, model, data, root = self.mujoco, self._model, self._data, self._root
        # the caller ran mj_step1 at the current state: subtree COM and mass matrix are current
        mujoco.mj_mulM(model, data, self._momentum, data.qvel)
        kinetic = 0.5 * float(self._momentum @ data.qvel)
        energy_height_m = self.energy_height_m = float(data.subtree_com[root][2]) - self.ground_z_m + \
            kinetic / (self.mass_kg * self.gravity_mps2)
        if energy_height_m >= self.highest_barrier_m:
            return None
        down_in_root = -data.xmat[root][6:9]
        return self.basins.decide(np.asarray(down_in_root, dtype=np.float64), energy_height_m)
