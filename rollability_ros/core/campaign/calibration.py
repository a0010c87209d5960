"""Sim-to-real calibration: fit the launch twin's uncertain parameters to recorded physical launch outcomes.

What is fitted
    The parameters listed in ``calibration.parameters`` (``config/calibration.yaml``) by their config keys in the
    twin's parameter files (``launch_twin.foam.contact_stiffness_npm``, ``sim.lateral_friction``,
    ``robot.com_offset_z_m``, ...), each within ``[lower, upper]`` (its own unit), searched on a linear or a log
    scale. CMA-ES (pycma) works on normalised coordinates u in [0, 1]^d (pycma's bound handling); u maps to
    ``lower + u (upper - lower)``, or ``lower (upper / lower) ** u`` on a log scale. It starts from the values the
    loaded parameter files give (the uncalibrated twin).
Objective
    The physical outcomes are grouped per condition (configuration, height, speed, angle:
    :func:`rollability_ros.core.results.analysis.group_conditions`): k successes of n repetitions. For a parameter set,
    the twin launches every grouped condition ``sim_repetitions`` (R) times; the predicted success probability
    is p = upright / R, clipped to [eps, 1 - eps] (``probability_floor``) so that one impossible outcome does not
    make the likelihood zero. CMA-ES maximises the binomial log-likelihood sum_c log C(n, k) + k log p +
    (n - k) log(1 - p). Launch j of every condition uses the same seed (the speed and angle scatter draws) for
    every parameter set: common random numbers, so two parameter sets differ by their physics, not by their luck.
    The fitted value is the best parameter set evaluated. Bench characterisation readings
    (:mod:`~rollability_ros.core.campaign.characterisation`, ``rollability calibrate --characterisation``) add
    their log-likelihood (each reading through a model of its measurement) to every parameter set's, in the fit
    and in the intervals; with them the physical launch outcomes may be absent (the unknowns pinned before the
    first launch).
Uncertainty (``interval``; bench/bench_calibration_direct.py --coverage measures how often it holds the truth)
    ``likelihood`` (default): for each parameter, the likelihood-ratio 95% interval along a grid of
    ``interval_points`` values over its bounds, the other parameters at their fitted values, with the
    beta-binomial likelihood (:func:`beta_binomial_log_likelihood`: the predicted probability is only known from
    ``sim_repetitions`` launches, and that Monte Carlo error widens the interval as it should); the ends are
    first grid points whose log-likelihood lies more than 1.92 below the maximum (conservative by up to one step). ``bootstrap``: the 2.5 and 97.5 percentiles of
    ``bootstrap_resamples`` (at least 20) repeated fits, each on a resample of the physical trials (every
    grouped condition's repetitions drawn with replacement) and with its own simulation seeds. Bootstrap fits
    are made whenever ``bootstrap_resamples`` > 0 and their standard deviation is reported either way (the
    former 2-3 fits made it too small: the truth lay 2.7 and 3.6 of them away).
Output
    :func:`calibrated_parameter_document` is a ROS 2 parameter file with the fitted values under their own
    namespaces, loaded on top of the defaults by the evaluator, the optimizer and the twin (``--config``,
    ``--params-file``); :func:`rig_parameter_document` sets a rig node's ``rig.twin_config`` to the defaults plus
    that file, so the rig's sim backend launches on the calibrated twin. See ``docs/calibration.md``.

Launches run in a process pool (``workers``); cma and pybullet are imported where they are used.
"""
import dataclasses
import math
import os
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core.results import (ConditionResult, SimVsExperiment, group_conditions, sim_vs_experiment,
                                          summarise)
from rollability_ros.core.campaign.characterisation import Characterisation, characterisation_log_likelihood
from rollability_ros.core.config import ConfigError, ParameterDocument, edge_parse, from_mapping, parameter_document, section
from rollability_ros.core.sim import (LaunchTwinSettings, simulate_valid_launch, spawn_pool, trial_seed, twin_value,
                                      twin_with_values)
from rollability_ros.core.optional import require
from rollability_ros.core.records import INVALID_LAUNCH, LaunchCondition, LaunchOutcome

#: The parameter files the twin is built from, in load order (``load_launch_twin_settings``' default).
TWIN_CONFIGS = ("sim", "robot", "launch_twin")
#: ``calibration.interval`` values: how the stated 95% interval of each parameter is made.
INTERVALS = ("likelihood", "bootstrap")
#: Fewest bootstrap fits a percentile interval is made of.
MIN_BOOTSTRAP = 20
#: Deviance of a 95% likelihood-ratio interval of one parameter (chi-squared, 1 degree of freedom).
CHI2_1_95 = 3.841458820694124

ConditionResult = ConditionResult
#: Config keys that act only on the twin's Mecanum wheels (:func:`check_fittable`).
MECANUM_KEYS = ("launch_twin.wheel_drag_torque_nm", "launch_twin.wheel_rolling_friction",
                "launch_twin.wheel_side_friction_factor")
#: The config key that acts only on a robot's own wheels (:func:`check_fittable`).
OWN_WHEEL_KEY = "launch_twin.wheel_rolling_resistance"


@dataclasses.dataclass
class CalibrationSettings:
    """The ``calibration`` namespace (``config/calibration.yaml``); see the module docstring."""

    parameters: typing.List[str] = dataclasses.field(default_factory=lambda: [
        "launch_twin.foam.contact_stiffness_npm", "launch_twin.foam.contact_damping_nspm",
        "launch_twin.foam.lateral_friction", "launch_twin.foam.restitution", "launch_twin.speed_sigma_fraction",
        "robot.com_offset_z_m", "launch_twin.foam.rolling_friction", "launch_twin.wheel_drag_torque_nm",
        "robot.profile_mass_scale", "launch_twin.launcher.ledge_rolling_friction",
        "launch_twin.launcher.speed_bias_fraction"])
    lower: typing.List[float] = dataclasses.field(default_factory=lambda: [5000.0, 20.0, 0.3, 0.0, 0.0, -0.019,
                                                                           0.002, 0.0005, 0.5, 0.0, -0.15])
    upper: typing.List[float] = dataclasses.field(default_factory=lambda: [160000.0, 600.0, 3.0, 1.0, 0.15, 0.015,
                                                                           0.05, 0.02, 2.0, 0.01, 0.15])
    log_scale: typing.List[bool] = dataclasses.field(default_factory=lambda: [True, True, True, False, False, False,
                                                                              True, True, True, False, False])
    sim_repetitions: int = 16
    probability_floor: float = 0.01
    popsize: int = 8
    sigma0: float = 0.3
    max_generations: int = 12
    seed: int = 1
    bootstrap_resamples: int = 0
    interval: str = "likelihood"
    interval_points: int = 13
    workers: int = 0

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        count = len(self.parameters)
        if not count:
            raise ValueError("parameters must name at least one parameter to fit")
        if not len(self.lower) == len(self.upper) == len(self.log_scale) == count:
            raise ValueError(f"lower ({len(self.lower)}), upper ({len(self.upper)}) and log_scale "
                             f"({len(self.log_scale)}) need one entry per parameter ({count})")
        if len(set(self.parameters)) != count:
            raise ValueError("parameters lists a name twice")
        for name, low, high, log in zip(self.parameters, self.lower, self.upper, self.log_scale):
            if not low < high:
                raise ValueError(f"{name}: need lower < upper, got [{low}, {high}]")
            if log and not low > 0:
                raise ValueError(f"{name}: a log-scale parameter needs lower > 0, got {low}")
        if self.sim_repetitions < 1:
            raise ValueError(f"sim_repetitions must be >= 1, got {self.sim_repetitions}")
        if not 0 < self.probability_floor < 0.5:
            raise ValueError(f"probability_floor must be in (0, 0.5), got {self.probability_floor}")
        if self.popsize < 2:
            raise ValueError(f"popsize must be >= 2, got {self.popsize}")
        if not 0 < self.sigma0 <= 1:
            raise ValueError(f"sigma0 must be in (0, 1] (normalised units), got {self.sigma0}")
        if self.max_generations < 1:
            raise ValueError(f"max_generations must be >= 1, got {self.max_generations}")
        if not 1 <= self.seed < 2**32:
            raise ValueError(f"seed must be in [1, 2**32), got {self.seed}")
        if self.bootstrap_resamples < 0 or self.workers < 0:
            raise ValueError("bootstrap_resamples and workers must be >= 0 (workers 0 = one per core)")
        if self.interval not in INTERVALS:
            raise ValueError(f"interval must be one of {', '.join(INTERVALS)}, got {self.interval!r}")
        if self.interval == "bootstrap" and self.bootstrap_resamples < MIN_BOOTSTRAP:
            raise ValueError(f"a bootstrap percentile interval needs bootstrap_resamples >= {MIN_BOOTSTRAP}, got "
                             f"{self.bootstrap_resamples}")
        if self.interval == "likelihood" and self.interval_points < 5:
            raise ValueError(f"interval_points must be >= 5, got {self.interval_points}")

    def selected(self, names: typing.Sequence[str]) -> "CalibrationSettings":
        """These settings fitting only ``names`` (a subset of ``parameters``, each with its declared bounds and
        scale; the others stay at their loaded values); ``ValueError`` naming one not declared."""
        undeclared = [name for name in names if name not in self.parameters]
        if undeclared:
            raise ValueError(f"{undeclared[0]} is not declared in calibration.parameters (declared: "
                             f"{', '.join(self.parameters)}); declare it there with its bounds and scale")
        index = [self.parameters.index(name) for name in dict.fromkeys(names)]
        return dataclasses.replace(self, parameters=[self.parameters[i] for i in index],
                                   lower=[self.lower[i] for i in index], upper=[self.upper[i] for i in index],
                                   log_scale=[self.log_scale[i] for i in index])

    def to_values(self, normalised: npt.ArrayLike) -> np.ndarray:
        """Parameter values (own units) of normalised coordinates ``normalised`` (d,), clipped to [0, 1]."""
        u = np.clip(np.asarray(normalised, dtype=np.float64), 0.0, 1.0)
        return np.array([low * (high / low) ** x if log else low + x * (high - low)
                         for x, low, high, log in zip(u, self.lower, self.upper, self.log_scale)])

    def to_normalised(self, values: typing.Union[typing.Sequence[float], np.ndarray]) -> np.ndarray:
        """Normalised coordinates of parameter ``values`` (d,); ``ValueError`` naming one outside its bounds."""
        out = []
        for name, value, low, high, log in zip(self.parameters, values, self.lower, self.upper, self.log_scale):
            if not low <= value <= high:
                raise ValueError(f"{name} = {value:g} lies outside its calibration bounds [{low:g}, {high:g}]")
            out.append(math.log(value / low) / math.log(high / low) if log else (value - low) / (high - low))
        return np.array(out)


@edge_parse
def calibration_settings(parameters: typing.Mapping[str, object]) -> CalibrationSettings:
    """The :class:`CalibrationSettings` of flat parameters (namespace ``calibration``), checked against the
    twin's keys: every fitted name must be a key of the loaded parameter files."""
    settings = from_mapping(CalibrationSettings, section(parameters, "calibration"), "calibration")
    unknown = [name for name in settings.parameters if name not in parameters]
    if unknown:
        raise ConfigError(f"calibration.parameters: {', '.join(unknown)} not set by the twin's parameter files "
                          f"({', '.join(TWIN_CONFIGS)}); name parameters by their config keys")
    return settings


def check_fittable(twin: LaunchTwinSettings, settings: CalibrationSettings) -> None:
    """Refuse a fitted key the typed twin ``twin`` does not use (``ValueError`` naming it): the Mecanum
    wheels' ``launch_twin.wheel_drag_torque_nm`` / ``wheel_rolling_friction`` / ``wheel_side_friction_factor``
    on a twin that gives the robot its own wheels (``launch_twin.wheel_model``), and the own wheels'
    ``launch_twin.wheel_rolling_resistance`` on a twin that gives it the Mecanum wheels."""
    from rollability_ros.core.sim import mecanum_wheels

    mecanum_only = [name for name in settings.parameters if name in MECANUM_KEYS]
    if mecanum_only and not mecanum_wheels(twin):
        raise ValueError(f"calibration.parameters: {mecanum_only[0]} acts on the twin's Mecanum wheels only, and "
                         f"this twin gives the robot its own wheels (launch_twin.wheel_model); fit the robot's own "
                         f"drag (robot.wheel_drag_torque_nm or urdf_robot.joint_drag_torque_nm) or "
                         f"{OWN_WHEEL_KEY} instead")
    if OWN_WHEEL_KEY in settings.parameters and mecanum_wheels(twin):
        raise ValueError(f"calibration.parameters: {OWN_WHEEL_KEY} acts on a robot's own wheels only, and this twin "
                         f"gives the robot its Mecanum wheels (launch_twin.wheel_model); fit "
                         f"launch_twin.wheel_rolling_friction instead")


def twin_settings_with(twin: LaunchTwinSettings, names: typing.Sequence[str],
                       values: typing.Union[typing.Sequence[float], np.ndarray]) -> LaunchTwinSettings:
    """The typed twin ``twin`` (:class:`~rollability_ros.core.sim.launch.settings.LaunchTwinSettings`, parsed once
    by the command) with ``names`` set to ``values`` (config keys, own units; ``values`` (d,) one per name; checked
    like file values: :func:`~rollability_ros.core.sim.launch.settings.twin_with_values`)."""
    return twin_with_values(twin, {name: float(value) for name, value in zip(names, values)})


def twin_values(twin: LaunchTwinSettings, names: typing.Sequence[str]) -> typing.List[float]:
    """The values (own units) the typed twin ``twin`` gives the config keys ``names``: a fit's starting point."""
    return [twin_value(twin, name) for name in names]


def simulation_seeds(seed: int, resample: int, repetitions: int) -> typing.List[int]:
    """The common random numbers of one fit: ``repetitions`` launch seeds from (``seed``, ``resample``);
    resample 0 is the main fit, 1.. the bootstrap fits."""
    base = trial_seed(seed, resample)
    return [trial_seed(base, j) for j in range(repetitions)]


def launch_condition(result: ConditionResult) -> LaunchCondition:
    """The :class:`LaunchCondition` of a grouped condition (:class:`~rollability_ros.core.results.analysis.ConditionResult`)."""
    return LaunchCondition(result.configuration, result.height_m, result.speed_mps, result.angle_deg)


def _count_upright(settings, condition, seeds):
    """Launch ``condition`` once per seed on the twin ``settings`` (an invalid launch retried,
    :func:`simulate_valid_launch`); return how many ended upright (a launch still invalid counts as not upright)."""
    launches = (simulate_valid_launch(condition, settings, seed) for seed in seeds)
    return sum(result.valid and result.upright for result in launches)


class LaunchPool:
    """Counts upright launches per (parameter set, grouped condition), in worker processes (or serially: 1).

    ``workers`` None or 0 = one per core, in :func:`~rollability_ros.core.sim.spawn_pool` processes.
    """

    def __init__(self, workers: typing.Optional[int] = None) -> None:
        self.workers = workers or os.cpu_count() or 1
        self._pool = None if self.workers == 1 else spawn_pool(self.workers)

    def predicted_upright(self, twin_settings_list: typing.Sequence[LaunchTwinSettings],
                          conditions: typing.Sequence[ConditionResult], seeds: typing.Sequence[int]) -> np.ndarray:
        """Upright counts (s, c): one row per twin of ``twin_settings_list`` (s), one column per condition (c), of
        ``len(seeds)`` launches each."""
        jobs = [(settings, launch_condition(c), seeds) for settings in twin_settings_list for c in conditions]
        if not jobs:   # no launch conditions (a characterisation alone)
            return np.zeros((len(twin_settings_list), len(conditions)), dtype=np.int64)
        if self._pool is None:
            counts = [_count_upright(*job) for job in jobs]
        else:
            counts = list(self._pool.map(_count_upright, *zip(*jobs)))
        return np.asarray(counts, dtype=np.int64).reshape(len(twin_settings_list), len(conditions))

    def characterisation(self, characterisation: typing.Optional[Characterisation],
                         twins: typing.Sequence[LaunchTwinSettings]) -> np.ndarray:
        """The characterisation log-likelihood (s,) of each typed twin of ``twins`` (zeros without one), in the
        worker processes (roll-outs are simulated)."""
        if characterisation is None:
            return np.zeros(len(twins))
        jobs = [characterisation] * len(twins)
        if self._pool is None:
            return np.array([characterisation_log_likelihood(c, t) for c, t in zip(jobs, twins)])
        return np.array(list(self._pool.map(characterisation_log_likelihood, jobs, twins)))

    def close(self) -> None:
        """Stop the worker processes."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> "LaunchPool":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def binomial_log_likelihood(successes: npt.ArrayLike, trials: npt.ArrayLike, probabilities: npt.ArrayLike,
                            floor: float) -> typing.Union[np.float64, npt.NDArray[np.float64]]:
    """Sum over conditions of log Binomial(successes | trials, p), p clipped to [floor, 1 - floor].

    ``successes``, ``trials`` and ``probabilities`` are (c,) arrays (or the last axis of broadcastable arrays);
    returns a float (numpy scalar), or an array over the leading axes.
    """
    k = np.asarray(successes, dtype=np.float64)
    n = np.asarray(trials, dtype=np.float64)
    if np.any(k < 0) or np.any(k > n):
        raise ValueError("need 0 <= successes <= trials in every condition")
    p = np.clip(np.asarray(probabilities, dtype=np.float64), floor, 1.0 - floor)
    if k.size == 0:   # no launch outcomes (a characterisation alone): they add nothing
        return np.zeros(np.broadcast_shapes(k.shape, n.shape, p.shape)[:-1])
    log_choose = np.vectorize(lambda a, b: math.lgamma(a + 1) - math.lgamma(b + 1) - math.lgamma(a - b + 1))(n, k)
    return (log_choose + k * np.log(p) + (n - k) * np.log1p(-p)).sum(axis=-1)


def beta_binomial_log_likelihood(successes: npt.ArrayLike, trials: npt.ArrayLike, upright: npt.ArrayLike,
                                 repetitions: int) -> typing.Union[np.float64, npt.NDArray[np.float64]]:
    """Sum over conditions of log P(successes | trials) when the success probability is only known from
    ``upright`` of ``repetitions`` simulated launches: p ~ Beta(upright + 1, repetitions - upright + 1), so the
    physical count is beta-binomial. Unlike the plug-in binomial it carries the simulation's Monte Carlo error,
    and it needs no probability floor. Arrays (c,) per condition broadcast as in :func:`binomial_log_likelihood`."""
    k = np.asarray(successes, dtype=np.float64)
    n = np.asarray(trials, dtype=np.float64)
    u = np.asarray(upright, dtype=np.float64)
    if np.any(k < 0) or np.any(k > n) or np.any(u < 0) or np.any(u > repetitions):
        raise ValueError("need 0 <= successes <= trials and 0 <= upright <= repetitions in every condition")
    if k.size == 0:   # no launch outcomes (a characterisation alone): they add nothing
        return np.zeros(np.broadcast_shapes(k.shape, n.shape, u.shape)[:-1])
    lgamma = np.vectorize(math.lgamma)

    def log_beta(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """log B(a, b) elementwise; ``a`` and ``b`` broadcast like the counts, e.g. (c,) or (g, c)."""
        return lgamma(a) + lgamma(b) - lgamma(a + b)
    log_choose = lgamma(n + 1) - lgamma(k + 1) - lgamma(n - k + 1)
    a, b = u + 1.0, repetitions - u + 1.0
    return (log_choose + log_beta(k + a, n - k + b) - log_beta(a, b)).sum(axis=-1)


def likelihood_interval(grid_values: npt.ArrayLike, log_likelihoods: npt.ArrayLike, deviance: float = CHI2_1_95,
                        ends: str = "grid") -> typing.Tuple[float, float]:
    """The likelihood-ratio interval on a grid: the values whose log-likelihood lies within ``deviance / 2`` of
    the grid's maximum. The likelihood is known at the grid points only, so with ``ends="grid"`` (default) each
    end is the first grid point outside that set (a bound of the grid when there is none): conservative by up to
    one grid step, which a coarse grid needs (bench_calibration_direct --coverage: interpolated ends held the truth in
    only 8 of 10 cases, all misses within one step). ``ends="interpolate"`` puts them where the straight line
    between neighbouring points crosses the level. ``grid_values`` (g,) ascending, own units, ``log_likelihoods``
    (g,); ``(low, high)``."""
    values = np.asarray(grid_values, dtype=np.float64)
    curve = np.asarray(log_likelihoods, dtype=np.float64)
    level = curve.max() - deviance / 2.0
    inside = np.flatnonzero(curve >= level)
    first, last = int(inside[0]), int(inside[-1])
    if ends == "grid":
        return float(values[max(first - 1, 0)]), float(values[min(last + 1, len(values) - 1)])
    if ends != "interpolate":
        raise ValueError(f"ends must be 'grid' or 'interpolate', got {ends!r}")

    def crossing(i: int, j: int) -> float:   # i inside, j outside: where the line between them meets the level
        return float(values[i] + (values[j] - values[i]) * (curve[i] - level) / (curve[i] - curve[j]))
    low = crossing(first, first - 1) if first > 0 else float(values[0])
    high = crossing(last, last + 1) if last < len(values) - 1 else float(values[-1])
    return low, high


def interval_grid(settings: CalibrationSettings, index: int, points: typing.Optional[int] = None) -> np.ndarray:
    """The grid of parameter ``index``: ``points`` values (points,) spread evenly over its bounds on its own scale
    (own units)."""
    u = np.linspace(0.0, 1.0, points or settings.interval_points)
    low, high, log = settings.lower[index], settings.upper[index], settings.log_scale[index]
    return low * (high / low) ** u if log else low + u * (high - low)


def predicted_on_grid(conditions: typing.Sequence[ConditionResult], twin: LaunchTwinSettings,
                      settings: CalibrationSettings, pool: LaunchPool, fitted: npt.ArrayLike,
                      index: int) -> typing.Tuple[np.ndarray, np.ndarray]:
    """Upright counts of ``sim_repetitions`` launches per grouped condition along parameter ``index``'s grid,
    the other parameters at ``fitted`` (d,) (own units): ``(grid values (g,), upright (g, c))``. Every grid point
    uses the main fit's seeds (common random numbers); the counts do not depend on the physical outcomes."""
    grid = interval_grid(settings, index)
    twins = []
    for value in grid:
        values = np.array(fitted, dtype=np.float64)
        values[index] = value
        twins.append(twin_settings_with(twin, settings.parameters, values))
    seeds = simulation_seeds(settings.seed, 0, settings.sim_repetitions)
    return grid, pool.predicted_upright(twins, conditions, seeds)


def likelihood_profile(conditions: typing.Sequence[ConditionResult], twin: LaunchTwinSettings,
                       settings: CalibrationSettings, pool: LaunchPool, fitted: npt.ArrayLike, index: int,
                       predicted: typing.Optional[typing.Tuple[np.ndarray, np.ndarray]] = None,
                       characterisation: typing.Optional[Characterisation] = None
                       ) -> typing.Tuple[np.ndarray, np.ndarray]:
    """Beta-binomial log-likelihood of grouped physical ``conditions`` (plus ``characterisation``'s, if any)
    along parameter ``index``'s grid, the other parameters at ``fitted`` (d,): ``(grid values (g,),
    log-likelihoods (g,))``; ``predicted`` reuses a :func:`predicted_on_grid` result made for the same conditions
    (in the same order)."""
    grid, upright = predicted or predicted_on_grid(conditions, twin, settings, pool, fitted, index)
    successes = np.array([c.successes for c in conditions])
    trials = np.array([c.trials for c in conditions])
    twins = []
    for value in grid:
        values = np.array(fitted, dtype=np.float64)
        values[index] = value
        twins.append(twin_settings_with(twin, settings.parameters, values))
    return grid, (beta_binomial_log_likelihood(successes, trials, upright, settings.sim_repetitions)
                  + pool.characterisation(characterisation, twins))


@dataclasses.dataclass(frozen=True)
class FitResult:
    """One fit: fitted values (own units, in ``CalibrationSettings.parameters`` order), normalised coordinates,
    log-likelihood, predicted upright counts per condition (of ``sim_repetitions``), generations and parameter
    sets evaluated."""

    values: np.ndarray
    normalised: np.ndarray
    log_likelihood: float
    predicted_upright: np.ndarray
    generations: int
    evaluations: int


def fit(conditions: typing.Sequence[ConditionResult], twin: LaunchTwinSettings,
        settings: CalibrationSettings, pool: LaunchPool, resample: int = 0,
        on_generation: typing.Optional[typing.Callable[[int, float], None]] = None,
        characterisation: typing.Optional[Characterisation] = None) -> "FitResult":
    """Fit ``settings.parameters`` to grouped physical ``conditions`` (list of ConditionResult) by CMA-ES; the
    :class:`FitResult`'s ``values`` and ``normalised`` are (d,), its ``predicted_upright`` (c,).

    Parameters
    ----------
    conditions : list of rollability_ros.core.results.analysis.ConditionResult
    twin : LaunchTwinSettings
        The typed twin of the loaded files (the starting values and everything not fitted).
    settings : CalibrationSettings
    pool : LaunchPool
    resample : int
        0 for the main fit, b >= 1 for bootstrap fit b (its own simulation seeds and CMA-ES seed).
    on_generation : callable(generation, best log-likelihood), optional
    characterisation : Characterisation, optional
        Bench readings whose log-likelihood adds to the launches' (module docstring).
    """
    cma = require("cma", feature="the calibration")
    if not conditions and characterisation is None:
        raise ValueError("no grouped conditions and no characterisation to calibrate against")
    successes = np.array([c.successes for c in conditions])
    trials = np.array([c.trials for c in conditions])
    seeds = simulation_seeds(settings.seed, resample, settings.sim_repetitions)
    x0 = settings.to_normalised(twin_values(twin, settings.parameters))
    options = {"popsize": settings.popsize, "bounds": [0.0, 1.0], "seed": settings.seed + resample,
               "verbose": -9, "verb_log": 0, "verb_disp": 0}
    if len(x0) == 1:  # pycma cannot rescale one coordinate's step to its bound range in 1-D (it raises): no limit
        options["maxstd_boundrange"] = math.inf
    global_state = np.random.get_state()
    try:
        strategy = cma.CMAEvolutionStrategy(x0, settings.sigma0, options)
        best = None
        evaluations = 0
        for generation in range(settings.max_generations):
            population = [np.asarray(x, dtype=np.float64) for x in strategy.ask()]
            twins = [twin_settings_with(twin, settings.parameters, settings.to_values(x)) for x in population]
            upright = pool.predicted_upright(twins, conditions, seeds)
            log_likelihood = binomial_log_likelihood(successes, trials, upright / settings.sim_repetitions,
                                                     settings.probability_floor) + pool.characterisation(
                characterisation, twins)
            strategy.tell(population, list(-log_likelihood))
            evaluations += len(population)
            top = int(np.argmax(log_likelihood))
            if best is None or log_likelihood[top] > best[1]:
                best = (population[top], float(log_likelihood[top]), upright[top])
            if on_generation is not None:
                on_generation(generation, best[1])
    finally:
        np.random.set_state(global_state)  # pycma's seed option reseeds the process-wide generator
    if best is None:   # CalibrationSettings.validate holds max_generations >= 1
        raise ValueError(f"max_generations must be >= 1, got {settings.max_generations}")
    x, log_likelihood, upright = best
    return FitResult(values=settings.to_values(x), normalised=np.clip(x, 0.0, 1.0), log_likelihood=log_likelihood,
                     predicted_upright=upright, generations=settings.max_generations, evaluations=evaluations)


def bootstrap_conditions(conditions: typing.Sequence[ConditionResult],
                         rng: np.random.Generator) -> typing.List[ConditionResult]:
    """A resample of the physical trials: each grouped condition's repetitions drawn with replacement."""
    return [dataclasses.replace(c, successes=int(rng.binomial(c.trials, c.successes / c.trials)))
            for c in conditions]


@dataclasses.dataclass(frozen=True)
class ParameterEstimate:
    """One fitted parameter: config key, starting value, fitted value, bootstrap fits, bounds, and the stated 95%
    interval with the method that made it (own units)."""

    name: str
    initial: float
    fitted: float
    bootstrap: typing.Tuple[float, ...]
    lower: float
    upper: float
    interval_low: float = math.nan
    interval_high: float = math.nan
    interval_method: str = ""

    @property
    def std(self) -> float:
        """Standard deviation of the bootstrap fits (the stated uncertainty); NaN with fewer than 2."""
        return float(np.std(self.bootstrap, ddof=1)) if len(self.bootstrap) >= 2 else math.nan

    def row(self) -> typing.Dict[str, object]:
        """Flat dict for a CSV table."""
        spread = (min(self.bootstrap), max(self.bootstrap)) if self.bootstrap else (math.nan, math.nan)
        return {"parameter": self.name, "initial": self.initial, "fitted": self.fitted,
                "interval_low": self.interval_low, "interval_high": self.interval_high,
                "interval_method": self.interval_method, "bootstrap_std": self.std,
                "bootstrap_min": spread[0], "bootstrap_max": spread[1], "bootstrap_fits": len(self.bootstrap),
                "lower": self.lower, "upper": self.upper}


@dataclasses.dataclass(frozen=True)
class CalibrationResult:
    """A calibration: physical conditions, the twin's predictions before and after, the fitted parameters."""

    conditions: typing.List[ConditionResult]
    sim_repetitions: int
    before_upright: np.ndarray
    after_upright: np.ndarray
    before_log_likelihood: float
    after_log_likelihood: float
    estimates: typing.List[ParameterEstimate]
    evaluations: int

    def fitted_values(self) -> typing.Dict[str, float]:
        """``{config key: fitted value}``."""
        return {e.name: e.fitted for e in self.estimates}

    def condition_rows(self) -> typing.List[typing.Dict[str, object]]:
        """Per grouped condition: measured vs predicted success rate before and after."""
        r = self.sim_repetitions
        return [{"configuration": c.configuration, "height_m": c.height_m, "speed_mps": c.speed_mps,
                 "angle_deg": c.angle_deg, "trials": c.trials, "successes": c.successes,
                 "measured_rate": c.successes / c.trials, "before_rate": before / r, "after_rate": after / r}
                for c, before, after in zip(self.conditions, self.before_upright, self.after_upright)]

    def predicted_conditions(self, upright: typing.Union[typing.Sequence[int], np.ndarray]) -> typing.List[ConditionResult]:
        """The twin's prediction as ConditionResults (``upright`` (c,) of ``sim_repetitions`` per condition)."""
        return [dataclasses.replace(c, successes=int(k), trials=self.sim_repetitions)
                for c, k in zip(self.conditions, upright)]

    def configuration_rows(self, configuration_order: typing.Optional[typing.Sequence[str]] = None
                           ) -> typing.List[typing.Dict[str, object]]:
        """Per configuration: measured trial and condition (majority rule) rates, predicted before and after."""
        measured = summarise(self.conditions, ("configuration",), configuration_order)
        before = summarise(self.predicted_conditions(self.before_upright), ("configuration",),
                           configuration_order)
        after = summarise(self.predicted_conditions(self.after_upright), ("configuration",),
                          configuration_order)
        return [{"configuration": m.key["configuration"], "measured_trial_rate": m.trial_rate,
                 "measured_condition_rate": m.condition_rate, "before_trial_rate": b.trial_rate,
                 "before_condition_rate": b.condition_rate, "after_trial_rate": a.trial_rate,
                 "after_condition_rate": a.condition_rate}
                for m, b, a in zip(measured, before, after)]

    def rank_agreement(self, configuration_order: typing.Optional[typing.Sequence[str]] = None
                       ) -> typing.Dict[str, SimVsExperiment]:
        """``{"before": SimVsExperiment, "after": SimVsExperiment}``: configurations' predicted vs measured trial
        rates (:func:`rollability_ros.core.results.analysis.sim_vs_experiment`)."""
        measured = summarise(self.conditions, ("configuration",), configuration_order)
        out: typing.Dict[str, SimVsExperiment] = {}
        for label, upright in (("before", self.before_upright), ("after", self.after_upright)):
            predicted = summarise(self.predicted_conditions(upright), ("configuration",), configuration_order)
            rates = {cell.key["configuration"]: cell.trial_rate for cell in predicted}
            out[label] = sim_vs_experiment(rates, measured, "trial_rate")
        return out


def calibrate(outcomes: typing.Iterable[LaunchOutcome], twin: LaunchTwinSettings,
              settings: CalibrationSettings, pool: LaunchPool,
              on_progress: typing.Optional[typing.Callable[[str], None]] = None,
              characterisation: typing.Optional[Characterisation] = None) -> CalibrationResult:
    """Calibrate the twin to physical launch ``outcomes`` (LaunchOutcome list); see the module docstring.

    Parameters
    ----------
    outcomes : list of LaunchOutcome
    twin : LaunchTwinSettings
        The typed twin of its files (:data:`TWIN_CONFIGS` and any overrides), parsed once by the command: the
        uncalibrated twin.
    settings : CalibrationSettings
    pool : LaunchPool
    on_progress : callable(str), optional
        One line per finished fit.
    characterisation : Characterisation, optional
        Bench readings (``--characterisation``); with them ``outcomes`` may be empty. A bootstrap fit resamples the
        launch outcomes only.
    """
    check_fittable(twin, settings)
    conditions = group_conditions(outcomes)
    say = on_progress or (lambda line: None)
    initial = twin_values(twin, settings.parameters)
    seeds = simulation_seeds(settings.seed, 0, settings.sim_repetitions)
    before = pool.predicted_upright([twin_settings_with(twin, settings.parameters, initial)], conditions,
                                    seeds)[0]
    main = fit(conditions, twin, settings, pool, characterisation=characterisation)
    say(f"fit: log-likelihood {main.log_likelihood:.2f} at "
        + ", ".join(f"{n} = {v:.4g}" for n, v in zip(settings.parameters, main.values)))
    rng = np.random.default_rng(settings.seed)
    resampled = []
    evaluations = 1 + main.evaluations
    for resample in range(1, settings.bootstrap_resamples + 1):
        result = fit(bootstrap_conditions(conditions, rng), twin, settings, pool, resample,
                     characterisation=characterisation)
        resampled.append(result.values)
        evaluations += result.evaluations
        say(f"bootstrap {resample}/{settings.bootstrap_resamples}: "
            + ", ".join(f"{n} = {v:.4g}" for n, v in zip(settings.parameters, result.values)))
    estimates = []
    for i, name in enumerate(settings.parameters):
        fits = tuple(float(values[i]) for values in resampled)
        if settings.interval == "bootstrap":
            low, high = (float(v) for v in np.percentile(fits, [2.5, 97.5]))
            method = f"bootstrap percentile ({len(fits)} fits)"
        else:
            grid, curve = likelihood_profile(conditions, twin, settings, pool, main.values, i,
                                             characterisation=characterisation)
            evaluations += len(grid)
            low, high = likelihood_interval(grid, curve)
            method = f"likelihood ratio, beta-binomial ({len(grid)} points, others at their fit)"
        say(f"{name}: 95% interval [{low:.4g}, {high:.4g}] ({method})")
        estimates.append(ParameterEstimate(name, initial[i], float(main.values[i]), fits, settings.lower[i],
                                           settings.upper[i], low, high, method))
    successes = np.array([c.successes for c in conditions])
    trials = np.array([c.trials for c in conditions])
    before_ll = float(binomial_log_likelihood(successes, trials, before / settings.sim_repetitions,
                                              settings.probability_floor)
                      + pool.characterisation(characterisation, [twin_settings_with(twin, settings.parameters,
                                                                                    initial)])[0])
    return CalibrationResult(conditions=conditions, sim_repetitions=settings.sim_repetitions, before_upright=before,
                             after_upright=main.predicted_upright, before_log_likelihood=before_ll,
                             after_log_likelihood=main.log_likelihood, estimates=estimates, evaluations=evaluations)


def calibrated_parameter_document(fitted: typing.Mapping[str, float]) -> ParameterDocument:
    """The calibrated ROS 2 parameter file as a dict: ``/**: {ros__parameters: {...}}``, ``fitted`` (config keys to
    values) nested under their namespaces: only keys of the twin's namespaces, so every command that reads the twin
    applies all of them (a key a command does not apply is refused: ``config.check_given_files``)."""
    return parameter_document({name: float(value) for name, value in fitted.items()})


def rig_parameter_document(calibrated_path: typing.Union[str, os.PathLike],
                           twin_configs: typing.Sequence[str] = TWIN_CONFIGS) -> ParameterDocument:
    """The rig's parameter file for a calibrated twin: ``rig.twin_config`` = ``twin_configs`` plus
    ``calibrated_path``, so a rig node given it (``--params-file``) launches its sim backend on the calibrated twin
    (a node drops parameters it does not declare, such as ``launch_twin.*``)."""
    return {"/**": {"ros__parameters": {"rig": {"twin_config": [*twin_configs, os.fspath(calibrated_path)]}}}}
