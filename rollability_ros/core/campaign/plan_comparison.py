"""The adaptive plan against the paper's matrix (issue 44.4), on simulated hidden truths.

:func:`compare_plans`: on hidden truths drawn from the prior, the paper's matrix (every grouped condition in turn, in
shuffled rounds) against the BALD plan (:mod:`~rollability_ros.core.campaign.adaptive`), both with the same posterior
machinery; how many launches each needs until every unknown's 95 % interval is at most a target width (normalised: a
fraction of its range on its search scale). :func:`adaptive_to_match_matrix`: the launches the adaptive plan needs to
reach the widths the matrix reaches in its 400 launches. bench/bench_adaptive_plan.py runs it. numpy only.
"""
import dataclasses
import math
import typing

import numpy as np

from rollability_ros.core.campaign.adaptive import Unknowns, UprightPredictor, WeightedPosterior
from rollability_ros.core.records import LaunchCondition

if typing.TYPE_CHECKING:   # annotations only: the learnt table is loaded by the caller
    from rollability_ros.core.campaign.learnt_plan import Launch, LearntTable
    from rollability_ros.core.campaign.likelihood import Observation
    from rollability_ros.core.campaign.likelihood_gate import GateModel


@dataclasses.dataclass(frozen=True)
class PlanRun:
    """One plan on one hidden truth: launches until every unknown's width reached the target (``None``: not within
    the budget), the widths (d,) at the end, the effective sample size at the end."""

    plan: str
    launches_to_target: typing.Optional[int]
    final_widths: np.ndarray
    effective_sample_size: float


def run_plan(plan: str, posterior: WeightedPosterior, truth_probabilities: np.ndarray, budget: int,
             target_width: float, rng: np.random.Generator, level: float = 0.95) -> PlanRun:
    """Launch ``plan`` ("matrix": every candidate once per round, each round shuffled; "adaptive": the BALD proposal
    each time) on a hidden truth whose P(upright) at every candidate is ``truth_probabilities`` (c,), drawing
    each outcome with ``rng``, until every unknown's normalised width is at most ``target_width`` or ``budget``
    launches were made. ``posterior`` is updated in place (pass a fresh one per run)."""
    if plan not in ("matrix", "adaptive"):
        raise ValueError(f"plan must be 'matrix' or 'adaptive', got {plan!r}")
    candidates = len(posterior.candidates)
    order: typing.List[int] = []
    reached = None
    for launch in range(1, budget + 1):
        if plan == "matrix":
            if not order:
                order = list(rng.permutation(candidates))
            index = order.pop()
        else:
            index = int(np.argmax(posterior.scores()))
        posterior.observe(index, bool(rng.random() < truth_probabilities[index]))
        if np.all(posterior.normalised_widths(level) <= target_width):
            reached = launch
            break
    return PlanRun(plan, reached, posterior.normalised_widths(level), posterior.effective_sample_size)


@dataclasses.dataclass(frozen=True)
class PlanComparison:
    """:func:`compare_plans`: per truth, the launches each plan needed (None: more than the budget)."""

    target_width: float
    budget: int
    truths: np.ndarray                                   # (t, d), own units
    matrix: typing.List[PlanRun]
    adaptive: typing.List[PlanRun]

    def summary(self) -> str:
        """One line per truth and the medians."""
        def text(run: PlanRun) -> str:
            return f">{self.budget}" if run.launches_to_target is None else str(run.launches_to_target)
        lines = [f"truth {i}: matrix {text(m)}, adaptive {text(a)} launches to widths <= {self.target_width:.0%}"
                 for i, (m, a) in enumerate(zip(self.matrix, self.adaptive))]

        def median(runs: typing.List[PlanRun]) -> str:
            counts = [r.launches_to_target if r.launches_to_target is not None else math.inf for r in runs]
            value = float(np.median(counts))
            return f">{self.budget}" if math.isinf(value) else f"{value:g}"
        lines.append(f"median: matrix {median(self.matrix)}, adaptive {median(self.adaptive)} launches "
                     f"({len(self.matrix)} truths drawn from the prior)")
        return "\n".join(lines)


def compare_plans(unknowns: Unknowns, predictor: UprightPredictor, candidates: typing.Sequence[LaunchCondition],
                  truths: int, target_width: float, budget: int, samples: int, seed: int = 0,
                  level: float = 0.95, renew: bool = True) -> PlanComparison:
    """The paper's matrix against the BALD plan (module docstring): ``truths`` hidden truths drawn from the prior;
    for each, both plans launch on the same truth (outcomes drawn from the predictor's P(upright) at the truth)
    with the same ``samples`` prior draws, until every unknown's 95 % interval is at most ``target_width`` of its
    range or ``budget`` launches. ``renew``: renew the samples as the posterior narrows (:class:`WeightedPosterior`;
    each renewal asks the predictor again)."""
    rng = np.random.default_rng(seed)
    prior = unknowns.draw(samples, rng)
    table = predictor.probabilities(prior, candidates)
    hidden = unknowns.draw(truths, rng)
    truth_table = predictor.probabilities(hidden, candidates)
    matrix: typing.List[PlanRun] = []
    adaptive: typing.List[PlanRun] = []
    for t in range(truths):
        for plan, runs in (("matrix", matrix), ("adaptive", adaptive)):
            posterior = WeightedPosterior(unknowns, prior, candidates, table, predictor if renew else None,
                                          np.random.default_rng([seed, t, len(runs), 2]))
            runs.append(run_plan(plan, posterior, truth_table[t], budget, target_width,
                                 np.random.default_rng([seed, t, len(runs)]), level))
    return PlanComparison(target_width, budget, hidden, matrix, adaptive)


@dataclasses.dataclass(frozen=True)
class MatchedWidths:
    """:func:`adaptive_to_match_matrix` on one truth: the matrix's widths (d,) after its launches, the launches the
    adaptive plan needed to reach them all (None: not within the budget), the adaptive widths then, and both plans'
    effective sample sizes at the end. With replicas of the matrix's posterior (:func:`match_matrix_on_truth`):
    ``width_error`` (d,), the Monte Carlo standard deviation of one width estimate on the same launches;
    ``tolerant_widths`` (d,), the replicas' mean width plus that error; ``tolerant_launches``, the adaptive
    launches to reach those (None: not within the budget; without replicas: None, and both zeros).
    ``adaptive_launched``: the candidate index of each adaptive launch, in order."""

    matrix_launches: int
    matrix_widths: np.ndarray
    adaptive_launches: typing.Optional[int]
    adaptive_widths: np.ndarray
    matrix_ess: float
    adaptive_ess: float
    width_error: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    tolerant_widths: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    tolerant_launches: typing.Optional[int] = None
    adaptive_launched: typing.Tuple[int, ...] = ()
    precise: typing.Optional["PreciseWidths"] = None


@dataclasses.dataclass(frozen=True)
class PreciseWidths:
    """:func:`learnt_to_match_matrix` with ``precise`` draws: the same launches' widths estimated again by importance
    sampling (:func:`~rollability_ros.core.campaign.learnt_plan.importance_widths`), once per independent draw set
    (r of them), each set shared by both plans (common random numbers). ``matrix_widths`` (r, d) after the
    matrix's launches; ``launches`` (r,), per set, the adaptive launches until every width is at most the matrix's
    on that set (None: not within its launches); ``tolerant_launches``, on set 0, to the sets' mean matrix width
    plus their standard deviation (with r >= 2); ``matrix_ess`` (r,) and ``adaptive_ess`` (r,) the importance
    weights' effective sample sizes after the matrix's launches and where the adaptive plan reached them (or at
    its last launch)."""

    matrix_widths: np.ndarray
    launches: typing.Tuple[typing.Optional[int], ...]
    tolerant_launches: typing.Optional[int]
    matrix_ess: np.ndarray
    adaptive_ess: np.ndarray
    adaptive_widths: np.ndarray   # (r, d): at the adaptive plan's strict stop on each set, or its last launch
    #: per tolerance of :data:`WIDTH_TOLERANCES` (points of each range), per set: the adaptive launches until every
    #: width is at most the matrix's plus that tolerance (None: not within its launches)
    within: typing.Tuple[typing.Tuple[float, typing.Tuple[typing.Optional[int], ...]], ...] = ()
    #: on set 0, per unknown: the adaptive launches until that unknown's width is first at most the matrix's (None:
    #: not within its launches); the strict count (``launches[0]``) is at least the largest of them
    per_unknown: typing.Tuple[typing.Optional[int], ...] = ()


#: Absolute tolerances (fractions of each unknown's range) of :attr:`PreciseWidths.within`: widths that differ by less
#: are the same to the resolution the calibration reports (its 95 % sets are read from a 50-bin histogram, 2 % of
#: the range per bin: "The learnt likelihood" in docs/calibration.md). An unknown that the shared start pins (the
#: profile's mass by the weighings) has the same width under both plans, and the strict count then turns on
#: differences far below that.
WIDTH_TOLERANCES = (0.0025, 0.005, 0.01)


#: A hidden truth's launch at a candidate (index, outcome generator) -> (upright, continuous outcomes or None, the
#: speed gate's reading in m/s or None).
Launcher = typing.Callable[[int, np.random.Generator],
                           typing.Tuple[bool, typing.Optional[np.ndarray], typing.Optional[float]]]


#: The adaptive plan's choice in the comparison: ``joint`` the expected information about all the unknowns
#: (:meth:`~WeightedPosterior.scores`); ``targeted`` about the unknown farthest from the width to reach
#: (:meth:`~WeightedPosterior.targeted_scores`, the matrix's widths as the targets); ``lagging`` about every unknown
#: not yet at its width, summed (:meth:`~WeightedPosterior.lagging_scores`).
ACQUISITIONS = ("joint", "targeted", "lagging")


def match_matrix_on_truth(make_posterior: typing.Callable[[int], WeightedPosterior], launch: Launcher,
                          matrix_launches: int, seed: typing.Sequence[int], level: float = 0.95,
                          budget: typing.Optional[int] = None, acquisition: str = "joint",
                          replicas: int = 0, full: bool = False) -> MatchedWidths:
    """One truth of :func:`adaptive_to_match_matrix`: the matrix's ``matrix_launches`` (every candidate once per
    shuffled round) on a fresh ``make_posterior(0)``, then the adaptive plan (the highest score of ``acquisition``,
    :data:`ACQUISITIONS`, each time) on a fresh ``make_posterior(1)`` until each unknown's width is at most the
    matrix's or ``budget`` launches (default ``matrix_launches``); ``launch`` draws the truth's outcomes.

    ``replicas``: the matrix's launches weighed again by ``make_posterior(2)``, ``make_posterior(3)``, ... (other
    draws of the samples, other renewals: the same launches), so the Monte Carlo error of a width estimate is
    measured (the standard deviation over the 1 + ``replicas`` estimates). Every width is such an estimate, and the
    strict criterion compares five of them with five of the matrix's, a maximum over noisy comparisons that the
    matrix's lucky draws decide; so the adaptive plan's launches are also counted to the replicas' mean width plus
    that error (``tolerant_launches``), beside the strict count, which is kept. ``full``: the adaptive plan
    launches its whole budget whatever its widths (for widths estimated again afterwards: ``learnt_to_match_matrix``'s
    ``precise``); the counts are the same first crossings."""
    if acquisition not in ACQUISITIONS:
        raise ValueError(f"acquisition must be one of {', '.join(ACQUISITIONS)}, got {acquisition!r}")
    if replicas == 1:
        raise ValueError("replicas: 0, or at least 2 (a standard deviation needs two estimates besides the first)")
    matrix = make_posterior(0)
    order: typing.List[int] = []
    rng = np.random.default_rng([*seed, 0])
    seen = []
    for _ in range(matrix_launches):
        if not order:
            order = list(rng.permutation(len(matrix.candidates)))
        index = order.pop()
        outcome = launch(index, rng)
        matrix.observe_launch(index, *outcome)
        seen.append((index, outcome))
    widths = matrix.normalised_widths(level)
    estimates = [widths]
    for replica in range(replicas):
        again = make_posterior(2 + replica)
        for index, outcome in seen:
            again.observe_launch(index, *outcome)
        estimates.append(again.normalised_widths(level))
    error = np.std(estimates, axis=0, ddof=1) if replicas else np.zeros(len(widths))
    tolerant_widths = np.mean(estimates, axis=0) + error if replicas else np.zeros(len(widths))
    score = {"joint": lambda posterior: posterior.scores(),
             "targeted": lambda posterior: posterior.targeted_scores(widths, level),
             "lagging": lambda posterior: posterior.lagging_scores(widths, level)}[acquisition]
    adaptive = make_posterior(1)
    outcome_rng = np.random.default_rng([*seed, 1])
    reached = tolerant = None
    launched: typing.List[int] = []
    for number in range(1, (budget or matrix_launches) + 1):
        index = int(np.argmax(score(adaptive)))
        adaptive.observe_launch(index, *launch(index, outcome_rng))
        launched.append(index)
        now = adaptive.normalised_widths(level)
        if replicas and tolerant is None and np.all(now <= tolerant_widths):
            tolerant = number
        if reached is None and np.all(now <= widths):
            reached = number
        if reached is not None and (tolerant is not None or not replicas) and not full:
            break
    return MatchedWidths(matrix_launches, widths, reached, adaptive.normalised_widths(level),
                         matrix.effective_sample_size, adaptive.effective_sample_size, error, tolerant_widths,
                         tolerant, tuple(launched))


def adaptive_to_match_matrix(unknowns: Unknowns, predictor: UprightPredictor,
                             candidates: typing.Sequence[LaunchCondition], truths: int, matrix_launches: int,
                             samples: int, seed: int = 0, level: float = 0.95,
                             budget: typing.Optional[int] = None, renew: bool = True,
                             acquisition: str = "joint") -> typing.List[MatchedWidths]:
    """Issue 44's comparison: on ``truths`` hidden truths drawn from the prior, the paper's matrix launches
    ``matrix_launches`` times (every candidate once per shuffled round: 400 = the 80 grouped conditions x 5); the
    adaptive plan then launches on the same truth, from the same prior draws, until each unknown's interval is at
    most as wide as the matrix's (or ``budget`` launches, default ``matrix_launches``). ``renew`` as for
    :func:`compare_plans`. Verdicts only, drawn from the predictor's P(upright) at the truth."""
    rng = np.random.default_rng(seed)
    prior = unknowns.draw(samples, rng)
    table = predictor.probabilities(prior, candidates)
    hidden = unknowns.draw(truths, rng)
    truth_table = predictor.probabilities(hidden, candidates)
    results = []
    for t in range(truths):
        def make(plan: int, t: int = t) -> WeightedPosterior:
            return WeightedPosterior(unknowns, prior, candidates, table, predictor if renew else None,
                                     np.random.default_rng([seed, t, 2 + plan]))

        def launch(index: int, outcome_rng: np.random.Generator, t: int = t) -> typing.Tuple[bool, None, None]:
            """Candidate ``index`` launched at truth ``t``: (upright, no outcomes, no gate reading)."""
            return bool(outcome_rng.random() < truth_table[t][index]), None, None
        results.append(match_matrix_on_truth(make, launch, matrix_launches, (seed, t), level, budget, acquisition))
    return results


#: A hidden truth's speed gate reading: (truth index, truth (d,) own units, the launch's condition, generator) -> m/s
#: (NaN: not read).
GateReading = typing.Callable[[int, np.ndarray, LaunchCondition, np.random.Generator], float]

#: A hidden truth's starting samples: (truth index, truth (d,) own units, replica: 0 for the two plans, 1, 2, ...
#: other draws for the replicas of the matrix's posterior) -> (samples (n, d) own units, the log density
#: (normalised (s, d) -> (s,)) they were drawn from beside the uniform prior, e.g. its characterisation's).
Start = typing.Callable[[int, np.ndarray, int],
                        typing.Tuple[np.ndarray, typing.Callable[[np.ndarray], np.ndarray]]]


#: Each truth's launcher characterisation: (truth index, truth (d,) own units) -> its gate shots as the bare robot's
#: readings (``likelihood_gate.shot_observations``), weighed by both plans in the gate's groups
#: (:meth:`GateModel.with_shots`); the start must then draw from a density that holds their term
#: (learnt_plan.OutcomePosterior's ``samples``).
Shots = typing.Callable[[int, np.ndarray], typing.Sequence["Observation"]]


def learnt_to_match_matrix(table: "LearntTable", truths: int, matrix_launches: int, samples: int, seed: int = 0,
                           level: float = 0.95, budget: typing.Optional[int] = None, draws: int = 32,
                           acquisition: str = "joint",
                           on_truth: typing.Optional[typing.Callable[[int, MatchedWidths], None]] = None,
                           start: typing.Optional[Start] = None, gate: typing.Optional["GateModel"] = None,
                           gate_reading: typing.Optional[GateReading] = None, replicas: int = 0,
                           precise: int = 0, precise_sets: int = 3, first_truth: int = 0,
                           shots: typing.Optional["Shots"] = None
                           ) -> typing.Tuple[np.ndarray, typing.List[MatchedWidths]]:
    """:func:`adaptive_to_match_matrix` on a learnt likelihood's table
    (:class:`~rollability_ros.core.campaign.learnt_plan.LearntTable`): each launch of a hidden truth draws the
    verdict and the table's continuous outcomes from the learnt model at the truth, both plans weigh the samples
    by all of it (:class:`~rollability_ros.core.campaign.learnt_plan.OutcomePosterior`, renewed), and the
    adaptive plan scores the information of verdict and outcomes (``draws`` Monte Carlo outcomes). Returns the
    truths (t, d) and the results; ``on_truth(t, result)`` after each. ``start`` (:data:`Start`): each truth's
    starting samples for both plans instead of the prior draws (the characterisation's posterior: both plans then
    begin from the same bench readings, and renewals keep their density). ``gate`` (the speed gate's exact term,
    :class:`~rollability_ros.core.campaign.likelihood_gate.GateModel`: the posteriors weigh the readings, the
    adaptive plan scores their information) and ``gate_reading`` (:data:`GateReading`: the
    truth's reading of a launch): every launch of both plans also gives its gate reading, weighed by that term
    (drawn from a generator of its own per truth and plan, so the verdicts are those drawn without it).
    ``replicas``: :func:`match_matrix_on_truth`'s, each from other starting samples (other prior draws, or
    ``start(t, truth, replica)``) and other renewals.

    ``precise`` (draws, 0: off): the adaptive plan launches its whole budget, and afterwards both plans' widths are
    estimated again from their recorded launches by importance sampling with ``precise`` draws, ``precise_sets``
    independent draw sets each shared by both plans (:class:`PreciseWidths` in each result's ``precise``): the
    proposal is a kernel mixture over the start samples, the matrix's final samples and the adaptive plan's samples
    every :data:`SNAPSHOT_EVERY` launches. ``first_truth``: begin at that truth (the same truths as a run from 0;
    the runs of a split measurement). ``shots`` (with ``gate``): :data:`Shots`."""
    from rollability_ros.core.campaign.learnt_plan import OutcomePosterior

    rng = np.random.default_rng(seed)
    prior = table.unknowns.draw(samples, rng)
    hidden = table.unknowns.draw(truths, rng)
    results = []
    for t in range(first_truth, truths):
        begin, log_prior = start(t, hidden[t], 0) if start is not None else (prior, None)
        truth_gate = gate.with_shots(shots(t, hidden[t])) if gate is not None and shots is not None else gate
        made: typing.Dict[int, WeightedPosterior] = {}
        records: typing.Dict[int, typing.List["Launch"]] = {}   # by the plan's outcome generator: matrix, adaptive
        snapshots: typing.List[typing.Tuple[np.ndarray, np.ndarray]] = []

        def make(plan: int, t: int = t, begin: np.ndarray = begin,
                 log_prior: typing.Optional[typing.Callable[[np.ndarray], np.ndarray]] = log_prior,
                 truth_gate: typing.Optional["GateModel"] = truth_gate) -> WeightedPosterior:
            """Plan ``plan``'s posterior at truth ``t`` (0 matrix, 1 adaptive, 2.. replicas) from ``begin`` (n, d)."""
            if plan >= 2:
                replica = plan - 1
                begin, log_prior = (start(t, hidden[t], replica) if start is not None else
                                    (table.unknowns.draw(samples, np.random.default_rng([seed, t, 8, replica])), None))
            made[plan] = OutcomePosterior(table, begin, np.random.default_rng([seed, t, 2 + plan]), draws=draws,
                                          log_prior=log_prior, gate=truth_gate)
            return made[plan]

        readers: typing.Dict[int, np.random.Generator] = {}   # by the plan's outcome generator: matrix, adaptive

        def launch(index: int, outcome_rng: np.random.Generator, t: int = t
                   ) -> typing.Tuple[bool, typing.Optional[np.ndarray], typing.Optional[float]]:
            """Candidate ``index`` launched at truth ``t``: (upright, outcomes (o,) or None, gate reading or None)."""
            record = records.setdefault(id(outcome_rng), [])
            if precise and len(records) == 2 and record and len(record) % SNAPSHOT_EVERY == 0:
                snapshots.append((made[1].samples.copy(), made[1].weights))   # the adaptive plan's, so far
            upright, values = table.draw(hidden[t], index, outcome_rng)
            reading = None
            if gate_reading is not None:
                reader = readers.setdefault(id(outcome_rng), np.random.default_rng([seed, t, 5, len(readers)]))
                reading = gate_reading(t, hidden[t], table.candidates[index], reader)
            record.append((index, upright, values, reading))
            return upright, values, reading
        result = match_matrix_on_truth(make, launch, matrix_launches, (seed, t), level, budget, acquisition,
                                       replicas, full=bool(precise))
        if precise:   # the proposal's sources: the start, the matrix's end, the adaptive plan's path and end
            result = dataclasses.replace(result, precise=precise_widths(table, list(records.values()), [
                (begin, np.ones(len(begin))), (made[0].samples, made[0].weights), *snapshots,
                (made[1].samples, made[1].weights)], precise, precise_sets, (seed, t), log_prior, truth_gate, level))
        results.append(result)
        if on_truth is not None:
            on_truth(t, results[-1])
    return hidden, results


#: The adaptive plan's samples enter the precise estimate's proposal every this many launches.
SNAPSHOT_EVERY = 50


def precise_widths(table: "LearntTable", plans: typing.Sequence[typing.Sequence["Launch"]],
                   sources: typing.Sequence[typing.Tuple[np.ndarray, np.ndarray]], draws: int, sets: int,
                   seed: typing.Sequence[int], log_prior: typing.Optional[typing.Callable[[np.ndarray], np.ndarray]],
                   gate: typing.Optional["GateModel"], level: float = 0.95) -> PreciseWidths:
    """:class:`PreciseWidths` of one truth's two recorded plans (``plans``: the matrix's and the adaptive plan's
    launches in order, learnt_plan's ``Launch``): ``sets`` independent importance-sampling estimates, ``draws``
    draws each from the kernel proposal over ``sources`` (each (samples (n, d) own units, weights (n,))), each set
    shared by the matrix's final widths and the adaptive plan's widths after every one of its launches."""
    from rollability_ros.core.campaign.learnt_plan import KernelProposal, importance_widths

    matrix, adaptive = plans
    matrix_widths, matrix_ess, counts, adaptive_ess, adaptive_widths, per_launch = [], [], [], [], [], []
    near: typing.List[typing.List[typing.Optional[int]]] = []
    for number in range(sets):
        rng = np.random.default_rng([*seed, 17, number])
        proposal = KernelProposal(table.unknowns, sources, rng)
        (m_widths, m_ess), (a_widths, a_ess) = importance_widths(
            table, [matrix, adaptive], [[len(matrix)], range(1, len(adaptive) + 1)], proposal, rng, draws,
            log_prior, gate, level)
        counts.append(first_launch(a_widths, m_widths[0]))
        near.append([first_launch(a_widths, m_widths[0] + tolerance) for tolerance in WIDTH_TOLERANCES])
        at = counts[-1] - 1 if counts[-1] is not None else len(adaptive) - 1
        matrix_widths.append(m_widths[0])
        matrix_ess.append(m_ess[0])
        adaptive_ess.append(a_ess[at])
        adaptive_widths.append(a_widths[at])
        per_launch.append(a_widths)
    tolerant = None
    if sets >= 2:
        allowed = np.mean(matrix_widths, axis=0) + np.std(matrix_widths, axis=0, ddof=1)
        tolerant = first_launch(per_launch[0], allowed)
    within = tuple((tolerance, tuple(row[i] for row in near)) for i, tolerance in enumerate(WIDTH_TOLERANCES))
    per_unknown = tuple(first_launch(per_launch[0][:, [j]], matrix_widths[0][[j]])
                        for j in range(len(matrix_widths[0])))
    return PreciseWidths(np.array(matrix_widths), tuple(counts), tolerant, np.array(matrix_ess),
                         np.array(adaptive_ess), np.array(adaptive_widths), within, per_unknown)


def first_launch(widths: np.ndarray, allowed: np.ndarray) -> typing.Optional[int]:
    """The first launch (1-based) after which every width of ``widths`` (launches, d) is at most ``allowed`` (d,);
    None when none is."""
    below = np.flatnonzero(np.all(widths <= allowed, axis=1))
    return int(below[0]) + 1 if len(below) else None

