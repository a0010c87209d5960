"""Robust fitness: each trial of an evaluation under its own draw of the quantities the paper does not pin down.

The disturbance trial's fitness depends on choices the paper does not give, and its sign can flip (issue 18: a
dome profile scores 36/60 against the bare chassis's 0/60 with the shipped disturbance, 31/60 against 34/60 with
it doubled, 18/60 against 23/60 started on its side). With ``objective.robust.enabled`` every trial draws, from
its own trial seed (so candidates evaluated with one base seed meet the same draws: common random numbers):

- ``disturbance_scale``: a factor on the force and torque ranges, log-uniform in
  [``disturbance_scale_min``, ``disturbance_scale_max``];
- ``start_roll_deg``: the start pose, one of ``start_rolls_deg`` (180 = upside down, 90 = on its side);
- ``contact_model``: how the paper's contact values are read, one of ``contact_models``
  (:data:`~rollability_ros.core.sim.world.CONTACT_MODELS`);
- ``com_offset_z_m``: the built-in chassis's centre-of-mass height, normal around its configured value with
  standard deviation ``com_sigma_m`` (kept inside the body);
- ``foam_stiffness_factor`` and ``foam_restitution``: on launch trials, a log-uniform factor in
  [``foam_stiffness_factor_min``, ``foam_stiffness_factor_max``] on the foam's stiffness and damping, and the
  foam's restitution uniform in [0, ``foam_restitution_max``];
- ``foam_lateral_friction``: on launch trials, the foam's own friction coefficient (``launch_twin.foam.
  lateral_friction``; the contact's is it times the robot's ``sim.lateral_friction``), log-uniform in
  [``foam_lateral_friction_min``, ``foam_lateral_friction_max``];
- ``foam_rolling_friction_m``: on launch trials, the foam's own rolling friction (``launch_twin.foam.
  rolling_friction``, m: the wheel-on-foam rolling resistance), log-uniform in [``foam_rolling_friction_min_m``,
  ``foam_rolling_friction_max_m``];
- ``wheel_drag_nm``: on launch trials, the back-drive drag torque of each wheel, log-uniform in
  [``wheel_drag_min_nm``, ``wheel_drag_max_nm``]: the twin's Mecanum wheels' ``launch_twin.wheel_drag_torque_nm``
  when the twin gives the robot those wheels, else the robot's own (``robot.wheel_drag_torque_nm`` or
  ``urdf_robot.joint_drag_torque_nm``), so the drawn value always acts;
- ``profile_mass_scale``: the multiplier on the printed profile's mass and inertia (``robot.profile_mass_scale``
  or ``urdf_robot.profile_mass_scale``: print settings, material and glue the mass model does not know),
  log-uniform in [``profile_mass_scale_min``, ``profile_mass_scale_max``], on every trial; the trial's profile
  body is scaled with it (:func:`scaled_profile`);
- ``ledge_rolling_friction_m``: on launch trials, the launcher base plate's own rolling friction
  (``launch_twin.launcher.ledge_rolling_friction``: slows the stroke launcher's coast to the edge), uniform in
  [0, ``ledge_rolling_friction_max_m``];
- ``speed_bias_fraction``: on launch trials, the lab's systematic speed-setting error
  (``launch_twin.launcher.speed_bias_fraction``), uniform in [-``speed_bias_fraction_max``,
  +``speed_bias_fraction_max``];
- ``launcher_model``: on launch trials, how the cylinder drives the plate, one of ``launcher_models``
  (``launch_twin.launcher.model``; default only ``stroke``, the paper's cylinder: the model is known from the
  paper, its quantities above are not; list ``push_through`` too to plan for a launcher that pushes to the edge);
- ``robot_restitution``: on launch trials on an engine that represents restitution (PyBullet), the robot's
  coefficient of restitution (``sim.restitution``: its contact with the launcher's plate and ledge edge, and times
  the foam's own with the foam), uniform in [``robot_restitution_min``, ``robot_restitution_max``]. An engine
  without restitution (MuJoCo, :data:`~rollability_ros.core.sim.engines.ENGINES_WITHOUT_RESTITUTION`) keeps the
  configured value, the one it accepts (its declared known difference); the draw is still taken, so the other
  unknowns of a trial are the same on both engines;
- ``wheel_rolling_resistance``: on launch trials of a twin that gives the robot its own wheels (a URDF robot,
  ``launch_twin.wheel_model`` robot), their rolling-resistance coefficient (``launch_twin.wheel_rolling_resistance``),
  log-uniform in [``wheel_rolling_resistance_min``, ``wheel_rolling_resistance_max``]; the twin's Mecanum wheels
  (the built-in chassis) keep the configured values (their own ``wheel_rolling_friction``), the draw still taken.

The ranges, their sources and how far each moves the designs' gain are in docs/twin-model.md. Both launch
engines read every drawn field (the MuJoCo twin puts them into its compiled model's contact values and joint
friction, :meth:`~rollability_ros.core.sim.launch.mujoco_twin.MujocoLaunchTwin.retarget`). The draws come from
the trial seed's own stream in a fixed order, new unknowns after the old, so a trial's earlier draws keep their
values when an unknown is added.

The robust fitness is the success rate over these draws: an estimate of the expected success when the unknowns
are spread as stated. Each robust trial builds its own world (the trials' cached world holds one robot), so it
costs about one world build more than a plain trial.
"""
import dataclasses
import math
import typing

import numpy as np

from rollability_ros.core.sim.engines import represents_restitution
from rollability_ros.core.sim.world import CONTACT_MODELS

if typing.TYPE_CHECKING:  # annotations only
    from rollability_ros.core.robots import ChassisSpec, ProfileBody, UrdfRobotSpec
    from rollability_ros.core.sim.trials import TrialSettings
    from rollability_ros.core.sim.world import PhysicsParams

#: Spawn key of the robustness draws within a trial seed (apart from the trial's own draws).
_ROBUST_STREAM = 0x7B0B


@dataclasses.dataclass
class RobustSettings:
    """``objective.robust``: the distribution of the uncertain quantities (module docstring)."""

    enabled: bool = dataclasses.field(default=False, metadata={"description": "true: score every trial under its own seeded draw of the uncertain quantities (robust fitness)"})
    disturbance_scale_min: float = dataclasses.field(default=0.5, metadata={"description": "lower end of the factor on the disturbance force and torque ranges (log-uniform), dimensionless", "range": (0.0, 100.0), "exclusive": "low"})
    disturbance_scale_max: float = dataclasses.field(default=2.0, metadata={"description": "upper end of the factor on the disturbance force and torque ranges (log-uniform), dimensionless", "range": (0.0, 100.0)})
    start_rolls_deg: typing.List[float] = dataclasses.field(default_factory=lambda: [180.0, 90.0], metadata={"description": "start roll angles drawn with equal probability, deg (180 = upside down, 90 = on its side)"})
    contact_models: typing.List[str] = dataclasses.field(default_factory=lambda: list(CONTACT_MODELS), metadata={"description": "readings of the paper's contact values drawn with equal probability: per_contact and/or per_body (config/sim.yaml)"})
    com_sigma_m: float = dataclasses.field(default=0.003, metadata={"description": "standard deviation of the chassis's centre-of-mass height offset, m", "range": (0.0, 1.0)})
    foam_stiffness_factor_min: float = dataclasses.field(default=0.5, metadata={"description": "launches: lower end of the factor on the foam's stiffness and damping (log-uniform), dimensionless", "range": (0.0, 100.0), "exclusive": "low"})
    foam_stiffness_factor_max: float = dataclasses.field(default=2.0, metadata={"description": "launches: upper end of the factor on the foam's stiffness and damping (log-uniform), dimensionless", "range": (0.0, 100.0)})
    foam_restitution_max: float = dataclasses.field(default=0.3, metadata={"description": "launches: the foam's restitution is drawn uniform in [0, this], coefficient", "range": (0.0, 1.0)})
    foam_lateral_friction_min: float = dataclasses.field(default=0.6, metadata={"description": "launches: lower end of the foam's own friction coefficient (log-uniform; the contact's is this times sim.lateral_friction), coefficient", "range": (0.0, 100.0), "exclusive": "low"})
    foam_lateral_friction_max: float = dataclasses.field(default=2.5, metadata={"description": "launches: upper end of the foam's own friction coefficient (log-uniform), coefficient", "range": (0.0, 100.0)})
    foam_rolling_friction_min_m: float = dataclasses.field(default=0.002, metadata={"description": "launches: lower end of the foam's own rolling friction, the wheel-on-foam rolling resistance (log-uniform), m", "range": (0.0, 1.0), "exclusive": "low"})
    foam_rolling_friction_max_m: float = dataclasses.field(default=0.05, metadata={"description": "launches: upper end of the foam's own rolling friction (log-uniform), m", "range": (0.0, 1.0)})
    wheel_drag_min_nm: float = dataclasses.field(default=0.0005, metadata={"description": "launches: lower end of each wheel's back-drive drag torque (log-uniform), N m", "range": (0.0, 10.0), "exclusive": "low"})
    wheel_drag_max_nm: float = dataclasses.field(default=0.02, metadata={"description": "launches: upper end of each wheel's back-drive drag torque (log-uniform), N m", "range": (0.0, 10.0)})
    profile_mass_scale_min: float = dataclasses.field(default=0.15, metadata={"description": "lower end of the multiplier on the printed profile's mass and inertia (log-uniform), dimensionless", "range": (0.0, 100.0), "exclusive": "low"})
    profile_mass_scale_max: float = dataclasses.field(default=1.5, metadata={"description": "upper end of the multiplier on the printed profile's mass and inertia (log-uniform), dimensionless", "range": (0.0, 100.0)})
    ledge_rolling_friction_max_m: float = dataclasses.field(default=0.01, metadata={"description": "launches: the launcher base plate's rolling friction is drawn uniform in [0, this], m", "range": (0.0, 0.01)})
    speed_bias_fraction_max: float = dataclasses.field(default=0.15, metadata={"description": "launches: the speed setting's systematic error is drawn uniform in [-this, +this], fraction of the set speed", "range": (0.0, 0.15)})
    launcher_models: typing.List[str] = dataclasses.field(default_factory=lambda: ["stroke"], metadata={"description": "launches: launcher models drawn with equal probability: stroke (the paper's cylinder) and/or push_through"})
    robot_restitution_min: float = dataclasses.field(default=0.0, metadata={"description": "launches on engines with restitution (pybullet): lower end of the robot's restitution, drawn uniform (sim.restitution: its contact with the launcher's plate and ledge), coefficient", "range": (0.0, 1.0)})
    robot_restitution_max: float = dataclasses.field(default=0.5, metadata={"description": "launches on engines with restitution (pybullet): upper end of the robot's restitution, drawn uniform, coefficient", "range": (0.0, 1.0)})
    wheel_rolling_resistance_min: float = dataclasses.field(default=0.005, metadata={"description": "launches of a robot on its own wheels: lower end of their rolling-resistance coefficient (log-uniform), dimensionless", "range": (0.0, 0.1), "exclusive": "low"})
    wheel_rolling_resistance_max: float = dataclasses.field(default=0.03, metadata={"description": "launches of a robot on its own wheels: upper end of their rolling-resistance coefficient (log-uniform), dimensionless", "range": (0.0, 0.1)})
    world_seed: int = dataclasses.field(default=-1, metadata={"description": "-1: every trial draws its own values of the unknowns; a seed >= 0: every trial uses the one draw of this seed, one plausible world (the world check, fidelity world:<seed>)", "range": (-1, 2 ** 32 - 1)})

    def validate(self) -> None:
        """Raise ``ValueError`` for a rule that spans fields (each number's range is declared in its metadata and
        checked by :func:`~rollability_ros.core.config.check_settings`)."""
        if not self.disturbance_scale_min <= self.disturbance_scale_max:
            raise ValueError("need disturbance_scale_min <= disturbance_scale_max")
        if not self.start_rolls_deg or not all(0 <= r <= 180 for r in self.start_rolls_deg):
            raise ValueError("start_rolls_deg must list angles in [0, 180] deg")
        unknown = [m for m in self.contact_models if m not in CONTACT_MODELS]
        if not self.contact_models or unknown:
            raise ValueError(f"contact_models must list some of {', '.join(CONTACT_MODELS)}, got {self.contact_models}")
        if not self.launcher_models or not set(self.launcher_models) <= {"stroke", "push_through"}:
            raise ValueError(f"launcher_models must list some of stroke, push_through, got {self.launcher_models}")
        if not self.robot_restitution_min <= self.robot_restitution_max:
            raise ValueError(f"need robot_restitution_min <= robot_restitution_max, got "
                             f"[{self.robot_restitution_min}, {self.robot_restitution_max}]")
        for name in ("foam_stiffness_factor", "foam_lateral_friction", "foam_rolling_friction", "wheel_drag",
                     "profile_mass_scale", "wheel_rolling_resistance"):
            low, high = self.range_of(name)
            if not low <= high:
                raise ValueError(f"need {name}_min <= {name}_max (log-uniform), got [{low}, {high}]")

    def range_of(self, unknown: str) -> typing.Tuple[float, float]:
        """``(low, high)`` of a log-uniform unknown: ``foam_stiffness_factor``, ``foam_lateral_friction``,
        ``foam_rolling_friction`` (m), ``wheel_drag`` (N m), ``profile_mass_scale`` or ``wheel_rolling_resistance``."""
        unit = {"foam_rolling_friction": "_m", "wheel_drag": "_nm"}.get(unknown, "")
        return getattr(self, f"{unknown}_min{unit}"), getattr(self, f"{unknown}_max{unit}")


@dataclasses.dataclass(frozen=True)
class Draw:
    """One trial's values of the uncertain quantities (units in the names)."""

    disturbance_scale: float
    start_roll_deg: float
    contact_model: str
    com_offset_z_m: float
    foam_stiffness_factor: float
    foam_restitution: float
    foam_lateral_friction: float
    foam_rolling_friction_m: float
    wheel_drag_nm: float
    profile_mass_scale: float
    ledge_rolling_friction_m: float
    speed_bias_fraction: float
    launcher_model: str
    robot_restitution: float
    wheel_rolling_resistance: float


class PerturbedSettings(typing.Protocol):
    """What a trial's :class:`Draw` perturbs: settings dataclasses with a disturbance ``trial``, ``physics`` and a
    robot (``robot``, ``urdf_robot``) -- an EvaluatorSettings or a LaunchTwinSettings (defined in sim/ modules that
    import this one; a twin's ``twin`` is perturbed too when present)."""

    __dataclass_fields__: typing.ClassVar[typing.Dict[str, "dataclasses.Field[typing.Any]"]]

    @property
    def trial(self) -> "TrialSettings": ...

    @property
    def physics(self) -> "PhysicsParams": ...

    @property
    def robot(self) -> "ChassisSpec": ...

    @property
    def urdf_robot(self) -> "UrdfRobotSpec": ...


#: The settings a function here is given, returned as the same type.
_Perturbed = typing.TypeVar("_Perturbed", bound=PerturbedSettings)


def draw(seed: int, robust: RobustSettings, nominal_com_offset_z_m: float, body_height_m: float) -> Draw:
    """The :class:`Draw` of the trial with ``seed`` (its own stream of the trial seed: common random numbers)."""
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(_ROBUST_STREAM,)))
    scale = math.exp(rng.uniform(math.log(robust.disturbance_scale_min), math.log(robust.disturbance_scale_max)))
    roll = float(robust.start_rolls_deg[rng.integers(len(robust.start_rolls_deg))])
    contact = str(robust.contact_models[rng.integers(len(robust.contact_models))])
    inside = 0.45 * body_height_m
    com = float(np.clip(nominal_com_offset_z_m + robust.com_sigma_m * rng.standard_normal(), -inside, inside))
    def log_uniform(unknown: str) -> float:
        low, high = robust.range_of(unknown)
        return math.exp(rng.uniform(math.log(low), math.log(high)))
    stiffness = log_uniform("foam_stiffness_factor")
    restitution = float(rng.uniform(0.0, robust.foam_restitution_max))
    # drawn after the older unknowns (module docstring): those keep their values
    foam_wheels = (log_uniform("foam_lateral_friction"), log_uniform("foam_rolling_friction"),
                   log_uniform("wheel_drag"))
    mass_scale = log_uniform("profile_mass_scale")
    ledge = float(rng.uniform(0.0, robust.ledge_rolling_friction_max_m))
    bias = float(rng.uniform(-robust.speed_bias_fraction_max, robust.speed_bias_fraction_max))
    launcher = str(robust.launcher_models[rng.integers(len(robust.launcher_models))])
    robot_restitution = float(rng.uniform(robust.robot_restitution_min, robust.robot_restitution_max))
    rolling_resistance = log_uniform("wheel_rolling_resistance")
    return Draw(scale, roll, contact, com, stiffness, restitution, *foam_wheels, mass_scale, ledge, bias, launcher,
                robot_restitution, rolling_resistance)


def perturb(settings: _Perturbed, drawn: Draw) -> _Perturbed:
    """Settings with a trial's :class:`Draw` applied: ``settings`` is an EvaluatorSettings or a
    LaunchTwinSettings (both have ``trial``, ``physics`` and ``robot``; a twin also has ``twin.foam``)."""
    trial = dataclasses.replace(
        settings.trial, start_roll_deg=drawn.start_roll_deg,
        force_min_n=settings.trial.force_min_n * drawn.disturbance_scale,
        force_max_n=settings.trial.force_max_n * drawn.disturbance_scale,
        torque_min_nm=settings.trial.torque_min_nm * drawn.disturbance_scale,
        torque_max_nm=settings.trial.torque_max_nm * drawn.disturbance_scale)
    changes = {"trial": trial, "physics": dataclasses.replace(settings.physics, contact_model=drawn.contact_model),
               "robot": dataclasses.replace(settings.robot, com_offset_z_m=drawn.com_offset_z_m,
                                            profile_mass_scale=drawn.profile_mass_scale)}
    if settings.urdf_robot.selected:   # the robot the profile is weighed for
        changes["urdf_robot"] = dataclasses.replace(settings.urdf_robot, profile_mass_scale=drawn.profile_mass_scale)
    twin = getattr(settings, "twin", None)
    if twin is not None:
        # a launch's early decision needs barriers built for its own foam and centre of mass; a draw runs the full
        # rule, so a kept MuJoCo twin serves every draw and a draw's launch never depends on the draws before it
        changes["trial"] = dataclasses.replace(trial, early_decision=False)
        foam = dataclasses.replace(twin.foam, restitution=drawn.foam_restitution,
                                   contact_stiffness_npm=twin.foam.contact_stiffness_npm * drawn.foam_stiffness_factor,
                                   contact_damping_nspm=twin.foam.contact_damping_nspm * drawn.foam_stiffness_factor,
                                   lateral_friction=drawn.foam_lateral_friction,
                                   rolling_friction=drawn.foam_rolling_friction_m)
        launcher = dataclasses.replace(twin.launcher, model=drawn.launcher_model,
                                       ledge_rolling_friction=drawn.ledge_rolling_friction_m,
                                       speed_bias_fraction=drawn.speed_bias_fraction)
        own_wheels = {} if mecanum_twin(settings) else {"wheel_rolling_resistance": drawn.wheel_rolling_resistance}
        changes["twin"] = dataclasses.replace(twin, foam=foam, launcher=launcher, **own_wheels)   # module docstring
        if represents_restitution(settings.physics.engine):   # else the configured value (module docstring)
            changes["physics"] = dataclasses.replace(settings.physics, contact_model=drawn.contact_model,
                                                     restitution=drawn.robot_restitution)
        changes.update(_with_wheel_drag(settings, changes, drawn.wheel_drag_nm))
    return dataclasses.replace(settings, **changes)


def wheel_drag_field(settings: _Perturbed) -> str:
    """The dotted settings name of the wheel drag a launch twin's ``settings`` uses: the twin's Mecanum wheels'
    (``twin.wheel_drag_torque_nm``), else the robot's own (``urdf_robot.joint_drag_torque_nm`` or
    ``robot.wheel_drag_torque_nm``)."""
    if mecanum_twin(settings):
        return "twin.wheel_drag_torque_nm"
    return "urdf_robot.joint_drag_torque_nm" if settings.urdf_robot.selected else "robot.wheel_drag_torque_nm"


def mecanum_twin(settings: _Perturbed) -> bool:
    """True for a launch twin's ``settings`` that give the robot the twin's Mecanum wheels."""
    from rollability_ros.core.sim.launch.settings import LaunchTwinSettings, mecanum_wheels  # heavier; sim-internal

    return isinstance(settings, LaunchTwinSettings) and mecanum_wheels(settings)


def _with_wheel_drag(settings, changes, drag_nm):
    """``changes`` (settings field -> replaced value) with the drag of the wheels the twin uses set to ``drag_nm``."""
    group, leaf = wheel_drag_field(settings).split(".")
    current = changes.get(group, getattr(settings, group))
    return {**changes, group: dataclasses.replace(current, **{leaf: drag_nm})}


def nominal_draw(settings: _Perturbed) -> Draw:
    """The :class:`Draw` that leaves ``settings`` (EvaluatorSettings or LaunchTwinSettings) as configured: each
    unknown at its configured value (disturbance and foam stiffness factors 1)."""
    twin = getattr(settings, "twin", None)
    if twin is None:   # a disturbance trial has no foam and keeps its robot's drag
        foam_values: typing.Tuple[float, float, float] = (0.0, 1.0, 0.01)
        drag = float(settings.robot.wheel_drag_torque_nm)
    else:
        foam_values = (twin.foam.restitution, twin.foam.lateral_friction, twin.foam.rolling_friction)
        group, leaf = wheel_drag_field(settings).split(".")
        drag = float(getattr(getattr(settings, group), leaf))
    launcher: typing.Tuple[float, float, str] = (0.0, 0.0, "stroke") if twin is None else (
        twin.launcher.ledge_rolling_friction, twin.launcher.speed_bias_fraction, twin.launcher.model)
    rolling_resistance = 0.01 if twin is None else float(twin.wheel_rolling_resistance)
    return Draw(1.0, settings.trial.start_roll_deg, settings.physics.contact_model, settings.robot.com_offset_z_m,
                1.0, *foam_values, drag, profile_mass_scale(settings), *launcher,
                robot_restitution=settings.physics.restitution, wheel_rolling_resistance=rolling_resistance)


def profile_mass_scale(settings: _Perturbed) -> float:
    """The ``profile_mass_scale`` of the robot ``settings`` weigh the profile for (the URDF robot's or the
    chassis's)."""
    return float((settings.urdf_robot if settings.urdf_robot.selected else settings.robot).profile_mass_scale)


def scaled_profile(profile: typing.Optional["ProfileBody"], before: _Perturbed,
                   after: _Perturbed) -> typing.Optional["ProfileBody"]:
    """``profile`` (a ProfileBody made for settings ``before``, or None) weighed for settings ``after``: mass and
    inertia times the ratio of their ``profile_mass_scale`` (the mass model is linear in it)."""
    ratio = profile_mass_scale(after) / profile_mass_scale(before)
    if profile is None or ratio == 1.0:
        return profile
    return dataclasses.replace(profile, mass_kg=profile.mass_kg * ratio, inertia_kgm2=profile.inertia_kgm2 * ratio)


def robust_settings_for(settings: _Perturbed, seed: int, robust: RobustSettings) -> _Perturbed:
    """``settings`` (EvaluatorSettings or LaunchTwinSettings) perturbed by the draw of trial ``seed``, or by the
    one world's draw when ``robust.world_seed`` is set (>= 0: every trial in the same world)."""
    drawn_seed = seed if robust.world_seed < 0 else robust.world_seed
    return perturb(settings, draw(drawn_seed, robust, settings.robot.com_offset_z_m, settings.robot.body_height_m))
