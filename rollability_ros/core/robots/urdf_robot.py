"""Any wheeled robot from its URDF, with a profile on a mount link: a :class:`RobotModel` for the trials.

Config (section ``urdf_robot``, see ``config/husky.yaml``) names the description (a file or an XML string),
the mount link and the mount footprint the profile grid spans, and how "upright" is judged. Naming a
``mount_link`` selects this robot instead of the built-in chassis (:class:`RobotChoice`, shared by the trials'
and the launch twin's settings; :func:`footprint_grid` gives the grid, :func:`profile_mount` the mount).

Frames
    Root frame = the URDF's root link (REP 103: x forward, y left, z up when the robot stands on its wheels);
    ``forward_axis`` names the root axis that points forward when it is not x; the robot is turned about its z
    so that axis faces world +x, and the trial start state rolls the robot about it. Profile frame = the
    footprint frame: origin
    ``footprint_offset_m`` in the mount link's frame, turned by ``footprint_yaw_deg`` about that link's z; its
    x runs along ``footprint_length_m``, y along ``footprint_width_m``, z away from the robot (the profile grid's
    frame, :mod:`rollability_ros.core.profile.geometry`).
Physics
    The robot is loaded with PyBullet's own URDF loader (masses and inertias from the URDF,
    ``URDF_USE_INERTIA_FROM_FILE``) from the rigid-body URDF of
    :mod:`rollability_ros.core.robots.urdf_description`. The profile is one more link of that URDF on a fixed joint
    to the mount's rigid body: a reduced-coordinate (Featherstone) fixed joint is exactly rigid and moves with
    every base reset, whereas a separate body held by ``createConstraint(JOINT_FIXED)`` is solved iteratively
    (it stretches under impacts) and would be left behind by the trials' ``resetBasePositionAndOrientation``
    (test_urdf_robot). The profile collides as the convex hull of its vertices with the mass, centre of mass and
    full inertia of its print (:class:`ProfileBody`, :mod:`rollability_ros.core.profile.print_mass`), read from the
    URDF by PyBullet and MuJoCo alike (test_print_mass).
Picklable
    The spec keeps the text of the checked description (:meth:`UrdfRobotSpec.description`, computed once in
    the process that loads the config and pickled with it), so pool workers only write and load files.
"""
import dataclasses
import hashlib
import math
import os
import re
import tempfile
import typing
import xml.etree.ElementTree as ElementTree

import numpy as np
import numpy.typing as npt

from rollability_ros.core.optional import require
from rollability_ros.core.profile import Mesh, ProfileGrid, ProfilePrintSpec
from rollability_ros.core.robots.robot import (PROFILE_MASS_SCALE, ChassisModel, ChassisSpec, ProfileBody,
                                               ProfileMountSpec, RobotModel, SpawnedRobot, SpecThresholds,
                                               StandingShapes, compliant_mount)
from rollability_ros.core.robots.urdf_description import (PROFILE_LINK, RobotDescription, describe, inertial_xml,
                                                          origin_xml, read_urdf_source, transform, without_visuals)

#: The profile joint of the simulator URDF: fixed, or prismatic on a compliant mount.
PROFILE_JOINT = f"{PROFILE_LINK}_joint"

#: ``forward_axis`` -> direction of that axis in the root link's x-y plane, deg from +x (REP 103 says x).
FORWARD_AXIS_DEG = {"x": 0.0, "y": 90.0, "-x": 180.0, "-y": -90.0}
#: Largest gap (m) allowed between the footprint plane and the top of the mount's collision shapes.
SURFACE_TOLERANCE_M = 0.002
#: Slack when checking that the footprint lies within the mount body's collision extent (m).
FOOTPRINT_TOLERANCE_M = 0.001
#: Directions across a wheel's axle searched for its smallest width: a coarse sweep over 180 deg, then a fine
#: one over one coarse step either side of the narrowest (resolution 0.001 deg: relative error < 1e-5).
WIDTH_SEARCH_STEPS = (720, 501)


@dataclasses.dataclass
class UrdfRobotSpec:
    """A robot from a URDF (``urdf_robot`` section): description, mount footprint, upright test, joints.

    Exactly one of ``urdf_path`` / ``robot_description`` gives the description (the sim_evaluator node can
    also take it from the ``robot_description`` topic). ``search_paths`` are folders for ``package://`` and
    relative mesh paths and a relative ``urdf_path`` (``python:<module>`` = an installed package's folder).
    Upright = the root frame's ``up_axis_xyz`` within ``upright_tilt_deg`` of world up (180 = not judged) and at
    least ``min_wheels_in_contact`` of the wheel links (``wheel_links`` plus links matching
    ``wheel_link_regex``) within ``contact_tolerance_m`` of the ground (0 = not judged). Every moving joint is
    held by a drag torque ``joint_drag_torque_nm`` (an unpowered drive). The profile's mass, centre of mass and
    inertia follow from its mesh and ``profile_print``, times ``profile_mass_scale`` (as on the chassis).
    """

    urdf_path: str = dataclasses.field(default="", metadata={
        "description": "URDF file of the robot; a relative path is looked up in the working directory, then each search"
                       " path"})
    robot_description: str = dataclasses.field(default="", metadata={
        "description": "URDF XML text of the robot (instead of urdf_path), e.g. a robot_state_publisher's "
                       "robot_description"})
    search_paths: tuple[str, ...] = dataclasses.field(default=(), metadata={
        "description": "folders searched for the URDF, package:// and relative meshes; python:<module> = that installed"
                       " package's folder"})
    ignore_visual_meshes: bool = dataclasses.field(default=False, metadata={
        "description": "true: drop the description's <visual> elements before checking it (the simulation never draws "
                       "them), so visual meshes missing on this machine stop nothing; exports then have no visuals"})
    mount_link: str = dataclasses.field(default="", metadata={
        "description": "URDF link the profile is fixed to; naming it selects the URDF robot instead of the built-in "
                       "chassis"})
    footprint_length_m: float = dataclasses.field(default=0.18, metadata={
        "description": "length of the mount footprint the profile grid spans, along the footprint x, m",
        "range": (0.0, 100.0), "exclusive": "low"})
    footprint_width_m: float = dataclasses.field(default=0.14, metadata={
        "description": "width of the mount footprint the profile grid spans, along the footprint y, m",
        "range": (0.0, 100.0), "exclusive": "low"})
    footprint_offset_m: tuple[float, ...] = dataclasses.field(default=(0.0, 0.0, 0.0), metadata={
        "description": "footprint centre in the mount link's frame (x, y, z), m"})
    footprint_yaw_deg: float = dataclasses.field(default=0.0, metadata={
        "description": "footprint x axis relative to the mount link's x axis, deg", "range": (-360.0, 360.0)})
    wheel_links: tuple[str, ...] = dataclasses.field(default=(), metadata={
        "description": "names of the wheel links that must touch the ground when upright"})
    wheel_link_regex: str = dataclasses.field(default="", metadata={
        "description": "regular expression (full match) naming the wheel links, instead of wheel_links"})
    min_wheels_in_contact: int = dataclasses.field(default=0, metadata={
        "description": "wheel links that must touch the ground for an upright verdict (count; 0 = wheels not judged)",
        "range": (0, 1000)})
    forward_axis: str = dataclasses.field(default="x", metadata={
        "description": "axis of the root link that points forward, the direction the robot drives: x (REP 103), y, "
                       "-x or -y; trials and launches turn the robot so it faces world +x"})
    up_axis_xyz: tuple[float, ...] = dataclasses.field(default=(0.0, 0.0, 1.0), metadata={
        "description": "unit vector in the root link's frame that points up when the robot is upright (no unit)"})
    upright_tilt_deg: float = dataclasses.field(default=30.0, metadata={
        "description": "upright when the up axis is within this angle of world up at rest, deg (180 = not judged)",
        "range": (0.0, 180.0), "exclusive": "low"})
    contact_tolerance_m: float = dataclasses.field(default=0.005, metadata={
        "description": "a wheel link this close to the ground counts as touching it, m",
        "range": (0.0, 10.0), "exclusive": "low"})
    joint_drag_torque_nm: float = dataclasses.field(default=0.0, metadata={
        "description": "back-drive drag torque of each unpowered joint (wheel drives), N m",
        "range": (0.0, 1000000.0)})
    profile_mass_scale: float = dataclasses.field(default=1.0, metadata=PROFILE_MASS_SCALE)
    profile_mount: ProfileMountSpec = dataclasses.field(default_factory=ProfileMountSpec)
    profile_print: ProfilePrintSpec = dataclasses.field(default_factory=ProfilePrintSpec)

    @property
    def selected(self) -> bool:
        """True when a mount link is named: the trials use this robot instead of the built-in chassis."""
        return bool(self.mount_link)

    @property
    def has_source(self) -> bool:
        """True when a description file or string is given (the node may still be waiting for the topic)."""
        return bool(self.urdf_path or self.robot_description)

    def validate(self) -> None:
        """Raise ``ValueError`` for a rule that spans fields or a list, name or description that is unusable (each
        number's range is declared in its metadata and checked by
        :func:`~rollability_ros.core.config.check_settings`); with a description, check it too (see
        :meth:`description`)."""
        if len(self.footprint_offset_m) != 3:
            raise ValueError(f"footprint_offset_m must be [x, y, z] in metres, got {list(self.footprint_offset_m)}")
        if len(self.up_axis_xyz) != 3 or not np.linalg.norm(self.up_axis_xyz) > 0:
            raise ValueError(f"up_axis_xyz must be a non-zero [x, y, z] vector, got {list(self.up_axis_xyz)}")
        if self.forward_axis not in FORWARD_AXIS_DEG:
            raise ValueError(f"forward_axis must be one of {', '.join(FORWARD_AXIS_DEG)} (an axis of the root link), "
                             f"got {self.forward_axis!r}")
        if self.selected and self.upright_tilt_deg >= 180 and self.min_wheels_in_contact == 0:
            raise ValueError("upright is judged by nothing: set upright_tilt_deg < 180 or min_wheels_in_contact > 0")
        try:
            re.compile(self.wheel_link_regex)
        except re.error as exc:
            raise ValueError(f"wheel_link_regex {self.wheel_link_regex!r} is not a regular expression: {exc}") from exc
        if self.selected:
            check_up_axis(self)
        if self.selected and self.has_source:
            self.description()

    def description(self) -> "MountedDescription":
        """The checked :class:`~rollability_ros.core.robots.urdf_robot.MountedDescription` (computed once, kept).

        Raises ``ValueError`` naming the problem: see :func:`~rollability_ros.core.robots.urdf_description.describe`,
        plus an unknown mount or wheel link, a wheel regex matching nothing, too few wheels for
        ``min_wheels_in_contact``, and a footprint beyond the mount body's collision extent.
        """
        key = dataclasses.astuple(self)
        cached = self.__dict__.get("_description")
        if cached is None or cached[0] != key:
            cached = (key, _mount(self))
            self.__dict__["_description"] = cached
        return cached[1]

    def __getstate__(self):
        state = dict(self.__dict__)
        if self.selected and self.has_source:  # workers get the checked text, never re-read files
            self.description()
            state["_description"] = self.__dict__["_description"]
        return state


@dataclasses.dataclass(frozen=True)
class MountedDescription:
    """A :class:`~rollability_ros.core.robots.urdf_description.RobotDescription` with its mount and wheels placed.

    ``profile_in_body`` (nested tuples, 4x4) is the profile frame in the frame of ``mount_body`` (the rigid body
    holding the mount link); ``wheel_bodies`` the rigid bodies of the wheel links, sorted.
    """

    robot: RobotDescription
    mount_body: str
    profile_in_body: tuple
    wheel_bodies: tuple


def footprint_corners(spec: UrdfRobotSpec) -> np.ndarray:
    """The four footprint corners ``(4, 3)`` in the mount link's frame (m)."""
    yaw = math.radians(spec.footprint_yaw_deg)
    rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    half = np.array([[sx * spec.footprint_length_m / 2, sy * spec.footprint_width_m / 2]
                     for sx in (-1, 1) for sy in (-1, 1)])
    corners = half @ rotation.T + np.asarray(spec.footprint_offset_m[:2])
    return np.column_stack([corners, np.full(4, spec.footprint_offset_m[2])])


def _mount(spec):
    text, folder = read_urdf_source(spec.urdf_path, spec.robot_description, spec.search_paths)
    robot = describe(without_visuals(text) if spec.ignore_visual_meshes else text, folder, spec.search_paths)
    mount_in_body = robot.link_transform(spec.mount_link)
    body = robot.body_of[spec.mount_link]
    points = robot.body_collision_points(body)
    if not len(points):
        raise ValueError(f"mount link {spec.mount_link!r}: its rigid body {body!r} has no collision shape to carry "
                         "a profile")
    mount_in_root = np.array(robot.body_in_root[body]) @ mount_in_body
    root_to_mount = np.linalg.inv(mount_in_root)
    shapes = []
    for link, shape_body, shape_points in robot.collision_shapes:
        in_root = np.array(robot.body_in_root[shape_body]) @ np.c_[np.array(shape_points), np.ones(len(shape_points))].T
        shapes.append((link, shape_body == body, (root_to_mount @ in_root)[:3].T))
    check_mount_surface(spec, shapes)
    wheels = set(spec.wheel_links)
    for name in wheels:
        robot.link_transform(name)  # names an unknown link
    if spec.wheel_link_regex:
        matched = {name for name in robot.body_of if re.fullmatch(spec.wheel_link_regex, name)}
        if not matched:
            raise ValueError(f"wheel_link_regex {spec.wheel_link_regex!r} matches no link of "
                             f"{', '.join(sorted(robot.body_of))}")
        wheels |= matched
    wheel_bodies = tuple(sorted({robot.body_of[name] for name in wheels}))
    if spec.min_wheels_in_contact > len(wheel_bodies):
        raise ValueError(f"min_wheels_in_contact {spec.min_wheels_in_contact} exceeds the {len(wheel_bodies)} "
                         f"wheel bodies named ({', '.join(wheel_bodies) or 'none'})")
    profile_in_mount = transform(spec.footprint_offset_m, (0.0, 0.0, math.radians(spec.footprint_yaw_deg)))
    return MountedDescription(robot=robot, mount_body=body,
                              profile_in_body=tuple(map(tuple, (mount_in_body @ profile_in_mount).tolist())),
                              wheel_bodies=wheel_bodies)


def check_up_axis(spec: UrdfRobotSpec) -> None:
    """Refuse an ``up_axis_xyz`` that is not the robot's up: the trials and the launch twin stand the robot with its
    root frame's z up (REP 103), so an up axis more than ``upright_tilt_deg`` from the root's z would score every
    robot standing on its wheels "not upright"; ``ValueError`` naming it."""
    up = np.asarray(spec.up_axis_xyz, dtype=np.float64)
    angle = math.degrees(math.acos(float(np.clip(up[2] / np.linalg.norm(up), -1.0, 1.0))))
    if spec.upright_tilt_deg < 180 and angle > spec.upright_tilt_deg:
        raise ValueError(f"up_axis_xyz {list(spec.up_axis_xyz)} is {angle:.0f} deg from the root link's z, the up of "
                         f"a robot standing on its wheels (REP 103: x forward, z up): the robot would never count as "
                         f"upright (upright_tilt_deg {spec.upright_tilt_deg}); use [0, 0, 1], or a description whose "
                         f"root frame has z up")


#: Samples per side of the footprint at which the shapes' tops are compared with the footprint plane.
FOOTPRINT_SAMPLES = 9


class _ShapeTop:
    """The top surface of one collision shape (the upper envelope of its points' convex hull), seen from above."""

    def __init__(self, points, scipy_spatial):
        self.points = points
        self.top_z = float(points[:, 2].max())
        try:
            self.outline = scipy_spatial.ConvexHull(points[:, :2]).equations            # (nx, ny, d), inside <= 0
            solid = scipy_spatial.ConvexHull(points).equations                        # (nx, ny, nz, d)
            self.upward = solid[solid[:, 2] > 1e-9]
        except Exception:  # QhullError: a flat shape (a plane seen edge-on, a single point) covers no area
            self.outline = None

    def covers(self, xy: np.ndarray) -> np.ndarray:
        """Which of the points ``xy`` (n, 2) lie within the shape seen from above (bool (n,))."""
        if self.outline is None:
            return np.zeros(len(xy), dtype=bool)
        return (xy @ self.outline[:, :2].T + self.outline[:, 2]).max(axis=1) <= FOOTPRINT_TOLERANCE_M

    def top_at(self, xy: np.ndarray) -> np.ndarray:
        """The shape's top z at the points ``xy`` (n, 2) it covers (m)."""
        if not len(self.upward):
            return np.full(len(xy), self.top_z)
        return np.min(-(xy @ self.upward[:, :2].T + self.upward[:, 3]) / self.upward[:, 2], axis=1)


def check_mount_surface(spec: UrdfRobotSpec,
                        shapes: typing.Sequence[typing.Tuple[str, bool, np.ndarray]]) -> None:
    """Refuse a footprint that does not sit on the mount, or that a collision shape rises through: ``ValueError``
    naming the problem and the link.

    ``shapes`` are ``(link, on_mount_body, points (k, 3))`` of every collision shape of the robot (joints at zero)
    in the mount link's frame (m). The footprint's corners must lie within the mount body's outline seen from
    above (the convex hull in x-y of its shapes, not the bounding box); at its corners and centre the top of the
    mount body's shapes must lie at the footprint plane (``footprint_offset_m[2]``) within
    :data:`SURFACE_TOLERANCE_M` (a profile above it would float, one below its top would sit inside it); and no
    shape of any link (a sensor mast, a lidar, an antenna, a wheel) may rise above the plane anywhere within the
    footprint, where the profile would pass through it.
    """
    scipy_spatial = require("scipy.spatial", feature="URDF robots")
    corners = footprint_corners(spec)
    z0 = float(spec.footprint_offset_m[2])
    describe_footprint = (f"footprint {spec.footprint_length_m} x {spec.footprint_width_m} m at offset "
                          f"{list(spec.footprint_offset_m)} m, yaw {spec.footprint_yaw_deg} deg")
    mount_points = np.vstack([points for _, on_mount, points in shapes if on_mount])
    try:
        outline = scipy_spatial.ConvexHull(mount_points[:, :2]).equations
    except Exception as exc:  # QhullError: flat or too few points
        raise ValueError(f"mount link {spec.mount_link!r}: its collision shapes enclose no volume ({exc})") from exc
    outside = (corners[:, :2] @ outline[:, :2].T + outline[:, 2]).max(axis=1) > FOOTPRINT_TOLERANCE_M
    if outside.any():
        low, high = mount_points[:, :2].min(axis=0), mount_points[:, :2].max(axis=0)
        raise ValueError(f"{describe_footprint}: corner(s) {np.round(corners[outside, :2], 4).tolist()} m lie "
                         f"outside mount link {spec.mount_link!r}'s collision shapes (extent x [{low[0]:.4f}, "
                         f"{high[0]:.4f}] m, y [{low[1]:.4f}, {high[1]:.4f}] m)")
    # the footprint sampled on a grid (corners included), plus every shape point inside it
    u = np.linspace(-0.5, 0.5, FOOTPRINT_SAMPLES)
    yaw = math.radians(spec.footprint_yaw_deg)
    along, across = np.array([math.cos(yaw), math.sin(yaw)]), np.array([-math.sin(yaw), math.cos(yaw)])
    grid = np.array([a * spec.footprint_length_m * along + b * spec.footprint_width_m * across
                     for a in u for b in u]) + np.asarray(spec.footprint_offset_m[:2])
    centre = np.asarray(spec.footprint_offset_m[:2], dtype=np.float64)

    def inside_footprint(xy: np.ndarray) -> np.ndarray:
        """Which points ``xy`` (n, 2) lie in the footprint (bool (n,)), m in the mount link's frame."""
        local = xy - centre
        return ((np.abs(local @ along) <= spec.footprint_length_m / 2 + FOOTPRINT_TOLERANCE_M)
                & (np.abs(local @ across) <= spec.footprint_width_m / 2 + FOOTPRINT_TOLERANCE_M))

    tops = [(link, on_mount, _ShapeTop(points, scipy_spatial)) for link, on_mount, points in shapes]
    probes = np.vstack([centre, corners[:, :2]])
    support = np.full(len(probes), -math.inf)
    for link, on_mount, top in tops:  # under each probe, the mount body's top nearest the plane (not a mast's)
        if on_mount:
            covered = top.covers(probes)
            heights = top.top_at(probes[covered])
            nearer = np.abs(heights - z0) < np.abs(support[covered] - z0)
            support[np.flatnonzero(covered)[nearer]] = heights[nearer]
    worst = int(np.argmax(np.abs(support - z0)))
    surface_z = float(support[worst])
    if not math.isfinite(surface_z):
        raise ValueError(f"{describe_footprint}: no collision shape of mount link {spec.mount_link!r}'s body lies "
                         f"under the footprint point {np.round(probes[worst], 4).tolist()} m")
    if abs(z0 - surface_z) > SURFACE_TOLERANCE_M:
        where = "above" if z0 > surface_z else "below"
        point = "centre" if worst == 0 else f"corner {np.round(probes[worst], 4).tolist()} m"
        raise ValueError(f"{describe_footprint}: the profile base at z = {z0:.4f} m is "
                         f"{abs(z0 - surface_z):.4f} m {where} the top of mount link {spec.mount_link!r}'s "
                         f"collision shapes at the footprint's {point} (z = {surface_z:.4f} m in that link's frame); "
                         f"set footprint_offset_m[2] to {surface_z:.5f} so the profile sits on the mount surface"
                         + ("" if np.ptp(support) <= SURFACE_TOLERANCE_M else
                            f", and move the footprint where the surface is level (its tops under the corners and "
                            f"centre range over {np.ptp(support):.4f} m)"))
    for link, _, top in tops:
        samples = grid[top.covers(grid)]
        tops_z = list(top.top_at(samples)) + list(top.points[inside_footprint(top.points[:, :2]), 2])
        highest = max(tops_z, default=-math.inf)
        if highest <= z0 + SURFACE_TOLERANCE_M:
            continue
        raise ValueError(f"{describe_footprint}: link {link!r} rises {highest - z0:.4f} m above the footprint "
                         f"plane inside the footprint (its collision shape reaches z = {highest:.4f} m in mount "
                         f"link {spec.mount_link!r}'s frame), so the profile would pass through it; shrink or "
                         f"move the footprint (footprint_length_m, footprint_width_m, footprint_offset_m) clear "
                         f"of {link!r}")


def footprint_grid(grid: ProfileGrid, urdf_robot: UrdfRobotSpec) -> ProfileGrid:
    """``grid`` (a :class:`~rollability_ros.core.profile.geometry.ProfileGrid`) as the robot in use needs it: with a
    selected ``urdf_robot`` (:class:`UrdfRobotSpec`) its ``length_m`` / ``width_m`` are the mount footprint's."""
    if not urdf_robot.selected:
        return grid
    return dataclasses.replace(grid, length_m=urdf_robot.footprint_length_m, width_m=urdf_robot.footprint_width_m)


def profile_mount(chassis: ChassisSpec, urdf_robot: UrdfRobotSpec) -> typing.Tuple[str, np.ndarray, float]:
    """Where the profile frame sits on the robot in use: ``(link, position_m (3,), yaw_deg)``.

    ``link`` names the link it is mounted on (the chassis URDF's body link, or ``urdf_robot.mount_link``);
    ``position_m`` is the profile frame's origin in that link's frame and ``yaw_deg`` its turn about the link's z.
    Arguments as :func:`footprint_grid` (``chassis`` a :class:`~rollability_ros.core.robots.robot.ChassisSpec`).
    """
    if urdf_robot.selected:
        return urdf_robot.mount_link, np.asarray(urdf_robot.footprint_offset_m, dtype=np.float64), \
            float(urdf_robot.footprint_yaw_deg)
    return ChassisModel.BODY_LINK, ChassisModel(chassis).mount_position_m, 0.0


class RobotChoice:
    """Mixin for settings dataclasses with a chassis ``robot`` (ChassisSpec) and a ``urdf_robot``
    (:class:`UrdfRobotSpec`) field: the built-in chassis unless ``urdf_robot`` names a mount link."""

    robot: ChassisSpec
    urdf_robot: UrdfRobotSpec

    def robot_model(self) -> RobotModel:
        """The :class:`~rollability_ros.core.robots.robot.RobotModel` in use (``ValueError`` for a bad URDF)."""
        if self.urdf_robot.selected:
            return UrdfRobotModel(self.urdf_robot)
        return ChassisModel(self.robot)

    def profile_body(self, mesh: Mesh) -> ProfileBody:
        """The :class:`ProfileBody` of ``mesh`` (trimesh, metres) on the robot in use: made as its ``profile_print``
        says, mass and inertia times its ``profile_mass_scale``."""
        spec = self.urdf_robot if self.urdf_robot.selected else self.robot
        return ProfileBody.from_mesh(mesh, spec.profile_print, spec.profile_mass_scale)

    def print_instructions(self) -> typing.Dict[str, typing.Union[str, float]]:
        """How the profile of the robot in use is printed and weighed (its ``profile_print`` fields and
        ``profile_mass_scale``): what a design set tells the lab to print, and what its masses assume."""
        spec = self.urdf_robot if self.urdf_robot.selected else self.robot
        return {**dataclasses.asdict(spec.profile_print), "profile_mass_scale": float(spec.profile_mass_scale)}


def half_width_across_m(points: np.ndarray, axis: npt.ArrayLike) -> float:
    """Half the smallest width of the points ``(k, 3)`` across ``axis`` (3,): over every direction normal to
    the axis, half the extent of the points along it (m). For a round wheel centred on its axle (a cylinder's
    bounding-box corners, a sphere, a mesh hull) this is its radius."""
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    first = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    first /= np.linalg.norm(first)
    second = np.cross(axis, first)

    def widths(angles: np.ndarray) -> np.ndarray:
        """The points' extent (m) along each direction at ``angles`` (n,), rad, about the axis: (n,)."""
        along = points @ (np.outer(np.cos(angles), first) + np.outer(np.sin(angles), second)).T  # (k, angles)
        return along.max(axis=0) - along.min(axis=0)

    coarse, fine = WIDTH_SEARCH_STEPS
    angles = np.linspace(0.0, math.pi, coarse, endpoint=False)
    step = math.pi / coarse
    narrowest = angles[np.argmin(widths(angles))]
    return float(widths(np.linspace(narrowest - step, narrowest + step, fine)).min() / 2)


def profile_inertia(profile: ProfileBody) -> typing.Tuple[np.ndarray, Mesh]:
    """The inertia (3, 3) about its centre of mass of a :class:`ProfileBody` (kg m^2, as computed from its print)
    and its collision hull (a trimesh)."""
    trimesh = require("trimesh", feature="profile meshes")
    return np.asarray(profile.inertia_kgm2, dtype=np.float64), trimesh.convex.convex_hull(profile.hull_vertices_m)


def profile_link_xml(mount_body: str, profile_in_body: npt.ArrayLike, mesh_filename: typing.Optional[str],
                     profile: typing.Optional[ProfileBody] = None,
                     joint: typing.Tuple[str, str] = ("fixed", "")) -> str:
    """URDF ``<link>`` and ``<joint>`` of the profile on ``mount_body`` (mesh file as collision and visual);
    ``profile_in_body`` (4, 4) places the profile frame in the mount body's frame (m); ``joint``: the joint's type and
    extra tags (:meth:`ProfileMountSpec.joint_xml`), fixed by default."""
    inertial = ""
    if profile is not None:
        inertia, _ = profile_inertia(profile)
        inertial = inertial_xml(profile.mass_kg, profile.com_m, inertia)
    geometry = f'<origin xyz="0 0 0" rpy="0 0 0"/><geometry><mesh filename="{mesh_filename}"/></geometry>'
    return (f'  <link name="{PROFILE_LINK}">{inertial}<visual>{geometry}</visual><collision>{geometry}</collision>'
            f'</link>\n  <joint name="{PROFILE_JOINT}" type="{joint[0]}"><parent link="{mount_body}"/>'
            f'<child link="{PROFILE_LINK}"/>{origin_xml(np.array(profile_in_body))}{joint[1]}</joint>\n')


def obj_text(mesh: Mesh) -> str:
    """``mesh`` (metres) as Wavefront OBJ text (vertices, then 1-based triangles), full float precision."""
    vertices = "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in np.asarray(mesh.vertices).tolist())
    faces = "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in np.asarray(mesh.faces).tolist())
    return vertices + faces


class UrdfRobotModel(SpecThresholds, RobotModel):
    """A robot loaded from a URDF (:class:`UrdfRobotSpec`): base = frame at the robot's centre of mass, one link
    per rigid body, the profile (if any) a link on the mount's body (fixed, or prismatic on a compliant mount)."""

    #: Name of the profile's joint in :meth:`sim_urdf`.
    profile_joint = PROFILE_JOINT

    def __init__(self, spec: UrdfRobotSpec) -> None:
        self.spec = spec
        self.mounted = spec.description()
        self._up_axis = np.asarray(spec.up_axis_xyz, dtype=np.float64) / np.linalg.norm(spec.up_axis_xyz)

    def sim_urdf(self, profile: typing.Optional[ProfileBody] = None, mesh_filename: typing.Optional[str] = None) -> str:
        """The URDF PyBullet loads: the rigid-body robot, plus the profile link on ``mesh_filename`` if given."""
        text = self.mounted.robot.sim_urdf
        if profile is not None:
            text += profile_link_xml(self.mounted.mount_body, self.mounted.profile_in_body, mesh_filename, profile,
                                     self.spec.profile_mount.joint_xml())
        return text + "</robot>\n"

    def spawn(self, client: int, profile: typing.Optional[ProfileBody], position: npt.ArrayLike,
              orientation: typing.Sequence[float], *, time_step_s: typing.Optional[float],
              exact_cylinders: bool = False) -> SpawnedRobot:
        """See :meth:`RobotModel.spawn`: the root frame at ``position`` (3,) m with ``orientation`` (x, y, z, w), turned
        about z so its forward axis points along the orientation's x; ``exact_cylinders``: its cylinders are
        Bullet's round ones (``URDF_USE_IMPLICIT_CYLINDER``)."""
        pybullet = require("pybullet", feature="the simulated evaluator")
        # turn the robot about its z so its forward axis is the start orientation's x (the world's +x upright)
        facing = pybullet.getQuaternionFromEuler([0.0, 0.0, -math.radians(FORWARD_AXIS_DEG[self.spec.forward_axis])])
        _, orientation = pybullet.multiplyTransforms([0.0, 0.0, 0.0], list(orientation), [0.0, 0.0, 0.0], facing)
        with tempfile.TemporaryDirectory(prefix="rollability_urdf_") as folder:
            mesh_filename = None
            if profile is not None:
                _, hull = profile_inertia(profile)
                obj = obj_text(hull)
                # named by content: PyBullet may cache meshes by file name
                mesh_filename = os.path.join(folder, f"profile_{hashlib.sha256(obj.encode()).hexdigest()[:16]}.obj")
                with open(mesh_filename, "w", encoding="utf-8") as stream:
                    stream.write(obj)
            urdf_path = os.path.join(folder, "robot.urdf")
            with open(urdf_path, "w", encoding="utf-8") as stream:
                stream.write(self.sim_urdf(profile, mesh_filename))
            body = pybullet.loadURDF(urdf_path, np.asarray(position, dtype=np.float64).tolist(), list(orientation),
                                     useFixedBase=False,
                                     flags=pybullet.URDF_USE_INERTIA_FROM_FILE | (
                                         pybullet.URDF_USE_IMPLICIT_CYLINDER if exact_cylinders else 0),
                                     physicsClientId=client)
        index, joints = {}, []
        for joint in range(pybullet.getNumJoints(body, physicsClientId=client)):
            info = pybullet.getJointInfo(body, joint, physicsClientId=client)
            index[info[12].decode()] = joint
            if info[2] != pybullet.JOINT_FIXED and info[1].decode() != PROFILE_JOINT:
                joints.append(joint)
        if joints:  # replaces the loader's default motors: an unpowered drive's drag, or free
            pybullet.setJointMotorControlArray(body, joints, pybullet.VELOCITY_CONTROL, targetVelocities=[0.0] * len(joints),
                                               forces=[self.spec.joint_drag_torque_nm] * len(joints),
                                               physicsClientId=client)
        spring = None
        if profile is not None and self.spec.profile_mount.compliant:
            spring = compliant_mount(client, body, index[PROFILE_LINK], self.spec.profile_mount, profile.mass_kg,
                                     time_step_s)
        return SpawnedRobot(body_id=body, wheel_links=tuple(index[name] for name in self.mounted.wheel_bodies),
                            mount_spring=spring, profile_link=None if profile is None else index[PROFILE_LINK],
                            profile_points_m=None if profile is None else profile.hull_vertices_m)

    def up_axis(self, client: int, robot: SpawnedRobot) -> np.ndarray:
        """``up_axis_xyz`` in the world frame, a unit vector (3,)."""
        pybullet = require("pybullet", feature="the simulated evaluator")
        _, orientation = pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)
        return np.asarray(pybullet.getMatrixFromQuaternion(orientation)).reshape(3, 3) @ self._up_axis

    def standing_shapes_m(self) -> StandingShapes:
        robot = self.mounted.robot
        yaw = -math.radians(FORWARD_AXIS_DEG[self.spec.forward_axis])
        facing = np.array([[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0], [0, 0, 1.0]])
        shapes = []
        for link, body, points in robot.collision_shapes:
            in_root = np.array(robot.body_in_root[body])
            shapes.append((link, (np.array(points) @ in_root[:3, :3].T + in_root[:3, 3]) @ facing.T))
        return shapes, facing @ np.asarray(robot.com_m), robot.mass_kg

    def simulator_urdf(self, profile: typing.Optional[ProfileBody] = None,
                       mesh_filename: typing.Optional[str] = None) -> str:
        return self.sim_urdf(profile, mesh_filename)

    def wheel_link_names(self) -> typing.Tuple[str, ...]:
        return tuple(self.mounted.wheel_bodies)

    def joint_drag_torque_nm(self) -> float:
        return self.spec.joint_drag_torque_nm

    def up_axis_in_root(self) -> typing.Tuple[float, ...]:
        return tuple(self.spec.up_axis_xyz)

    def wheel_radii_m(self) -> typing.Tuple[float, ...]:
        """Each wheel body's :func:`half_width_across_m` of its collision shapes across its joint axis (m).

        Raises ``ValueError`` for a wheel body on no moving joint or without a collision shape.
        """
        robot = self.mounted.robot
        joints = {}
        for joint in ElementTree.fromstring(robot.sim_urdf + "</robot>").iter("joint"):
            child = joint.find("child")
            if joint.get("type") != "fixed" and child is not None:
                joints[child.get("link")] = joint
        radii = []
        for body in self.mounted.wheel_bodies:
            if body not in joints:
                raise ValueError(f"wheel body {body!r} turns on no joint: a wheel link must be on a moving joint")
            points = robot.body_collision_points(body)
            if not len(points):
                raise ValueError(f"wheel body {body!r} has no collision shape to roll on")
            axis = joints[body].find("axis")  # in the child link's frame = the wheel body's frame
            xyz = [float(v) for v in (axis.get("xyz", "1 0 0") if axis is not None else "1 0 0").split()]
            radii.append(half_width_across_m(points, xyz))
        return tuple(radii)

    def to_urdf(self, profile_mesh_filename: typing.Optional[str] = None,
                profile: typing.Optional[ProfileBody] = None) -> str:
        """The description as given, plus the profile link (mesh file, inertia if ``profile``) on the mount."""
        text = self.mounted.robot.original_urdf
        if profile_mesh_filename is None:
            return text
        mount_in_body = self.mounted.robot.link_transform(self.spec.mount_link)
        profile_in_mount = np.linalg.inv(mount_in_body) @ np.array(self.mounted.profile_in_body)
        link = profile_link_xml(self.spec.mount_link, profile_in_mount, profile_mesh_filename, profile)
        end = text.rstrip().rfind("</robot>")
        return text[:end] + link + text[end:]
