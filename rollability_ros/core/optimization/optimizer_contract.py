"""The optimiser contract: what an optimizer method (``optimizer.method``) implements, :class:`IncumbentOptimizer`,
with the bookkeeping every method shares; the :data:`OPTIMIZER_METHODS` table; and the types the contract is written
in: the run's typed settings (:class:`RunSettings`: the ``optimizer`` section, :class:`OptimizerSettings`, the
quality-diversity section, :class:`QualityDiversitySettings`, the start-point screen and the printer), the
estimates and results a method reports, and the seed streams (:func:`derive_seed`).

The methods live beside it, one module each: ``cmaes`` (the paper's CMA-ES,
:class:`~rollability_ros.core.optimization.cmaes.ProfileOptimizer`) and ``quality_diversity`` (CMA-MAE). Adding a method is one module with an
:class:`IncumbentOptimizer` subclass plus one entry in :data:`OPTIMIZER_METHODS`.
"""
import abc
import copy
import dataclasses
import time
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core import config
from rollability_ros.core.profile import PrinterSpec, ProfileGrid, simple_profiles
from rollability_ros.core.registry import Registry
from rollability_ros.core.sim import ScreenSettings

#: Seed streams of :func:`derive_seed`: population evaluations, incumbent re-evaluations, design selection.
STREAM_POPULATION = 0
STREAM_REEVALUATION = 1
STREAM_SELECTION = 2
STREAM_RACE = 3
STREAM_START = 4

#: What ranks the candidate start means (``optimizer.initial_mean_measure``).
INITIAL_MEAN_MEASURES = ("stable_poses", "objective")


def derive_seed(run_seed: int, generation: int, stream: int, index: int = 0) -> int:
    """Return a disturbance seed (int in [0, 2**32)) for one evaluation, independent across its keys.

    ``stream`` is one of the ``STREAM_*`` constants; ``index`` is the candidate index (independent-seed mode)
    or 0 (common random numbers: the whole generation shares one seed).
    """
    sequence = np.random.SeedSequence([int(run_seed), int(generation), int(stream), int(index)])
    return int(sequence.generate_state(1, dtype=np.uint32)[0])


@dataclasses.dataclass
class OptimizerSettings:
    """The ``optimizer`` parameter namespace (``config/optimizer.yaml``, ``config/paper.yaml``).

    Heights and ``sigma0`` are in simulation units (the geometry grid's ``height_min``/``height_max`` give the
    bounds). A cap of 0 disables that stop criterion; ``target_fitness`` above 1 disables the target.
    """

    method: str = dataclasses.field(default="cmaes", metadata={
        "description": "search method: cmaes (one CMA-ES, the paper's) or cma_mae (quality diversity over maximum "
                       "height x sharpness, section quality_diversity; needs the ribs package)"})
    popsize: int = dataclasses.field(default=12, metadata={
        "description": "candidates per CMA-ES generation (count; paper 12)", "range": (2, 100000)})
    sigma0: float = dataclasses.field(default=0.02, metadata={
        "description": "initial CMA-ES step size, simulation units of vertex height (paper 0.02)",
        "range": (0.0, 100.0), "exclusive": "low"})
    seed: int = dataclasses.field(default=1, metadata={
        "description": "seed of pycma, the random initial mean and the disturbance seeds (integer >= 1)",
        "range": (1, 2147483647)})
    trials: int = dataclasses.field(default=60, metadata={
        "description": "disturbance trials per candidate evaluation (count; paper 60)", "range": (1, 10000000)})
    max_generations: int = dataclasses.field(default=500, metadata={
        "description": "stop after this many CMA-ES generations (count; 0 = no cap; paper 500)",
        "range": (0, 2147483647)})
    target_fitness: float = dataclasses.field(default=1.0, metadata={
        "description": "stop when the best-so-far fitness (upright trials / trials) reaches this; above 1 never",
        "range": (0.0, 2.0), "exclusive": "low"})
    stagnation_generations: int = dataclasses.field(default=0, metadata={
        "description": "stop after this many generations without a new best design (count; 0 = never)",
        "range": (0, 2147483647)})
    max_evaluations: int = dataclasses.field(default=0, metadata={
        "description": "stop after this many profile evaluations, population and re-evaluations (count; 0 = no cap)",
        "range": (0, 2147483647)})
    max_wall_time_s: float = dataclasses.field(default=0.0, metadata={
        "description": "stop after this much optimization wall time summed over resumes, s (0 = no cap)",
        "range": (0.0, 1000000000.0)})
    common_random_numbers: bool = dataclasses.field(default=True, metadata={
        "description": "true: all candidates of a generation share one disturbance seed (fairer ranking); false: one "
                       "seed each"})
    reevaluate_incumbent: bool = dataclasses.field(default=True, metadata={
        "description": "true: re-evaluate the best-so-far design with a fresh seed each generation and pool the "
                       "trials"})
    output_dir: str = dataclasses.field(default="runs", metadata={
        "description": "folder of run directories <output_dir>/<run_id>/, relative to the working directory"})
    race_looks: typing.List[int] = dataclasses.field(default_factory=lambda: [0], metadata={
        "description": "sequential racing: cumulative trial counts at which a candidate is looked at before its "
                       "full trials; at each look it stops when clearly worse than the incumbent (CMA-ES) or its "
                       "cell's elite (CMA-MAE), an exact one-sided binomial test at level race_alpha / looks "
                       "(strictly increasing counts in [1, trials); [0] = no racing, every candidate gets all trials)"})
    race_alpha: float = dataclasses.field(default=0.1, metadata={
        "description": "racing: at most this chance, over all looks, of stopping a candidate at least as good as "
                       "the bar (the lower 95% bound of the incumbent's or elite's estimate) (probability)",
        "range": (0.0, 1.0), "exclusive": "both"})
    race_survivors: int = dataclasses.field(default=0, metadata={
        "description": "racing by successive halving: after each look at most this many candidates go on to their "
                       "full trials, the best by pooled estimate over the incumbent (CMA-ES) or their cell's elite "
                       "(CMA-MAE); the others are told their estimate so far (count; needs race_looks; 0 = off)",
        "range": (0, 100000)})
    initial_mean_screen: int = dataclasses.field(default=0, metadata={
        "description": "random CMA-ES start means screened by the quasi-static stable-pose screen; the best is used "
                       "(count; 0 = the paper's one random mean)", "range": (0, 10000)})
    initial_mean_measure: str = dataclasses.field(default="stable_poses", metadata={
        "description": "what ranks the candidate start means when initial_mean_screen > 0: stable_poses (the "
                       "quasi-static stable-pose screen) or objective (one evaluation of each on the search's own "
                       "measure, optimizer.trials trials on one common seed; the most successes starts)"})
    initial_mean_shapes: bool = dataclasses.field(default=False, metadata={
        "description": "true: the 27 simple parametric profiles (flat tops, ridges, pyramids; "
                       "geometry.simple_profiles) are candidate start means beside the random ones when the "
                       "start means are ranked (initial_mean_screen > 0; 0 starts from the paper's one random mean "
                       "whatever this says)"})

    @property
    def race_stages(self) -> typing.Optional[typing.List[int]]:
        """Trials of each racing stage (:func:`racing.sequential_stages`), or None without racing; ValueError for
        looks that are not strictly increasing counts in [1, trials)."""
        looks = [int(n) for n in self.race_looks]
        if looks in ([], [0]):
            return None
        from rollability_ros.core.optimization.racing import sequential_stages

        return sequential_stages(looks, self.trials)

    @property
    def race_looks_used(self) -> typing.List[int]:
        """The looks of racing ([] without racing)."""
        return [] if self.race_stages is None else [int(n) for n in self.race_looks]

    def validate(self) -> None:
        """Raise ``ValueError`` for a rule that spans fields (each number's range is declared in its metadata and
        checked by :func:`~rollability_ros.core.config.check_settings`)."""
        OPTIMIZER_METHODS.check(self.method)
        if self.race_survivors and self.race_stages is None:
            raise ValueError("race_survivors needs race_looks (the looks after which the candidates are halved)")
        if self.race_survivors >= self.popsize:
            raise ValueError(f"race_survivors must be below popsize {self.popsize} (0 = no halving), got "
                             f"{self.race_survivors}")
        if self.race_stages is not None and not self.common_random_numbers:
            raise ValueError("race_looks needs common_random_numbers: true (every stage runs the candidates still "
                             "going on one common seed)")
        if not self.output_dir:
            raise ValueError("output_dir must be a non-empty path")
        if self.initial_mean_measure not in INITIAL_MEAN_MEASURES:
            raise ValueError(f"initial_mean_measure must be one of {', '.join(INITIAL_MEAN_MEASURES)}, got "
                             f"{self.initial_mean_measure!r}")


@dataclasses.dataclass
class QualityDiversitySettings:
    """The ``quality_diversity`` parameter namespace: the archive's grid and CMA-MAE's settings."""

    height_cells: int = dataclasses.field(default=10, metadata={
        "description": "archive cells along the maximum-height descriptor, from 0 to the grid's tallest profile "
                       "(height_max x unit_m) (count)", "range": (1, 1000)})
    sharpness_cells: int = dataclasses.field(default=6, metadata={
        "description": "archive cells along the sharpness descriptor (length-weighted mean ridge angle of the hull) "
                       "(count)", "range": (1, 1000)})
    sharpness_min_deg: float = dataclasses.field(default=0.0, metadata={
        "description": "lower end of the sharpness axis, deg (lower values fall in the first cell)",
        "range": (0.0, 180.0)})
    sharpness_max_deg: float = dataclasses.field(default=90.0, metadata={
        "description": "upper end of the sharpness axis, deg (box edges measure 90; higher fall in the last cell)",
        "range": (0.0, 180.0)})
    emitters: int = dataclasses.field(default=3, metadata={
        "description": "CMA-ES emitters sharing the optimizer.popsize candidates of a generation (count; each gets "
                       "at least 2)", "range": (1, 1000)})
    lowest_ceiling: float = dataclasses.field(default=0.5, metadata={
        "description": "height ceiling of the last emitter as a fraction of the height bound; the emitters' ceilings "
                       "step evenly from the bound (first emitter) down to it (fraction, (0, 1]; 1 = no ceilings)",
        "range": (0.0, 1.0), "exclusive": "low"})
    sigma0: float = dataclasses.field(default=0.0, metadata={
        "description": "initial step size of every emitter's CMA-ES, simulation units of vertex height (0 = "
                       "optimizer.sigma0)", "range": (0.0, 100.0)})
    learning_rate: float = dataclasses.field(default=0.01, metadata={
        "description": "CMA-MAE archive learning rate alpha (fraction, (0, 1]; 1 = CMA-ME, small = more "
                       "exploration first)", "range": (0.0, 1.0), "exclusive": "low"})
    threshold_min: float = dataclasses.field(default=0.0, metadata={
        "description": "fitness threshold of an empty cell for CMA-MAE (fitness units, upright trials / trials)",
        "range": (-1.0, 1.0), "exclusive": "high"})

    def validate(self, popsize: int | None = None) -> None:
        """Raise ``ValueError`` for a rule that spans fields (``popsize``: the optimizer's, to split; each number's
        range is declared in its metadata and checked by :func:`~rollability_ros.core.config.check_settings`)."""
        if not self.sharpness_min_deg < self.sharpness_max_deg:
            raise ValueError(f"need sharpness_min_deg < sharpness_max_deg, got [{self.sharpness_min_deg}, "
                             f"{self.sharpness_max_deg}]")
        if popsize is not None and popsize < 2 * self.emitters:
            raise ValueError(f"optimizer.popsize {popsize} cannot give {self.emitters} emitters 2 candidates each; "
                             "lower quality_diversity.emitters or raise optimizer.popsize")


@dataclasses.dataclass(frozen=True)
class RunSettings:
    """The typed settings of one optimization run, each field a namespace of its flat parameters: parsed once
    (:func:`run_settings`, or built by the node from the sections it declared) and handed down to the method, the
    start-point screen and the printability check, none of which reads the flat dict."""

    optimizer: OptimizerSettings = dataclasses.field(default_factory=OptimizerSettings)
    quality_diversity: QualityDiversitySettings = dataclasses.field(default_factory=QualityDiversitySettings)
    stable_poses: ScreenSettings = dataclasses.field(default_factory=ScreenSettings)
    #: None when the parameters hold no ``printer`` namespace (the printability check is then skipped).
    printer: typing.Optional[PrinterSpec] = None


@dataclasses.dataclass(frozen=True)
class Estimate:
    """A design's fitness estimate pooled over its evaluations: heights (simulation units), fitness, trials."""

    heights: np.ndarray
    fitness: float
    trials: int
    evaluations: int = 1
    generation: int = 0                # generation in which the design was first evaluated

    def pooled(self, fitness: float, trials: int) -> "Estimate":
        """Return this estimate pooled with one more evaluation (``fitness`` over ``trials``), trial-weighted."""
        total = self.trials + trials
        return dataclasses.replace(self, fitness=(self.fitness * self.trials + fitness * trials) / total,
                                   trials=total, evaluations=self.evaluations + 1)


@dataclasses.dataclass(frozen=True)
class OptimizerResult:
    """Outcome so far: the incumbent, counts, the distribution mean (phenotype) and step size, stop criteria."""

    best: typing.Optional[Estimate]   # None before the first evaluation
    generations: int
    evaluations: int
    elapsed_s: float
    mean: np.ndarray
    sigma: float
    stop: dict


def random_initial_means(settings: OptimizerSettings, n_variables: int, lower: float = 0.0,
                         upper: float = 0.45) -> npt.NDArray[np.float64]:
    """The seeded random initial means ``(max(1, settings.initial_mean_screen), n_variables)``, uniform in
    ``[lower, upper]``; row 0 is the one the paper's settings start from (``initial_mean_screen`` 0 or 1)."""
    rows = max(1, settings.initial_mean_screen)
    return np.random.default_rng(settings.seed).uniform(lower, upper, (rows, int(n_variables)))


def initial_mean_candidates(settings: OptimizerSettings, grid: ProfileGrid
                            ) -> typing.Tuple[npt.NDArray[np.float64], typing.List[str]]:
    """``(means, names)``: the candidate start means ``(count, grid.n_variables)`` a screened run ranks
    (:func:`random_initial_means`, then with ``initial_mean_shapes`` the simple parametric profiles of
    :func:`~rollability_ros.core.profile.geometry.simple_profiles`) and a name each (``"random 3"``, ``"H 0.32 a 1.0
    b 0.5"``)."""
    means = random_initial_means(settings, grid.n_variables, grid.height_min, grid.height_max)
    names = [f"random {i}" for i in range(len(means))]
    if settings.initial_mean_shapes:
        shapes = simple_profiles(grid)
        means = np.vstack([means, np.array(list(shapes.values()), dtype=np.float64)])
        names += list(shapes)
    return means, names


class IncumbentOptimizer(abc.ABC):
    """The contract of an optimizer method (``optimizer.method``, :data:`OPTIMIZER_METHODS`) and what every method
    shares: the ask/tell bookkeeping, the incumbent with its re-evaluation, the stop criteria and the wall time.

    A method subclasses it, supplies ``_ask() -> [heights]`` and ``_tell(population, fitness, trials)`` (its own
    search state), calls :meth:`_init_bookkeeping` in its constructor, and declares :meth:`create` (new, or
    restored from a checkpoint state); :meth:`check_settings` and :meth:`archive_rows` have defaults for a method
    that reads only the ``optimizer`` section and keeps no archive.
    """

    # --- the method seam ----------------------------------------------------------------------------------------
    @classmethod
    def check_settings(cls, settings: "RunSettings") -> None:
        """Raise ``ValueError`` naming the first unusable setting this method reads from the run's typed
        ``settings`` (default: the ``optimizer`` section), before a run starts."""
        config.check_settings(settings.optimizer, "optimizer")

    @classmethod
    @abc.abstractmethod
    def create(cls, grid: "ProfileGrid", settings: "RunSettings", clock: typing.Callable[[], float],
               initial_mean: typing.Optional[npt.ArrayLike] = None,
               state: typing.Optional[dict] = None) -> "IncumbentOptimizer":
        """The optimizer over ``grid``'s variables and bounds with the run's typed ``settings``, new or restored
        from a checkpoint ``state``; ``initial_mean`` ``(grid.n_variables,)`` simulation units (None: the paper's
        random start)."""

    @abc.abstractmethod
    def _ask(self) -> list:
        """This generation's ``popsize`` height arrays ``(n_variables,)``, within the bounds."""

    @abc.abstractmethod
    def _tell(self, population: list, fitness: list, trials: list) -> None:
        """Update the search state with the population's fitness (upright / trials, [0, 1]) and trial counts."""

    @property
    @abc.abstractmethod
    def sigma(self) -> float:
        """The search's step size now (simulation units), as the generation summary reports it."""

    @property
    @abc.abstractmethod
    def result(self) -> "OptimizerResult":
        """The run's result so far (incumbent, evaluations, generations, stop reason)."""

    @abc.abstractmethod
    def state_dict(self) -> dict:
        """The checkpoint state (JSON data, never a pickle) :meth:`create` restores from."""

    def archive_rows(self) -> typing.Optional[typing.List[dict]]:
        """One row per elite of the method's archive (quality diversity); None for a method without one."""
        return None

    def _init_bookkeeping(self, settings, clock):
        self.settings = settings
        self._clock = clock
        self._started = clock()
        self._elapsed_before_s = 0.0
        self.generation = 0                # completed generations
        self.evaluations = 0
        self._asked = None
        self._incumbent = None
        self._challenger = None
        self._reevaluation_pending = False
        self._improved_at = 0              # generation count when the incumbent last changed
        # every generation's tell (fitness, trials, re-evaluation): the checkpoint rebuilds the search from it
        self._tells = []

    # --- ask / tell -------------------------------------------------------------------------------------------
    def ask(self) -> typing.List[npt.NDArray[np.float64]]:
        """Return ``popsize`` candidate height arrays ``(n_variables,)`` within the bounds."""
        if self._reevaluation_pending:
            raise ValueError("ask() before tell_reevaluation(): the incumbent re-evaluation of generation "
                             f"{self.generation - 1} is still pending")
        if self._asked is not None:
            raise ValueError(f"ask() called twice for generation {self.generation}; tell() the first population")
        self._asked = [np.asarray(x, dtype=np.float64) for x in self._ask()]
        return [x.copy() for x in self._asked]

    def tell(self, solutions: typing.Sequence[npt.ArrayLike], fitness: typing.Iterable[float],
             trials: typing.Optional[typing.Iterable[int]] = None) -> None:
        """Pass the fitness (in [0, 1], maximised) of the asked ``solutions`` (each ``(n_variables,)``), in the
        asked order.

        ``trials`` (one int per solution, or None for weight 1) weights the pooling of re-evaluations.
        """
        if self._asked is None:
            raise ValueError("tell() without a preceding ask()")
        fitness = [float(f) for f in fitness]
        trials = [1] * len(fitness) if trials is None else [int(t) for t in trials]
        if not (len(solutions) == len(fitness) == len(trials) == len(self._asked)):
            raise ValueError(f"tell() needs {len(self._asked)} solutions, fitnesses and trials, got "
                             f"{len(solutions)}, {len(fitness)}, {len(trials)}")
        for index, (given, asked) in enumerate(zip(solutions, self._asked)):
            if not np.array_equal(np.asarray(given, dtype=np.float64), asked):
                raise ValueError(f"solution {index} is not the one asked (order changed or values altered)")
        if not all(0.0 <= f <= 1.0 for f in fitness):
            raise ValueError(f"fitness values must lie in [0, 1], got {fitness}")
        self._tell(self._asked, fitness, trials)
        self._tells.append({"fitness": fitness, "trials": trials, "reevaluation": None})
        best = int(np.argmax(fitness))
        candidate = Estimate(self._asked[best].copy(), fitness[best], trials[best], 1, self.generation)
        self._asked = None
        self.generation += 1
        self.evaluations += len(fitness)
        if self._incumbent is None or candidate.fitness > self._incumbent.fitness:
            if self.settings.reevaluate_incumbent:
                self._challenger = candidate
            else:
                self._adopt(candidate)
        self._reevaluation_pending = self.settings.reevaluate_incumbent

    def reevaluation_request(self) -> typing.Optional[npt.NDArray[np.float64]]:
        """Return the heights ``(n_variables,)`` to re-evaluate now (challenger, else incumbent), or None when
        nothing is due."""
        if not self._reevaluation_pending:
            return None
        due = self._challenger or self._incumbent
        assert due is not None   # a re-evaluation is due only once there is an incumbent
        return due.heights.copy()

    def tell_reevaluation(self, fitness: float, trials: int = 1) -> None:
        """Pool a fresh evaluation (``fitness`` over ``trials``) into the design :meth:`reevaluation_request` named."""
        if not self._reevaluation_pending:
            raise ValueError("tell_reevaluation() without a pending re-evaluation")
        if not 0.0 <= fitness <= 1.0:
            raise ValueError(f"fitness must lie in [0, 1], got {fitness}")
        self.evaluations += 1
        self._reevaluation_pending = False
        self._tells[-1]["reevaluation"] = [float(fitness), int(trials)]
        if self._challenger is None:
            assert self._incumbent is not None   # see reevaluation_request
            self._incumbent = self._incumbent.pooled(float(fitness), int(trials))
            return
        challenger, self._challenger = self._challenger.pooled(float(fitness), int(trials)), None
        if self._incumbent is None or challenger.fitness > self._incumbent.fitness:
            self._adopt(challenger)

    def race_reference(self, heights: npt.ArrayLike) -> typing.Optional[typing.Tuple[int, int]]:
        """``(successes, trials)`` of the estimate a candidate at ``heights`` ``(n_variables,)`` is raced against
        (sequential racing, :mod:`~rollability_ros.core.optimization.racing`): the incumbent's pooled estimate; None
        before there is one. Depends only on the state between generations, so a resumed generation races alike."""
        incumbent = self._incumbent
        if incumbent is None:
            return None
        return int(round(incumbent.fitness * incumbent.trials)), int(incumbent.trials)

    def _adopt(self, estimate):
        self._incumbent = estimate
        self._improved_at = self.generation

    # --- state --------------------------------------------------------------------------------------------------
    @property
    def best(self) -> typing.Optional[Estimate]:
        """The incumbent :class:`Estimate` (best-so-far), or None before the first generation."""
        return self._incumbent

    @property
    def elapsed_s(self) -> float:
        """Optimization wall time, s, summed over resumed sessions."""
        return self._elapsed_before_s + (self._clock() - self._started)

    def stop(self) -> typing.Dict[str, float]:
        """Return ``{criterion: value}`` for every stop criterion met (empty: keep going).

        Criteria: ``max_generations``, ``target_fitness``, ``stagnation_generations``, ``max_evaluations``,
        ``max_wall_time_s``. pycma's internal criteria (flat fitness, tolx, ...) are deliberately not used:
        a binomial fitness is flat (all 0) for whole early generations, which is no reason to stop.
        """
        if self._reevaluation_pending or self._asked is not None:
            return {}
        s = self.settings
        met = {}
        if s.max_generations and self.generation >= s.max_generations:
            met["max_generations"] = s.max_generations
        if self._incumbent is not None and self._incumbent.fitness >= s.target_fitness:
            met["target_fitness"] = s.target_fitness
        if s.stagnation_generations and self.generation - self._improved_at >= s.stagnation_generations:
            met["stagnation_generations"] = s.stagnation_generations
        if s.max_evaluations and self.evaluations >= s.max_evaluations:
            met["max_evaluations"] = s.max_evaluations
        if s.max_wall_time_s and self.elapsed_s >= s.max_wall_time_s:
            met["max_wall_time_s"] = s.max_wall_time_s
        return met

    def _bookkeeping_state(self):
        """The shared part of ``state_dict()``: the tells and counters (between generations only)."""
        if self._reevaluation_pending or self._asked is not None:
            raise ValueError("the optimizer state is only saved between generations")
        return {"tells": copy.deepcopy(self._tells), "generation": self.generation, "evaluations": self.evaluations,
                "elapsed_s": self.elapsed_s, "improved_at": self._improved_at}

    def _replay(self, state):
        """Replay the saved tells into this fresh optimizer; ValueError when they do not fit these settings."""
        for tell in state["tells"]:
            population = self.ask()
            self.tell(population, tell["fitness"], tell["trials"])
            if tell["reevaluation"] is not None:
                self.reevaluation_request()
                self.tell_reevaluation(*tell["reevaluation"])
            elif self._reevaluation_pending:
                raise ValueError("saved optimizer state lacks a re-evaluation these settings ask for")
        if (self.generation != int(state["generation"]) or self.evaluations != int(state["evaluations"])
                or self._improved_at != int(state["improved_at"])):
            raise ValueError("replaying the saved tells does not reproduce the saved counters: the checkpoint "
                             "belongs to other settings or code")

    def _resume_clock(self, state):
        self._started = self._clock()
        self._elapsed_before_s = float(state["elapsed_s"])


#: ``optimizer.method`` -> its :class:`IncumbentOptimizer` subclass (``"module:Class"``: imported when chosen).
#: A new method is one module with the subclass plus one entry here.
OPTIMIZER_METHODS: Registry[IncumbentOptimizer] = Registry("method", IncumbentOptimizer, {
    "cmaes": "rollability_ros.core.optimization.cmaes:ProfileOptimizer",
    "cma_mae": "rollability_ros.core.optimization.quality_diversity:QualityDiversityOptimizer",
})
