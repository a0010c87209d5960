"""Aggregation of launch outcomes into the paper's views, rank agreement, convergence and summaries.

Two measures are kept side by side for every cell of a view:

- ``condition_rate``: the paper's measure (2.2.6, Figures 9-12). Each grouped condition (configuration,
  height, speed, angle) is a success when its successful repetitions outnumber its failed ones (a tie is a
  failure); a cell's rate is the fraction of its grouped conditions that succeeded. A height x angle cell of
  the paper matrix holds 2 grouped conditions (the two speeds), so it reads 0, 50 or 100 %.
- ``trial_rate``: upright trials / trials of the cell, with a Wilson 95 % interval.

Pure Python (no numpy, no matplotlib); figures are drawn by :mod:`rollability_ros.core.results.report_figures`.
"""
import dataclasses
import itertools
import math
import random
import statistics
import typing

from rollability_ros.core.records import CandidateRecord, GenerationRecord, LaunchCondition, LaunchOutcome, TipEventRecord
from rollability_ros.core.stats import wilson_interval

#: The grouping factors of a grouped condition, LaunchCondition field names.
FACTORS = ("configuration", "height_m", "speed_mps", "angle_deg")


#: What :func:`group_conditions` tallies: a stored :class:`LaunchOutcome`, or ``(LaunchCondition, upright)``.
Outcome = typing.Union[LaunchOutcome, typing.Tuple[LaunchCondition, bool]]


@dataclasses.dataclass(frozen=True)
class ConditionResult:
    """One grouped condition (every factor but the repetition) and its repetitions' tally."""

    configuration: str
    height_m: float
    speed_mps: float
    angle_deg: float
    successes: int
    trials: int

    @property
    def failures(self) -> int:
        """Repetitions that did not end upright."""
        return self.trials - self.successes

    @property
    def success(self) -> bool:
        """Paper's majority rule: successes > failures; a tie is a failure."""
        return self.successes > self.failures


@dataclasses.dataclass(frozen=True)
class CellSummary:
    """One cell of a view: the factor values that define it and both success measures."""

    key: dict                 # factor name -> value, e.g. {"configuration": "A", "angle_deg": -30.0}
    conditions: int           # grouped conditions in the cell
    conditions_succeeded: int  # of them successful by the majority rule
    trials: int
    successes: int

    @property
    def condition_rate(self) -> float:
        """Fraction of grouped conditions that succeeded (paper's measure), NaN for an empty cell."""
        return self.conditions_succeeded / self.conditions if self.conditions else math.nan

    @property
    def trial_rate(self) -> float:
        """Upright trials / trials, NaN for an empty cell."""
        return self.successes / self.trials if self.trials else math.nan

    @property
    def trial_ci(self) -> typing.Tuple[float, float]:
        """Wilson 95 % interval of ``trial_rate``: (low, high)."""
        return wilson_interval(self.successes, self.trials)

    def row(self) -> typing.Dict[str, typing.Any]:
        """Flat dict for a CSV table: factors, counts, rates in [0, 1] and the interval."""
        low, high = self.trial_ci
        return {**self.key, "conditions": self.conditions, "conditions_succeeded": self.conditions_succeeded,
                "condition_rate": self.condition_rate, "trials": self.trials, "successes": self.successes,
                "trial_rate": self.trial_rate, "trial_ci_low": low, "trial_ci_high": high}


def group_conditions(outcomes: typing.Iterable[Outcome]) -> typing.List["ConditionResult"]:
    """Tally launch outcomes per grouped condition, sorted by (configuration, height, speed, angle).

    Parameters
    ----------
    outcomes : iterable of LaunchOutcome or LaunchCondition-with-upright pairs
        Each item is a :class:`LaunchOutcome`, or a ``(LaunchCondition, upright)`` tuple. Invalid launches
        (``LaunchOutcome.valid`` false) are left out: they are no outcome.
    """
    tallies: typing.Dict[typing.Tuple[str, float, float, float], typing.Tuple[int, int]] = {}
    for item in outcomes:
        if not getattr(item, "valid", True):
            continue
        condition, upright = (item if isinstance(item, tuple) else (item.condition, item.upright))
        if not isinstance(condition, LaunchCondition):
            raise ValueError(f"expected a LaunchCondition, got {condition!r}")
        successes, trials = tallies.get(condition.group_key, (0, 0))
        tallies[condition.group_key] = (successes + bool(upright), trials + 1)
    return [ConditionResult(*key, successes, trials)
            for key, (successes, trials) in sorted(tallies.items())]


def summarise(conditions: typing.Iterable["ConditionResult"], by: typing.Sequence[str],
              configuration_order: typing.Optional[typing.Sequence[str]] = None) -> typing.List["CellSummary"]:
    """Aggregate grouped conditions into cells keyed by the factors ``by`` (a subset of FACTORS).

    Cells are sorted by their factor values; ``configuration_order`` (ids) sorts configurations by that
    list instead of alphabetically (unknown ids last).
    """
    unknown = [factor for factor in by if factor not in FACTORS]
    if unknown:
        raise ValueError(f"unknown factor(s) {unknown}; known: {', '.join(FACTORS)}")
    cells: typing.Dict[tuple, typing.List[int]] = {}
    for condition in conditions:
        key = tuple(getattr(condition, factor) for factor in by)
        counts = cells.setdefault(key, [0, 0, 0, 0])
        counts[0] += 1
        counts[1] += condition.success
        counts[2] += condition.trials
        counts[3] += condition.successes
    rank = _configuration_rank(configuration_order)

    def sort_key(key: tuple) -> tuple:
        return tuple(rank(value) if factor == "configuration" else (0, value) for factor, value in zip(by, key))

    return [CellSummary(dict(zip(by, key)), *cells[key]) for key in sorted(cells, key=sort_key)]


def _configuration_rank(configuration_order):
    """Sort key for configuration ids: listed ones in that order, then the rest alphabetically."""
    order = list(configuration_order or [])
    return lambda configuration: (order.index(configuration) if configuration in order else len(order),
                                  configuration)


def configurations_in(conditions: typing.Iterable["ConditionResult"],
                      configuration_order: typing.Optional[typing.Sequence[str]] = None) -> typing.List[str]:
    """The configuration ids present, in ``configuration_order`` first, then alphabetically."""
    return sorted({c.configuration for c in conditions}, key=_configuration_rank(configuration_order))


@dataclasses.dataclass(frozen=True)
class Views:
    """The paper's views of one campaign, each a list of :class:`CellSummary`."""

    conditions: list          # every grouped condition (ConditionResult)
    height_angle: list        # Figure 9: configuration x height x angle
    speed_angle: list         # Figures 10 and 11: configuration x speed x angle
    by_speed: list            # Figure 12a: configuration x speed
    by_height: list           # Figure 12b: configuration x height
    by_angle: list            # Figure 12c: configuration x angle
    by_configuration: list    # Figure 12d: configuration


def paper_views(outcomes: typing.Iterable[Outcome],
                configuration_order: typing.Sequence[str] = ("baseline", "A", "B", "C")) -> "Views":
    """Compute every view of Figures 9-12 from launch outcomes."""
    conditions = group_conditions(outcomes)

    def view(*by: str) -> typing.List["CellSummary"]:
        return summarise(conditions, ("configuration",) + by, configuration_order)

    return Views(conditions, view("height_m", "angle_deg"), view("speed_mps", "angle_deg"), view("speed_mps"),
                 view("height_m"), view("angle_deg"), view())


def grid(cells: typing.Sequence["CellSummary"], row_factor: str, column_factor: str,
         measure: str = "condition_rate") -> typing.Tuple[list, list, list]:
    """Arrange cells (already restricted to one configuration) as a table for a heatmap.

    Returns
    -------
    rows, columns : list
        Sorted distinct values of ``row_factor`` and ``column_factor``.
    values : list of list of float
        ``values[i][j]`` is ``measure`` of the cell (rows[i], columns[j]); NaN where no cell exists.
    """
    rows = sorted({cell.key[row_factor] for cell in cells})
    columns = sorted({cell.key[column_factor] for cell in cells})
    values = [[math.nan] * len(columns) for _ in rows]
    for cell in cells:
        values[rows.index(cell.key[row_factor])][columns.index(cell.key[column_factor])] = getattr(cell, measure)
    return rows, columns, values


def cells_of(cells: typing.Iterable["CellSummary"], **key: object) -> typing.List["CellSummary"]:
    """The cells whose key matches every ``factor=value`` given."""
    return [cell for cell in cells if all(cell.key.get(f) == v for f, v in key.items())]


def average_ranks(values: typing.Sequence[float]) -> typing.List[float]:
    """Ranks 1..n of ``values`` (1 = smallest), ties sharing the mean of their ranks."""
    order = sorted(range(len(values)), key=lambda i: values[i])
    ranks = [0.0] * len(values)
    start = 0
    while start < len(order):
        end = start
        while end + 1 < len(order) and values[order[end + 1]] == values[order[start]]:
            end += 1
        for position in range(start, end + 1):
            ranks[order[position]] = (start + end) / 2.0 + 1.0
        start = end + 1
    return ranks


def _check_pairs(x, y):
    if len(x) != len(y):
        raise ValueError(f"need paired values, got {len(x)} and {len(y)}")
    if any(not math.isfinite(v) for v in list(x) + list(y)):
        raise ValueError("rank agreement needs finite values")


def spearman_rho(x: typing.Sequence[float], y: typing.Sequence[float]) -> float:
    """Spearman's rank correlation (Pearson on average ranks; ties handled); NaN if a side is constant or n < 2."""
    _check_pairs(x, y)
    if len(x) < 2:
        return math.nan
    rx, ry = average_ranks(x), average_ranks(y)
    mx, my = statistics.fmean(rx), statistics.fmean(ry)
    sxy = sum((a - mx) * (b - my) for a, b in zip(rx, ry))
    sxx = sum((a - mx) ** 2 for a in rx)
    syy = sum((b - my) ** 2 for b in ry)
    return sxy / math.sqrt(sxx * syy) if sxx > 0 and syy > 0 else math.nan


def kendall_tau_b(x: typing.Sequence[float], y: typing.Sequence[float]) -> float:
    """Kendall's tau-b (ties in either variable corrected); NaN if a side is constant or n < 2."""
    _check_pairs(x, y)
    concordant = discordant = ties_x = ties_y = 0
    for i in range(len(x)):
        for j in range(i + 1, len(x)):
            dx, dy = x[i] - x[j], y[i] - y[j]
            if dx == 0 and dy == 0:
                continue
            if dx == 0:
                ties_x += 1
            elif dy == 0:
                ties_y += 1
            elif (dx > 0) == (dy > 0):
                concordant += 1
            else:
                discordant += 1
    denominator = math.sqrt((concordant + discordant + ties_x) * (concordant + discordant + ties_y))
    return (concordant - discordant) / denominator if denominator > 0 else math.nan


#: Fewest configurations a rank statistic is given for: with two, any correlation is +-1.
MIN_RANKED = 3
#: Permutations sampled by :func:`spearman_p_value` when the exact test would need more than this many.
PERMUTATION_SAMPLES = 40320


def spearman_p_value(x: typing.Sequence[float], y: typing.Sequence[float], seed: int = 0) -> float:
    """Two-sided permutation p-value of Spearman's rho (m/s-free: a probability): the share of orderings of ``y``
    whose |rho| is at least the observed |rho|; exact for up to 8 values, else from ``PERMUTATION_SAMPLES``
    seeded random orderings. NaN when rho is undefined."""
    observed = spearman_rho(x, y)
    if not math.isfinite(observed):
        return math.nan
    y = list(y)
    orderings: typing.Iterable[typing.Sequence[float]]
    if math.factorial(len(y)) <= PERMUTATION_SAMPLES:
        orderings = itertools.permutations(y)
    else:
        rng = random.Random(seed)
        orderings = (rng.sample(y, len(y)) for _ in range(PERMUTATION_SAMPLES))
    total = extreme = 0
    for ordering in orderings:
        rho = spearman_rho(x, ordering)
        total += 1
        extreme += math.isfinite(rho) and abs(rho) >= abs(observed) - 1e-12
    return extreme / total


def rank_agreement_text(rho: float, tau: float, p_value: float = math.nan, count: typing.Optional[int] = None) -> str:
    """``"Spearman rho 0.95 (permutation p = 0.02), Kendall tau-b 0.91"``; a NaN (a constant side, too few
    values) says undefined; with ``count`` < :data:`MIN_RANKED` configurations it says why there is none."""
    if count is not None and count < MIN_RANKED:
        return f"no rank statistic: {count} configuration(s), ranks need at least {MIN_RANKED}"

    def show(value: float) -> str:
        return f"{value:.2f}" if math.isfinite(value) else "undefined"
    p_text = f" (permutation p = {p_value:.3f})" if math.isfinite(p_value) else ""
    text = f"Spearman rho {show(rho)}{p_text}, Kendall tau-b {show(tau)}"
    return text if math.isfinite(rho) and math.isfinite(tau) else text + " (all tied, or fewer than 2 values)"


@dataclasses.dataclass(frozen=True)
class SimVsExperiment:
    """Simulated fitness against campaign success per configuration, with rank agreement (NaN with fewer than
    :data:`MIN_RANKED` configurations) and the permutation p-value of Spearman's rho."""

    rows: list                # dicts: configuration, sim_fitness, experimental_rate, sim_rank, experimental_rank
    spearman_rho: float
    kendall_tau_b: float
    measure: str              # the experimental measure compared: "condition_rate" or "trial_rate"
    spearman_p: float = math.nan
    campaign: str = "experimental"   # what the campaign was: "experimental", "simulated" or "mixed"

    def agreement_text(self) -> str:
        """:func:`rank_agreement_text` of this comparison."""
        return rank_agreement_text(self.spearman_rho, self.kendall_tau_b, self.spearman_p, len(self.rows))


def sim_vs_experiment(sim_fitness: typing.Mapping[str, float], by_configuration: typing.Sequence["CellSummary"],
                      measure: str = "condition_rate", campaign: str = "experimental") -> "SimVsExperiment":
    """Compare simulated fitness with experimental success (the Discussion's comparison).

    Parameters
    ----------
    sim_fitness : dict
        ``{configuration id: simulated fitness in [0, 1]}``; configurations without an experiment are ignored.
    by_configuration : list of CellSummary
        The per-configuration view (``Views.by_configuration``).
    measure : str
        ``"condition_rate"`` (paper) or ``"trial_rate"``.

    Ranks are 1 = best (highest) and average over ties. Rank statistics (rho, tau, p) are NaN with fewer than
    :data:`MIN_RANKED` configurations; ``campaign`` labels where the campaign's outcomes came from
    (:func:`campaign_kind`).
    """
    experimental = {cell.key["configuration"]: getattr(cell, measure) for cell in by_configuration}
    common = [c for c in experimental if c in sim_fitness]
    sims = [float(sim_fitness[c]) for c in common]
    exps = [experimental[c] for c in common]
    sim_ranks = average_ranks([-v for v in sims])
    exp_ranks = average_ranks([-v for v in exps])
    rows = [{"configuration": c, "sim_fitness": s, "experimental_rate": e, "sim_rank": sr, "experimental_rank": er}
            for c, s, e, sr, er in zip(common, sims, exps, sim_ranks, exp_ranks)]
    if len(common) < MIN_RANKED:
        return SimVsExperiment(rows, math.nan, math.nan, measure, math.nan, campaign)
    return SimVsExperiment(rows, spearman_rho(sims, exps), kendall_tau_b(sims, exps), measure,
                           spearman_p_value(sims, exps), campaign)


def campaign_kind(outcomes: typing.Iterable[LaunchOutcome]) -> str:
    """``"simulated"`` (every outcome from the sim backend), ``"experimental"`` (every one physical), ``"mixed"``,
    or ``"none"``: how a report must label a campaign."""
    backends = {outcome.backend for outcome in outcomes}
    if not backends:
        return "none"
    if backends == {"sim"}:
        return "simulated"
    return "experimental" if backends == {"physical"} else "mixed"


@dataclasses.dataclass(frozen=True)
class ConvergencePoint:
    """One generation of an optimization run (Figure 4); fitness values in [0, 1]."""

    run_id: str
    generation: int
    best_fitness: float
    mean_fitness: float
    best_so_far: float
    evaluations: int


def convergence(generations: typing.Iterable[GenerationRecord] = (),
                candidates: typing.Iterable[CandidateRecord] = ()) -> typing.List["ConvergencePoint"]:
    """Best-so-far fitness per generation, per run, sorted by (run, generation).

    Uses generation summaries where a run has them: their ``best_so_far`` is the optimizer's pooled estimate of
    its incumbent (re-evaluated with fresh trials), which can go down when a lucky estimate is corrected; a
    running maximum of noisy per-generation bests would overstate it. Runs with candidates only derive each
    generation (best, mean, count) and use the running maximum of ``best_fitness``, the only estimate there is.
    """
    per_run: typing.Dict[str, typing.Dict[int, tuple]] = {}
    for record in generations:
        per_run.setdefault(record.run_id, {})[record.generation] = (record.best_fitness, record.mean_fitness,
                                                                    record.evaluations, record.best_so_far)
    derived: typing.Dict[str, typing.Dict[int, typing.List[float]]] = {}
    for candidate in candidates:
        if candidate.run_id not in per_run:
            derived.setdefault(candidate.run_id, {}).setdefault(candidate.generation, []).append(candidate.fitness)
    for run_id, by_generation in derived.items():
        evaluations = 0
        per_run[run_id] = {}
        for generation in sorted(by_generation):
            fitnesses = by_generation[generation]
            evaluations += len(fitnesses)
            per_run[run_id][generation] = (max(fitnesses), statistics.fmean(fitnesses), evaluations, None)
    points = []
    for run_id in sorted(per_run):
        running_max = -math.inf
        for generation in sorted(per_run[run_id]):
            best, mean, evaluations, pooled = per_run[run_id][generation]
            running_max = max(running_max, best)
            best_so_far = pooled if pooled is not None and math.isfinite(pooled) else running_max
            points.append(ConvergencePoint(run_id, generation, best, mean, best_so_far, evaluations))
    return points


#: Columns of the geometry table (Table 3): required, in m.
GEOMETRY_COLUMNS = ("configuration", "length_m", "width_m", "max_height_m")


def geometry_table(rows: typing.Iterable[typing.Mapping[str, typing.Any]],
                   configuration_order: typing.Sequence[str] = ("baseline", "A", "B", "C")
                   ) -> typing.List[typing.Dict[str, typing.Any]]:
    """Check and order the rows of Table 3 (overall dimensions and maximum profile height per configuration).

    Parameters
    ----------
    rows : iterable of dict
        Each with ``configuration`` and ``length_m``, ``width_m``, ``max_height_m`` (m, >= 0 finite; the
        baseline has no profile: 0); other keys are kept as extra columns.
    """
    checked = []
    for number, row in enumerate(rows, start=1):
        missing = [c for c in GEOMETRY_COLUMNS if c not in row]
        if missing:
            raise ValueError(f"geometry row {number}: missing {', '.join(missing)}")
        out = dict(row)
        for column in GEOMETRY_COLUMNS[1:]:
            try:
                out[column] = float(row[column])
            except (TypeError, ValueError):
                raise ValueError(f"geometry row {number}: {column} must be a number, got {row[column]!r}") from None
            if not math.isfinite(out[column]) or out[column] < 0:
                raise ValueError(f"geometry row {number}: {column} must be >= 0 m, got {row[column]!r}")
        checked.append(out)
    rank = _configuration_rank(configuration_order)
    return sorted(checked, key=lambda r: rank(str(r["configuration"])))


def tip_event_summary(events: typing.Iterable[TipEventRecord]) -> typing.List[typing.Dict[str, typing.Any]]:
    """Per robot: events, recovered, recovery rate with Wilson interval, median duration s, worst tilt deg."""
    per_robot: typing.Dict[str, list] = {}
    for event in events:
        per_robot.setdefault(event.robot, []).append(event)
    rows = []
    for robot in sorted(per_robot):
        robot_events = per_robot[robot]
        recovered = sum(e.recovered for e in robot_events)
        low, high = wilson_interval(recovered, len(robot_events))
        rows.append({"robot": robot, "events": len(robot_events), "recovered": recovered,
                     "recovery_rate": recovered / len(robot_events), "ci_low": low, "ci_high": high,
                     "median_duration_s": statistics.median(e.duration_s for e in robot_events),
                     "max_peak_tilt_deg": max(e.peak_tilt_deg for e in robot_events)})
    return rows
