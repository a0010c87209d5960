"""The launch twin's settings (``config/launch_twin.yaml`` and the namespaces it reads) and their parameter files;
the model they parameterise is described in :mod:`rollability_ros.core.sim.launch`."""
import dataclasses
import math
import os
import typing

import numpy as np

from rollability_ros.core.config import ConfigError, from_mapping, load_parameters, resolve_config_path, section
from rollability_ros.core.profile import DesignSources
from rollability_ros.core.robots import ChassisSpec, RobotChoice, UrdfRobotSpec
from rollability_ros.core.sim.trials import TrialSettings
from rollability_ros.core.sim.world import PhysicsParams


#: ``launch_twin.angle_convention`` values (see the package docstring).
ANGLE_CONVENTIONS = ("yaw_of_push", "chassis_yaw")

#: ``launch_twin.wheel_model`` values: whose wheel contact and drag the twin uses (package docstring, "Wheels").
WHEEL_MODELS = ("auto", "mecanum", "robot")


#: ``launch_twin.launcher.model`` values: how the cylinder drives the push plate (package docstring, "Launch").
LAUNCHER_MODELS = ("stroke", "push_through")

#: Pa per psi (the paper's regulator reads psi).
PA_PER_PSI = 6894.757

def _setting(default: typing.Any, description: str, value_range: typing.Optional[tuple] = None) -> typing.Any:
    """A settings field with the project's metadata (``description``, and ``range`` (low, high) when numeric)."""
    metadata = {"description": description, **({"range": value_range} if value_range is not None else {})}
    if isinstance(default, list):
        return dataclasses.field(default_factory=lambda: list(default), metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)

@dataclasses.dataclass
class LauncherSpec:
    """The launcher's run, ledge and cylinder (``launch_twin.launcher``); metres (package docstring, "Launch").

    Sources: ``run_length_m``, ``stroke_m``, the 25 mm bore and the regulator's 30 / 60 psi for 0.8 / 1.5 m/s are
    the paper's (section 2.2); ``ledge_rolling_friction`` and ``speed_bias_fraction`` are unknowns (0 = none), for
    calibration and the robust draws."""

    run_length_m: float = _setting(0.34, "travel of the robot's foremost point from its start to the edge, m "
                                         "(paper 2.2: the speed gate's run)", (0.05, 2.0))
    ledge_depth_m: float = _setting(0.0, "base plate and table behind the edge, m; 0 = derived from the robot",
                                    (0.0, 20.0))
    ledge_width_m: float = _setting(0.0, "base plate along the edge, m; 0 = derived from the robot", (0.0, 20.0))
    start_clearance_m: float = _setting(0.0005, "gap under the lowest wheel when placed on the plate, m",
                                        (0.0, 0.01))
    model: str = _setting("stroke", "how the cylinder drives the push plate: stroke (the paper's cylinder: pushes "
                                    "for stroke_m, then stops; the robot coasts to the edge) | push_through (the "
                                    "plate drives the robot at the launch speed until it goes over the edge)")
    stroke_m: float = _setting(0.15, "cylinder stroke: the plate's travel before it stops, m (paper 2.2: MAL 25 x "
                                     "150)", (0.01, 2.0))
    bore_m: float = _setting(0.0, "cylinder bore, m; 0 = derived: the paper's 25 mm on the built-in chassis, "
                                  "scaled with the square root of a heavier robot's mass", (0.0, 0.5))
    pressure_speeds_mps: typing.List[float] = _setting(
        [0.8, 1.5], "set launch speeds the regulator pressures below belong to, m/s (paper 2.2; as "
                    "config/rig.yaml valve.regulator)")
    pressures_psi: typing.List[float] = _setting(
        [30.0, 60.0], "regulator pressure per set speed above, psi (paper 2.2); between and beyond them the "
                      "pressure is interpolated linearly and held at the end values")
    ledge_rolling_friction: float = _setting(
        0.0, "UNKNOWN: the launcher base plate's own rolling friction, m (Bullet's rolling friction: a wheel "
             "coasting on it meets this x the wheel's friction more); slows the coast from the stroke's end to the "
             "edge", (0.0, 0.01))
    speed_bias_fraction: float = _setting(
        0.0, "UNKNOWN: systematic error of the lab's speed setting, fraction of the set speed (the gate accepts "
             "launches within speed_gate.tolerance_fraction of it)", (-0.15, 0.15))

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field (a ledge size or bore of 0 is derived from the
        robot)."""
        if not self.run_length_m > 0:
            raise ValueError(f"run_length_m must be > 0, got {self.run_length_m}")
        for name in ("ledge_depth_m", "ledge_width_m"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0 (0 = derived from the robot), got {getattr(self, name)}")
        if self.ledge_depth_m and self.ledge_depth_m <= self.run_length_m:
            raise ValueError(f"ledge_depth_m {self.ledge_depth_m} must exceed run_length_m {self.run_length_m}")
        if not 0 <= self.start_clearance_m < 0.01:
            raise ValueError(f"start_clearance_m must be in [0, 0.01), got {self.start_clearance_m}")
        if self.model not in LAUNCHER_MODELS:
            raise ValueError(f"model must be one of {', '.join(LAUNCHER_MODELS)}, got {self.model!r}")
        if not 0 < self.stroke_m <= 2.0:
            raise ValueError(f"stroke_m must be in (0, 2], got {self.stroke_m}")
        if not 0 <= self.bore_m <= 0.5:
            raise ValueError(f"bore_m must be in [0, 0.5] (0 = derived from the robot), got {self.bore_m}")
        speeds, pressures = list(self.pressure_speeds_mps), list(self.pressures_psi)
        if not speeds or len(speeds) != len(pressures):
            raise ValueError(f"pressure_speeds_mps ({len(speeds)}) and pressures_psi ({len(pressures)}) must be "
                             "non-empty and the same length")
        if not all(0 < s < math.inf for s in speeds) or any(b <= a for a, b in zip(speeds, speeds[1:])):
            raise ValueError(f"pressure_speeds_mps must be positive and increasing, got {speeds}")
        if not all(0 < p < math.inf for p in pressures):
            raise ValueError(f"pressures_psi must be positive, got {pressures}")
        if not 0 <= self.ledge_rolling_friction <= 0.01:
            raise ValueError(f"ledge_rolling_friction must be in [0, 0.01], got {self.ledge_rolling_friction}")
        if not -0.15 <= self.speed_bias_fraction <= 0.15:
            raise ValueError(f"speed_bias_fraction must be in [-0.15, 0.15], got {self.speed_bias_fraction}")

    def pressure_psi(self, speed_mps: float) -> float:
        """The regulator pressure (psi) the lab sets for a set speed of ``speed_mps``: linear between the
        configured pairs, the end values beyond them."""
        return float(np.interp(speed_mps, self.pressure_speeds_mps, self.pressures_psi))

@dataclasses.dataclass
class PushPlateSpec:
    """The launcher's push plate (``launch_twin.plate``): a box on a velocity-controlled prismatic joint; metres.

    ``offset_m`` shifts the plate sideways (+ = left of the push direction) off the chassis's path and
    ``yaw_bias_deg`` turns its face (counterclockwise from above) away from square to the push: the rig's
    asymmetry, which calibration can fit. ``max_force_n`` is the most the cylinder pushes with (a 25 mm bore
    gives about 100 N at 30 psi and 200 N at 60 psi); the plate's speed ramps from rest to the launch speed in
    ``ramp_s`` (the chassis is pushed up to speed through the plate, so the plate's offset and turn act on it).
    """

    width_m: float = 0.0
    height_m: float = 0.0
    thickness_m: float = 0.01
    mass_kg: float = 0.3
    clearance_m: float = 0.0
    max_force_n: float = 0.0
    ramp_s: float = 0.012
    offset_m: float = 0.0
    yaw_bias_deg: float = 0.0

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field (``width_m``, ``height_m`` and ``clearance_m`` of 0
        are derived from the robot: :mod:`~rollability_ros.core.sim.launcher_geometry`)."""
        for name in ("thickness_m", "mass_kg", "ramp_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("width_m", "height_m", "max_force_n"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0 (0 = derived from the robot), got {getattr(self, name)}")
        if not 0 <= self.clearance_m < 0.1:
            raise ValueError(f"clearance_m must be in [0, 0.1), got {self.clearance_m}")
        if not abs(self.offset_m) < 0.5:
            raise ValueError(f"offset_m must be within +-0.5 m, got {self.offset_m}")
        if not abs(self.yaw_bias_deg) <= 20:
            raise ValueError(f"yaw_bias_deg must be within +-20 deg, got {self.yaw_bias_deg}")

@dataclasses.dataclass
class FoamSpec:
    """The memory-foam layer under the impact region (``launch_twin.foam``)."""

    thickness_m: float = 0.05
    length_m: float = 2.5
    width_m: float = 3.0
    contact_stiffness_npm: float = _setting(2.0e4, "UNKNOWN: Bullet contact stiffness per contact point, N/m "
                                                   "(guessed: ~4 cm under a 1.3 m drop)", (1.0e3, 1.0e6))
    contact_damping_nspm: float = _setting(150.0, "UNKNOWN: Bullet contact damping per contact point, N s/m "
                                                  "(guessed: memory foam barely rebounds)", (0.0, 2000.0))
    lateral_friction: float = _setting(1.0, "UNKNOWN: the foam's own friction coefficient; Bullet multiplies it with "
                                            "the robot's (sim.lateral_friction 0.35) (guessed)", (0.3, 3.0))
    rolling_friction: float = _setting(0.01, "UNKNOWN: the foam's own rolling friction, m: a wheel on the foam meets "
                                             "this x the wheel's friction more (guessed: a wheel sinks in)",
                                       (0.0, 0.05))
    restitution: float = _setting(0.1, "UNKNOWN: the foam's own restitution; times the robot's 0.3 per contact "
                                       "(guessed)", (0.0, 1.0))

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        for name in ("thickness_m", "length_m", "width_m", "contact_stiffness_npm"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("contact_damping_nspm", "lateral_friction", "rolling_friction"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not 0 <= self.restitution <= 1:
            raise ValueError(f"restitution must be in [0, 1], got {self.restitution}")

    def contact(self, ground_contact: typing.Mapping[str, float]) -> typing.Dict[str, float]:
        """The foam's ``changeDynamics`` keywords: ``ground_contact``'s spinning friction, the foam's own rest."""
        return {**ground_contact, "lateralFriction": self.lateral_friction, "rollingFriction": self.rolling_friction,
                "restitution": self.restitution,
                "contactStiffness": self.contact_stiffness_npm, "contactDamping": self.contact_damping_nspm}

@dataclasses.dataclass
class LaunchTwinOptions:
    """The twin's own parameters (``config/launch_twin.yaml``, namespace ``launch_twin``)."""

    angle_convention: str = "yaw_of_push"
    wheel_model: str = "auto"
    speed_sigma_fraction: float = 0.03
    angle_sigma_deg: float = 1.0
    wheel_side_friction_factor: float = _setting(
        0.1, "UNKNOWN: Mecanum wheels' friction along the axle / across it (guessed: the rollers slide)", (0.0, 1.0))
    wheel_rolling_friction: float = _setting(
        0.0002, "UNKNOWN: Bullet rolling friction of a Mecanum wheel, m (force ~ this / wheel radius x load; "
                "guessed so the chassis covers the 0.34 m run)", (0.0, 0.01))
    wheel_drag_torque_nm: float = _setting(
        0.0005, "UNKNOWN: back-drive drag of each unpowered wheel motor, N m (guessed)", (0.0, 0.05))
    wheel_friction_left_factor: float = 1.0
    wheel_friction_right_factor: float = 1.0
    max_attempts: int = 3
    pose_rate_hz: float = 30.0
    launcher: LauncherSpec = dataclasses.field(default_factory=LauncherSpec)
    plate: PushPlateSpec = dataclasses.field(default_factory=PushPlateSpec)
    foam: FoamSpec = dataclasses.field(default_factory=FoamSpec)
    designs: DesignSources = dataclasses.field(default_factory=DesignSources)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if self.angle_convention not in ANGLE_CONVENTIONS:
            raise ValueError(f"angle_convention must be one of {', '.join(ANGLE_CONVENTIONS)}, "
                             f"got {self.angle_convention!r}")
        if self.wheel_model not in WHEEL_MODELS:
            raise ValueError(f"wheel_model must be one of {', '.join(WHEEL_MODELS)}, got {self.wheel_model!r}")
        if not 0 <= self.speed_sigma_fraction <= 0.5:
            raise ValueError(f"speed_sigma_fraction must be in [0, 0.5], got {self.speed_sigma_fraction}")
        if not 0 <= self.angle_sigma_deg <= 30:
            raise ValueError(f"angle_sigma_deg must be in [0, 30], got {self.angle_sigma_deg}")
        if not 0 <= self.wheel_side_friction_factor <= 1:
            raise ValueError(f"wheel_side_friction_factor must be in [0, 1], got {self.wheel_side_friction_factor}")
        if self.wheel_rolling_friction < 0 or self.wheel_drag_torque_nm < 0:
            raise ValueError("wheel_rolling_friction and wheel_drag_torque_nm must be >= 0")
        for name in ("wheel_friction_left_factor", "wheel_friction_right_factor"):
            if not 0 < getattr(self, name) <= 5:
                raise ValueError(f"{name} must be in (0, 5], got {getattr(self, name)}")
        if not 1 <= self.max_attempts <= 20:
            raise ValueError(f"max_attempts must be in [1, 20], got {self.max_attempts}")
        if not self.pose_rate_hz > 0:
            raise ValueError(f"pose_rate_hz must be > 0, got {self.pose_rate_hz}")
        # one seam per swap: the settings of the launcher model not chosen cannot be honoured, so they are refused
        if self.launcher.model == "stroke" and self.plate.max_force_n:
            raise ValueError(f"plate.max_force_n ({self.plate.max_force_n} N) drives the push_through plate only; "
                             "the stroke cylinder pushes with launcher.pressures_psi x its bore: set it to 0 or "
                             "launcher.model to push_through")
        if self.launcher.model == "push_through" and self.launcher.bore_m:
            raise ValueError(f"launcher.bore_m ({self.launcher.bore_m} m) sizes the stroke cylinder only; the "
                             "push_through plate pushes with plate.max_force_n: set it to 0 or launcher.model to "
                             "stroke")

@dataclasses.dataclass
class LaunchTwinSettings(RobotChoice):
    """Everything a simulated launch needs (picklable); every field can be replaced per call (calibration).

    The robot launched is the built-in chassis (``robot``) unless ``urdf_robot`` names a mount link, chosen as
    for the trials (:class:`~rollability_ros.core.robots.urdf_robot.RobotChoice`: ``robot_model()``,
    ``profile_body(mesh)``).
    """

    physics: PhysicsParams = dataclasses.field(default_factory=PhysicsParams)
    robot: ChassisSpec = dataclasses.field(default_factory=ChassisSpec)
    trial: TrialSettings = dataclasses.field(default_factory=TrialSettings)
    twin: LaunchTwinOptions = dataclasses.field(default_factory=LaunchTwinOptions)
    urdf_robot: UrdfRobotSpec = dataclasses.field(default_factory=UrdfRobotSpec)

#: settings field -> config namespace
_SECTIONS = {"physics": "sim", "robot": "robot", "trial": "trial", "twin": "launch_twin", "urdf_robot": "urdf_robot"}

#: The namespace of the twin's own parameters (``config/launch_twin.yaml``), and every namespace the twin reads.
TWIN_NAMESPACE = _SECTIONS["twin"]

TWIN_SECTIONS = frozenset(_SECTIONS.values())

def twin_files(paths: typing.Sequence[str], namespaces: typing.Iterable[str] = (TWIN_NAMESPACE,)) -> typing.List[str]:
    """The parameter files among ``paths`` that set parameters in ``namespaces`` (default: the twin's own), as
    absolute paths: those a command appends to its twin's file list (``objective.twin_config``,
    ``rig.twin_config``) so that the twin reads them."""
    prefixes = tuple(namespace + "." for namespace in namespaces)
    return [os.path.abspath(resolve_config_path(path)) for path in paths
            if any(name.startswith(prefixes) for name in load_parameters([path]))]

def launch_twin_settings_from_parameters(flat: typing.Mapping[str, typing.Any],
                                         overrides: typing.Optional[typing.Mapping[str, typing.Any]] = None
                                         ) -> LaunchTwinSettings:
    """Build :class:`LaunchTwinSettings` from flat ``{dotted name: value}`` parameters (e.g. a node's).

    ``overrides`` maps dotted *settings* names (``"twin.foam.contact_stiffness_npm"``, ``"physics.restitution"``,
    ``"robot.body_mass_kg"``) to values; they are checked like file values (:class:`ConfigError` if unknown or bad).
    """
    nested: typing.Dict[str, typing.Any] = {name: section(flat, prefix) for name, prefix in _SECTIONS.items()}
    for dotted, value in (overrides or {}).items():
        *parents, leaf = dotted.split(".")
        node = nested
        for part in parents:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ConfigError(f"override {dotted}: {part} is not a group of settings")
        node[leaf] = value
    return from_mapping(LaunchTwinSettings, nested, "launch twin settings")

def load_launch_twin_settings(config_paths: typing.Sequence[str] = ("sim", "robot", "launch_twin"),
                              node_name: str = "/**",
                              overrides: typing.Optional[typing.Mapping[str, typing.Any]] = None
                              ) -> LaunchTwinSettings:
    """Read :class:`LaunchTwinSettings` from ROS 2 parameter files (names of shipped files or paths).

    Namespaces: ``sim`` and ``trial`` (sim.yaml), ``robot`` (robot.yaml), ``launch_twin`` (launch_twin.yaml),
    ``urdf_robot`` (a URDF robot's config such as husky.yaml: that robot is launched instead of the chassis).
    Missing keys keep their defaults; see :func:`launch_twin_settings_from_parameters` for ``overrides``.
    """
    return launch_twin_settings_from_parameters(load_parameters(list(config_paths), node_name), overrides)

def mecanum_wheels(settings: LaunchTwinSettings) -> bool:
    """True when the twin gives the wheels its Mecanum contact and drag (``wheel_model`` mecanum, or auto on the
    built-in chassis); False when the robot keeps its own (robot, or auto on a URDF robot), as in the trials."""
    wheel_model = settings.twin.wheel_model
    return wheel_model == "mecanum" or (wheel_model == "auto" and not settings.urdf_robot.selected)
