"""A robot description (URDF) read, checked and turned into the rigid-body model the simulation loads.

Reading
    :func:`read_urdf_source` takes a file path or an XML string, URDF or xacro (expanded with the ``xacro``
    package, :func:`expand_xacro`; an expression left unexpanded is refused naming the element); :func:`resolve_mesh_path` finds mesh files
    named ``package://<pkg>/<rest>``, ``file://<path>``, absolute or relative, against a search path (the
    URDF's own folder first, then the configured folders, then ``<prefix>/share`` of every ``AMENT_PREFIX_PATH``
    prefix for ``package://``). A search-path entry ``python:<module>`` is the folder of an installed Python
    package (e.g. ``python:pybullet_data``), so a config needs no machine paths.
Checking
    :func:`describe` refuses, with a message naming the link, joint or file: unparsable XML, no single root,
    unknown links in joints, unsupported joint types, meshes that do not resolve, ``<inertial>`` elements with a
    missing, zero or negative mass or an inertia that is not positive definite, moving links without mass. An
    ASCII STL collision mesh is replaced by its binary STL (:mod:`~rollability_ros.core.robots.mesh_files`), or
    refused when it is no whole mesh. Non-physical numbers that ran as given: a robot's mass outside
    :data:`~rollability_ros.core.robots.robot.ROBOT_MASS_RANGE_KG`, a rigid body's radius of gyration or a collision
    shape's extent over :data:`~rollability_ros.core.robots.robot.ROBOT_SIZE_MAX_M`.
Rigid bodies
    Links joined by ``fixed`` joints form one rigid body, named after its top link (the root, or a link on a
    moving joint). :func:`describe` merges each body's masses, inertias (parallel-axis theorem, URDF values
    exactly) and collision shapes into one link, and drops links that carry nothing (massless frames such as
    ``imu_link``; PyBullet's loader would otherwise give each 1 kg and a 1 kg m^2 inertia). The result is a
    URDF with one link per rigid body below a frame link ``rollability_base`` placed at the robot's centre of
    mass, axes parallel to the root link (REP 103: x forward, z up). That frame link is PyBullet's base: it has
    an identity inertial frame, so the base pose PyBullet reports and sets is the robot's, not the principal
    axes of some body's inertia, and the trial's start orientation applies to the robot's own axes. It weighs
    :data:`FRAME_MASS_FRACTION` of the robot, joined by a fixed (zero-DOF, exactly rigid) joint.

Frames: every transform is a 4x4 homogeneous matrix (metres); ``T_a_b`` maps coordinates in frame b to a.
"""
import dataclasses
import importlib.util
import math
import os
import typing
import xml.etree.ElementTree as ElementTree

import numpy as np
import numpy.typing as npt

from rollability_ros.core.robots.mesh_files import collision_mesh_file
from rollability_ros.core.robots.robot import ROBOT_SIZE_MAX_M, check_robot_mass

#: Name of the frame link added as PyBullet's base (see the module docstring).
BASE_LINK = "rollability_base"
#: Name of the profile link added on the mount.
PROFILE_LINK = "rollability_profile"
#: Mass of the base frame link relative to the robot (small, but a zero mass would fix the base in place).
FRAME_MASS_FRACTION = 1e-6
MOVING_JOINTS = ("revolute", "continuous", "prismatic")
SUPPORTED_JOINTS = MOVING_JOINTS + ("fixed",)


class _BadTransform:
    """A joint origin that could not be read: an error raised only if a body that matters hangs below it."""

    def __init__(self, message):
        self.message = message


def read_urdf_source(urdf_path: str, robot_description: str, search_paths: typing.Sequence[str] = (),
                     xacro_args: typing.Sequence[str] = ()) -> typing.Tuple[str, typing.Optional[str]]:
    """Return ``(xml_text, folder)`` of the description: the string if given, else the file (its folder).

    A relative ``urdf_path`` is tried from the working directory, then in each search folder. A xacro file
    (``.xacro`` or a root with the xacro namespace) or xacro text is expanded with the ``xacro`` package first.
    Raises ``ValueError`` naming the problem (both or neither given, file not found or unreadable, a xacro that
    does not expand).
    """
    if robot_description and urdf_path:
        raise ValueError("give either urdf_path or robot_description, not both")
    if robot_description:
        return expand_xacro(robot_description, None, search_paths, xacro_args), None
    if not urdf_path:
        raise ValueError("no robot description: set urdf_path or robot_description")
    path = os.path.expanduser(os.path.expandvars(urdf_path))
    candidates = [path] if os.path.isabs(path) else [path] + [os.path.join(d, path) for d in search_folders(search_paths)]
    for candidate in candidates:
        if os.path.isfile(candidate):
            try:
                with open(candidate, encoding="utf-8") as stream:
                    text = stream.read()
            except (OSError, UnicodeDecodeError) as exc:
                raise ValueError(f"cannot read URDF file {candidate}: {exc}") from exc
            return (expand_xacro(text, candidate, search_paths, xacro_args),
                    os.path.dirname(os.path.abspath(candidate)))
    raise ValueError(f"URDF file not found: {urdf_path} (looked in {', '.join(candidates)})")


#: The xacro XML namespace; a description using it needs expanding.
XACRO_NAMESPACE = "http://www.ros.org/wiki/xacro"


def is_xacro(text: str, path: typing.Optional[str] = None) -> bool:
    """True for xacro input: a ``.xacro`` file name, or text that declares the xacro namespace."""
    return bool(path and path.endswith(".xacro")) or XACRO_NAMESPACE in text[:4096] or "<xacro:" in text


def expand_xacro(text: str, path: typing.Optional[str] = None, search_paths: typing.Sequence[str] = (),
                 xacro_args: typing.Sequence[str] = ()) -> str:
    """Expand xacro ``text`` (read from ``path``, for relative includes) with the ``xacro`` package; plain URDF
    is returned unchanged. ``xacro_args`` are ``name:=value`` as on xacro's command line (``$(arg name)``). ``$(find pkg)`` is the package's folder found as ``package://pkg`` is
    (:func:`package_folders`: a search folder's ``pkg`` or a search folder named ``pkg``, then
    ``<prefix>/share/pkg`` of every ``AMENT_PREFIX_PATH`` prefix), so a clone of an upstream repository expands
    without a ROS install. ``ValueError`` names the file and the problem (an undefined property or macro, a
    missing include, ``$(find pkg)`` of a package found nowhere, naming it and where it was looked for)."""
    where = path or "robot_description"
    if not is_xacro(text, path):
        if xacro_args:
            raise ValueError(f"urdf_robot.xacro_args {list(xacro_args)} given, but {where} is not a xacro: nothing "
                             "reads them; remove them")
        return text
    mappings = _XacroArgs()
    for entry in xacro_args:
        name, separator, value = entry.partition(":=")
        if not separator or not name.strip():
            raise ValueError(f"urdf_robot.xacro_args entry {entry!r}: expected name:=value, as on xacro's command line")
        if name.strip() in mappings.given:
            raise ValueError(f"urdf_robot.xacro_args sets {name.strip()!r} twice: give each argument once")
        mappings.given[name.strip()] = value
    mappings.update(mappings.given)
    from rollability_ros.core.optional import require

    xacro = require("xacro", feature="xacro robot descriptions")
    substitution_args = importlib.import_module("xacro.substitution_args")
    folders = [os.path.abspath(folder) for folder in search_folders(search_paths)]   # before the chdir below
    previous = os.getcwd()
    finds = (getattr(substitution_args, "_eval_find"), substitution_args._eval_dict["find"])
    not_found: typing.List[str] = []

    def find(package: str) -> str:
        for candidate in package_folders(package, folders):
            if os.path.isdir(candidate):
                return os.path.abspath(candidate)
        not_found.append(f"$(find {package}): package {package} not found (looked in: "
                         f"{', '.join(package_folders(package, folders)) or 'no search folders'}); add the folder "
                         f"holding {package}/ to urdf_robot.search_paths or put the install prefix holding "
                         f"share/{package} on AMENT_PREFIX_PATH")
        raise ValueError(not_found[-1])

    try:
        # xacro has no hook for $(find): its module function is replaced while this document expands
        setattr(substitution_args, "_eval_find", find)
        substitution_args._eval_dict["find"] = find
        if path:
            os.chdir(os.path.dirname(os.path.abspath(path)))  # xacro resolves relative includes from here
        document = xacro.parse(text, os.path.abspath(path) if path else None)
        xacro.process_doc(document, mappings=mappings)
    except Exception as exc:  # xacro raises XacroException, NameError, KeyError, ... with a readable message
        reason = not_found[-1] if not_found else " ".join(str(exc).split())   # xacro's own spans several lines
        raise ValueError(f"cannot expand xacro {where}: {reason}") from exc
    finally:
        setattr(substitution_args, "_eval_find", finds[0])
        substitution_args._eval_dict["find"] = finds[1]
        os.chdir(previous)
    unread = [name for name in mappings.given if name not in mappings.asked]
    if unread:   # xacro itself expands without them, silently: a misspelt argument would leave its default in place
        raise ValueError(f"urdf_robot.xacro_args {unread[0]!r}: {where} declares no such argument (<xacro:arg>) and "
                         f"reads none by that name; its arguments: {', '.join(sorted(mappings.asked)) or 'none'}")
    return document.toxml()


class _XacroArgs(dict):
    """xacro's table of arguments (it keeps the object it is given): the ``xacro_args`` given, and every name xacro
    looks up in it, as a ``<xacro:arg>`` declares one (``name in``) or a ``$(arg name)`` reads one (``[name]``)."""

    def __init__(self) -> None:
        super().__init__()
        self.given: typing.Dict[str, str] = {}
        self.asked: typing.Set[str] = set()

    def __contains__(self, name: object) -> bool:
        self.asked.add(str(name))
        return super().__contains__(name)

    def __getitem__(self, name: str) -> str:
        self.asked.add(name)
        return super().__getitem__(name)


def without_visuals(xml_text: str) -> str:
    """``xml_text`` with every link's ``<visual>`` elements removed (the simulation never draws them), so visual
    meshes that are not on this machine stop nothing; collision meshes must still resolve."""
    try:
        root = ElementTree.fromstring(xml_text)
    except ElementTree.ParseError as exc:
        raise ValueError(f"robot description is not valid XML: {exc}") from exc
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
    return ElementTree.tostring(root, encoding="unicode")


def search_folders(search_paths: typing.Iterable[str]) -> typing.List[str]:
    """The folders of ``search_paths``: ``~`` and ``$VARS`` expanded, ``python:<module>`` -> the module's folder."""
    folders = []
    for entry in search_paths:
        if entry.startswith("python:"):
            module = entry[len("python:"):]
            try:
                spec = importlib.util.find_spec(module)
            except (ImportError, ValueError):   # a dotted name whose parent is missing, a relative or empty name
                spec = None
            if spec is None or not (spec.submodule_search_locations or spec.origin):
                raise ValueError(f"search path entry {entry}: no installed Python package {module}")
            folders.append(list(spec.submodule_search_locations)[0] if spec.submodule_search_locations
                           else os.path.dirname(str(spec.origin)))
        else:
            folders.append(os.path.expanduser(os.path.expandvars(entry)))
    return folders


def package_folders(package: str, folders: typing.Sequence[str]) -> typing.List[str]:
    """Where package ``package`` may be, in order: ``<folder>/<package>`` of each search folder (or the folder
    itself when it is named ``package``), then ``<prefix>/share/<package>`` of each ``AMENT_PREFIX_PATH`` prefix."""
    tried = []
    for folder in folders:
        tried.append(os.path.join(folder, package))
        if os.path.basename(os.path.normpath(folder)) == package:
            tried.append(folder)
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return tried + [os.path.join(prefix, "share", package) for prefix in prefixes]


def resolve_mesh_path(filename: str, urdf_folder: typing.Optional[str], folders: typing.Sequence[str]) -> str:
    """Return the absolute path of mesh ``filename`` (see the module docstring) or raise ``ValueError``."""
    tried = []
    if filename.startswith("package://"):
        package, _, rest = filename[len("package://"):].partition("/")
        tried += [os.path.join(folder, rest) for folder in package_folders(package, folders)]
    else:
        path = filename[len("file://"):] if filename.startswith("file://") else filename
        if os.path.isabs(path):
            tried.append(path)
        else:
            tried += [os.path.join(folder, path) for folder in ([urdf_folder] if urdf_folder else []) + list(folders)]
    for candidate in tried:
        if os.path.isfile(candidate):
            return os.path.abspath(candidate)
    hint = (f" or put the install prefix holding share/{filename[len('package://'):].partition('/')[0]} on "
            "AMENT_PREFIX_PATH" if filename.startswith("package://") else "")
    raise ValueError(f"mesh {filename} not found (looked in: {', '.join(tried) or 'no search folders'}); "
                     f"add its folder to urdf_robot.search_paths{hint}")


# --- small frame algebra ----------------------------------------------------------------------------------------
def rpy_matrix(rpy: typing.Sequence[float]) -> np.ndarray:
    """Rotation matrix (3, 3) of URDF roll-pitch-yaw (rad): fixed axes x, then y, then z."""
    r, p, y = rpy
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def matrix_rpy(rotation: np.ndarray) -> typing.Tuple[float, float, float]:
    """URDF roll-pitch-yaw (rad) of a rotation matrix (3, 3)."""
    pitch = math.atan2(-rotation[2, 0], math.hypot(rotation[0, 0], rotation[1, 0]))
    if math.hypot(rotation[0, 0], rotation[1, 0]) < 1e-12:  # gimbal lock: put it all in roll
        return (math.atan2(-rotation[1, 2], rotation[1, 1]), pitch, 0.0)
    return (math.atan2(rotation[2, 1], rotation[2, 2]), pitch, math.atan2(rotation[1, 0], rotation[0, 0]))


def transform(xyz: typing.Sequence[float] = (0.0, 0.0, 0.0),
              rpy: typing.Sequence[float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """4x4 transform of a URDF origin (xyz metres, rpy rad)."""
    matrix = np.eye(4)
    matrix[:3, :3] = rpy_matrix(rpy)
    matrix[:3, 3] = xyz
    return matrix


def _numbers(text, count, where):
    try:
        values = [float(v) for v in (text or "").split()]
    except ValueError:
        values = []
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{where}: expected {count} numbers, got {text!r}")
    return values


def origin_of(element: ElementTree.Element, where: str) -> np.ndarray:
    """The 4x4 transform of ``element``'s ``<origin>`` child (identity when absent)."""
    origin = element.find("origin")
    if origin is None:
        return np.eye(4)
    return transform(_numbers(origin.get("xyz", "0 0 0"), 3, f"{where} origin xyz"),
                     _numbers(origin.get("rpy", "0 0 0"), 3, f"{where} origin rpy"))


def _fmt(values):
    return " ".join(repr(float(v)) for v in values)


def origin_xml(matrix: np.ndarray) -> str:
    """``<origin .../>`` of a 4x4 transform (full float precision)."""
    return f'<origin xyz="{_fmt(matrix[:3, 3])}" rpy="{_fmt(matrix_rpy(matrix[:3, :3]))}"/>'


def inertial_xml(mass_kg: float, com_m: typing.Iterable[float], inertia: npt.ArrayLike) -> str:
    """``<inertial>`` with the centre of mass ``com_m`` (3,) and the inertia (3, 3) about it, link axes."""
    i = np.asarray(inertia, dtype=np.float64).tolist()
    return (f'<inertial><origin xyz="{_fmt(com_m)}" rpy="0 0 0"/><mass value="{float(mass_kg)!r}"/>'
            f'<inertia ixx="{i[0][0]!r}" ixy="{i[0][1]!r}" ixz="{i[0][2]!r}" iyy="{i[1][1]!r}" iyz="{i[1][2]!r}" '
            f'izz="{i[2][2]!r}"/></inertial>')


# --- the description --------------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class RobotDescription:
    """A checked robot description, picklable: what :class:`~rollability_ros.core.robots.urdf_robot.UrdfRobotModel`
    spawns and exports.

    ``sim_urdf`` is the rigid-body URDF (see the module docstring) without its closing ``</robot>``, so a profile
    link can be appended; its mesh paths are absolute. ``original_urdf`` is the description as given.
    ``body_of`` maps every link name to its rigid body's name; ``link_in_body`` holds each link's 4x4 transform
    in its body's frame (nested tuples), for the links whose placement could be read. ``moving_joints`` are the
    sim URDF's non-fixed joints; ``mass_kg`` and ``com_m`` the robot's total mass and centre of mass (root frame).
    ``collision_shapes`` holds one ``(link, body, points)`` per collision element (its corner / vertex points in
    the body's frame, m) and ``body_in_root`` each rigid body's 4x4 transform in the root link's frame with every
    joint at zero (nested tuples).
    """

    name: str
    sim_urdf: str
    original_urdf: str
    body_of: dict
    link_in_body: dict
    moving_joints: tuple
    mass_kg: float
    com_m: tuple
    collision_points: dict
    collision_shapes: tuple = ()
    body_in_root: dict = dataclasses.field(default_factory=dict)

    def link_transform(self, link: str) -> np.ndarray:
        """4x4 transform of ``link`` in its rigid body's frame; ``ValueError`` if unknown or unreadable."""
        if link not in self.body_of:
            raise ValueError(f"unknown link {link!r}; the description has: {', '.join(sorted(self.body_of))}")
        value = self.link_in_body[link]
        if isinstance(value, str):
            raise ValueError(value)
        return np.array(value)

    def body_collision_points(self, body: str) -> np.ndarray:
        """Corner / vertex points ``(k, 3)`` of the collision shapes of rigid body ``body`` (body frame, m)."""
        return np.array(self.collision_points.get(body, ()), dtype=np.float64).reshape(-1, 3)


def _parse(xml_text):
    try:
        root = ElementTree.fromstring(xml_text)
    except ElementTree.ParseError as exc:
        raise ValueError(f"robot description is not valid XML: {exc}") from exc
    if root.tag != "robot":
        raise ValueError(f"robot description must have a <robot> root element, got <{root.tag}>")
    # names and link references must be final; a number left as an expression is caught where it is read (an
    # unused frame's origin may stay unexpanded, as in the Husky URDF of pybullet_data)
    for element in root.iter():
        for attribute, value in element.attrib.items():
            if attribute in ("name", "link") and ("${" in value or "$(" in value):
                raise ValueError(f"<{element.tag} {attribute}={value!r}> holds an unexpanded xacro expression: "
                                 f"give the .xacro file itself (it is expanded with the xacro package) or "
                                 f"expand it first with `xacro robot.urdf.xacro > robot.urdf`")
    links = {}
    for link in root.findall("link"):
        name = link.get("name")
        if not name:
            raise ValueError("a <link> has no name")
        if name in links:
            raise ValueError(f"link {name!r} is defined twice")
        if name in (BASE_LINK, PROFILE_LINK):
            raise ValueError(f"link name {name!r} is reserved for the profile simulation")
        links[name] = link
    if not links:
        raise ValueError("robot description has no <link>")
    joints: typing.Dict[str, ElementTree.Element] = {}
    for joint in root.findall("joint"):
        name, kind = joint.get("name"), joint.get("type")
        parent, child = joint.find("parent"), joint.find("child")
        if not name or parent is None or child is None:
            raise ValueError(f"joint {name!r} needs a name, a <parent> and a <child>")
        if kind not in SUPPORTED_JOINTS:
            raise ValueError(f"joint {name!r} has type {kind!r}; supported: {', '.join(SUPPORTED_JOINTS)}")
        for end in (parent.get("link"), child.get("link")):
            if end not in links:
                raise ValueError(f"joint {name!r} refers to unknown link {end!r}")
        if child.get("link") in {_end(j, "child") for j in joints.values()}:
            raise ValueError(f"link {child.get('link')!r} is the child of more than one joint")
        if kind in MOVING_JOINTS:
            _check_joint_numbers(joint, name)
        joints[name] = joint
    return root, links, joints


def _check_joint_numbers(joint: ElementTree.Element, name: str) -> None:
    """``ValueError`` naming a moving joint whose ``<axis>``, ``<limit>`` or ``<dynamics>`` (copied into the
    simulation's URDF) holds a value that is not a finite number, or whose axis is the zero vector: PyBullet and
    MuJoCo take them as given and a NaN damping or a zero axis ends in NaN poses or verdicts, not an error."""
    for tag in ("axis", "limit", "dynamics"):
        for element in joint.findall(tag):
            for key, value in element.attrib.items():
                _numbers(value, 3 if tag == "axis" else 1, f"joint {name!r} {tag} {key}")
    axis = joint.find("axis")
    if axis is not None and not np.linalg.norm(_numbers(axis.get("xyz", "1 0 0"), 3, f"joint {name!r} axis xyz")) > 0:
        raise ValueError(f"joint {name!r} has axis xyz {axis.get('xyz')!r}: a moving joint needs a non-zero axis")


def _end(joint: ElementTree.Element, end: str) -> str:
    """The link named by a checked joint's ``<parent>`` or ``<child>`` (``_read_links`` refused one without)."""
    element = joint.find(end)
    assert element is not None, end
    return element.get("link", "")


def _tree(links, joints):
    """Return ``(root link, {parent: [joint, ...]})``, checking there is one root and no loop."""
    children: typing.Dict[str, typing.List[ElementTree.Element]] = {name: [] for name in links}
    child_links = set()
    for joint in joints.values():
        children[_end(joint, "parent")].append(joint)
        child_links.add(_end(joint, "child"))
    roots = [name for name in links if name not in child_links]
    if len(roots) != 1:
        raise ValueError(f"robot description needs exactly one root link, found {len(roots)}: {', '.join(roots)}")
    return roots[0], children


def _inertial(link, name):
    """``(mass, com (3,), inertia (3, 3) about the com, link axes)`` of a link, or None without ``<inertial>``."""
    inertial = link.find("inertial")
    if inertial is None:
        return None
    mass_element, tensor = inertial.find("mass"), inertial.find("inertia")
    if mass_element is None or tensor is None:
        raise ValueError(f"link {name!r}: <inertial> needs <mass> and <inertia>")
    (mass,) = _numbers(mass_element.get("value"), 1, f"link {name!r} mass")
    if mass <= 0:
        raise ValueError(f"link {name!r} has mass {mass} kg: masses must be > 0 (remove <inertial> for a frame)")
    values = {key: _numbers(tensor.get(key, "0"), 1, f"link {name!r} inertia {key}")[0]
              for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    matrix = np.array([[values["ixx"], values["ixy"], values["ixz"]],
                       [values["ixy"], values["iyy"], values["iyz"]],
                       [values["ixz"], values["iyz"], values["izz"]]])
    if np.linalg.eigvalsh(matrix).min() <= 0:
        raise ValueError(f"link {name!r} has an inertia that is not positive definite: {values}")
    frame = origin_of(inertial, f"link {name!r} inertial")
    return mass, frame[:3, 3], frame[:3, :3] @ matrix @ frame[:3, :3].T


def _sizes(text, count, where):
    """``count`` positive finite numbers of ``text`` (a box's size, a radius, a length: m); ``ValueError`` naming
    ``where`` otherwise (MuJoCo refuses a size <= 0 in two lines from the middle of a launch; PyBullet runs it)."""
    values = _numbers(text, count, where)
    if min(values) <= 0:
        raise ValueError(f"{where}: expected {count} number(s) > 0, got {text!r}")
    return values


def _check_extent(points, where, mesh):
    """``ValueError`` naming ``where`` when the shape's points ``(k, 3)`` (m) span more than
    :data:`ROBOT_SIZE_MAX_M`."""
    extent = float(np.ptp(points, axis=0).max())
    if extent > ROBOT_SIZE_MAX_M:
        hint = " (a mesh in millimetres needs scale=\"0.001 0.001 0.001\")" if mesh is not None else ""
        raise ValueError(f"{where}: the shape spans {extent:g} m, over the {ROBOT_SIZE_MAX_M:g} m any part of a robot "
                         f"on the rig may{hint}")


def _check_body_inertia(name, mass_kg, inertia):
    """``ValueError`` naming the rigid body ``name`` whose radius of gyration (sqrt(largest moment / mass)) is over
    :data:`ROBOT_SIZE_MAX_M`: an inertia no body of that mass and size has (1e300 kg m^2 ran as given)."""
    radius_m = math.sqrt(float(np.linalg.eigvalsh(inertia).max()) / mass_kg)
    if radius_m > ROBOT_SIZE_MAX_M:
        raise ValueError(f"rigid body {name!r} ({mass_kg:g} kg): its inertia's largest moment "
                         f"{float(np.linalg.eigvalsh(inertia).max()):g} kg m^2 means a radius of gyration of "
                         f"{radius_m:g} m, over the {ROBOT_SIZE_MAX_M:g} m any part of a robot on the rig may")


def mesh_hull_vertices(mesh_path: str, where: str) -> np.ndarray:
    """The vertices ``(k, 3)`` of the convex hull of the mesh file ``mesh_path`` (its units); ``ValueError`` in one
    line naming ``where`` and the file when it cannot be read, holds no vertex or a vertex that is not a finite
    number, or encloses no volume (a flat or empty file: trimesh and Qhull raise in several lines, or as an error
    that is not a ``ValueError``). Both engines collide with a mesh's hull."""
    from rollability_ros.core.optional import require

    trimesh = require("trimesh", feature="URDF mesh collision shapes")
    try:
        loaded = trimesh.load(mesh_path, force="mesh")
        vertices = np.asarray(getattr(loaded, "vertices", ()), dtype=np.float64).reshape(-1, 3)
    except Exception as exc:  # trimesh raises assorted parser errors
        raise ValueError(f"{where}: cannot read mesh {mesh_path}: {' '.join(str(exc).split())}") from exc
    if not len(vertices) or not np.all(np.isfinite(vertices)):
        raise ValueError(f"{where}: mesh {mesh_path} holds no vertices, or one that is not a finite number (an empty, "
                         "damaged or foreign file?)")
    try:
        hull = loaded.convex_hull
    except Exception as exc:  # QhullError: flat, a line or too few points
        raise ValueError(f"{where}: mesh {mesh_path} encloses no volume (its {len(vertices)} vertices lie in a "
                         "plane or on a line)") from exc
    return np.asarray(hull.vertices, dtype=np.float64)


def _geometry_points(geometry, where, mesh_path):
    """Points ``(k, 3)`` whose hull bounds a URDF geometry, in the geometry's frame (m). A mesh in ASCII STL is
    renamed in ``geometry`` to its binary STL (:func:`~rollability_ros.core.robots.mesh_files.collision_mesh_file`),
    the file the simulation's URDF then names."""
    box, cylinder, sphere, mesh = (geometry.find(tag) for tag in ("box", "cylinder", "sphere", "mesh"))
    if box is not None:
        half = np.array(_sizes(box.get("size"), 3, f"{where} box size")) / 2
    elif cylinder is not None:
        radius = _sizes(cylinder.get("radius"), 1, f"{where} cylinder radius")[0]
        half = np.array([radius, radius, _sizes(cylinder.get("length"), 1, f"{where} cylinder length")[0] / 2])
    elif sphere is not None:
        half = np.full(3, _sizes(sphere.get("radius"), 1, f"{where} sphere radius")[0])
    elif mesh is not None:
        scale = np.array(_numbers(mesh.get("scale", "1 1 1"), 3, f"{where} mesh scale"))
        if not np.all(scale):
            raise ValueError(f"{where}: mesh scale {mesh.get('scale')!r} has a zero: the shape would be flat")
        mesh_path = collision_mesh_file(mesh_path, where)   # an ASCII STL: its binary STL, which the engines read
        mesh.set("filename", mesh_path)
        points = mesh_hull_vertices(mesh_path, where) * scale
        _check_extent(points, where, mesh)
        return points
    else:
        raise ValueError(f"{where}: geometry must be a box, cylinder, sphere or mesh")
    points = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    _check_extent(points, where, None)
    return points


def _resolve_meshes(root_element, urdf_folder, folders):
    """Set every ``<mesh filename>`` of the description to the file it names (:func:`resolve_mesh_path`)."""
    visual_meshes = {id(mesh) for visual in root_element.iter("visual") for mesh in visual.iter("mesh")}
    for element in root_element.iter("mesh"):
        try:
            element.set("filename", resolve_mesh_path(element.get("filename", ""), urdf_folder, folders))
        except ValueError as exc:
            if id(element) not in visual_meshes:
                raise
            raise ValueError(f"visual {exc}, or set urdf_robot.ignore_visual_meshes: true (the simulation never "
                             "draws visuals)") from None


def _place_links(root, children):
    """``(link_in_body, body_of, order, moving)``: each link's placement in its body (a 4x4 transform, or the
    _BadTransform that keeps it from being placed), the body (the moving link) each link is fixed to, the links
    breadth first from ``root``, and the moving joints as ``(joint element, parent link, placement)``."""
    link_in_body: typing.Dict[str, typing.Any] = {root: np.eye(4)}
    body_of, order = {root: root}, [root]
    moving: typing.List[typing.Tuple[typing.Any, str, typing.Any]] = []
    for name in order:  # breadth first: parents before children
        for joint in children[name]:
            child = _end(joint, "child")
            order.append(child)
            parent_in_body = link_in_body[name]
            joint_origin: typing.Any   # a 4x4 transform or a _BadTransform
            try:
                joint_origin = origin_of(joint, f"joint {joint.get('name')!r}")
            except ValueError as exc:
                joint_origin = _BadTransform(str(exc))
            if isinstance(parent_in_body, _BadTransform) or isinstance(joint_origin, _BadTransform):
                placement = parent_in_body if isinstance(parent_in_body, _BadTransform) else joint_origin
            else:
                placement = parent_in_body @ joint_origin
            if joint.get("type") == "fixed":
                body_of[child], link_in_body[child] = body_of[name], placement
            else:
                body_of[child], link_in_body[child] = child, np.eye(4)
                moving.append((joint, name, placement))
    return link_in_body, body_of, order, moving


def _check_masses(bodies, moving, root):
    """``ValueError`` naming a moving link, or the root, whose body has no mass."""
    for joint, _, _ in moving:
        child = _end(joint, "child")
        if bodies[child]["mass"] <= 0:
            raise ValueError(f"link {child!r} moves on joint {joint.get('name')!r} but has no mass (no <inertial> "
                             "on it or on links fixed to it)")
    if bodies[root]["mass"] <= 0:
        raise ValueError(f"root link {root!r} and the links fixed to it have no mass (no <inertial>)")


def _body_inertials(bodies):
    """``{body: (mass, centre of mass, inertia about it)}`` of the bodies with mass, their parts combined."""
    body_inertials = {}
    for name, body in bodies.items():
        if body["mass"] <= 0:
            continue  # cannot happen for a moving body (describe checks): the root is checked too
        com = body["moment"] / body["mass"]
        inertia = np.zeros((3, 3))
        for mass, centre, part in body["parts"]:
            offset = centre - com
            inertia += part + mass * (offset @ offset * np.eye(3) - np.outer(offset, offset))
        _check_body_inertia(name, body["mass"], inertia)
        body_inertials[name] = (body["mass"], com, inertia)
    return body_inertials


def _sim_urdf(name, root, mass_kg, com_m, bodies, body_inertials, moving, body_of):
    """The simulation's URDF text: a base link at the robot's centre of mass, one link per body, the moving
    joints."""
    parts = [f'<?xml version="1.0"?>\n<robot name="{name}_rollability">',
             f'<link name="{BASE_LINK}">' + inertial_xml(mass_kg * FRAME_MASS_FRACTION, np.zeros(3),
                                                         np.eye(3) * mass_kg * FRAME_MASS_FRACTION * 1e-2) + "</link>",
             f'<joint name="{BASE_LINK}_joint" type="fixed"><parent link="{BASE_LINK}"/><child link="{root}"/>'
             f'{origin_xml(transform(-com_m))}</joint>']
    for link, body in bodies.items():
        inertial = inertial_xml(*body_inertials[link]) if link in body_inertials else ""
        parts.append(f'<link name="{link}">{inertial}{"".join(body["collisions"])}{body["contact"] or ""}</link>')
    for joint, parent, placement in moving:
        extras = "".join(ElementTree.tostring(element, encoding="unicode").strip()
                         for tag in ("axis", "limit", "dynamics") for element in joint.findall(tag))
        parts.append(f'<joint name="{joint.get("name")}" type="{joint.get("type")}"><parent link="{body_of[parent]}"/>'
                     f'<child link="{_end(joint, "child")}"/>{origin_xml(placement)}{extras}</joint>')
    return "\n".join(parts) + "\n"


def describe(xml_text: str, urdf_folder: typing.Optional[str] = None,
             search_paths: typing.Sequence[str] = ()) -> RobotDescription:
    """Check a URDF and build its :class:`RobotDescription` (see the module docstring); ``ValueError`` if bad."""
    root_element, links, joints = _parse(xml_text)
    root, children = _tree(links, joints)
    _resolve_meshes(root_element, urdf_folder, search_folders(search_paths))
    link_in_body, body_of, order, moving = _place_links(root, children)
    if len(order) != len(links):
        raise ValueError("robot description has links not connected to the root: "
                         f"{', '.join(sorted(set(links) - set(order)))}")

    def placed(link: str, what: str) -> np.ndarray:
        """``link``'s 4x4 transform in its body's frame; ``ValueError`` when its placement could not be read."""
        value = link_in_body[link]
        if isinstance(value, _BadTransform):
            raise ValueError(f"{value.message} (needed to place {what} of link {link!r})")
        return value

    bodies: typing.Dict[str, typing.Dict[str, typing.Any]] = {
        name: {"mass": 0.0, "moment": np.zeros(3), "parts": [], "collisions": [], "points": [], "contact": None}
        for name in order if body_of[name] == name}
    shapes = []
    for name in order:
        body = bodies[body_of[name]]
        inertial = _inertial(links[name], name)
        if inertial is not None:
            frame = placed(name, "the inertial")
            mass, com, inertia = inertial
            centre = frame[:3, :3] @ com + frame[:3, 3]
            body["parts"].append((mass, centre, frame[:3, :3] @ inertia @ frame[:3, :3].T))
            body["mass"] += mass
            body["moment"] += mass * centre
        for index, collision in enumerate(links[name].findall("collision")):
            where = f"link {name!r} collision {index}"
            geometry = collision.find("geometry")
            if geometry is None:
                raise ValueError(f"{where} has no <geometry>")
            frame = placed(name, "a collision shape") @ origin_of(collision, where)
            mesh = geometry.find("mesh")
            points = _geometry_points(geometry, where, mesh.get("filename") if mesh is not None else None)
            in_body = (points @ frame[:3, :3].T + frame[:3, 3]).tolist()
            body["points"].extend(in_body)
            shapes.append((name, body_of[name], tuple(map(tuple, in_body))))
            body["collisions"].append(f"<collision>{origin_xml(frame)}"
                                      f"{ElementTree.tostring(geometry, encoding='unicode').strip()}</collision>")
        if body["contact"] is None and links[name].find("contact") is not None:
            body["contact"] = ElementTree.tostring(links[name].find("contact"), encoding="unicode").strip()

    _check_masses(bodies, moving, root)

    body_inertials = _body_inertials(bodies)

    # centre of mass of the whole robot (joints at zero), in the root frame
    body_in_root = {root: np.eye(4)}
    for joint, parent, placement in moving:
        child = joint.find("child").get("link")
        if isinstance(placement, _BadTransform):
            raise ValueError(f"{placement.message} (needed to place link {child!r})")
        body_in_root[child] = body_in_root[body_of[parent]] @ placement
    mass_kg = sum(b[0] for b in body_inertials.values())
    check_robot_mass(mass_kg, "robot description (its <inertial> masses)")
    com_m = sum(b[0] * (body_in_root[n][:3, :3] @ b[1] + body_in_root[n][:3, 3])
                for n, b in body_inertials.items()) / mass_kg

    sim_urdf = _sim_urdf(root_element.get("name", "robot"), root, mass_kg, com_m, bodies, body_inertials, moving,
                         body_of)
    return RobotDescription(
        name=root_element.get("name", "robot"), sim_urdf=sim_urdf, original_urdf=xml_text,
        body_of=dict(body_of),
        link_in_body={k: (v.message if isinstance(v, _BadTransform) else tuple(map(tuple, v.tolist())))
                      for k, v in link_in_body.items()},
        moving_joints=tuple(j.get("name") for j, _, _ in moving), mass_kg=float(mass_kg),
        com_m=tuple(float(v) for v in com_m),
        collision_points={name: tuple(map(tuple, body["points"])) for name, body in bodies.items() if body["points"]},
        collision_shapes=tuple(shapes),
        body_in_root={name: tuple(map(tuple, matrix.tolist())) for name, matrix in body_in_root.items()})
