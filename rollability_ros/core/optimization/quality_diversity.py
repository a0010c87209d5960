"""Quality diversity over profiles: CMA-MAE (pyribs) filling a map of maximum height x sharpness with fit designs.

One CMA-ES run converges to one basin, so designs picked from its log are neighbours. CMA-MAE (Fontaine and
Nikolaidis 2023, pyribs' ``EvolutionStrategyEmitter`` with the improvement ranker on a ``GridArchive`` with a
learning rate) instead keeps an *archive*: a grid over the two behaviour descriptors of
:mod:`rollability_ros.core.profile.descriptors` (maximum height, mm; sharpness, deg), each cell holding the best
design found with those traits (its *elite*). Emitters are CMA-ES instances ranked by how much a candidate improves
its cell, so the search spreads across the map while it climbs fitness; A/B/C are then chosen from fit elites in
different cells (``selection.select_from_archive``).

:class:`QualityDiversityOptimizer` speaks the protocol of :class:`~rollability_ros.core.optimization.cmaes.
ProfileOptimizer` (ask / tell / incumbent re-evaluation / stop / result / state_dict), so the same
:class:`~rollability_ros.core.optimization.optimization_run.OptimizationRun`, evaluators (any objective), node,
store and checkpoint run it (``optimizer.method: cma_mae``). Per generation it asks ``popsize`` candidates, split
over the emitters, so an evaluation budget means the same as for CMA-ES.

Choices
-------
* The emitters search an unbounded space that pycma's ``BoundTransform`` maps into [height_min, ceiling] (the same
  boundary handling as the CMA-ES method); pyribs' own bound handling resamples, which never ends once many
  vertices sit at a bound. The archives store each elite's heights beside its search point.
* Height-stratified emitters: emitter ``k`` of ``K`` searches under its own height ceiling, stepping evenly from the
  height bound (the first emitter) down to ``lowest_ceiling`` of it (the last), and starts from the run's initial
  mean scaled under that ceiling. Fitness tends to grow with height on this problem (the report measures it), so
  without ceilings every emitter drifts to the tallest cells and the lower rows of the map only hold the first,
  unoptimized visitors; with them each height band gets optimization effort of its own, and A/B/C can come from
  different heights while staying among the fittest. All start with ``quality_diversity.sigma0`` (default: the
  optimizer's); an emitter whose CMA-ES has
  converged restarts from a random elite (pyribs' ``basic`` rule).
* Two archives: the CMA-MAE archive (thresholds annealed by ``learning_rate``, starting at ``threshold_min``) drives
  the emitters; a plain elitist *result archive* keeps each cell's best evaluated design, and is the map that is
  stored, reported and selected from.
* Fitness is a noisy binomial estimate, so an elite is partly there by luck; selection re-evaluates the chosen
  designs on fresh trials and reports both numbers.
* The checkpoint holds plain data: the tells. pyribs' emitters and archives are seeded from ``optimizer.seed`` and
  deterministic given what they are told, so :meth:`QualityDiversityOptimizer.from_state_dict` replays the tells and
  checks the replay against the saved archive digest; nothing is pickled.
"""
import functools
import hashlib
import re
import time
import typing
import warnings

import numpy as np
import numpy.typing as npt

from rollability_ros.core import config
from rollability_ros.core.optional import require
from rollability_ros.core.optimization.cmaes import check_search_space
from rollability_ros.core.optimization.optimizer_contract import (IncumbentOptimizer, OptimizerResult,
                                                                  OptimizerSettings, QualityDiversitySettings,
                                                                  RunSettings)
from rollability_ros.core.profile import ProfileGrid, height_bound_mm, profile_descriptors

#: The archive's behaviour descriptors, in measure order, with their units.
DESCRIPTOR_NAMES = ("max_height_mm", "sharpness_deg")
#: The start of pyribs' warning (``Scheduler._add_to_archives``) that a tell left the CMA-MAE archive empty: expected
#: while no design told so far scored above ``threshold_min`` (a hard objective can score whole generations 0; the
#: emitters then restart from their start: ``_emitter_class``), so it is silenced for those tells only. The result
#: archive's (no threshold: never left empty by a tell) still warns.
EMPTY_ARCHIVE_WARNING = "`archive` was empty before adding solutions"


def emitter_ceilings(emitters: int, lowest_ceiling: float) -> list[float]:
    """Each emitter's height ceiling as a fraction of the height range: evenly from 1 down to ``lowest_ceiling``."""
    if emitters == 1:
        return [1.0]
    return [1.0 - k * (1.0 - lowest_ceiling) / (emitters - 1) for k in range(emitters)]


def emitter_batch_sizes(popsize: int, emitters: int) -> list[int]:
    """Candidates per emitter: ``popsize`` split as evenly as possible, the first emitters taking the remainder."""
    return [popsize // emitters + (1 if k < popsize % emitters else 0) for k in range(emitters)]


@functools.cache
def _emitter_class():
    """pyribs' ``EvolutionStrategyEmitter``, restarting from its own start point while the archive has no elite.

    pyribs restarts a converged emitter from an elite sampled from the archive. While every design told so far
    scored at or below ``threshold_min`` (a hard objective can score whole generations 0), the archive is empty
    and that sampling raised IndexError; the emitter then goes back to where it started instead.
    """
    from ribs.emitters import EvolutionStrategyEmitter

    class StartRestartEmitter(EvolutionStrategyEmitter):
        def tell(self, solution: npt.ArrayLike, objective: npt.ArrayLike, measures: npt.ArrayLike,
                 add_info: dict[str, np.ndarray], **fields: npt.ArrayLike) -> None:
            """pyribs' ``tell`` of a batch: ``solution`` (batch, solution_dim), ``objective`` (batch,),
            ``measures`` (batch, 2); with an empty archive a restart goes back to the emitter's ``x0``."""
            archive = self.archive
            if not archive.empty:
                return super().tell(solution, objective, measures, add_info, **fields)
            start = np.asarray(self.x0, dtype=np.float64)
            # an instance attribute shadowing the method for this one call (pyribs types it as a method)
            setattr(archive, "sample_elites", lambda n: {"solution": np.repeat(start[None, :], n, axis=0)})
            try:
                return super().tell(solution, objective, measures, add_info, **fields)
            finally:
                del archive.sample_elites

    return StartRestartEmitter


class QualityDiversityOptimizer(IncumbentOptimizer):
    """CMA-MAE over ``grid.n_variables`` heights in the grid's bounds; see the module docstring.

    Parameters
    ----------
    settings : OptimizerSettings
        ``popsize`` (candidates per generation over all emitters), ``sigma0``, ``seed``, stop criteria,
        ``reevaluate_incumbent``.
    qd_settings : QualityDiversitySettings
    grid : ProfileGrid
        Bounds and the descriptors' geometry.
    clock : callable, optional
    initial_mean : array_like, optional
        ``(n_variables,)`` start of the first emitter (default: the paper's random mean).
    """

    @classmethod
    def check_settings(cls, settings: "RunSettings") -> None:
        """The ``optimizer`` section, and the ``quality_diversity`` section against the popsize."""
        config.check_settings(settings.optimizer, "optimizer")
        config.check_settings(settings.quality_diversity, "quality_diversity")
        settings.quality_diversity.validate(settings.optimizer.popsize)

    @classmethod
    def create(cls, grid: ProfileGrid, settings: "RunSettings", clock: typing.Callable[[], float],
               initial_mean: npt.ArrayLike | None = None,
               state: dict[str, typing.Any] | None = None) -> "QualityDiversityOptimizer":
        """``optimizer.method: cma_mae``: CMA-MAE over the grid with the ``optimizer`` and ``quality_diversity``
        sections; ``initial_mean`` ``(grid.n_variables,)`` simulation units, None: the paper's random mean."""
        config.check_settings(settings.optimizer, "optimizer")
        if state is None:
            return cls(settings.optimizer, settings.quality_diversity, grid, clock, initial_mean)
        return cls.from_state_dict(state, settings.optimizer, settings.quality_diversity, grid, clock, initial_mean)

    def __init__(self, settings, qd_settings, grid, clock=time.monotonic, initial_mean=None):
        require("ribs", feature="quality-diversity optimization (optimizer.method cma_mae)")
        require("cma", feature="quality-diversity optimization (optimizer.method cma_mae)")
        from cma.boundary_handler import BoundTransform
        from ribs.archives import GridArchive
        from ribs.schedulers import Scheduler

        config.check_settings(settings, "optimizer")
        config.check_settings(qd_settings, "quality_diversity")
        qd_settings.validate(settings.popsize)
        self.qd_settings = qd_settings
        self.grid = grid
        self.n_variables, self.lower, self.upper, self.initial_mean = check_search_space(
            grid.n_variables, settings, grid.height_min, grid.height_max, initial_mean)
        seeds = np.random.SeedSequence([int(settings.seed), 0x51D]).generate_state(qd_settings.emitters + 2)
        dims = [qd_settings.height_cells, qd_settings.sharpness_cells]
        self.ranges = [(0.0, height_bound_mm(grid)),
                       (qd_settings.sharpness_min_deg, qd_settings.sharpness_max_deg)]
        extra: typing.Dict[str, typing.Any] = {"trials": ((), np.int64), "generation": ((), np.int64),
                 "heights": ((self.n_variables,), np.float64)}
        self.archive = GridArchive(solution_dim=self.n_variables, dims=dims, ranges=self.ranges,
                                   learning_rate=qd_settings.learning_rate, threshold_min=qd_settings.threshold_min,
                                   seed=int(seeds[0]), extra_fields=extra)
        self.result_archive = GridArchive(solution_dim=self.n_variables, dims=dims, ranges=self.ranges,
                                          seed=int(seeds[1]), extra_fields=extra)
        self.emitters, self._bounds = [], []
        self.ceilings = [self.lower + (self.upper - self.lower) * fraction
                         for fraction in emitter_ceilings(qd_settings.emitters, qd_settings.lowest_ceiling)]
        for k, batch_size in enumerate(emitter_batch_sizes(settings.popsize, qd_settings.emitters)):
            bounds = BoundTransform([self.lower, self.ceilings[k]])
            start = self.lower + (self.initial_mean - self.lower) * (self.ceilings[k] - self.lower) / (
                self.upper - self.lower)
            self.emitters.append(_emitter_class()(
                self.archive, x0=bounds.inverse(start), sigma0=qd_settings.sigma0 or settings.sigma0, ranker="imp",
                selection_rule="mu", restart_rule="basic", batch_size=batch_size, seed=int(seeds[2 + k])))
            self._bounds.extend([bounds] * batch_size)
        self.scheduler = Scheduler(self.archive, self.emitters, result_archive=self.result_archive)
        self._init_bookkeeping(settings, clock)

    def _ask(self):
        # candidate i comes from the emitter whose batch holds i (the scheduler asks them in order)
        return [np.asarray(bounds.transform(np.asarray(solution, dtype=np.float64)), dtype=np.float64)
                for bounds, solution in zip(self._bounds, self.scheduler.ask())]

    def _tell(self, population, fitness, trials):
        measures = np.array([profile_descriptors(heights, self.grid).as_tuple()
                             for heights in population], dtype=np.float64)
        with warnings.catch_warnings():
            if self.archive.empty:   # no design scored yet: an archive still empty after this tell is expected
                warnings.filterwarnings("ignore", message=re.escape(EMPTY_ARCHIVE_WARNING), category=UserWarning)
            self.scheduler.tell(np.asarray(fitness, dtype=np.float64), measures,
                                trials=np.asarray(trials, dtype=np.int64), heights=np.asarray(population),
                                generation=np.full(len(population), self.generation, dtype=np.int64))

    def race_reference(self, heights: npt.ArrayLike) -> tuple[int, int] | None:
        """``(successes, trials)`` of the elite of the result-archive cell ``heights`` ``(grid.n_variables,)``
        (simulation units) falls in (sequential racing
        against its cell's elite); None for an empty cell (any candidate would fill it). The cell follows from the
        geometry alone and the archive is the state between generations, so a resumed generation races alike."""
        measures = np.array([profile_descriptors(heights, self.grid).as_tuple()], dtype=np.float64)
        occupied, data = self.result_archive.retrieve(measures)
        if not bool(occupied[0]):
            return None
        trials = int(data["trials"][0])
        return int(round(float(data["objective"][0]) * trials)), trials

    # --- state ----------------------------------------------------------------------------------------------------
    @property
    def sigma(self) -> float:
        """Mean CMA-ES step size over the emitters, simulation units."""
        return float(np.mean([emitter._opt.sigma for emitter in self.emitters]))

    @property
    def result(self) -> OptimizerResult:
        """The :class:`OptimizerResult` so far (``mean``: the heights of the first emitter's CMA-ES mean)."""
        mean = np.asarray(self._bounds[0].transform(np.asarray(self.emitters[0]._opt.mean, dtype=np.float64)),
                          dtype=np.float64)
        return OptimizerResult(best=self._incumbent, generations=self.generation, evaluations=self.evaluations,
                               elapsed_s=self.elapsed_s, mean=mean,
                               sigma=self.sigma, stop=self.stop())

    def archive_rows(self) -> typing.List[dict]:
        """The result archive's elites, one dict per filled cell in cell order: ``cell`` [height index, sharpness
        index], ``heights`` (simulation units), ``fitness``, ``trials``, ``generation`` (0-based index of the
        generation that found it), ``max_height_mm``, ``sharpness_deg``."""
        data = self.result_archive.data()
        rows = []
        for index, heights, fitness, measures, trials, generation in sorted(zip(
                data["index"], data["heights"], data["objective"], data["measures"], data["trials"],
                data["generation"]), key=lambda row: int(row[0])):
            cell = [int(i) for i in self.result_archive.int_to_grid_index([index])[0]]
            rows.append({"cell": cell, "heights": [float(h) for h in heights], "fitness": float(fitness),
                         "trials": int(trials), "generation": int(generation),
                         DESCRIPTOR_NAMES[0]: float(measures[0]), DESCRIPTOR_NAMES[1]: float(measures[1])})
        return rows

    def archive_summary(self) -> dict:
        """``{"dims", "ranges", "descriptors", "filled_cells", "coverage", "qd_score"}`` of the result archive
        (QD score: the sum of elite fitnesses; coverage: filled cells / cells)."""
        stats = self.result_archive.stats
        cells = self.qd_settings.height_cells * self.qd_settings.sharpness_cells
        return {"dims": [self.qd_settings.height_cells, self.qd_settings.sharpness_cells],
                "ranges": [list(r) for r in self.ranges], "descriptors": list(DESCRIPTOR_NAMES),
                "filled_cells": int(stats.num_elites), "coverage": float(stats.num_elites) / cells,
                "qd_score": float(stats.qd_score)}

    def _archive_digest(self, rows=None):
        rows = self.archive_rows() if rows is None else rows
        text = repr([(r["cell"], r["heights"], r["fitness"]) for r in rows])
        return hashlib.sha256(text.encode("utf-8")).hexdigest()

    def state_dict(self) -> dict[str, typing.Any]:
        """Plain-data state between generations: the tells (replayed by :meth:`from_state_dict`), the initial
        mean, and the result archive's digest and size as a check of the replay."""
        rows = self.archive_rows()
        return {**self._bookkeeping_state(), "method": "cma_mae", "initial_mean": self.initial_mean.tolist(),
                "archive_sha256": self._archive_digest(rows), "elites": len(rows)}

    @classmethod
    def from_state_dict(cls, state: dict[str, typing.Any], settings: OptimizerSettings,
                        qd_settings: QualityDiversitySettings, grid: ProfileGrid,
                        clock: typing.Callable[[], float] = time.monotonic,
                        initial_mean: npt.ArrayLike | None = None) -> "QualityDiversityOptimizer":
        """Rebuild an optimizer saved by :meth:`state_dict`; ValueError when it belongs to other settings or code
        (``initial_mean`` ``(grid.n_variables,)`` as for :meth:`create`)."""
        if state.get("method") != "cma_mae":
            raise ValueError("saved optimizer state is not a cma_mae state (optimizer.method changed?)")
        optimizer = cls(settings, qd_settings, grid, clock, initial_mean)
        if not np.array_equal(optimizer.initial_mean, np.asarray(state["initial_mean"], dtype=np.float64)):
            raise ValueError("saved optimizer state does not match these settings (different initial mean)")
        optimizer._replay(state)
        if optimizer._archive_digest() != state["archive_sha256"]:
            raise ValueError("replaying the saved tells does not reproduce the saved archive: the checkpoint belongs "
                             "to other settings or code")
        optimizer._resume_clock(state)
        return optimizer
