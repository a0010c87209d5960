"""The launch twin's settings (``config/launch_twin.yaml`` and the namespaces it reads) and their parameter files;
the model they parameterise is described in :mod:`rollability_ros.core.sim.launch`."""
import dataclasses
import math
import os
import typing

import numpy as np

from rollability_ros.core.config import (ConfigError, edge_parse, from_mapping, load_parameters, resolve_config_path,
                                         section, value_of, with_values, wrong_type)
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

def _setting(default: typing.Any, description: str, value_range: typing.Optional[tuple] = None,
             exclusive: str = "") -> typing.Any:
    """A settings field with the project's metadata (``description``, and ``range`` (low, high) when numeric, with
    ``exclusive`` naming an end it leaves out: ``"low"``, ``"high"`` or ``"both"``)."""
    metadata = {"description": description, **({"range": value_range} if value_range is not None else {}),
                **({"exclusive": exclusive} if exclusive else {})}
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
                                        (0.0, 0.01), "high")
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
        """Raise ``ValueError`` for an unknown model, unusable speed-pressure pairs or a rule that spans fields
        (each number's range is declared in its metadata and checked by
        :func:`~rollability_ros.core.config.check_settings`; a ledge size or bore of 0 is derived from the robot)."""
        if self.ledge_depth_m and self.ledge_depth_m <= self.run_length_m:
            raise ValueError(f"ledge_depth_m {self.ledge_depth_m} must exceed run_length_m {self.run_length_m}")
        if self.model not in LAUNCHER_MODELS:
            raise ValueError(f"model must be one of {', '.join(LAUNCHER_MODELS)}, got {self.model!r}")
        speeds, pressures = list(self.pressure_speeds_mps), list(self.pressures_psi)
        if not speeds or len(speeds) != len(pressures):
            raise ValueError(f"pressure_speeds_mps ({len(speeds)}) and pressures_psi ({len(pressures)}) must be "
                             "non-empty and the same length")
        if not all(0 < s < math.inf for s in speeds) or any(b <= a for a, b in zip(speeds, speeds[1:])):
            raise ValueError(f"pressure_speeds_mps must be positive and increasing, got {speeds}")
        if not all(0 < p < math.inf for p in pressures):
            raise ValueError(f"pressures_psi must be positive, got {pressures}")

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

    width_m: float = _setting(0.0, "plate face across the push, m; 0 = derived from the robot", (0.0, 5.0))
    height_m: float = _setting(0.0, "vertical extent of the plate face, m; 0 = derived from the robot", (0.0, 5.0))
    thickness_m: float = _setting(0.01, "plate along the push, m", (0.0, 1.0), "low")
    mass_kg: float = _setting(0.3, "plate with the cylinder's piston and rod, kg (guessed; not in the paper)",
                              (0.0, 100.0), "low")
    clearance_m: float = _setting(0.0, "gap between the plate's bottom and the launcher's base plate, m; 0 = derived "
                                       "from the robot", (0.0, 0.1), "high")
    max_force_n: float = _setting(0.0, "push_through only: most the plate pushes with, N (stroke: pressures_psi x "
                                       "bore)", (0.0, 100000.0))
    ramp_s: float = _setting(0.012, "time the plate's speed takes from rest to the launch speed, s", (0.0, 10.0),
                             "low")
    offset_m: float = _setting(0.0, "plate centre off the chassis's path (+ = left of the push), m: rig asymmetry",
                               (-0.5, 0.5), "both")
    yaw_bias_deg: float = _setting(0.0, "plate face turned from square to the push (+ = ccw from above), deg",
                                   (-20.0, 20.0))

@dataclasses.dataclass
class FoamSpec:
    """The memory-foam layer under the impact region (``launch_twin.foam``)."""

    thickness_m: float = _setting(0.05, "memory foam on the floor in front of the ledge, m; its top is the impact "
                                        "surface", (0.0, 1.0), "low")
    length_m: float = _setting(2.5, "foam away from the ledge (x from 0 to length), m", (0.0, 100.0), "low")
    width_m: float = _setting(3.0, "foam along the edge, centred, m", (0.0, 100.0), "low")
    contact_stiffness_npm: float = _setting(2.0e4, "UNKNOWN: Bullet contact stiffness per contact point, N/m "
                                                   "(guessed: ~4 cm under a 1.3 m drop)", (1.0e3, 1.0e6))
    contact_damping_nspm: float = _setting(150.0, "UNKNOWN: Bullet contact damping per contact point, N s/m "
                                                  "(guessed: memory foam barely rebounds)", (0.0, 2000.0))
    lateral_friction: float = _setting(1.0, "UNKNOWN: the foam's own friction coefficient; Bullet multiplies it with "
                                            "the robot's (sim.lateral_friction 0.35) (guessed; > 0)", (0.0, 3.0), "low")
    rolling_friction: float = _setting(0.01, "UNKNOWN: the foam's own rolling friction, m: a wheel on the foam meets "
                                             "this x the wheel's friction more (guessed: a wheel sinks in)",
                                       (0.0, 0.05))
    restitution: float = _setting(0.1, "UNKNOWN: the foam's own restitution; times the robot's 0.3 per contact "
                                       "(guessed)", (0.0, 1.0))

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
    speed_sigma_fraction: float = _setting(0.03, "standard deviation of the actual launch speed, fraction of the "
                                                 "nominal speed", (0.0, 0.5))
    angle_sigma_deg: float = _setting(1.0, "standard deviation of the chassis's placement angle against the push "
                                           "plate, deg", (0.0, 30.0))
    wheel_side_friction_factor: float = _setting(
        0.1, "UNKNOWN: Mecanum wheels' friction along the axle / across it (guessed: the rollers slide)", (0.0, 1.0))
    wheel_rolling_friction: float = _setting(
        0.0002, "UNKNOWN: Bullet rolling friction of a Mecanum wheel, m (force ~ this / wheel radius x load; "
                "guessed so the chassis covers the 0.34 m run)", (0.0, 0.01))
    wheel_drag_torque_nm: float = _setting(
        0.0005, "UNKNOWN: back-drive drag of each unpowered wheel motor, N m (guessed)", (0.0, 0.05))
    wheel_rolling_resistance: float = _setting(
        0.01, "UNKNOWN: rolling-resistance coefficient of the robot's own wheels (wheel_model robot): resisting force "
              "/ load, dimensionless; each wheel's rolling friction is this x its radius (rubber tyres on a hard "
              "floor 0.005-0.02, typically 0.01: docs/twin-model.md)", (0.0, 0.1))
    wheel_friction_left_factor: float = _setting(1.0, "the left wheels' friction / the chassis's (sim.yaml): rig "
                                                      "asymmetry, fittable", (0.0, 5.0), "low")
    wheel_friction_right_factor: float = _setting(1.0, "the right wheels' friction / the chassis's (sim.yaml): rig "
                                                       "asymmetry, fittable", (0.0, 5.0), "low")
    max_attempts: int = _setting(3, "a launch that does not leave the ledge or lands off the foam is retried up to "
                                    "this many times in all (count)", (1, 20))
    pose_rate_hz: float = _setting(30.0, "rate of the chassis pose reported during a launch, Hz of simulated time",
                                   (0.0, 1000.0), "low")
    launcher: LauncherSpec = dataclasses.field(default_factory=LauncherSpec)
    plate: PushPlateSpec = dataclasses.field(default_factory=PushPlateSpec)
    foam: FoamSpec = dataclasses.field(default_factory=FoamSpec)
    designs: DesignSources = dataclasses.field(default_factory=DesignSources)

    def validate(self) -> None:
        """Raise ``ValueError`` for an unknown convention or wheel model, or a rule that spans fields (each number's
        range is declared in its metadata and checked by :func:`~rollability_ros.core.config.check_settings`)."""
        if self.angle_convention not in ANGLE_CONVENTIONS:
            raise ValueError(f"angle_convention must be one of {', '.join(ANGLE_CONVENTIONS)}, "
                             f"got {self.angle_convention!r}")
        if self.wheel_model not in WHEEL_MODELS:
            raise ValueError(f"wheel_model must be one of {', '.join(WHEEL_MODELS)}, got {self.wheel_model!r}")
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

@edge_parse
def launch_twin_settings_from_parameters(flat: typing.Mapping[str, object],
                                         overrides: typing.Optional[typing.Mapping[str, object]] = None
                                         ) -> LaunchTwinSettings:
    """Build :class:`LaunchTwinSettings` from flat ``{dotted name: value}`` parameters (e.g. a node's).

    ``overrides`` maps dotted *settings* names (``"twin.foam.contact_stiffness_npm"``, ``"physics.restitution"``,
    ``"robot.body_mass_kg"``) to values; they are checked like file values (:class:`ConfigError` if unknown or bad,
    naming the parameter: ``launch_twin.foam.contact_stiffness_npm out of range: ...``).
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
    unknown = sorted(set(nested) - set(_SECTIONS))
    if unknown:
        raise ConfigError(f"launch twin settings: unknown group(s) {', '.join(unknown)}; known: "
                          f"{', '.join(sorted(_SECTIONS))}")
    hints = typing.get_type_hints(LaunchTwinSettings)
    settings = LaunchTwinSettings(**{name: from_mapping(hints[name], values, _SECTIONS[name])
                                     for name, values in nested.items()})
    check_wheel_keys(settings)
    return settings

@edge_parse
def load_launch_twin_settings(config_paths: typing.Sequence[str] = ("sim", "robot", "launch_twin"),
                              node_name: str = "/**",
                              overrides: typing.Optional[typing.Mapping[str, object]] = None
                              ) -> LaunchTwinSettings:
    """Read :class:`LaunchTwinSettings` from ROS 2 parameter files (names of shipped files or paths).

    Namespaces: ``sim`` and ``trial`` (sim.yaml), ``robot`` (robot.yaml), ``launch_twin`` (launch_twin.yaml),
    ``urdf_robot`` (a URDF robot's config such as husky.yaml: that robot is launched instead of the chassis).
    Missing keys keep their defaults; see :func:`launch_twin_settings_from_parameters` for ``overrides``.
    """
    return launch_twin_settings_from_parameters(load_parameters(list(config_paths), node_name), overrides)

def twin_with_values(settings: LaunchTwinSettings, values: typing.Mapping[str, object]) -> LaunchTwinSettings:
    """Typed twin ``settings`` with parameters set by their config keys (``{"launch_twin.foam.restitution": 0.4,
    "robot.com_offset_z_m": 0.01}``), each checked as a parameter file's value is (:func:`config.with_values`):
    the twin at one point of a calibration's fitted keys, without parsing parameters again."""
    changed = with_values(settings, _SECTIONS, values)
    check_wheel_keys(changed)
    return changed


def twin_value(settings: LaunchTwinSettings, name: str) -> float:
    """The number the config key ``name`` (``launch_twin.foam.restitution``) holds in typed twin ``settings``;
    :class:`ConfigError` in one line naming it when it is no parameter of the twin or not a number."""
    value = value_of(settings, _SECTIONS, name)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(wrong_type(name, float, value))
    return float(value)


#: The twin's keys of each wheel model (package docstring, "Wheels"): a value other than the default of a key whose
#: model the twin does not use is refused (:func:`check_wheel_keys`).
MECANUM_WHEEL_FIELDS = ("wheel_side_friction_factor", "wheel_rolling_friction", "wheel_drag_torque_nm")
OWN_WHEEL_FIELDS = ("wheel_rolling_resistance",)


def check_wheel_keys(settings: LaunchTwinSettings) -> None:
    """Refuse (:class:`ConfigError`, one line naming the key) a wheel key set away from its default that the twin's
    wheel model (:func:`mecanum_wheels`) does not read: it would be silently ignored."""
    mecanum = mecanum_wheels(settings)
    unused = OWN_WHEEL_FIELDS if mecanum else MECANUM_WHEEL_FIELDS
    used_by = "the robot's own wheels (wheel_model robot)" if mecanum else "the twin's Mecanum wheels (wheel_model " \
                                                                            "mecanum)"
    given = "its Mecanum wheels" if mecanum else "its own wheels"
    defaults = LaunchTwinOptions()
    for name in unused:
        value, default = getattr(settings.twin, name), getattr(defaults, name)
        if value != default:
            raise ConfigError(f"{TWIN_NAMESPACE}.{name} ({value:g}) acts on {used_by} only, and this twin gives the "
                              f"robot {given} ({TWIN_NAMESPACE}.wheel_model {settings.twin.wheel_model}); leave it "
                              f"at {default:g} or set {TWIN_NAMESPACE}.wheel_model")


def wheel_rolling_friction_m(settings: LaunchTwinSettings,
                             radii_m: typing.Sequence[float]) -> typing.Tuple[float, ...]:
    """Each wheel's own rolling friction (m: Bullet's ``rollingFriction``, a torque per unit normal force), one per
    wheel of radius ``radii_m`` (the robot model's ``wheel_radii_m()``): the Mecanum wheels'
    ``wheel_rolling_friction``, or on the robot's own wheels the value that makes the wheel-launcher contact's
    rolling friction ``wheel_rolling_resistance`` x the wheel's radius under either ``sim.contact_model`` (a rolling
    wheel then resists with the coefficient x its load)."""
    options = settings.twin
    if mecanum_wheels(settings):
        return tuple(options.wheel_rolling_friction for _ in radii_m)
    # Bullet's contact: wheel.rolling x ground.friction + ground.rolling x wheel.friction, the launcher's ground
    # rolling 0 under a robot's own wheels (ledge_contact): the contact's rolling friction is the coefficient x radius
    ground_lateral = settings.physics.ground_contact()["lateralFriction"]
    return tuple(options.wheel_rolling_resistance * radius / ground_lateral for radius in radii_m)


def mecanum_wheels(settings: LaunchTwinSettings) -> bool:
    """True when the twin gives the wheels its Mecanum contact and drag (``wheel_model`` mecanum, or auto on the
    built-in chassis); False when the robot keeps its own (robot, or auto on a URDF robot), as in the trials."""
    wheel_model = settings.twin.wheel_model
    return wheel_model == "mecanum" or (wheel_model == "auto" and not settings.urdf_robot.selected)
