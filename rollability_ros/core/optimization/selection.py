"""Design selection (paper 2.1.5): pick N high-fitness, printable, geometrically diverse designs from a run's log.

Procedure
---------
1. Every logged evaluation of the run (population candidates and incumbent re-evaluations) is pooled per
   distinct height vector: successes and trials add up.
2. Designs are ranked by the lower bound of the 95% Wilson interval of their pooled fitness, then by fitness:
   a design seen once at 60/60 does not outrank one confirmed at 55/60 twice only because it was lucky once.
3. Walking down that ranking, a design is taken when its convex-hull solid passes the printability checks
   (:func:`check_printability`) and its RMS height distance (simulation units) to every design already
   taken is at least ``min_distance``. Picks follow the ranking (labels: "Labels follow the evidence" below).
4. Optionally the chosen designs and the baseline (no profile) are re-evaluated in one batch with a fresh
   common seed and ``reevaluate_trials`` trials: a fitness picked as a maximum is biased upward, a fresh
   estimate is not, so Table 3 then reports the re-evaluated fitness.
If fewer than ``count`` designs qualify, the result says how many and why; nothing is padded.

A quality-diversity run (``optimizer.method: cma_mae``) stores an archive of elites over maximum height x sharpness
(:mod:`~rollability_ros.core.optimization.quality_diversity`); its designs come from that map instead
(:func:`select_from_archive`):

1. The *top pool* is the archive's elites whose fitness is at least the ``1 - top_fraction`` quantile of all elite
   fitnesses (the top decile by default).
2. Each elite's evaluations are pooled as above; "A" is the printable elite of the pool with the highest lower
   Wilson bound.
3. Each next design is the printable elite of the pool, in a cell not yet taken, farthest from every design already
   taken in the descriptor plane (height and sharpness, each divided by its axis length), ties going to the higher
   Wilson bound: farthest-point sampling, so A/B/C span the map as far as the fit designs allow.
4. Re-evaluation as in step 4 above. Each design carries the sentence saying why it was chosen.

Ranked by the rig's measure (``race_launches``)
-----------------------------------------------
The disturbance trials the optimizer maximises need not predict the launch campaign the rig runs. With
``selection.race_launches`` (launches per design in each round) the ranking is by robust launches on the twin
(the campaign's launch matrix, every launch under its own draw of the unknowns; fidelity ``launch`` of
:mod:`~rollability_ros.core.sim.objectives`): the ``race_elites`` printable elites (or logged designs) with the
best screen race against each other and the bare robot by successive halving
(:mod:`~rollability_ros.core.optimization.racing`: one common seed per round; a design clearly worse than the
leader, or outside the better half, stops; never fewer than ``race_keep`` go on). A/B/C come from the survivors
whose pooled launch rate is above the bare robot's (all survivors when none is): the first pick the highest
lower Wilson bound of its launches, the next ones farthest-point over the map as above (a ranked-log run: the
distance rule). Then the chosen designs and the bare robot get ``launch_trials`` fresh robust launches on one new
seed: each design's *gain* over the bare robot, with Newcombe's 95% hybrid score interval, goes into Table 3 and
designs.yaml (``beats_baseline`` true only when the interval lies above 0). When no design beats the bare robot
the designs are still written, for inspection, each marked ``beats_baseline: false``; ``select`` warns and the
report says so.
Without launches, the gain is taken on the fresh re-evaluation and labelled as such.

The plausible-world check and the recommendation
-------------------------------------------------
With ``world_count`` > 0 the chosen designs and the bare robot are launched in ``world_count`` fixed draws of all
unknowns, ``world_launches`` paired launches each (:func:`with_world_check`,
:mod:`~rollability_ros.core.sim.world_check`), and the recommendation rule
(:mod:`~rollability_ros.core.optimization.recommendation`) names the design to print first: only one that wins in
at least ``recommend_world_share`` of the worlds with its pooled gain's interval above 0; none when no design does.

Labelling by the evidence is :mod:`~rollability_ros.core.optimization.labelling`; writing the design set (STL, 3MF,
Table 3, designs.yaml, the world check) is :mod:`~rollability_ros.core.optimization.design_set`.
"""
import dataclasses
import re
import string
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core import config
from rollability_ros.core.profile import (MESH_UNITS, Mesh, PrinterSpec, ProfileGrid, ProfileMetrics,
                                          check_printability, is_baseline, mesh_metrics, profile_mesh)
from rollability_ros.core.optimization.optimizer_contract import STREAM_SELECTION, derive_seed
from rollability_ros.core.optimization import racing
from rollability_ros.core.optimization.recommendation import Recommendation, recommend
from rollability_ros.core.stats import newcombe_interval, wilson_interval

if typing.TYPE_CHECKING:
    from collections.abc import Hashable

    from rollability_ros.core.records import CandidateRecord

#: ``evaluate_batch(heights_list, seed) -> [(successes, trials, eval_time_s, evaluator), ...]``: heights
#: ``(n_variables,)`` each, simulation units; one result per profile.
BatchEvaluator = typing.Callable[[typing.List[np.ndarray], int], typing.Sequence["EvaluatedProfile"]]
#: ``launch_batch(heights_list, seed, trials) -> [(successes, trials, eval_time_s, evaluator), ...]``: robust twin
#: launches of each profile (heights ``(n_variables,)``, simulation units).
LaunchEvaluator = typing.Callable[[typing.List[np.ndarray], int, int], typing.Sequence["EvaluatedProfile"]]
#: One profile's evaluation: ``(successes, trials, eval_time_s, evaluator)``.
EvaluatedProfile = typing.Tuple[int, int, float, str]

#: ``launch(heights_list, world_seed, launch_seed, launches) -> [(successes, trials, eval_time_s, evaluator), ...]``:
#: launches of each profile (heights ``(n_variables,)``, simulation units; zeros = the bare robot) all in the one
#: world drawn from ``world_seed`` (evaluation fidelity ``world:<seed>``), on ``launch_seed``.
WorldLaunch = typing.Callable[[typing.List[np.ndarray], int, int, int], typing.Sequence["EvaluatedProfile"]]
#: ``describe(world_seed) -> {unknown: drawn value}``: names a world's draws in the world check's rows.
WorldDescriber = typing.Callable[[int], typing.Mapping[str, typing.Union[str, int, float]]]

#: The race's id of the bare robot (the reference that runs every round).
BASELINE = "baseline"
#: Generation keys of the selection's seeds (stream STREAM_SELECTION): the chosen designs' fresh launches, the
#: world check, and the race's rounds from RACE_SEED_KEY on (0 and 1 are the re-evaluation and the screen).
LAUNCH_SEED_KEY = 2
WORLD_SEED_KEY = 3
RACE_SEED_KEY = 10

#: Columns of ``archive.csv`` (quality-diversity runs): each elite, its run and screen estimates, its label if chosen.
ARCHIVE_COLUMNS = ("cell_height", "cell_sharpness", "max_height_mm", "sharpness_deg", "in_run_fitness",
                   "in_run_trials", "screen_successes", "screen_trials", "screen_fitness", "top_pool", "label",
                   "race_round1_successes", "race_round1_trials", "race_successes", "race_trials", "race_stopped")
#: What a design's gain over the bare robot is measured on (``gain_source`` of Table 3).
GAIN_SOURCES = {"launches": "fresh robust launches on the twin (the rig's measure)",
                "reevaluated": "fresh simulated trials of the optimized objective (not the rig's measure)"}


@dataclasses.dataclass
class SelectionSettings:
    """The ``selection`` parameter namespace.

    ``min_distance`` is the minimum RMS difference between the height vectors of two chosen designs, in
    simulation units (the heights' own unit; 0.05 = 11% of the paper's [0, 0.45] range).
    """

    count: int = dataclasses.field(default=3, metadata={
        "description": "designs to choose for fabrication, labelled A, B, C, ... (count)", "range": (1, 26)})
    min_distance: float = dataclasses.field(default=0.05, metadata={
        "description": "smallest RMS height difference between two chosen designs, simulation units",
        "range": (0.0, 1000.0)})
    reevaluate_trials: int = dataclasses.field(default=0, metadata={
        "description": "fresh trials per chosen design and the baseline for Table 3 (count; 0 = report the logged "
                       "estimate)", "range": (0, 10000000)})
    mesh_units: str = dataclasses.field(default="mm", metadata={
        "description": "length unit of the written STL files: mm (what slicers expect) or m"})
    top_fraction: float = dataclasses.field(default=0.1, metadata={
        "description": "quality-diversity runs: choose among the archive elites whose fitness is in this top "
                       "fraction of all elite fitnesses (fraction, (0, 1]; 0.1 = the top decile)",
        "range": (0.0, 1.0), "exclusive": "low"})

    race_launches: typing.List[int] = dataclasses.field(default_factory=lambda: [0], metadata={
        "description": "launches per elite in each round of the launch race that ranks designs by robust twin "
                       "launches (counts; use multiples of the campaign's conditions); [0] = no race, rank by the "
                       "screen"})
    race_elites: int = dataclasses.field(default=16, metadata={
        "description": "printable elites (or logged designs) with the best screen entering the launch race "
                       "(count; 0 = all)", "range": (0, 100000)})
    race_keep: int = dataclasses.field(default=6, metadata={
        "description": "fewest designs kept after a race round (halving never goes below it; count)",
        "range": (1, 100000)})
    launch_trials: int = dataclasses.field(default=0, metadata={
        "description": "fresh robust twin launches per chosen design and the bare robot, for the gain over the "
                       "bare robot in Table 3 and designs.yaml (count; 0 = none)", "range": (0, 10000000)})
    world_count: int = dataclasses.field(default=0, metadata={
        "description": "worlds of the selection's plausible-world check (each one draw of every unknown; the "
                       "chosen designs and the bare robot launched in each on the same seeds); 0 = no check and no "
                       "recommendation (count)", "range": (0, 100000)})
    world_launches: int = dataclasses.field(default=20, metadata={
        "description": "paired launches per configuration in each world of the check (count; use multiples of "
                       "the campaign's conditions)", "range": (1, 10000000)})
    recommend_world_share: float = dataclasses.field(default=0.9, metadata={
        "description": "a design is recommended only where it beats the bare robot (point gain > 0) in at least "
                       "this share of the worlds, with its pooled gain's 95% interval above 0 (fraction)",
        "range": (0.0, 1.0)})

    def validate(self) -> None:
        """Raise ``ValueError`` for a rule that spans fields (each number's range is declared in its metadata and
        checked by :func:`~rollability_ros.core.config.check_settings`)."""
        if list(self.race_launches) not in ([], [0]) and any(int(n) < 1 for n in self.race_launches):
            raise ValueError(f"race_launches must list counts >= 1 (or be [0]: no race), got {self.race_launches}")
        if self.mesh_units not in MESH_UNITS:
            raise ValueError(f"mesh_units must be one of {', '.join(MESH_UNITS)}, got {self.mesh_units!r}")

    @property
    def race_rounds(self) -> typing.List[int]:
        """Launches per design in each round of the launch race; [] without a race."""
        return [] if list(self.race_launches) in ([], [0]) else [int(n) for n in self.race_launches]


@dataclasses.dataclass(frozen=True)
class PooledDesign:
    """All logged evaluations of one height vector: heights (simulation units), successes, trials."""

    heights: np.ndarray
    successes: int
    trials: int
    evaluations: int
    first_generation: int

    @property
    def fitness(self) -> float:
        """Pooled successes / trials."""
        return self.successes / self.trials

    @property
    def wilson_low(self) -> float:
        """Lower bound of the 95% Wilson interval of the pooled fitness."""
        return wilson_interval(self.successes, self.trials)[0]


@dataclasses.dataclass(frozen=True)
class SelectedDesign:
    """A chosen design: label, pooled log estimate, optional fresh re-evaluation, solid and its metrics."""

    label: str
    design: PooledDesign
    mesh: object                       # trimesh.Trimesh, metres, profile frame
    metrics: ProfileMetrics
    reevaluation: typing.Optional[tuple] = None         # (successes, trials, seed) of the fresh estimate, or None
    reason: str = ""                   # why it was chosen, one sentence
    descriptors: typing.Optional[tuple] = None          # (max_height_mm, sharpness_deg) for archive selections, else None
    cell: typing.Optional[tuple] = None                 # archive cell (height index, sharpness index), or None
    launches: typing.Optional[tuple] = None             # (successes, trials, seed) of fresh robust twin launches, or None
    race: typing.Optional[tuple] = None                 # (successes, trials) pooled over the launch race's rounds, or None
    printed_mass_kg: typing.Optional[float] = None      # the profile as printed and mounted on the twin, or None

    @property
    def reported(self) -> typing.Tuple[int, int, str]:
        """(successes, trials, source) reported in Table 3: the re-evaluation if any, else the pooled log."""
        if self.reevaluation is not None:
            return self.reevaluation[0], self.reevaluation[1], "reevaluated"
        return self.design.successes, self.design.trials, "logged"


@dataclasses.dataclass(frozen=True)
class SelectionResult:
    """Chosen designs (best first), the baseline's fresh estimate, and how the shortlist was filtered."""

    designs: list
    requested: int
    considered: int                    # distinct designs in the log
    rejected: dict                     # reason -> count ("not printable", "too close", "flat")
    # (successes, trials, seed) of the baseline re-evaluation, or None
    baseline: typing.Optional[typing.Tuple[int, int, int]] = None
    top_threshold: typing.Optional[float] = None        # archive runs: the fitness an elite needed to be in the top pool
    archive: typing.Optional[list] = None               # archive runs: one row per elite (ARCHIVE_COLUMNS), else None
    baseline_launches: typing.Optional[tuple] = None    # (successes, trials, seed) of the bare robot's fresh launches, or None
    race: typing.Optional[racing.RaceResult] = None     # the launch race, or None without one
    world_rows: typing.Optional[list] = None            # the world check's rows (world_check.WORLD_CHECK_COLUMNS), or None
    recommendation: typing.Optional[Recommendation] = None   # the rule applied to the world check, or None
    printed_with: typing.Optional[dict] = None          # how the designs are printed and weighed (designs.yaml `print`), or None

    def gains(self) -> typing.List[typing.Optional["Gain"]]:
        """One :class:`Gain` per chosen design: its gain over the bare robot on fresh robust launches when there
        are any, else on the fresh re-evaluation, else None (nothing fresh to compare)."""
        return [design_gain(d, self) for d in self.designs]

    def no_design_helps(self) -> str:
        """A sentence when gains were measured and no design's 95% interval lies above 0, else ''."""
        gains = [g for g in self.gains() if g is not None]
        if not gains or any(g.beats for g in gains):
            return ""
        return (f"no design beats the bare robot on {GAIN_SOURCES[gains[0].source]}: "
                + "; ".join(g.text() for g in gains))

    @property
    def shortfall(self) -> str:
        """A sentence when fewer designs than requested qualified, else ''."""
        if len(self.designs) >= self.requested:
            return ""
        reasons = "; ".join(f"{count} {reason}" for reason, count in sorted(self.rejected.items())) or "none"
        if any(r.startswith("not printable") for r in self.rejected):
            advice = "check the printer section of the configuration (select --config) or the profile size"
        elif self.top_threshold is not None:
            advice = "raise selection.top_fraction (select --top-fraction) or run the optimizer longer"
        else:
            advice = "lower min_distance or run the optimizer longer"
        among = (f"the top pool of the {self.considered} archive elites (fitness >= {self.top_threshold:.3f})"
                 if self.top_threshold is not None else f"{self.considered} distinct logged designs")
        return (f"only {len(self.designs)} of {self.requested} requested designs qualify among {among} "
                f"(rejected: {reasons}); {advice}")


@dataclasses.dataclass(frozen=True)
class Gain:
    """A design's success rate minus the bare robot's on the same fresh trials, with Newcombe's 95% interval."""

    label: str
    source: str                        # a key of GAIN_SOURCES
    successes: int
    trials: int
    baseline_successes: int
    baseline_trials: int

    @property
    def interval(self) -> typing.Tuple[float, float, float]:
        """``(difference, low, high)``: Newcombe's hybrid score 95% interval."""
        return newcombe_interval(self.successes, self.trials, self.baseline_successes, self.baseline_trials)

    @property
    def beats(self) -> bool:
        """True when the whole 95% interval of the gain lies above 0."""
        return self.interval[1] > 0

    def text(self) -> str:
        """One line: the design's and the bare robot's counts and the gain with its 95% interval."""
        difference, low, high = self.interval
        return (f"{self.label} {self.successes}/{self.trials} vs bare {self.baseline_successes}/"
                f"{self.baseline_trials}: {difference:+.2f} [{low:+.2f}, {high:+.2f}]")


def design_gain(design: SelectedDesign, result: SelectionResult) -> typing.Optional[Gain]:
    """The :class:`Gain` of ``design`` over the bare robot in ``result``, or None (see SelectionResult.gains)."""
    if design.launches is not None and result.baseline_launches is not None:
        return Gain(design.label, "launches", design.launches[0], design.launches[1], *result.baseline_launches[:2])
    if design.reevaluation is not None and result.baseline is not None:
        return Gain(design.label, "reevaluated", design.reevaluation[0], design.reevaluation[1],
                    *result.baseline[:2])
    return None


def _limits_named(problems):
    """The configuration keys (``printer.bed_x_m / bed_y_m``, ...) that the printability ``problems`` name."""
    named = [re.search(r"\((printer\.[^)]*)\)", problem) for problem in problems]
    return [match.group(1) if match else problem for match, problem in zip(named, problems)]


def pool_candidates(candidates: typing.Iterable["CandidateRecord"]) -> typing.List[PooledDesign]:
    """Pool :class:`CandidateRecord` s by identical heights; return :class:`PooledDesign` s in first-seen order."""
    pooled: typing.Dict[tuple, PooledDesign] = {}
    for record in candidates:
        key = tuple(record.heights)
        previous = pooled.get(key)
        if previous is None:
            pooled[key] = PooledDesign(np.asarray(key, dtype=np.float64), record.successes, record.trials, 1,
                                       record.generation)
        else:
            pooled[key] = dataclasses.replace(previous, successes=previous.successes + record.successes,
                                              trials=previous.trials + record.trials,
                                              evaluations=previous.evaluations + 1)
    return list(pooled.values())


def rms_distance(heights_a: npt.ArrayLike, heights_b: npt.ArrayLike) -> float:
    """RMS difference of two height vectors ``(n_variables,)``, simulation units."""
    return float(np.sqrt(np.mean((np.asarray(heights_a) - np.asarray(heights_b)) ** 2)))


def select_designs(candidates: typing.Iterable["CandidateRecord"], grid: ProfileGrid,
                   printer: PrinterSpec, settings: SelectionSettings,
                   evaluate_batch: typing.Optional[BatchEvaluator] = None, run_seed: int = 1,
                   launch_batch: typing.Optional[LaunchEvaluator] = None) -> SelectionResult:
    """Choose designs from a run's candidate log; see the module docstring.

    Parameters
    ----------
    candidates : iterable of CandidateRecord
    grid : ProfileGrid
    printer : PrinterSpec
    settings : SelectionSettings
    evaluate_batch : callable(heights_list, seed) -> [(successes, trials, eval_time_s, evaluator)], optional
        Runs ``settings.reevaluate_trials`` trials per profile; needed when ``reevaluate_trials > 0``.
    run_seed : int
        The run's seed; the re-evaluation seed is derived from it (stream ``STREAM_SELECTION``).
    launch_batch : callable(heights_list, seed, trials) -> [(successes, trials, eval_time_s, evaluator)], optional
        Runs robust twin launches; needed for ``race_launches`` or ``launch_trials``. With ``race_launches`` the
        ``race_elites`` printable designs ranked best race on launches, and A/B/C are taken from the survivors
        by their launches (same distance rule).
    """
    _check_evaluators(settings, evaluate_batch, launch_batch)
    pooled = [d for d in pool_candidates(candidates) if not is_baseline(d.heights)]
    ranked = sorted(pooled, key=lambda d: (-d.wilson_low, -d.fitness, d.first_generation))
    chosen: typing.List[SelectedDesign] = []
    rejected: typing.Dict[str, int] = {}
    race: typing.Optional[racing.RaceResult] = None
    meshes: typing.Dict[int, typing.Any] = {}
    reasons: typing.Dict[int, str] = {}
    if settings.race_rounds:
        for index, design in enumerate(ranked):
            if settings.race_elites and len(meshes) == settings.race_elites:
                break
            mesh, problem = _printable_mesh(design.heights, grid, printer)
            if mesh is None:
                rejected[problem] = rejected.get(problem, 0) + 1
            else:
                meshes[index] = mesh
        entrants = list(meshes)
        race = _launch_race(ranked, entrants, settings, launch_batch, run_seed, grid.n_variables)
        order, _, _, race_text, pool_text = _race_pool(race, entrants, ranked)
        order = [i for i in sorted(race.survivors, key=lambda i: (i not in order, -wilson_interval(*race.totals[i])[0]))]
        reasons = {i: f"{pool_text}, rank {rank} by its launches: {race_text(i)}" for rank, i in enumerate(order, 1)}
        walk = [(i, ranked[i]) for i in order]
    else:
        walk = list(enumerate(ranked))
    for rank, (index, design) in enumerate(walk, 1):
        if len(chosen) == settings.count:
            break
        if any(rms_distance(design.heights, c.design.heights) < settings.min_distance for c in chosen):
            rejected["too close"] = rejected.get("too close", 0) + 1
            continue
        mesh, problem = (meshes[index], "") if index in meshes else _printable_mesh(design.heights, grid, printer)
        if mesh is None:
            rejected[problem] = rejected.get(problem, 0) + 1
            continue
        reason = reasons.get(index) or (f"rank {rank} of {len(ranked)} logged designs by lower Wilson bound "
                                        f"({design.successes}/{design.trials}, bound {design.wilson_low:.2f})")
        if chosen:
            reason += f", at least {settings.min_distance} units RMS from {_picks(len(chosen))}"
        chosen.append(SelectedDesign(string.ascii_uppercase[len(chosen)], design, mesh, mesh_metrics(mesh),
                                     reason=reason, race=race.totals[index] if race else None))
    chosen, baseline = _reevaluate(chosen, grid, settings, evaluate_batch, run_seed)
    chosen, baseline_launches = _launch_reevaluate(chosen, grid, settings, launch_batch, run_seed)
    return SelectionResult(chosen, settings.count, len(pooled), rejected, baseline,
                           baseline_launches=baseline_launches, race=race)


def _check_evaluators(settings, evaluate_batch, launch_batch):
    """Check ``settings`` (declared ranges and cross-field rules) and refuse a setting whose evaluator is missing."""
    config.check_settings(settings, "selection")
    if settings.reevaluate_trials and evaluate_batch is None:
        raise ValueError("reevaluate_trials > 0 needs an evaluator")
    if (settings.race_rounds or settings.launch_trials) and launch_batch is None:
        raise ValueError("race_launches or launch_trials > 0 need a launch evaluator")


def with_world_check(result: SelectionResult, grid: ProfileGrid, settings: SelectionSettings,
                     world_launch: typing.Optional[WorldLaunch], run_seed: int,
                     describe: typing.Optional[WorldDescriber] = None
                     ) -> SelectionResult:
    """``result`` with the plausible-world check of its designs and the bare robot (``settings.world_count``
    worlds x ``world_launches`` paired launches, seed ``derive_seed(run_seed, WORLD_SEED_KEY, STREAM_SELECTION)``;
    :mod:`~rollability_ros.core.sim.world_check`) and the recommendation it gives
    (:mod:`~rollability_ros.core.optimization.recommendation`); unchanged without a check or designs.
    ``describe(world seed)`` names a world's draws in the rows (empty columns without it)."""
    from rollability_ros.core.sim import run_world_check, summarize_worlds

    if not (settings.world_count and result.designs):
        return result
    if world_launch is None:
        raise ValueError("world_count > 0 needs a world launch evaluator (fidelity world:<seed>)")
    labels = [BASELINE] + [d.label for d in result.designs]
    heights = [np.zeros(grid.n_variables)] + [d.design.heights for d in result.designs]

    def evaluate(world_seed: int, launch_seed: int, launches: int) -> typing.Dict[str, typing.Tuple[int, int]]:
        results = world_launch(heights, world_seed, launch_seed, launches)
        return {label: (int(r[0]), int(r[1])) for label, r in zip(labels, results)}

    rows = run_world_check(evaluate, settings.world_count, settings.world_launches,
                                       derive_seed(run_seed, WORLD_SEED_KEY, STREAM_SELECTION), describe)
    verdict = recommend(summarize_worlds(rows), settings.recommend_world_share)
    return dataclasses.replace(result, world_rows=rows, recommendation=verdict)


def _reevaluate(chosen, grid, settings, evaluate_batch, run_seed):
    """``(chosen, baseline)``: the chosen designs and the baseline re-evaluated in one batch on a fresh common seed
    (``settings.reevaluate_trials`` each); unchanged and None without re-evaluation."""
    if not (settings.reevaluate_trials and chosen):
        return chosen, None
    seed = derive_seed(run_seed, 0, STREAM_SELECTION)
    profiles = [c.design.heights for c in chosen] + [np.zeros(grid.n_variables)]
    results = evaluate_batch(profiles, seed)
    chosen = [dataclasses.replace(c, reevaluation=(int(r[0]), int(r[1]), seed)) for c, r in zip(chosen, results)]
    return chosen, (int(results[-1][0]), int(results[-1][1]), seed)


def _printable_mesh(heights: npt.ArrayLike, grid: ProfileGrid, printer: PrinterSpec
                    ) -> typing.Tuple[typing.Optional[Mesh], str]:
    """``(mesh, "")`` for a printable profile (heights ``(n_variables,)``, simulation units), else
    ``(None, reason)`` (the rejection count's key)."""
    try:
        mesh = profile_mesh(heights, grid)
    except ValueError:
        return None, "flat"
    if mesh is None:
        return None, "flat"
    printability = check_printability(mesh, printer)
    if not printability.printable:
        return None, "not printable: " + ", ".join(_limits_named(printability.problems))
    return mesh, ""


def top_pool(fitnesses: typing.Sequence[float], top_fraction: float) -> typing.Tuple[float, typing.List[int]]:
    """``(threshold, indices)``: the indices of ``fitnesses`` at least their ``1 - top_fraction`` quantile (numpy's
    linear interpolation), and that quantile."""
    threshold = float(np.quantile(fitnesses, 1.0 - top_fraction))
    return threshold, [i for i, f in enumerate(fitnesses) if f >= threshold]


def select_from_archive(archive: typing.Mapping[str, typing.Any], candidates: typing.Iterable["CandidateRecord"],
                        grid: ProfileGrid, printer: PrinterSpec, settings: SelectionSettings,
                        evaluate_batch: typing.Optional[BatchEvaluator] = None, run_seed: int = 1,
                        launch_batch: typing.Optional[LaunchEvaluator] = None) -> SelectionResult:
    """Choose designs from a quality-diversity ``archive`` (the run info's ``archive``: ``ranges`` and
    ``elites``); see the module docstring. Arguments as :func:`select_designs`.

    With ``reevaluate_trials`` > 0 every elite is first *screened* on fresh trials (one common seed) and the top pool
    and ranking use the screen, not the elites' in-run estimates (each a maximum of noisy draws: the cells' lucky
    winners); the chosen designs are then re-evaluated once more on another seed for the reported fitness, since a
    design picked for its screen is again picked partly for luck. Without re-evaluation the in-run estimates
    (pooled over the run's evaluations of the design) are used. With ``race_launches`` the printable elites with
    the best screen race on robust twin launches (``launch_batch``) and A/B/C come from the race's survivors
    (module docstring, "Ranked by the rig's measure").
    """
    _check_evaluators(settings, evaluate_batch, launch_batch)
    elites = [e for e in archive["elites"] if not is_baseline(e["heights"])]
    if not elites:
        return SelectionResult([], settings.count, 0, {"no elites": 1})
    pooled = {tuple(d.heights): d for d in pool_candidates(candidates)}
    designs = []
    for elite in elites:
        key = tuple(float(h) for h in elite["heights"])
        designs.append(pooled.get(key) or PooledDesign(np.asarray(key), int(round(elite["fitness"] * elite["trials"])),
                                                       int(elite["trials"]), 1, int(elite["generation"])))
    source = "in the run"
    if settings.reevaluate_trials and evaluate_batch is not None:   # (checked above: one with the other)
        seed = derive_seed(run_seed, 1, STREAM_SELECTION)
        results = evaluate_batch([d.heights for d in designs], seed)
        designs = [PooledDesign(d.heights, int(r[0]), int(r[1]), 1, d.first_generation)
                   for d, r in zip(designs, results)]
        source = f"in the screen of all {len(elites)} elites"
    top, pool = top_pool([d.fitness for d in designs], settings.top_fraction)
    picker = _MapPicker(elites, designs, pooled, [float(high - low) for low, high in archive["ranges"]])
    rejected: typing.Dict[str, int] = {}
    race: typing.Optional[racing.RaceResult] = None
    threshold: typing.Optional[float] = top
    if settings.race_rounds:
        race, pool = _pick_by_race(picker, grid, printer, settings, launch_batch, run_seed, rejected)
        threshold = None
    else:
        screen = f"{len(pool)} of {len(elites)} elites in the top {settings.top_fraction:.0%} (fitness >= {top:.3f} " \
                 f"{source})"
        _pick_by_screen(picker, pool, screen, source, grid, printer, settings, rejected)
    chosen, baseline = _reevaluate(picker.chosen, grid, settings, evaluate_batch, run_seed)
    chosen, baseline_launches = _launch_reevaluate(chosen, grid, settings, launch_batch, run_seed)
    rows = _archive_rows(elites, designs, chosen, set(pool), bool(settings.reevaluate_trials), race)
    return SelectionResult(chosen, settings.count, len(elites), rejected, baseline, threshold, rows,
                           baseline_launches, race)


class _MapPicker:
    """Farthest-point picking over an archive's (height, sharpness) plane: the elites, their estimates, and the
    designs taken so far with their points."""

    def __init__(self, elites: typing.List[typing.Dict[str, typing.Any]], designs: typing.List[PooledDesign],
                 pooled: typing.Dict[tuple, PooledDesign], spans: typing.List[float]) -> None:
        self.elites, self.designs, self.pooled, self.spans = elites, designs, pooled, spans
        self.chosen: typing.List[SelectedDesign] = []
        self.points: typing.List[np.ndarray] = []

    def screen_key(self, i: int) -> tuple:
        """Rank of elite ``i`` by its screen: the higher lower Wilson bound, then fitness, then the earlier one."""
        return -self.designs[i].wilson_low, -self.designs[i].fitness, self.designs[i].first_generation

    def spread(self, i: int) -> float:
        """How far elite ``i`` lies from the nearest design already taken, in the normalised descriptor plane."""
        return min(float(np.hypot(*(_descriptor_point(self.elites[i], self.spans) - point)))
                   for point in self.points)

    def where(self, i: int) -> str:
        """Where elite ``i`` lies on the map: its height, sharpness and cell."""
        elite = self.elites[i]
        return (f"{elite['max_height_mm']:.0f} mm tall, sharpness {elite['sharpness_deg']:.0f} deg, cell "
                f"{tuple(elite['cell'])}")

    def taken(self) -> str:
        """The designs taken so far, by the order they were picked in ("pick 1", "picks 1, 2"): the labels follow
        the evidence after the pick (:func:`label_by_evidence`), so a reason names picks, not labels."""
        return _picks(len(self.chosen))

    def take(self, index: int, mesh: typing.Any, reason: str, ranked: typing.List[int],
             race: typing.Optional[tuple] = None) -> typing.List[int]:
        """Take elite ``index`` as the next design; return ``ranked`` without the elites of its cell."""
        elite, design = self.elites[index], self.designs[index]
        self.chosen.append(SelectedDesign(string.ascii_uppercase[len(self.chosen)],
                                          self.pooled.get(tuple(design.heights), design), mesh,
                                          mesh_metrics(mesh), reason=reason,
                                          descriptors=(elite["max_height_mm"], elite["sharpness_deg"]),
                                          cell=tuple(elite["cell"]), race=race))
        self.points.append(_descriptor_point(elite, self.spans))
        return [i for i in ranked if tuple(self.elites[i]["cell"]) != tuple(elite["cell"])]


def _pick_by_race(picker, grid, printer, settings, launch_batch, run_seed, rejected):
    """Race the printable elites with the best screen on launches and take A/B/C from the race's pool (module
    docstring, "Ranked by the rig's measure"); ``(race, pool)``."""
    meshes = {}
    for index in sorted(range(len(picker.elites)), key=picker.screen_key):
        mesh, problem = _printable_mesh(picker.designs[index].heights, grid, printer)
        if mesh is None:
            rejected[problem] = rejected.get(problem, 0) + 1
        else:
            meshes[index] = mesh
    entrants = sorted(meshes, key=picker.screen_key)[:settings.race_elites or None]
    race = _launch_race(picker.designs, entrants, settings, launch_batch, run_seed, grid.n_variables)
    pool, ranked, race_low, race_text, pool_text = _race_pool(race, entrants, picker.designs)
    while ranked and len(picker.chosen) < settings.count:
        if picker.chosen:
            index = ranked.pop(max(range(len(ranked)), key=lambda k: (picker.spread(ranked[k]), race_low(ranked[k]))))
            reason = (f"the {pool_text} farthest from {picker.taken()} in (height, sharpness): "
                      f"{picker.where(index)}; {race_text(index)}")
        else:
            index = ranked.pop(0)
            reason = f"highest lower Wilson bound of any {pool_text}: {race_text(index)}; {picker.where(index)}"
        ranked = picker.take(index, meshes[index], reason, ranked, race.totals[index])
    return race, pool


def _pick_by_screen(picker, pool, screen, source, grid, printer, settings, rejected):
    """Take A/B/C from the top ``pool`` by the screen (``screen`` names the pool): A the highest lower Wilson bound,
    then farthest-point over the map."""
    ranked = sorted(pool, key=picker.screen_key)
    while ranked and len(picker.chosen) < settings.count:
        if picker.chosen:
            index = ranked.pop(max(range(len(ranked)),
                                   key=lambda k: (picker.spread(ranked[k]), picker.designs[ranked[k]].wilson_low)))
        else:
            index = ranked.pop(0)
        design = picker.designs[index]
        mesh, problem = _printable_mesh(design.heights, grid, printer)
        if mesh is None:
            rejected[problem] = rejected.get(problem, 0) + 1
            continue
        estimate = f"{design.successes}/{design.trials} {source}, lower 95% bound {design.wilson_low:.2f}"
        if not picker.chosen:
            reason = f"highest lower Wilson bound among the {screen}: {estimate}; {picker.where(index)}"
        else:
            reason = (f"the top-{settings.top_fraction:.0%} elite farthest from {picker.taken()} in (height, "
                      f"sharpness): {picker.where(index)}; {estimate}")
        ranked = picker.take(index, mesh, reason, ranked)


def _archive_rows(elites, designs, chosen, in_pool, screened, race):
    """``archive.csv``'s rows (:data:`ARCHIVE_COLUMNS`): each elite, its run and screen estimates, its label."""
    labels = {d.cell: d.label for d in chosen}
    rows = []
    for index, (elite, design) in enumerate(zip(elites, designs)):
        rows.append({"cell_height": elite["cell"][0], "cell_sharpness": elite["cell"][1],
                     "max_height_mm": elite["max_height_mm"], "sharpness_deg": elite["sharpness_deg"],
                     "in_run_fitness": elite["fitness"], "in_run_trials": elite["trials"],
                     "screen_successes": design.successes if screened else "",
                     "screen_trials": design.trials if screened else "",
                     "screen_fitness": design.fitness if screened else "", "top_pool": int(index in in_pool),
                     "label": labels.get(tuple(elite["cell"]), ""), **_race_columns(race, index)})
    return rows


def _race_columns(race: typing.Optional[racing.RaceResult], index: int) -> typing.Dict[str, typing.Any]:
    """The archive row's race columns of elite ``index``: its first round, its pooled launches and the round it was
    stopped in; empty text when it did not race (or there was no race)."""
    if race is None or index not in race.totals:
        return dict.fromkeys(("race_round1_successes", "race_round1_trials", "race_successes", "race_trials",
                              "race_stopped"), "")
    return {"race_round1_successes": race.first_round[index][0], "race_round1_trials": race.first_round[index][1],
            "race_successes": race.totals[index][0], "race_trials": race.totals[index][1],
            "race_stopped": race.stopped[index][0] if index in race.stopped else ""}


def _launch_race(designs, entrants, settings, launch_batch, run_seed, n_variables):
    """Race the ``entrants`` (indices of ``designs``) and the bare robot on robust twin launches
    (:func:`racing.race`; round ``r`` on seed ``derive_seed(run_seed, RACE_SEED_KEY + r, STREAM_SELECTION)``)."""
    def evaluate(ids: typing.List["Hashable"], seed: int, trials: int) -> typing.List[typing.Tuple[int, int]]:
        """``(successes, trials)`` of each id (a design index or :data:`BASELINE`) on ``trials`` launches."""
        heights = [np.zeros(n_variables) if i == BASELINE else designs[i].heights for i in ids]
        return [(int(r[0]), int(r[1])) for r in launch_batch(heights, seed, trials)]

    rounds = settings.race_rounds
    seeds = [derive_seed(run_seed, RACE_SEED_KEY + r, STREAM_SELECTION) for r in range(len(rounds))]
    return racing.race(entrants, evaluate, rounds, seeds, keep_fraction=0.5, min_keep=settings.race_keep,
                       reference=BASELINE)


def _race_pool(race, entrants, designs):
    """``(pool, ranked, lower_bound, text, name)`` after a launch race: the survivors whose pooled launch rate is
    above the bare robot's (all survivors when none is), ranked by the lower Wilson bound of their launches; a
    function giving a design's lower bound and one describing its estimates; the pool's name for reasons."""
    rate = lambda i: race.totals[i][0] / race.totals[i][1]  # noqa: E731
    low = lambda i: wilson_interval(*race.totals[i])[0]  # noqa: E731
    base_s, base_n = race.reference
    better = [i for i in race.survivors if rate(i) > base_s / base_n]
    pool = better or list(race.survivors)
    ranked = sorted(pool, key=lambda i: (-low(i), -rate(i), designs[i].first_generation))
    rounds = "+".join(str(r["trials"]) for r in race.rounds)

    def text(i: int) -> str:
        """Design ``i``'s launches in the race, the bare robot's and its screen, as a phrase."""
        return (f"{race.totals[i][0]}/{race.totals[i][1]} robust twin launches in the race (lower 95% bound "
                f"{low(i):.2f}; bare robot {base_s}/{base_n} on the same draws), screen "
                f"{designs[i].successes}/{designs[i].trials}")

    name = (f"race survivor{'' if better else ' (none above the bare robot)'} of {len(entrants)} elites "
            f"raced on {rounds} launches")
    return pool, ranked, low, text, name


def _launch_reevaluate(chosen, grid, settings, launch_batch, run_seed):
    """``(chosen, baseline_launches)``: the chosen designs and the bare robot on ``settings.launch_trials`` fresh
    robust twin launches, one common seed; unchanged and None without them."""
    if not (settings.launch_trials and chosen):
        return chosen, None
    seed = derive_seed(run_seed, LAUNCH_SEED_KEY, STREAM_SELECTION)
    results = launch_batch([c.design.heights for c in chosen] + [np.zeros(grid.n_variables)], seed,
                           settings.launch_trials)
    chosen = [dataclasses.replace(c, launches=(int(r[0]), int(r[1]), seed)) for c, r in zip(chosen, results)]
    return chosen, (int(results[-1][0]), int(results[-1][1]), seed)


def _picks(count: int) -> str:
    """The first ``count`` picks of a selection, named by order: "pick 1", "picks 1, 2"."""
    return f"pick{'s' if count > 1 else ''} {', '.join(str(k) for k in range(1, count + 1))}"


def _descriptor_point(elite, spans):
    """An elite's (height, sharpness) divided by the axis lengths: the plane farthest-point sampling measures in."""
    return np.array([elite["max_height_mm"] / spans[0], elite["sharpness_deg"] / spans[1]])
