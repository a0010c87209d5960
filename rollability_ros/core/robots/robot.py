"""Robot models for the simulation: a body with wheels and a profile mount, spawned into a PyBullet client.

:class:`RobotModel` is the interface trials use: spawn the robot with a profile on its mount, say whether it
stands on its wheels, export URDF. :class:`ChassisModel` is the project's own four-wheeled chassis
(``config/robot.yaml``); a robot loaded from any URDF implements the same interface.

Chassis frame: x forward along the body length, y left, z up, origin at the centre of the body box. The
profile frame (see :mod:`rollability_ros.core.profile.geometry`) sits at the centre of the body's top face.
"""
import abc
import dataclasses
import math
import typing
from xml.sax.saxutils import quoteattr

import numpy as np
import numpy.typing as npt

from rollability_ros.core.optional import require
from rollability_ros.core.profile import Mesh, ProfilePrintSpec, print_mass_properties

#: A robot's collision shapes standing level (:meth:`RobotModel.standing_shapes_m`): ``(shapes, com_m, mass_kg)``.
StandingShapes = typing.Tuple[typing.List[typing.Tuple[str, np.ndarray]], np.ndarray, float]


@dataclasses.dataclass(frozen=True)
class ProfileBody:
    """A profile ready to attach: collision hull vertices ``(k, 3)`` (metres, profile frame), mass (kg), centre of
    mass ``com_m`` (3,) and inertia ``inertia_kgm2`` (3, 3) about it (kg m^2, profile frame axes)."""

    hull_vertices_m: np.ndarray
    mass_kg: float
    com_m: np.ndarray
    inertia_kgm2: np.ndarray

    @classmethod
    def from_mesh(cls, mesh: Mesh, make: ProfilePrintSpec, mass_scale: float = 1.0) -> "ProfileBody":
        """Build from a watertight trimesh (metres) made as ``make`` says (a printed shell with infill, or a uniform
        solid; :func:`~rollability_ros.core.profile.print_mass.print_mass_properties`), mass and inertia times
        ``mass_scale`` (``profile_mass_scale``). ``ValueError`` for a degenerate or open mesh."""
        properties = print_mass_properties(mesh, make, mass_scale)
        return cls(hull_vertices_m=np.asarray(mesh.convex_hull.vertices, dtype=np.float64),
                   mass_kg=properties.mass_kg, com_m=properties.com_m, inertia_kgm2=properties.inertia_kgm2)

    def principal_inertia(self) -> typing.Tuple[np.ndarray, typing.Tuple[float, float, float, float]]:
        """The principal moments (3,) kg m^2 and the rotation (x, y, z, w) from the profile frame to their axes."""
        moments, axes = np.linalg.eigh(self.inertia_kgm2)
        if np.linalg.det(axes) < 0:
            axes[:, 2] = -axes[:, 2]
        transform = require("scipy.spatial.transform", feature="the profile's inertia")
        x, y, z, w = (float(q) for q in transform.Rotation.from_matrix(axes).as_quat())
        return moments, (x, y, z, w)


@dataclasses.dataclass
class ProfileMountSpec:
    """How the profile is held on its mount (``robot.profile_mount`` / ``urdf_robot.profile_mount``).

    Rigid (``stiffness_npm`` = 0, the default; the paper's bolted profile): the profile is a link on a fixed
    joint. Compliant (``stiffness_npm`` > 0; e.g. rubber or TPU standoffs): the profile slides along the
    mount's normal (the profile frame's z) on a prismatic joint against a linear spring of ``stiffness_npm``
    and a viscous damper of ``damping_nspm``, its rest position (no load) at 0 and its travel limited to
    +-``travel_m`` by end stops. Both engines apply the same spring-damper law: MuJoCo as the joint's own
    stiffness and damping, PyBullet as a joint force set before every step (:class:`MountSpring`). Both
    integrate it explicitly, so a spawn refuses a mount whose undamped frequency or damping rate is too high for
    the time step (:meth:`check_time_step`). The early decision assumes a rigid hull and is not used with a
    compliant mount (its trials run to rest).
    """

    stiffness_npm: float = dataclasses.field(default=0.0, metadata={
        "description": "spring stiffness of the mount along its normal, N/m (0 = rigid mount, fixed joint)",
        "range": (0.0, 10000000.0)})
    damping_nspm: float = dataclasses.field(default=0.0, metadata={
        "description": "viscous damping of the compliant mount along its normal, N s/m", "range": (0.0, 1000000.0)})
    travel_m: float = dataclasses.field(default=0.005, metadata={
        "description": "end stops of the compliant mount: the profile moves at most this far either way along "
                       "the normal, m", "range": (0.0, 1.0), "exclusive": "low"})

    #: Largest explicit-integration rate (undamped angular frequency x step, damping rate x step) accepted.
    MAX_RATE_PER_STEP = 1.0

    @property
    def compliant(self) -> bool:
        """True when the profile rides on a spring (``stiffness_npm`` > 0)."""
        return self.stiffness_npm > 0

    def check_time_step(self, profile_mass_kg: float, time_step_s: float) -> None:
        """Raise ``ValueError`` when the spring-damper on a profile of ``profile_mass_kg`` would be integrated
        unstably at ``time_step_s`` (both rates, per step, must stay at or below :attr:`MAX_RATE_PER_STEP`)."""
        if not self.compliant or profile_mass_kg <= 0:
            return
        omega = math.sqrt(self.stiffness_npm / profile_mass_kg) * time_step_s
        decay = self.damping_nspm / profile_mass_kg * time_step_s
        if omega > self.MAX_RATE_PER_STEP or decay > self.MAX_RATE_PER_STEP:
            raise ValueError(
                f"profile_mount: stiffness {self.stiffness_npm:g} N/m and damping {self.damping_nspm:g} N s/m on a "
                f"{profile_mass_kg * 1000:.0f} g profile give {omega:.2f} rad and {decay:.2f} per {time_step_s:g} s "
                f"step (at most {self.MAX_RATE_PER_STEP:g}): lower them or sim.time_step_s")

    def joint_xml(self) -> typing.Tuple[str, str]:
        """The URDF ``type`` and extra tags of the profile joint: fixed, or prismatic along z with its stops."""
        if not self.compliant:
            return "fixed", ""
        return "prismatic", (f'<axis xyz="0 0 1"/><limit lower="{-self.travel_m!r}" upper="{self.travel_m!r}" '
                             f'effort="1000000" velocity="1000"/><dynamics damping="{self.damping_nspm!r}"/>')


class MountSpring:
    """The compliant mount's spring-damper in a PyBullet world: call :meth:`apply` before every step.

    PyBullet has no joint spring; this sets the prismatic joint's force to ``-k q - c q'`` (the default joint
    motor is switched off at spawn). A force set by torque control lasts one step.
    """

    def __init__(self, client: int, body_id: int, joint: int, mount: ProfileMountSpec) -> None:
        self.pybullet = require("pybullet", feature="the simulated evaluator")
        self.client, self.body_id, self.joint = client, body_id, joint
        self.stiffness_npm, self.damping_nspm = mount.stiffness_npm, mount.damping_nspm
        self.pybullet.setJointMotorControl2(body_id, joint, self.pybullet.VELOCITY_CONTROL, targetVelocity=0.0,
                                            force=0.0, physicsClientId=client)

    def apply(self) -> None:
        """Set the spring-damper force for the next step from the joint's current position and speed."""
        pybullet = self.pybullet
        position, speed, _, _ = pybullet.getJointState(self.body_id, self.joint, physicsClientId=self.client)
        pybullet.setJointMotorControl2(self.body_id, self.joint, pybullet.TORQUE_CONTROL,
                                       force=-self.stiffness_npm * position - self.damping_nspm * speed,
                                       physicsClientId=self.client)

    def position_m(self) -> float:
        """The profile's displacement along the mount normal, m (negative = pressed towards the robot)."""
        return self.pybullet.getJointState(self.body_id, self.joint, physicsClientId=self.client)[0]


def compliant_mount(client: int, body_id: int, joint: int, mount: ProfileMountSpec, profile_mass_kg: float,
                    time_step_s: typing.Optional[float]) -> MountSpring:
    """Set up the compliant profile joint ``joint`` of ``body_id``: its end stops, the time-step check
    (:meth:`ProfileMountSpec.check_time_step` at ``time_step_s``, the world's step as its caller set it; None for
    a world that is never stepped) and its :class:`MountSpring`."""
    pybullet = require("pybullet", feature="the simulated evaluator")
    if time_step_s is not None:
        mount.check_time_step(profile_mass_kg, time_step_s)
    pybullet.changeDynamics(body_id, joint, jointLowerLimit=-mount.travel_m, jointUpperLimit=mount.travel_m,
                            physicsClientId=client)
    return MountSpring(client, body_id, joint, mount)


@dataclasses.dataclass(frozen=True)
class SpawnedRobot:
    """A robot in a PyBullet world: its body id, the link indices of its wheels (``-1`` = base), on a compliant
    mount the :class:`MountSpring` to apply before every step (None when rigid), and with a profile its link index
    and hull vertices ``(k, 3)`` in that link's frame (m): its exact extent, where Bullet's bounding box of a mesh
    link on rotated inertial axes is up to twice the mesh's size."""

    body_id: int
    wheel_links: typing.Tuple[int, ...]
    mount_spring: typing.Optional[MountSpring] = None
    profile_link: typing.Optional[int] = None
    profile_points_m: object = None

    def before_step(self) -> None:
        """Apply the per-step forces of the robot itself (the compliant mount's spring); call before each step."""
        if self.mount_spring is not None:
            self.mount_spring.apply()


class RobotModel(abc.ABC):
    """What a trial needs from a robot: spawn it, judge "on its wheels", describe it as URDF."""

    @abc.abstractmethod
    def spawn(self, client: int, profile: typing.Optional[ProfileBody], position: npt.ArrayLike,
              orientation: typing.Sequence[float], *, time_step_s: typing.Optional[float],
              exact_cylinders: bool = False) -> SpawnedRobot:
        """Create the robot with ``profile`` (a :class:`ProfileBody` or None) in ``client``; return a SpawnedRobot.

        ``exact_cylinders``: a description's cylinders (wheels) are Bullet's own round cylinder shapes, not
        PyBullet's URDF default, a convex hull of points on their rims (a polygon that bumps as it rolls: a
        four-wheeled robot on 33 mm wheels coasting at 1 m/s lost 0.4 m/s^2 to it, and hopped); the launch twin
        asks for them (MuJoCo's cylinders are round). The built-in chassis's wheels are always round.

        ``position`` (3,) metres and ``orientation`` (x, y, z, w) place the robot's base frame in the world.
        ``time_step_s`` is the world's fixed step (s) as the caller set it (``sim.time_step_s``), against which a
        compliant mount is checked (:meth:`ProfileMountSpec.check_time_step`); None for a world that is never
        stepped (geometry only). It flows down from the settings: no model reads it back from the engine.
        """

    @abc.abstractmethod
    def up_axis(self, client: int, robot: SpawnedRobot) -> np.ndarray:
        """Return the robot's body up-axis as a world-frame unit vector (3,)."""

    @property
    @abc.abstractmethod
    def upright_tilt_deg(self) -> float:
        """Largest angle between the body up-axis and world up that still counts as upright (deg)."""

    @property
    @abc.abstractmethod
    def min_wheels_in_contact(self) -> int:
        """How many wheel links must touch the ground for the robot to stand on its wheels."""

    @property
    @abc.abstractmethod
    def contact_tolerance_m(self) -> float:
        """A wheel within this distance of the ground counts as touching it (m)."""

    @abc.abstractmethod
    def to_urdf(self, profile_mesh_filename: typing.Optional[str] = None,
                profile: typing.Optional[ProfileBody] = None) -> str:
        """Return a URDF document (str) of the robot, with the profile mesh file on its mount if given."""

    def simulator_urdf(self, profile: typing.Optional[ProfileBody] = None,
                       mesh_filename: typing.Optional[str] = None) -> str:
        """The URDF a simulator loads (str): the robot with ``profile`` (ProfileBody) on ``mesh_filename``."""
        return self.to_urdf(mesh_filename, profile)

    #: Name of the profile's joint in :meth:`simulator_urdf` (None: no compliant mount possible).
    profile_joint: typing.Optional[str] = None

    @property
    def profile_mount(self) -> ProfileMountSpec:
        """How the profile is held (:class:`ProfileMountSpec`); rigid unless a model says otherwise."""
        return ProfileMountSpec()

    @abc.abstractmethod
    def wheel_link_names(self) -> typing.Tuple[str, ...]:
        """Names of the wheel links in :meth:`to_urdf`, in the order of :attr:`SpawnedRobot.wheel_links`."""

    @abc.abstractmethod
    def joint_drag_torque_nm(self) -> float:
        """Back-drive drag torque of each unpowered joint (N m)."""

    @abc.abstractmethod
    def up_axis_in_root(self) -> typing.Tuple[float, ...]:
        """The up axis (3,) in the frame of :meth:`to_urdf`'s root link."""

    @abc.abstractmethod
    def wheel_radii_m(self) -> typing.Tuple[float, ...]:
        """Rolling radius of each wheel (m), a tuple in the order of :attr:`SpawnedRobot.wheel_links`."""

    @abc.abstractmethod
    def standing_shapes_m(self) -> StandingShapes:
        """The collision shapes of the bare robot standing level, facing +x, every joint at zero: ``(shapes,
        com_m, mass_kg)``, ``shapes`` a list of ``(link name, points (k, 3))`` (corner / vertex points of each
        shape), ``com_m`` (3,) the centre of mass, all in the robot's root frame turned about z so it faces +x (m);
        ``mass_kg`` the robot's mass.
        Engine-free: the launcher is sized from it (:mod:`rollability_ros.core.sim.launcher_geometry`)."""

    def tilt_deg(self, client: int, robot: SpawnedRobot) -> float:
        """Angle between the body up-axis and world +z, degrees."""
        return math.degrees(math.acos(float(np.clip(self.up_axis(client, robot)[2], -1.0, 1.0))))

    def wheels_in_contact(self, client: int, robot: SpawnedRobot, ground_id: int) -> int:
        """Number of wheel links within ``contact_tolerance_m`` of the ground body."""
        pybullet = require("pybullet", feature="the simulated evaluator")
        return sum(bool(pybullet.getClosestPoints(robot.body_id, ground_id, self.contact_tolerance_m, linkIndexA=link,
                                                  physicsClientId=client))
                   for link in robot.wheel_links)

    def is_upright(self, client: int, robot: SpawnedRobot, ground_id: int) -> typing.Tuple[bool, float]:
        """Return ``(upright, tilt_deg)``: upright = tilt within the threshold and enough wheels on the ground."""
        tilt = self.tilt_deg(client, robot)
        upright = tilt <= self.upright_tilt_deg and \
            self.wheels_in_contact(client, robot, ground_id) >= self.min_wheels_in_contact
        return upright, tilt


#: The robot masses (kg) PyBullet and MuJoCo integrate stably at the default 1/240 s step on the launch twin (the
#: 0.3 kg push plate, the 20 kN/m foam pad), measured by launching a four-wheeled 1.62 kg robot with every mass and
#: inertia scaled (docs/other-robots.md, "Robot masses the engines integrate"). Light: MuJoCo's twin went unstable
#: at 0.016-0.049 kg and landed off the foam at 0.081 kg, as the explicit limit sqrt(k / m) x step = 2 predicts
#: (0.087 kg on 20 kN/m); the robust launches draw the foam up to twice as stiff (0.17 kg), hence 0.2 kg. Heavy:
#: MuJoCo's twin went unstable at 486 kg (1,620 x the plate) and 1,620 kg, PyBullet divided by zero at 16,200 kg;
#: the heaviest robot tried is the 82 kg Scout.
ROBOT_MASS_RANGE_KG = (0.2, 250.0)
#: Largest size (m) of a robot's part: a collision shape's extent, a rigid body's radius of gyration. The chassis's
#: dimensions are bounded so in its parameter file; the robots tried are 0.2-1.0 m long and the rig's ledge 0.75 m
#: high. A larger value is a unit error (a mesh in millimetres without scale 0.001) or a placeholder.
ROBOT_SIZE_MAX_M = 10.0


def check_robot_mass(mass_kg: float, what: str) -> None:
    """``ValueError`` in one line naming ``what`` when the robot's mass ``mass_kg`` is outside
    :data:`ROBOT_MASS_RANGE_KG` (or not a finite number)."""
    low, high = ROBOT_MASS_RANGE_KG
    if not low <= mass_kg <= high:
        raise ValueError(f"{what}: the robot weighs {mass_kg:g} kg, outside {low:g}-{high:g} kg, the masses PyBullet "
                         "and MuJoCo integrate stably on the launch twin at its 1/240 s step with the 0.3 kg push "
                         "plate and the 20-40 kN/m foam (MuJoCo went unstable at 0.049 kg and 486 kg)")


#: Metadata of ``profile_mass_scale`` (the chassis's and a URDF robot's): an unknown, drawn and calibrated.
PROFILE_MASS_SCALE = {
    "description": "unknown multiplier on the profile's mass and inertia as computed from profile_print (no unit; "
                   "1 = as computed; covers what the print model leaves out: extrusion rate, infill pattern, seams, "
                   "glue and tape, and an infill the lab chose other than profile_print's: 0.16 is about a hollow shell and 1.4 about "
                   "35 % infill for the default 20 %)", "range": (0.1, 3.0)}


@dataclasses.dataclass
class ChassisSpec:
    """The built-in chassis (``config/robot.yaml``, section ``robot``): a box body with four wheels.

    The body's centre of mass sits ``com_offset_z_m`` below the box centre (battery and motors low). Wheel
    axles run along y at x = +-``wheelbase_m``/2, y = +-``track_m``/2 and ``axle_offset_z_m`` from the box
    centre. Wheels spin freely against a drag torque ``wheel_drag_torque_nm`` (an unpowered geared motor).
    The profile's mass, centre of mass and inertia follow from its mesh and ``profile_print`` (a printed shell
    with infill, or a uniform solid; :class:`~rollability_ros.core.profile.print_mass.ProfilePrintSpec`), mass and
    inertia times ``profile_mass_scale``.
    """

    body_length_m: float = dataclasses.field(default=0.18, metadata={
        "description": "chassis body box length along x (forward), m", "range": (0.0, 10.0), "exclusive": "low"})
    body_width_m: float = dataclasses.field(default=0.14, metadata={
        "description": "chassis body box width along y (left), m", "range": (0.0, 10.0), "exclusive": "low"})
    body_height_m: float = dataclasses.field(default=0.04, metadata={
        "description": "chassis body box height (z), m; the profile sits on its top face",
        "range": (0.0, 10.0), "exclusive": "low"})
    body_mass_kg: float = dataclasses.field(default=0.9, metadata={
        "description": "chassis body mass with battery and motors, kg", "range": (0.0, 10000.0), "exclusive": "low"})
    com_offset_z_m: float = dataclasses.field(default=-0.015, metadata={
        "description": "centre of mass height relative to the body centre, m (negative = below)",
        "range": (-1.0, 1.0)})
    wheel_radius_m: float = dataclasses.field(default=0.03, metadata={
        "description": "radius of each wheel at the tyre surface, m", "range": (0.0, 10.0), "exclusive": "low"})
    wheel_width_m: float = dataclasses.field(default=0.025, metadata={
        "description": "wheel width (tyre tread), m", "range": (0.0, 10.0), "exclusive": "low"})
    wheel_mass_kg: float = dataclasses.field(default=0.05, metadata={
        "description": "mass of one wheel, kg", "range": (0.0, 1000.0), "exclusive": "low"})
    wheelbase_m: float = dataclasses.field(default=0.12, metadata={
        "description": "distance between the front and rear axles, m", "range": (0.0, 10.0), "exclusive": "low"})
    track_m: float = dataclasses.field(default=0.17, metadata={
        "description": "distance between the left and right wheel centres, m",
        "range": (0.0, 10.0), "exclusive": "low"})
    axle_offset_z_m: float = dataclasses.field(default=-0.015, metadata={
        "description": "height of the wheel axles relative to the body centre, m (negative = below)",
        "range": (-1.0, 1.0)})
    wheel_drag_torque_nm: float = dataclasses.field(default=0.02, metadata={
        "description": "back-drive drag torque of each unpowered wheel drive, N m", "range": (0.0, 1000.0)})
    profile_mass_scale: float = dataclasses.field(default=1.0, metadata=PROFILE_MASS_SCALE)
    upright_tilt_deg: float = dataclasses.field(default=30.0, metadata={
        "description": "upright when the body +z axis is within this angle of world up at rest, deg",
        "range": (0.0, 90.0), "exclusive": "both"})
    min_wheels_in_contact: int = dataclasses.field(default=3, metadata={
        "description": "wheels that must touch the ground for an upright verdict (count)", "range": (1, 4)})
    contact_tolerance_m: float = dataclasses.field(default=0.003, metadata={
        "description": "a wheel this close to the ground counts as touching it, m",
        "range": (0.0, 1.0), "exclusive": "low"})
    profile_mount: ProfileMountSpec = dataclasses.field(default_factory=ProfileMountSpec)
    profile_print: ProfilePrintSpec = dataclasses.field(default_factory=ProfilePrintSpec)

    def validate(self) -> None:
        """Raise ``ValueError`` for a rule that spans fields (each number's range is declared in its metadata and
        checked by :func:`~rollability_ros.core.config.check_settings`)."""
        check_robot_mass(self.body_mass_kg + 4 * self.wheel_mass_kg, "robot.body_mass_kg + 4 x robot.wheel_mass_kg")
        if abs(self.com_offset_z_m) >= self.body_height_m / 2:
            raise ValueError(f"com_offset_z_m {self.com_offset_z_m} must lie inside the body (|.| < height/2)")
        if self.track_m / 2 - self.wheel_width_m / 2 < self.body_width_m / 2 - 1e-9 and \
                self.axle_offset_z_m + self.wheel_radius_m > -self.body_height_m / 2:
            raise ValueError("wheels intersect the body: increase track_m or lower axle_offset_z_m")


class SpecThresholds:
    """Mixin for a :class:`RobotModel` whose ``self.spec`` holds the upright thresholds and how its profile is made."""

    #: A :class:`ChassisSpec` or a ``UrdfRobotSpec``: both have the fields read here.
    spec: typing.Any

    @property
    def upright_tilt_deg(self) -> float:
        return float(self.spec.upright_tilt_deg)

    @property
    def min_wheels_in_contact(self) -> int:
        return int(self.spec.min_wheels_in_contact)

    @property
    def contact_tolerance_m(self) -> float:
        return float(self.spec.contact_tolerance_m)

    def profile_body(self, mesh: Mesh) -> ProfileBody:
        """The :class:`ProfileBody` of ``mesh`` (trimesh, metres) made as this robot's ``profile_print`` says, mass
        and inertia times its ``profile_mass_scale``."""
        return ProfileBody.from_mesh(mesh, self.spec.profile_print, self.spec.profile_mass_scale)

    @property
    def profile_mount(self) -> ProfileMountSpec:
        """How the profile is held (:class:`ProfileMountSpec`): rigid, or on a spring-damper."""
        return self.spec.profile_mount


#: Name of the profile's joint in the chassis URDF (fixed, or prismatic on a compliant mount).
PROFILE_JOINT = "profile_joint"
_WHEEL_ORIENTATION = (math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5))  # cylinder axis (local z) along chassis y


class ChassisModel(SpecThresholds, RobotModel):
    """The project's four-wheeled chassis from a :class:`ChassisSpec`: base = body, link 0 = profile (if any), wheels last."""

    #: Name of the body link (the chassis frame) in :meth:`to_urdf`: the link the profile is mounted on.
    BODY_LINK = "base_link"
    #: Name of the profile's joint in :meth:`simulator_urdf`.
    profile_joint = PROFILE_JOINT

    def __init__(self, spec: ChassisSpec) -> None:
        self.spec = spec

    @property
    def mount_position_m(self) -> np.ndarray:
        """The profile frame's origin in the chassis frame (3,): centre of the body's top face."""
        return np.array([0.0, 0.0, self.spec.body_height_m / 2])

    def wheel_radii_m(self) -> typing.Tuple[float, ...]:
        return (self.spec.wheel_radius_m,) * 4

    #: The wheels' link names in :meth:`to_urdf`, front-left, front-right, rear-left, rear-right.
    WHEEL_NAMES = ("front_left", "front_right", "rear_left", "rear_right")

    def wheel_link_names(self) -> typing.Tuple[str, ...]:
        return tuple(f"{name}_wheel" for name in self.WHEEL_NAMES)

    def joint_drag_torque_nm(self) -> float:
        return self.spec.wheel_drag_torque_nm

    def up_axis_in_root(self) -> typing.Tuple[float, ...]:
        return (0.0, 0.0, 1.0)

    def wheel_positions_m(self) -> np.ndarray:
        """Wheel centres in the chassis frame, (4, 3): front-left, front-right, rear-left, rear-right."""
        s = self.spec
        return np.array([[sx * s.wheelbase_m / 2, sy * s.track_m / 2, s.axle_offset_z_m]
                         for sx in (1, -1) for sy in (1, -1)])

    def standing_shapes_m(self) -> StandingShapes:
        s = self.spec
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
        shapes = [(self.BODY_LINK, corners * [s.body_length_m / 2, s.body_width_m / 2, s.body_height_m / 2])]
        wheel_half = np.array([s.wheel_radius_m, s.wheel_width_m / 2, s.wheel_radius_m])
        wheels = self.wheel_positions_m()
        shapes += [(name, corners * wheel_half + centre) for name, centre in zip(self.wheel_link_names(), wheels)]
        mass = s.body_mass_kg + 4 * s.wheel_mass_kg
        com = (s.body_mass_kg * np.array([0.0, 0.0, s.com_offset_z_m]) + s.wheel_mass_kg * wheels.sum(axis=0)) / mass
        return shapes, com, mass

    def spawn(self, client: int, profile: typing.Optional[ProfileBody], position: npt.ArrayLike,
              orientation: typing.Sequence[float], *, time_step_s: typing.Optional[float],
              exact_cylinders: bool = False) -> SpawnedRobot:
        """See :meth:`RobotModel.spawn`: the base frame at ``position`` (3,) m with ``orientation`` (x, y, z, w);
        its wheels are Bullet's round cylinders whatever ``exact_cylinders``."""
        pybullet = require("pybullet", feature="the simulated evaluator")
        s = self.spec
        body_shape = pybullet.createCollisionShape(
            pybullet.GEOM_BOX, halfExtents=[s.body_length_m / 2, s.body_width_m / 2, s.body_height_m / 2],
            physicsClientId=client)
        wheel_shape = pybullet.createCollisionShape(pybullet.GEOM_CYLINDER, radius=s.wheel_radius_m,
                                                    height=s.wheel_width_m, physicsClientId=client)
        links: typing.Dict[str, list] = {"mass": [], "shape": [], "position": [], "orientation": [], "com": [],
                                         "joint": [], "axis": []}

        def add_link(mass: float, shape: int, position_m: npt.ArrayLike, orientation_xyzw: typing.Sequence[float],
                     com_m: npt.ArrayLike, joint: int, axis: typing.Sequence[float]) -> None:
            """One link on the body: ``position_m`` and ``com_m`` (3,) in the body frame (m), axis (3,)."""
            for key, value in zip(links, (mass, shape, position_m, orientation_xyzw, com_m, joint, axis)):
                links[key].append(value)

        inertial_turns = []
        if profile is not None:
            profile_shape = pybullet.createCollisionShape(pybullet.GEOM_MESH,
                                                          vertices=profile.hull_vertices_m.tolist(),
                                                          physicsClientId=client)
            mount = s.profile_mount
            add_link(profile.mass_kg, profile_shape, self.mount_position_m, (0, 0, 0, 1), profile.com_m,
                     pybullet.JOINT_PRISMATIC if mount.compliant else pybullet.JOINT_FIXED,
                     (0, 0, 1) if mount.compliant else (0, 0, 0))
            moments, principal_axes = profile.principal_inertia()
            inertial_turns.append(principal_axes)
        for wheel in self.wheel_positions_m():
            add_link(s.wheel_mass_kg, wheel_shape, wheel, _WHEEL_ORIENTATION, (0, 0, 0), pybullet.JOINT_REVOLUTE,
                     (0, 0, 1))
        count = len(links["mass"])
        body = pybullet.createMultiBody(
            baseMass=s.body_mass_kg, baseCollisionShapeIndex=body_shape,
            basePosition=np.asarray(position, dtype=np.float64).tolist(),
            baseOrientation=list(orientation), baseInertialFramePosition=[0, 0, s.com_offset_z_m],
            linkMasses=links["mass"], linkCollisionShapeIndices=links["shape"], linkVisualShapeIndices=[-1] * count,
            linkPositions=[list(p) for p in links["position"]], linkOrientations=links["orientation"],
            linkInertialFramePositions=[list(c) for c in links["com"]],
            linkInertialFrameOrientations=inertial_turns + [(0, 0, 0, 1)] * (count - len(inertial_turns)),
            linkParentIndices=[0] * count,
            linkJointTypes=links["joint"], linkJointAxis=links["axis"], physicsClientId=client)
        wheels = tuple(range(count - 4, count))  # a massless placeholder link would break external torques
        pybullet.setJointMotorControlArray(body, list(wheels), pybullet.VELOCITY_CONTROL, targetVelocities=[0.0] * 4,
                                           forces=[s.wheel_drag_torque_nm] * 4, physicsClientId=client)
        if profile is not None:  # Bullet took the mesh's box inertia: set the print's, on its principal axes
            pybullet.changeDynamics(body, 0, localInertiaDiagonal=moments.tolist(), physicsClientId=client)
        spring = None
        if profile is not None and s.profile_mount.compliant:
            spring = compliant_mount(client, body, 0, s.profile_mount, profile.mass_kg, time_step_s)
        return SpawnedRobot(body_id=body, wheel_links=wheels, mount_spring=spring,
                            profile_link=None if profile is None else 0,
                            profile_points_m=None if profile is None else profile.hull_vertices_m)

    def up_axis(self, client: int, robot: SpawnedRobot) -> np.ndarray:
        """The body's +z in the world frame, a unit vector (3,)."""
        pybullet = require("pybullet", feature="the simulated evaluator")
        _, orientation = pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)
        return np.asarray(pybullet.getMatrixFromQuaternion(orientation)).reshape(3, 3)[:, 2]

    def to_urdf(self, profile_mesh_filename: typing.Optional[str] = None,
                profile: typing.Optional[ProfileBody] = None) -> str:
        """URDF of the chassis (inertias of solid boxes/cylinders); the profile link uses the given mesh file."""
        return self._urdf(profile_mesh_filename, profile, ("fixed", ""))

    def simulator_urdf(self, profile: typing.Optional[ProfileBody] = None,
                       mesh_filename: typing.Optional[str] = None) -> str:
        """As :meth:`to_urdf`, the profile on a prismatic joint when its mount is compliant (ProfileMountSpec)."""
        return self._urdf(mesh_filename, profile, self.spec.profile_mount.joint_xml())

    def _urdf(self, profile_mesh_filename, profile, profile_joint):
        s = self.spec
        box = (s.body_length_m, s.body_width_m, s.body_height_m)
        parts = ['<?xml version="1.0"?>', '<robot name="rollability_chassis">',
                 _urdf_link(self.BODY_LINK, f'<box size="{box[0]} {box[1]} {box[2]}"/>', s.body_mass_kg,
                            (0, 0, s.com_offset_z_m), _box_inertia(s.body_mass_kg, box))]
        if profile_mesh_filename is not None:
            mass = profile.mass_kg if profile is not None else 0.0
            com = tuple(profile.com_m) if profile is not None else (0, 0, 0)
            parts.append(_urdf_link("profile_link", f"<mesh filename={quoteattr(profile_mesh_filename)}/>", mass, com,
                                    profile.inertia_kgm2 if profile is not None else (0, 0, 0)))
            kind, tags = profile_joint
            parts.append(_urdf_joint(PROFILE_JOINT, kind, self.BODY_LINK, "profile_link", self.mount_position_m,
                                     (0, 0, 0), extra=tags))
        r, w, m = s.wheel_radius_m, s.wheel_width_m, s.wheel_mass_kg
        across = m * (3 * r * r + w * w) / 12
        wheel_inertia = (across, m * r * r / 2, across)  # axis along the link's y
        for name, position in zip(self.WHEEL_NAMES, self.wheel_positions_m()):
            parts.append(_urdf_link(f"{name}_wheel", f'<cylinder radius="{r}" length="{w}"/>', m, (0, 0, 0),
                                    wheel_inertia, rpy=(math.pi / 2, 0, 0)))
            parts.append(_urdf_joint(f"{name}_wheel_joint", "continuous", self.BODY_LINK, f"{name}_wheel", position,
                                     (0, 0, 0), axis=(0, 1, 0)))
        parts.append("</robot>")
        return "\n".join(parts) + "\n"


def _box_inertia(mass, size):
    x, y, z = size
    return (mass * (y * y + z * z) / 12, mass * (x * x + z * z) / 12, mass * (x * x + y * y) / 12)


def _xyz(values):
    return " ".join(f"{float(v):.6g}" for v in values)


def _urdf_link(name, geometry, mass, com, inertia, rpy=(0, 0, 0)):
    """A URDF link; ``inertia`` about the centre of mass: principal moments (3,) or a full tensor (3, 3)."""
    shape = f'<origin xyz="0 0 0" rpy="{_xyz(rpy)}"/><geometry>{geometry}</geometry>'
    i = np.asarray(inertia, dtype=np.float64)
    i = np.diag(i) if i.ndim == 1 else i
    return (f'  <link name="{name}">\n'
            f'    <inertial><origin xyz="{_xyz(com)}"/><mass value="{mass:.9g}"/>'
            f'<inertia ixx="{i[0, 0]:.9g}" iyy="{i[1, 1]:.9g}" izz="{i[2, 2]:.9g}" ixy="{i[0, 1]:.9g}" '
            f'ixz="{i[0, 2]:.9g}" iyz="{i[1, 2]:.9g}"/></inertial>\n'
            f'    <visual>{shape}</visual>\n    <collision>{shape}</collision>\n  </link>')


def _urdf_joint(name, kind, parent, child, xyz, rpy, axis=None, extra=""):
    axis_tag = f'<axis xyz="{_xyz(axis)}"/>' if axis is not None else ""
    return (f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{_xyz(xyz)}" rpy="{_xyz(rpy)}"/>{axis_tag}{extra}</joint>')
