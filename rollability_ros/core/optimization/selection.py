"""Design selection (paper 2.1.5): pick N high-fitness, printable, geometrically diverse designs from a run's log.

Procedure
---------
1. Every logged evaluation of the run (population candidates and incumbent re-evaluations) is pooled per
   distinct height vector: successes and trials add up.
2. Designs are ranked by the lower bound of the 95% Wilson interval of their pooled fitness, then by fitness:
   a design seen once at 60/60 does not outrank one confirmed at 55/60 twice only because it was lucky once.
3. Walking down that ranking, a design is taken when its convex-hull solid passes the printability checks
   (:func:`check_printability`) and its RMS height distance (simulation units) to every design already
   taken is at least ``min_distance``. Labels follow the ranking: "A" is the best.
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
whose pooled launch rate is above the bare robot's (all survivors when none is): A the highest lower Wilson bound
of its launches, B and C farthest-point over the map as above (a ranked-log run: the distance rule). Then the
chosen designs and the bare robot get ``launch_trials`` fresh robust launches on one new seed: each design's
*gain* over the bare robot, with Newcombe's 95% hybrid score interval, goes into Table 3 and designs.yaml
(``beats_baseline`` true only when the interval lies above 0). When no design beats the bare robot the designs are
still written, for inspection, each marked ``beats_baseline: false``; ``select`` warns and the report says so.
Without launches, the gain is taken on the fresh re-evaluation and labelled as such.

Outputs (``<run_dir>/designs/``, or ``designs-<n>/`` for a later selection of the same run: design sets are
append-only, see :func:`write_selection`): ``mesh_<label>.stl`` (millimetres by default, ``mesh_units``; the unit is
written in the STL header), ``mesh_<label>.3mf`` (millimetres, the 3MF unit attribute), ``table3.csv`` (the paper's Table 3 with the
simulated fitness and its Wilson interval, baseline row first; beside it the in-run estimate with its interval
and the selection bias, in-run minus fresh) and ``designs.yaml``, a ROS 2 parameter file
with the heights of each design and its grid, for the rig's simulation twin.
"""
import csv
import dataclasses
import io
import math
import os
import re
import shutil
import string
import typing

import numpy as np
import numpy.typing as npt
import yaml

from rollability_ros.core import config
from rollability_ros.core.profile import (MESH_UNITS, Mesh, PrinterSpec, ProfileGrid, ProfileMetrics,
                                          check_printability, export_mesh, is_baseline, mesh_metrics, profile_mesh)
from rollability_ros.core.optimization.checkpoint import atomic_write_bytes
from rollability_ros.core.optimization.cmaes import STREAM_SELECTION, derive_seed
from rollability_ros.core.optimization import racing
from rollability_ros.core.stats import newcombe_interval, wilson_interval

if typing.TYPE_CHECKING:
    from collections.abc import Hashable

    from rollability_ros.core.records import CandidateRecord
    from rollability_ros.core.store import Store

#: ``evaluate_batch(heights_list, seed) -> [(successes, trials, eval_time_s, evaluator), ...]``: heights
#: ``(n_variables,)`` each, simulation units; one result per profile.
BatchEvaluator = typing.Callable[[typing.List[np.ndarray], int], typing.Sequence["EvaluatedProfile"]]
#: ``launch_batch(heights_list, seed, trials) -> [(successes, trials, eval_time_s, evaluator), ...]``: robust twin
#: launches of each profile (heights ``(n_variables,)``, simulation units).
LaunchEvaluator = typing.Callable[[typing.List[np.ndarray], int, int], typing.Sequence["EvaluatedProfile"]]
#: One profile's evaluation: ``(successes, trials, eval_time_s, evaluator)``.
EvaluatedProfile = typing.Tuple[int, int, float, str]

#: The race's id of the bare robot (the reference that runs every round).
BASELINE = "baseline"
#: Generation keys of the selection's seeds (stream STREAM_SELECTION): the chosen designs' fresh launches, and
#: the race's rounds from RACE_SEED_KEY on (0 and 1 are the re-evaluation and the screen).
LAUNCH_SEED_KEY = 2
RACE_SEED_KEY = 10

#: Columns of ``archive.csv`` (quality-diversity runs): each elite, its run and screen estimates, its label if chosen.
ARCHIVE_COLUMNS = ("cell_height", "cell_sharpness", "max_height_mm", "sharpness_deg", "in_run_fitness",
                   "in_run_trials", "screen_successes", "screen_trials", "screen_fitness", "top_pool", "label",
                   "race_round1_successes", "race_round1_trials", "race_successes", "race_trials", "race_stopped")
#: Columns of ``traits.csv``: every evaluation of the run pooled per bin of one descriptor.
TRAIT_COLUMNS = ("trait", "bin_low", "bin_high", "designs", "successes", "trials", "fitness", "ci_low", "ci_high")
#: Sub-directory of the run directory that receives the selected designs.
DESIGNS_DIRNAME = "designs"
#: Columns of ``table3.csv`` (configuration and dimensions as in ``analysis.GEOMETRY_COLUMNS``).
TABLE_COLUMNS = ("configuration", "length_m", "width_m", "max_height_m", "printed_mass_g", "simulated_fitness",
                 "ci_low", "ci_high",
                 "successes", "trials", "fitness_source", "in_run_fitness", "in_run_ci_low", "in_run_ci_high",
                 "in_run_successes", "in_run_trials", "selection_bias", "launch_successes", "launch_trials",
                 "launch_fitness", "gain_source", "gain", "gain_low", "gain_high", "beats_baseline")
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
    config.check_settings(settings, "selection")
    if settings.reevaluate_trials and evaluate_batch is None:
        raise ValueError("reevaluate_trials > 0 needs an evaluator")
    if (settings.race_rounds or settings.launch_trials) and launch_batch is None:
        raise ValueError("race_launches or launch_trials > 0 need a launch evaluator")
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
            reason += f", at least {settings.min_distance} units RMS from {', '.join(c.label for c in chosen)}"
        chosen.append(SelectedDesign(string.ascii_uppercase[len(chosen)], design, mesh, mesh_metrics(mesh),
                                     reason=reason, race=race.totals[index] if race else None))
    chosen, baseline = _reevaluate(chosen, grid, settings, evaluate_batch, run_seed)
    chosen, baseline_launches = _launch_reevaluate(chosen, grid, settings, launch_batch, run_seed)
    return SelectionResult(chosen, settings.count, len(pooled), rejected, baseline,
                           baseline_launches=baseline_launches, race=race)


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
    config.check_settings(settings, "selection")
    if settings.reevaluate_trials and evaluate_batch is None:
        raise ValueError("reevaluate_trials > 0 needs an evaluator")
    if (settings.race_rounds or settings.launch_trials) and launch_batch is None:
        raise ValueError("race_launches or launch_trials > 0 need a launch evaluator")
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
    threshold: typing.Optional[float] = top
    by_screen = lambda i: (-designs[i].wilson_low, -designs[i].fitness, designs[i].first_generation)  # noqa: E731
    spans = [float(high - low) for low, high in archive["ranges"]]
    chosen: typing.List[SelectedDesign] = []
    rejected: typing.Dict[str, int] = {}
    points: typing.List[np.ndarray] = []
    race: typing.Optional[racing.RaceResult] = None

    def spread(i: int) -> float:
        """How far elite ``i`` lies from the nearest design already taken, in the normalised descriptor plane."""
        return min(float(np.hypot(*(_descriptor_point(elites[i], spans) - point))) for point in points)

    def where(elite: typing.Dict[str, typing.Any]) -> str:
        """Where ``elite`` lies on the map: its height, sharpness and cell."""
        return (f"{elite['max_height_mm']:.0f} mm tall, sharpness {elite['sharpness_deg']:.0f} deg, cell "
                f"{tuple(elite['cell'])}")

    if settings.race_rounds:
        meshes = {}
        for index in sorted(range(len(elites)), key=by_screen):
            mesh, problem = _printable_mesh(designs[index].heights, grid, printer)
            if mesh is None:
                rejected[problem] = rejected.get(problem, 0) + 1
            else:
                meshes[index] = mesh
        entrants = sorted(meshes, key=by_screen)[:settings.race_elites or None]
        race = _launch_race(designs, entrants, settings, launch_batch, run_seed, grid.n_variables)
        pool, ranked, race_low, race_text, pool_text = _race_pool(race, entrants, designs)
        threshold = None
        while ranked and len(chosen) < settings.count:
            if chosen:
                index = ranked.pop(max(range(len(ranked)), key=lambda k: (spread(ranked[k]), race_low(ranked[k]))))
                reason = (f"the {pool_text} farthest from {', '.join(c.label for c in chosen)} in (height, "
                          f"sharpness): {where(elites[index])}; {race_text(index)}")
            else:
                index = ranked.pop(0)
                reason = (f"highest lower Wilson bound among the {pool_text}s: {race_text(index)}; "
                          f"{where(elites[index])}")
            elite, design = elites[index], designs[index]
            chosen.append(SelectedDesign(string.ascii_uppercase[len(chosen)], pooled.get(tuple(design.heights), design),
                                         meshes[index], mesh_metrics(meshes[index]), reason=reason,
                                         descriptors=(elite["max_height_mm"], elite["sharpness_deg"]),
                                         cell=tuple(elite["cell"]), race=race.totals[index]))
            points.append(_descriptor_point(elite, spans))
            ranked = [i for i in ranked if tuple(elites[i]["cell"]) != tuple(elite["cell"])]
    else:
        ranked = sorted(pool, key=by_screen)
        while ranked and len(chosen) < settings.count:
            if chosen:
                index = ranked.pop(max(range(len(ranked)),
                                       key=lambda k: (spread(ranked[k]), designs[ranked[k]].wilson_low)))
            else:
                index = ranked.pop(0)
            elite, design = elites[index], designs[index]
            mesh, problem = _printable_mesh(design.heights, grid, printer)
            if mesh is None:
                rejected[problem] = rejected.get(problem, 0) + 1
                continue
            estimate = f"{design.successes}/{design.trials} {source}, lower 95% bound {design.wilson_low:.2f}"
            if not chosen:
                reason = (f"highest lower Wilson bound among the {len(pool)} of {len(elites)} elites in the top "
                          f"{settings.top_fraction:.0%} (fitness >= {top:.3f} {source}): {estimate}; "
                          f"{where(elite)}")
            else:
                reason = (f"the top-{settings.top_fraction:.0%} elite farthest from "
                          f"{', '.join(c.label for c in chosen)} in (height, sharpness): {where(elite)}; {estimate}")
            chosen.append(SelectedDesign(string.ascii_uppercase[len(chosen)], pooled.get(tuple(design.heights), design),
                                         mesh, mesh_metrics(mesh), reason=reason,
                                         descriptors=(elite["max_height_mm"], elite["sharpness_deg"]),
                                         cell=tuple(elite["cell"])))
            points.append(_descriptor_point(elite, spans))
            ranked = [i for i in ranked if tuple(elites[i]["cell"]) != tuple(elite["cell"])]
    chosen, baseline = _reevaluate(chosen, grid, settings, evaluate_batch, run_seed)
    chosen, baseline_launches = _launch_reevaluate(chosen, grid, settings, launch_batch, run_seed)
    labels = {d.cell: d.label for d in chosen}
    in_pool = set(pool)
    rows = []
    screened = bool(settings.reevaluate_trials)
    for index, (elite, design) in enumerate(zip(elites, designs)):
        rows.append({"cell_height": elite["cell"][0], "cell_sharpness": elite["cell"][1],
                     "max_height_mm": elite["max_height_mm"], "sharpness_deg": elite["sharpness_deg"],
                     "in_run_fitness": elite["fitness"], "in_run_trials": elite["trials"],
                     "screen_successes": design.successes if screened else "",
                     "screen_trials": design.trials if screened else "",
                     "screen_fitness": design.fitness if screened else "", "top_pool": int(index in in_pool),
                     "label": labels.get(tuple(elite["cell"]), ""), **_race_columns(race, index)})
    return SelectionResult(chosen, settings.count, len(elites), rejected, baseline, threshold, rows,
                           baseline_launches, race)


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


def trait_rows(candidates: typing.Iterable["CandidateRecord"], grid: ProfileGrid,
               ranges: typing.Sequence[typing.Sequence[float]], bins: typing.Sequence[int]
               ) -> typing.List[typing.Dict[str, typing.Any]]:
    """Every evaluation of a run pooled per bin of each descriptor: rows with :data:`TRAIT_COLUMNS`.

    ``ranges`` ``[[0, height mm], [low, high deg]]`` and ``bins`` ``[height bins, sharpness bins]`` (the archive's
    grid). A design's evaluations all fall in its bins; the fitness of a bin is its pooled successes / trials with a
    Wilson 95% interval: how well the designs the optimizer tried with that trait did (not a random sample of
    designs).
    """
    from rollability_ros.core.profile import profile_descriptors

    pooled = [d for d in pool_candidates(candidates) if not is_baseline(d.heights)]
    measured = [profile_descriptors(d.heights, grid).as_tuple() for d in pooled]
    rows = []
    for axis, trait in enumerate(("max_height_mm", "sharpness_deg")):
        edges = np.linspace(ranges[axis][0], ranges[axis][1], int(bins[axis]) + 1)
        # the bin of each design; values below the first edge or above the last fall in the end bins
        where = [int(np.clip(np.searchsorted(edges, m[axis], side="right") - 1, 0, len(edges) - 2))
                 if math.isfinite(m[axis]) else None for m in measured]
        for number, (low, high) in enumerate(zip(edges[:-1], edges[1:])):
            members = [d for d, b in zip(pooled, where) if b == number]
            successes, trials = sum(d.successes for d in members), sum(d.trials for d in members)
            ci_low, ci_high = wilson_interval(successes, trials)
            rows.append({"trait": trait, "bin_low": float(low), "bin_high": float(high), "designs": len(members),
                         "successes": successes, "trials": trials,
                         "fitness": successes / trials if trials else math.nan, "ci_low": ci_low, "ci_high": ci_high})
    return rows


def _descriptor_point(elite, spans):
    """An elite's (height, sharpness) divided by the axis lengths: the plane farthest-point sampling measures in."""
    return np.array([elite["max_height_mm"] / spans[0], elite["sharpness_deg"] / spans[1]])


def table_rows(result: SelectionResult) -> typing.List[typing.Dict[str, typing.Any]]:
    """Rows of Table 3 as dicts with :data:`TABLE_COLUMNS` keys: the baseline first, then the designs.

    The baseline has no profile, so its dimensions are 0 m; its fitness is given only when re-evaluated. Each
    design's gain over the baseline (``gain``, Newcombe 95% ``gain_low`` .. ``gain_high``, ``beats_baseline`` when
    the interval lies above 0) is on fresh robust twin launches when there are any (``gain_source``), else on
    the fresh re-evaluation, else empty.
    """
    rows: typing.List[typing.Dict[str, typing.Any]] = []
    baseline_fitness = _fitness_columns(*result.baseline[:2], "reevaluated") if result.baseline else \
        _fitness_columns(0, 0, "not evaluated")
    rows.append({"configuration": "baseline", "length_m": 0.0, "width_m": 0.0, "max_height_m": 0.0,
                 "printed_mass_g": 0.0,
                 **baseline_fitness, **_in_run_columns(0, 0, math.nan),
                 **_launch_columns(result.baseline_launches), **_gain_columns(None)})
    for design, gain in zip(result.designs, result.gains()):
        reported = _fitness_columns(*design.reported)
        fresh = reported["simulated_fitness"] if design.reevaluation is not None else math.nan
        rows.append({"configuration": design.label, "length_m": design.metrics.length_m,
                     "width_m": design.metrics.width_m, "max_height_m": design.metrics.max_height_m,
                     "printed_mass_g": "" if design.printed_mass_kg is None else design.printed_mass_kg * 1000.0,
                     **reported, **_in_run_columns(design.design.successes, design.design.trials, fresh),
                     **_launch_columns(design.launches), **_gain_columns(gain)})
    return rows


def _launch_columns(launches):
    if launches is None:
        return {"launch_successes": "", "launch_trials": "", "launch_fitness": ""}
    return {"launch_successes": launches[0], "launch_trials": launches[1],
            "launch_fitness": launches[0] / launches[1] if launches[1] else math.nan}


def _gain_columns(gain):
    if gain is None:
        return {"gain_source": "", "gain": "", "gain_low": "", "gain_high": "", "beats_baseline": ""}
    difference, low, high = gain.interval
    return {"gain_source": gain.source, "gain": difference, "gain_low": low, "gain_high": high,
            "beats_baseline": str(bool(gain.beats)).lower()}


def _in_run_columns(successes, trials, fresh_fitness):
    """The in-run (pooled log) estimate of a design, its Wilson interval and the selection bias: in-run minus
    fresh fitness (NaN without a fresh re-evaluation). A design picked for its high logged fitness is picked
    partly for its luck, so the bias is expected to be positive."""
    low, high = wilson_interval(successes, trials)
    in_run = successes / trials if trials else math.nan
    return {"in_run_fitness": in_run, "in_run_ci_low": low, "in_run_ci_high": high, "in_run_successes": successes,
            "in_run_trials": trials, "selection_bias": in_run - fresh_fitness}


def _fitness_columns(successes, trials, source):
    low, high = wilson_interval(successes, trials)
    return {"simulated_fitness": successes / trials if trials else math.nan, "ci_low": low, "ci_high": high,
            "successes": successes, "trials": trials, "fitness_source": source}


def designs_document(result: SelectionResult, grid: ProfileGrid, run_id: str,
                     mesh_units: str = "mm") -> typing.Dict[str, typing.Any]:
    """The ``designs.yaml`` content: a ROS 2 parameter file with namespace ``designs`` (heights per label).

    Each design carries its gain over the bare robot (``gain_over_baseline``: what it was measured on, the
    difference, Newcombe's 95% interval) and ``beats_baseline`` (the interval lies above 0) when a fresh
    comparison was made; a design that does not beat the bare robot is exported for inspection, marked so."""
    body: typing.Dict[str, typing.Any] = {
        "run_id": run_id, "labels": [d.label for d in result.designs],
        "grid": {"rows": grid.rows, "cols": grid.cols, "length_m": grid.length_m, "width_m": grid.width_m,
                 "height_min": grid.height_min, "height_max": grid.height_max, "unit_m": grid.unit_m}}
    if result.baseline_launches is not None:
        body["baseline_launches"] = {"successes": result.baseline_launches[0], "trials": result.baseline_launches[1]}
    race = result.race
    if race is not None:
        body["launch_race"] = {"rounds": [r["trials"] for r in race.rounds], "designs_raced": len(race.totals),
                               "survivors": len(race.survivors), "launches_spent": race.trials_spent}
        if race.reference is not None:   # the bare robot runs every round of a selection's race
            body["launch_race"]["baseline"] = {"successes": race.reference[0], "trials": race.reference[1]}
    for design, gain in zip(result.designs, result.gains()):
        successes, trials, source = design.reported
        body[design.label] = {"heights": [float(h) for h in design.design.heights],
                              "mesh_file": f"mesh_{design.label}.stl", "mesh_units": mesh_units,
                              "fitness": successes / trials,
                              "successes": successes, "trials": trials, "fitness_source": source,
                              "why": design.reason}
        if design.descriptors is not None:
            body[design.label].update(max_height_mm=float(design.descriptors[0]),
                                      sharpness_deg=float(design.descriptors[1]),
                                      archive_cell=[int(i) for i in design.cell])
        if design.launches is not None:
            body[design.label]["launches"] = {"successes": design.launches[0], "trials": design.launches[1]}
        if gain is not None:
            difference, low, high = gain.interval
            body[design.label]["gain_over_baseline"] = {"measured_on": GAIN_SOURCES[gain.source],
                                                        "difference": float(difference),
                                                        "newcombe_95": [float(low), float(high)]}
            body[design.label]["beats_baseline"] = bool(gain.beats)
    return {"/**": {"ros__parameters": {"designs": body}}}


def record_selection(store: "Store", run_id: str, result: SelectionResult, folder: str = "") -> None:
    """Add ``sim_fitness`` ({configuration: fitness}) and ``geometry`` (Table 3 rows of the designs) to the run's
    info in ``store``, the keys ``rollability report`` reads; the baseline has no geometry row (no profile).
    ``folder`` is the design set written; an earlier selection's entries move to ``earlier_selections``."""
    rows = table_rows(result)
    described = store.run_info(run_id) or {"kind": "optimization", "info": {}}
    info = dict(described["info"])
    if "selection" in info:   # append-only: the earlier design set's numbers stay in the run's record
        earlier = {key: info[key] for key in ("sim_fitness", "geometry", "table3", "selection") if key in info}
        info["earlier_selections"] = [*info.get("earlier_selections", []), earlier]
    info["sim_fitness"] = {r["configuration"]: r["simulated_fitness"] for r in rows if r["trials"]}
    info["geometry"] = [{k: r[k] for k in TABLE_COLUMNS[:5]} for r in rows if r["configuration"] != "baseline"]
    info["table3"] = rows   # fresh and in-run fitness side by side, for the report's headline
    info["selection"] = {"why": {d.label: d.reason for d in result.designs},
                         "no_design_helps": result.no_design_helps(),
                         "archive_cells": {d.label: list(d.cell) for d in result.designs if d.cell is not None},
                         "top_threshold": result.top_threshold, "folder": os.path.basename(folder)}
    store.set_run_info(run_id, described["kind"], info)


def _write_csv(path, columns, rows):
    table = io.StringIO()
    writer = csv.DictWriter(table, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})
    atomic_write_bytes(path, table.getvalue().encode("utf-8"))


def design_set_folders(run_dir: str) -> typing.List[str]:
    """The run's design sets in the order they were written: ``designs/``, then ``designs-2/``, ``designs-3/``, ..."""
    if not os.path.isdir(run_dir):
        return []
    pattern = re.compile(re.escape(DESIGNS_DIRNAME) + r"(-[1-9]\d*)?")
    found = [name for name in os.listdir(run_dir)
             if pattern.fullmatch(name) and os.path.isdir(os.path.join(run_dir, name))]
    return [os.path.join(run_dir, name) for name in sorted(found, key=lambda n: (len(n), n))]


def next_design_folder(run_dir: str) -> str:
    """The folder a new selection of the run writes: ``designs/`` for the first, else the next free
    ``designs-<n>/``. A written design set is never rewritten (docs/optimization.md, "Design sets are append-only")."""
    existing = design_set_folders(run_dir)
    if not existing:
        return os.path.join(run_dir, DESIGNS_DIRNAME)
    number = len(existing) + 1
    while os.path.exists(os.path.join(run_dir, f"{DESIGNS_DIRNAME}-{number}")):
        number += 1
    return os.path.join(run_dir, f"{DESIGNS_DIRNAME}-{number}")


def write_selection(run_dir: str, result: SelectionResult, grid: ProfileGrid, run_id: str,
                    mesh_units: str = "mm", traits: typing.Optional[typing.List[typing.Dict[str, typing.Any]]] = None
                    ) -> str:
    """Write the STL (in ``mesh_units``) and 3MF files, ``table3.csv`` and ``designs.yaml`` into a new design set
    folder (:func:`next_design_folder`: ``<run_dir>/designs/``, or ``designs-<n>/`` when the run has one) and, for a
    quality-diversity run, ``archive.csv`` and the ``traits`` rows as ``traits.csv``; return that folder.

    Append-only: an earlier design set (which a campaign's stored outcomes may refer to by label, and whose meshes
    may have been printed) is never touched. The set is written into a hidden temporary folder and renamed into
    place only when complete, so a killed selection leaves no half-written set.
    """
    folder = next_design_folder(run_dir)
    partial = os.path.join(run_dir, f".{os.path.basename(folder)}.partial")
    if os.path.isdir(partial):   # left by a selection killed before its rename: never referenced by anything
        shutil.rmtree(partial)
    os.makedirs(partial)
    for design in result.designs:
        export_mesh(design.mesh, os.path.join(partial, f"mesh_{design.label}.stl"), mesh_units)
        export_mesh(design.mesh, os.path.join(partial, f"mesh_{design.label}.3mf"))
    _write_csv(os.path.join(partial, "table3.csv"), TABLE_COLUMNS, table_rows(result))
    for name, columns, rows in (("archive.csv", ARCHIVE_COLUMNS, result.archive),
                                ("traits.csv", TRAIT_COLUMNS, traits)):
        if rows is not None:
            _write_csv(os.path.join(partial, name), columns, rows)
    text = yaml.safe_dump(designs_document(result, grid, run_id, mesh_units), sort_keys=False)
    atomic_write_bytes(os.path.join(partial, "designs.yaml"), text.encode("utf-8"))
    os.rename(partial, folder)   # fails rather than replace: a folder that appeared meanwhile is kept
    return folder


def select_run(store: "Store", run_id: str, run_dir: str, grid: ProfileGrid, printer: PrinterSpec,
               settings: SelectionSettings, evaluate_batch: typing.Optional[BatchEvaluator] = None, run_seed: int = 1,
               launch_batch: typing.Optional[LaunchEvaluator] = None,
               weigh: typing.Optional[typing.Callable[[Mesh], float]] = None
               ) -> typing.Tuple[SelectionResult, str]:
    """Select the designs of run ``run_id`` from its logged candidates, record them in ``store`` (run info:
    simulated fitness and geometry) and write a new design set (``<run_dir>/designs/`` or ``designs-<n>/``);
    return ``(SelectionResult, folder)``. ``weigh(mesh) -> kg`` gives each design's printed mass for Table 3 (the
    robot's ``profile_body(mesh).mass_kg``: what the twin mounts); without it the column is empty.

    The one selection flow of ``rollability select`` and the optimizer node: from the archive when the run has one
    (a quality-diversity run), else from the ranked log. Raises ``ValueError`` when the run
    has no evaluated candidates.
    """
    candidates = store.candidates(run_id=run_id)
    if not candidates:
        raise ValueError(f"run {run_id} in {run_dir} has no evaluated candidates yet")
    archive = ((store.run_info(run_id) or {}).get("info") or {}).get("archive")
    traits = None
    if archive:
        result = select_from_archive(archive, candidates, grid, printer, settings, evaluate_batch, run_seed,
                                     launch_batch)
        traits = trait_rows(candidates, grid, archive["ranges"], archive["dims"])
    else:
        result = select_designs(candidates, grid, printer, settings, evaluate_batch, run_seed, launch_batch)
    if weigh is not None:
        result = dataclasses.replace(result, designs=[dataclasses.replace(design, printed_mass_kg=weigh(design.mesh))
                                                      for design in result.designs])
    folder = write_selection(run_dir, result, grid, run_id, settings.mesh_units, traits)
    record_selection(store, run_id, result, folder)
    return result, folder
