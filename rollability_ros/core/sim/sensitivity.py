"""Sensitivity study: the simulated fitness of the bare chassis and of profiles against each uncertain factor.

Each factor is varied alone, the others at their configured values: ``disturbance_scale`` (a factor on the
disturbance's force and torque ranges), ``start_roll_deg`` (180 = upside down, 90 = on its side),
``contact_model`` (how the paper's contact values are read, config/sim.yaml) and ``com_offset_z_m`` (the
chassis's centre-of-mass height, m). Every (profile, factor, level) is evaluated with ``trials`` trials from one
base seed (common random numbers: the same start tilts and push directions at every level and for every profile),
plus the ``robust`` fitness (:mod:`~rollability_ros.core.sim.robustness`: every trial under its own draw of all
factors). Each fitness comes with its Wilson 95% interval. ``rollability sensitivity`` writes the rows as a CSV
and draws them (:func:`rollability_ros.core.results.report_figures.sensitivity`).
"""
import dataclasses
import typing

from rollability_ros.core.profile import Mesh
from rollability_ros.core.sim.evaluation import EvaluatorSettings, TrialExecutor, evaluate_mesh
from rollability_ros.core.sim.robustness import RobustSettings, perturb, Draw

#: factor -> default levels.
DEFAULT_LEVELS = {"disturbance_scale": (0.5, 1.0, 2.0), "start_roll_deg": (180.0, 90.0),
                  "contact_model": ("per_contact", "per_body"), "com_offset_z_m": (-0.015, -0.005, 0.005)}

#: One row of the study (configuration, factor, level, successes, trials, fitness and its interval).
Row = typing.Dict[str, typing.Any]


def with_factor(settings: EvaluatorSettings, factor: str, level: typing.Any) -> EvaluatorSettings:
    """EvaluatorSettings ``settings`` with one factor set to ``level`` (its type is the factor's: a name for
    ``contact_model``, else a number; the others as configured)."""
    nominal = Draw(disturbance_scale=1.0, start_roll_deg=settings.trial.start_roll_deg,
                   contact_model=settings.physics.contact_model, com_offset_z_m=settings.robot.com_offset_z_m,
                   foam_stiffness_factor=1.0, foam_restitution=0.0)
    if factor not in DEFAULT_LEVELS:
        raise ValueError(f"unknown factor {factor!r}; known: {', '.join(DEFAULT_LEVELS)}")
    return perturb(settings, dataclasses.replace(nominal, **{factor: level}))


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
            result = evaluate_mesh(mesh, trials, seed, case_settings, executor)
            row = {"configuration": label, "factor": factor, "level": level, "successes": result.successes,
                   "trials": result.trials, "fitness": result.fitness, "ci_low": result.ci_low,
                   "ci_high": result.ci_high}
            rows.append(row)
            if on_row is not None:
                on_row(row)
    return rows

