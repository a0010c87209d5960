"""Sensitivity study: the simulated fitness of the bare chassis and of profiles against each uncertain factor.

Each factor is varied alone, the others at their configured values: ``disturbance_scale`` (a factor on the
disturbance's force and torque ranges), ``start_roll_deg`` (180 = upside down, 90 = on its side),
``contact_model`` (how the paper's contact values are read, config/sim.yaml) and ``com_offset_z_m`` (the
chassis's centre-of-mass height, m). Every (profile, factor, level) is evaluated with ``trials`` trials from one
base seed (common random numbers: the same start tilts and push directions at every level and for every profile),
plus the ``robust`` fitness (:mod:`~rollability_ros.core.sim.robustness`: every trial under its own draw of all
factors). Each fitness comes with its Wilson 95% interval. ``rollability sensitivity`` writes the rows as a CSV
and draws them (:func:`rollability_ros.core.results.report_figures.sensitivity_figure`).

For launches (:func:`launch_sensitivity_rows`, ``rollability sensitivity --launches``) the factors are the launch
twin's unknowns, each at the low and the high end of its plausible range as the robust draws state it
(:func:`launch_levels`): the contact reading, the chassis's centre-of-mass height (configured value -+ 2 sigma),
the foam's stiffness factor, restitution, friction and rolling friction, the wheels' drag, the profile's mass
multiplier, the launcher base plate's rolling friction, the speed setting's bias and the launcher model (both,
whatever the robust draws list). Every evaluation
is ``trials`` launches on the twin under the campaign's conditions (condition ``i mod C`` for launch ``i``), from
one base seed, so each design's gain over the bare robot at a level is on the same launches.
"""
import dataclasses
import typing

from rollability_ros.core import config
from rollability_ros.core.profile import Mesh
from rollability_ros.core.sim.engines import represents_restitution
from rollability_ros.core.sim.evaluation import (EvaluatorSettings, TrialExecutor, evaluate_job, evaluate_mesh, mesh_job,
                                                  settings_at_fidelity)
from rollability_ros.core.sim.robustness import RobustSettings, mecanum_twin, nominal_draw, perturb, scaled_profile

if typing.TYPE_CHECKING:  # annotations only: the twin is imported when a launch runs
    from rollability_ros.core.sim.launch.settings import LaunchTwinSettings

#: factor -> default levels.
DEFAULT_LEVELS = {"disturbance_scale": (0.5, 1.0, 2.0), "start_roll_deg": (180.0, 90.0),
                  "contact_model": ("per_contact", "per_body"), "com_offset_z_m": (-0.015, -0.005, 0.005)}

#: The launch twin's unknowns (the robust draws' fields varied by :func:`launch_sensitivity_rows`), in row order.
LAUNCH_FACTORS = ("contact_model", "com_offset_z_m", "foam_stiffness_factor", "foam_restitution",
                  "foam_lateral_friction", "foam_rolling_friction_m", "wheel_drag_nm", "profile_mass_scale",
                  "ledge_rolling_friction_m", "speed_bias_fraction", "launcher_model", "robot_restitution",
                  "wheel_rolling_resistance")

#: One row of the study (configuration, factor, level, successes, trials, fitness and its interval).
Row = typing.Dict[str, typing.Any]
#: A factor's level: a name (``contact_model``, the launcher model) or a number in the factor's units.
Level = typing.Union[str, float]
#: Settings dataclasses :func:`with_setting` copies (EvaluatorSettings, LaunchTwinSettings, ...).
_Settings = typing.TypeVar("_Settings")


def _row(label: str, factor: str, level: typing.Any, result: typing.Any,
         on_row: typing.Optional[typing.Callable[[Row], None]]) -> Row:
    """The :data:`Row` of one evaluation (an EvaluationResult), shown through ``on_row``."""
    row = {"configuration": label, "factor": factor, "level": level, "successes": result.successes,
           "trials": result.trials, "fitness": result.fitness, "ci_low": result.ci_low, "ci_high": result.ci_high}
    if on_row is not None:
        on_row(row)
    return row


def with_factor(settings: EvaluatorSettings, factor: str, level: Level) -> EvaluatorSettings:
    """EvaluatorSettings ``settings`` with one factor set to ``level`` (its type is the factor's: a name for
    ``contact_model``, else a number; the others as configured)."""
    nominal = dataclasses.replace(nominal_draw(settings), foam_restitution=0.0)
    if factor not in DEFAULT_LEVELS:
        raise ValueError(f"unknown factor {factor!r}; known: {', '.join(DEFAULT_LEVELS)}")
    field: typing.Dict[str, typing.Any] = {factor: level}   # the factor's field, of the level's type
    return perturb(settings, dataclasses.replace(nominal, **field))


def sensitivity_rows(profiles: typing.Mapping[str, typing.Optional[Mesh]], settings: EvaluatorSettings, trials: int,
                     seed: int, executor: typing.Optional[TrialExecutor] = None,
                     levels: typing.Optional[typing.Mapping[str, typing.Sequence[typing.Union[float, str]]]] = None,
                     robust: typing.Optional[RobustSettings] = None,
                     on_row: typing.Optional[typing.Callable[[Row], None]] = None) -> typing.List[Row]:
    """Evaluate every profile at every factor level and robustly; return the rows (dicts).

    Parameters
    ----------
    profiles : dict
        ``{label: profile solid (trimesh, metres) or None for the bare chassis}``.
    settings : EvaluatorSettings
        The configured trial; its objective must be ``disturbance`` (the study varies the disturbance trial).
    trials, seed : int
        Trials per evaluation and the one base seed of all of them.
    levels : dict, optional
        ``{factor: levels}``; default :data:`DEFAULT_LEVELS`.
    robust : RobustSettings, optional
        The distribution of the robust row (default: :class:`RobustSettings` enabled).
    """
    if settings.objective.kind != "disturbance":
        raise ValueError("the sensitivity study varies the disturbance trial: use objective.kind disturbance")
    levels = levels or DEFAULT_LEVELS
    robust = dataclasses.replace(robust or RobustSettings(), enabled=True)
    plain = dataclasses.replace(settings, objective=dataclasses.replace(settings.objective,
                                                                        robust=RobustSettings()))
    cases = [(factor, level, with_factor(plain, factor, level)) for factor, values in levels.items()
             for level in values]
    cases.append(("robust", "all factors drawn", dataclasses.replace(
        plain, objective=dataclasses.replace(plain.objective, robust=robust))))
    rows = []
    for label, mesh in profiles.items():
        for factor, level, case_settings in cases:
            rows.append(_row(label, factor, level, evaluate_mesh(mesh, trials, seed, case_settings, executor), on_row))
    return rows


def launch_levels(robust: RobustSettings, nominal_com_offset_z_m: float
                  ) -> typing.Dict[str, typing.Tuple[typing.Union[float, str], ...]]:
    """``{factor: (low, high)}`` of every launch unknown (:data:`LAUNCH_FACTORS`): the ends of its range in
    ``robust`` (the contact readings it lists; the centre of mass at its configured value -+ 2 ``com_sigma_m``)."""
    com = tuple(round(nominal_com_offset_z_m + k * robust.com_sigma_m, 9) for k in (-2, 2))   # m, no float noise
    return {"contact_model": tuple(robust.contact_models), "com_offset_z_m": com,
            "foam_stiffness_factor": robust.range_of("foam_stiffness_factor"),
            "foam_restitution": (0.0, robust.foam_restitution_max),
            "foam_lateral_friction": robust.range_of("foam_lateral_friction"),
            "foam_rolling_friction_m": robust.range_of("foam_rolling_friction"),
            "wheel_drag_nm": robust.range_of("wheel_drag"),
            "profile_mass_scale": robust.range_of("profile_mass_scale"),
            "ledge_rolling_friction_m": (0.0, robust.ledge_rolling_friction_max_m),
            "speed_bias_fraction": (-robust.speed_bias_fraction_max, robust.speed_bias_fraction_max),
            "launcher_model": ("stroke", "push_through"),
            "robot_restitution": (robust.robot_restitution_min, robust.robot_restitution_max),
            "wheel_rolling_resistance": robust.range_of("wheel_rolling_resistance")}


def with_launch_factor(twin: "LaunchTwinSettings", factor: str, level: Level) -> "LaunchTwinSettings":
    """LaunchTwinSettings ``twin`` with one unknown (:data:`LAUNCH_FACTORS`) set to ``level``, the others as
    configured (its early decision off, as for every draw)."""
    if factor not in LAUNCH_FACTORS:
        raise ValueError(f"unknown launch factor {factor!r}; known: {', '.join(LAUNCH_FACTORS)}")
    if factor == "robot_restitution" and not represents_restitution(twin.physics.engine):
        raise ValueError(f"the launch factor robot_restitution cannot be varied on {twin.physics.engine!r}: it "
                         f"has no restitution (docs/engines.md); run the sensitivity on pybullet")
    if factor == "wheel_rolling_resistance" and mecanum_twin(twin):
        raise ValueError("the launch factor wheel_rolling_resistance acts on a robot's own wheels, and this twin "
                         "gives the robot its Mecanum wheels (launch_twin.wheel_model); vary "
                         "twin.wheel_rolling_friction instead (--vary)")
    field: typing.Dict[str, typing.Any] = {factor: level}   # the factor's field, of the level's type
    return perturb(twin, dataclasses.replace(nominal_draw(twin), **field))


def launch_sensitivity_rows(profiles: typing.Mapping[str, typing.Optional[Mesh]], settings: EvaluatorSettings,
                            trials: int, seed: int, executor: typing.Optional[TrialExecutor] = None,
                            levels: typing.Optional[typing.Mapping[str, typing.Sequence[typing.Union[float, str]]]] = None,
                            robust: typing.Optional[RobustSettings] = None,
                            on_row: typing.Optional[typing.Callable[[Row], None]] = None,
                            settings_levels: typing.Optional[typing.Mapping[str, typing.Sequence[float]]] = None
                            ) -> typing.List[Row]:
    """Launch every profile on the twin at both ends of every unknown's range and robustly; the rows (dicts,
    as :func:`sensitivity_rows`). ``settings_levels`` adds rows for any numeric twin setting by its dotted
    settings name (``{"twin.wheel_side_friction_factor": (0.03, 0.5)}``; :func:`with_setting`).

    ``settings`` are the evaluator's (its ``objective`` names the campaign and twin files; its launch engine
    runs the launches: :func:`~rollability_ros.core.sim.evaluation.settings_at_fidelity` ``launch``); ``robust``
    gives the ranges and the robust row's distribution (default: ``settings.objective.robust``); ``levels``
    overrides :func:`launch_levels` (``{factor: levels}``).
    """
    at_launch = settings_at_fidelity(settings, "launch")
    robust = dataclasses.replace(robust or settings.objective.robust, enabled=True)
    config.check_settings(robust, "objective.robust")
    plain = dataclasses.replace(at_launch, objective=dataclasses.replace(at_launch.objective,
                                                                         robust=RobustSettings()))
    drawn = dataclasses.replace(at_launch, objective=dataclasses.replace(at_launch.objective, robust=robust))
    rows = []
    for label, mesh in profiles.items():
        job = mesh_job(mesh, plain)
        if job.launch is None:   # settings_at_fidelity("launch") always has launches
            raise ValueError("the launch sensitivity needs launch trials")
        chosen = levels if levels is not None else launch_levels(robust, job.launch.twin.robot.com_offset_z_m)
        if levels is None and not represents_restitution(job.launch.twin.physics.engine):
            chosen = {f: v for f, v in chosen.items() if f != "robot_restitution"}   # no such row: none to vary
        if levels is None and mecanum_twin(job.launch.twin):   # the Mecanum wheels have their own rolling friction
            chosen = {f: v for f, v in chosen.items() if f != "wheel_rolling_resistance"}
        cases = [(factor, level, _factor_case(job, factor, level)) for factor, values in chosen.items()
                 for level in values]
        cases.append(("robust", "all unknowns drawn", dataclasses.replace(job, settings=drawn)))
        cases += [(name, level, _setting_case(mesh, plain, name, level)) for name, values in
                  (settings_levels or {}).items() for level in values]
        for factor, level, case in cases:
            rows.append(_row(label, factor, level, evaluate_job(case, trials, seed, executor), on_row))
    return rows


def _factor_case(job: typing.Any, factor: str, level: typing.Any) -> typing.Any:
    """The TrialJob ``job`` with launch unknown ``factor`` at ``level`` (its profile weighed for it)."""
    twin = with_launch_factor(job.launch.twin, factor, level)
    return dataclasses.replace(job, launch=dataclasses.replace(job.launch, twin=twin),
                               profile=scaled_profile(job.profile, job.settings, twin))


def with_setting(settings: _Settings, dotted: str, value: float, full_name: str = "") -> _Settings:
    """Dataclass ``settings`` with the numeric field at ``dotted`` (``"twin.foam.thickness_m"``) set to
    ``value``; ``ValueError`` naming a path that is not a numeric setting, or a value its group refuses."""
    full_name = full_name or dotted
    head, _, rest = dotted.partition(".")
    if not dataclasses.is_dataclass(settings) or head not in {f.name for f in dataclasses.fields(settings)}:
        raise ValueError(f"{full_name!r} is not a launch twin setting (dotted settings names, e.g. "
                         f"twin.foam.thickness_m, robot.body_mass_kg)")
    current = getattr(settings, head)
    group: typing.Any = settings   # a dataclass instance (checked above)
    if rest:
        replaced = dataclasses.replace(group, **{head: with_setting(current, rest, value, full_name)})
    elif isinstance(current, bool) or not isinstance(current, (int, float)):
        raise ValueError(f"{full_name} is not a numeric setting (it holds {current!r})")
    else:
        replaced = dataclasses.replace(group, **{head: type(current)(value)})
    config.check_settings(replaced, full_name[:-len(dotted)].rstrip("."))   # the group's ranges and rules
    return replaced


def _setting_case(mesh: typing.Optional[Mesh], plain: EvaluatorSettings, dotted: str, value: float) -> typing.Any:
    """The TrialJob of ``mesh`` with twin setting ``dotted`` at ``value``; a ``robot.*`` setting also reaches
    the evaluator's robot, whose profile density weighs the candidate's profile."""
    evaluator = plain
    if dotted.startswith("robot."):
        evaluator = dataclasses.replace(plain, robot=with_setting(plain.robot, dotted.partition(".")[2], value,
                                                                  dotted))
    job = mesh_job(mesh, evaluator)
    if job.launch is None:
        raise ValueError("the launch sensitivity needs launch trials")
    nominal = perturb(job.launch.twin, nominal_draw(job.launch.twin))   # early decision off, as every row
    twin = with_setting(nominal, dotted, value)
    return dataclasses.replace(job, launch=dataclasses.replace(job.launch, twin=twin))
