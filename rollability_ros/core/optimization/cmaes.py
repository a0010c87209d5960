"""CMA-ES over profile heights: ask / tell / stop / result around ``cma.CMAEvolutionStrategy``.

Fitness (successes / trials, in [0, 1]) is maximised; pycma minimises, so it is told ``1 - fitness``.
Bounds are pycma's own boundary handling (``BoundTransform``): every asked candidate lies within the bounds.

How the optimizer copes with a noisy binomial fitness
-----------------------------------------------------
1. Common random numbers (``common_random_numbers``, run level): every candidate of a generation is evaluated
   with the same disturbance seed, so within a generation all candidates face the same pushes and the ranking
   CMA-ES uses reflects geometry rather than luck of the draw. Seeds differ between generations
   (:func:`derive_seed`), so no design is tuned to one fixed set of disturbances.
2. Re-evaluation of the incumbent (``reevaluate_incumbent``): the best-so-far design is the *incumbent*. A
   generation's best candidate that beats the incumbent's estimate is only a *challenger*: it is evaluated once
   more with a fresh seed and its two estimates are pooled (weighted by trials); it replaces the incumbent only
   if the pooled estimate still beats it. Without a challenger the incumbent itself is re-evaluated and pooled.
   So a lucky 60-trial estimate cannot stick as "best so far": the reported best-so-far is always an estimate
   over at least two independent evaluations, and the incumbent's estimate tightens every generation.
   The cost is one extra evaluation per generation (1 / popsize).
pycma's own noise handling (``cma.NoiseHandler``) is not used: it changes the evaluation count per generation,
which the node's fixed-size dispatch and the exact-resume guarantee would both have to model.

pycma draws its samples from ``np.random`` (seeded by its ``seed`` option). :class:`ProfileOptimizer` gives its
strategy a private copy of that generator right after construction, so other code in the process using
``np.random`` cannot change the sequence, and pickling the strategy (the checkpoint) captures the generator state.
"""
import abc
import copy
import dataclasses
import pickle
import time
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core import config
from rollability_ros.core.optional import require
from rollability_ros.core.registry import Registry

if typing.TYPE_CHECKING:
    from rollability_ros.core.optimization.optimization_run import RunSettings
    from rollability_ros.core.profile import ProfileGrid

#: Seed streams of :func:`derive_seed`: population evaluations, incumbent re-evaluations, design selection.
STREAM_POPULATION = 0
STREAM_REEVALUATION = 1
STREAM_SELECTION = 2
STREAM_RACE = 3


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


class ProfileOptimizer(IncumbentOptimizer):
    """CMA-ES over ``n_variables`` heights in ``[lower, upper]`` with the protocol ask -> tell ->
    (:meth:`reevaluation_request` -> :meth:`tell_reevaluation` when re-evaluation is on) -> :meth:`stop`.

    Parameters
    ----------
    n_variables : int
        Design variables (half-grid vertices).
    settings : OptimizerSettings
    lower, upper : float
        Height bounds, simulation units.
    clock : callable, optional
        Monotonic clock in seconds, for the wall-time cap.
    initial_mean : array_like, optional
        The CMA-ES start ``(n_variables,)`` within the bounds (e.g. the best of :func:`random_initial_means` by
        the stable-pose screen); default: row 0 of :func:`random_initial_means`.
    """

    @classmethod
    def create(cls, grid: "ProfileGrid", settings: "RunSettings", clock: typing.Callable[[], float],
               initial_mean: typing.Optional[npt.ArrayLike] = None,
               state: typing.Optional[dict] = None) -> "ProfileOptimizer":
        """``optimizer.method: cmaes``: one CMA-ES over the grid's heights with ``settings.optimizer``
        (``initial_mean`` ``(grid.n_variables,)``, simulation units; None: the paper's random start)."""
        if state is None:
            return cls(grid.n_variables, settings.optimizer, grid.height_min, grid.height_max, clock, initial_mean)
        return cls.from_state_dict(state, grid.n_variables, settings.optimizer, grid.height_min, grid.height_max,
                                   clock, initial_mean)

    def __init__(self, n_variables: int, settings: OptimizerSettings, lower: float = 0.0, upper: float = 0.45,
                 clock: typing.Callable[[], float] = time.monotonic,
                 initial_mean: typing.Optional[npt.ArrayLike] = None) -> None:
        cma = require("cma", feature="the CMA-ES optimizer")
        config.check_settings(settings, "optimizer")
        self.n_variables, self.lower, self.upper, self.initial_mean = check_search_space(
            n_variables, settings, lower, upper, initial_mean)
        self.cma_options = {"popsize": settings.popsize, "bounds": [self.lower, self.upper], "seed": settings.seed,
                            "verbose": -9, "verb_log": 0, "verb_disp": 0}
        global_state = np.random.get_state()
        strategy = cma.CMAEvolutionStrategy(self.initial_mean, settings.sigma0, self.cma_options)
        # the round trip replaces pycma's reference to the global np.random by a private copy in the same state
        self._es = pickle.loads(pickle.dumps(strategy))
        np.random.set_state(global_state)  # pycma's seed option reseeded the process-wide generator
        self._init_bookkeeping(settings, clock)

    def _ask(self):
        return self._es.ask()

    def _tell(self, population, fitness, trials):
        self._es.tell(population, [1.0 - f for f in fitness])

    @property
    def sigma(self) -> float:
        """Current CMA-ES step size, simulation units."""
        return float(self._es.sigma)

    @property
    def result(self) -> OptimizerResult:
        """The :class:`OptimizerResult` so far."""
        return OptimizerResult(best=self._incumbent, generations=self.generation, evaluations=self.evaluations,
                               elapsed_s=self.elapsed_s, mean=np.asarray(self._es.result.xfavorite, dtype=np.float64),
                               sigma=self.sigma, stop=self.stop())

    def state_dict(self) -> dict:
        """Return the full optimizer state between generations as plain data (JSON-serialisable, no pickle).

        pycma's strategy is deterministic given its seed and the values told to it, so the state is the list of
        tells (per generation: fitnesses, trials, the re-evaluation) and :meth:`from_state_dict` replays them;
        ``mean`` and ``sigma`` are stored to check that the replay reproduced the strategy exactly.
        """
        return {**self._bookkeeping_state(), "initial_mean": self.initial_mean.tolist(),
                "mean": np.asarray(self._es.mean).tolist(), "sigma": float(self._es.sigma)}

    @classmethod
    def from_state_dict(cls, state: dict, n_variables: int, settings: OptimizerSettings, lower: float = 0.0,
                        upper: float = 0.45, clock: typing.Callable[[], float] = time.monotonic,
                        initial_mean: typing.Optional[npt.ArrayLike] = None) -> "ProfileOptimizer":
        """Rebuild an optimizer saved by :meth:`state_dict`; it continues exactly where that one stopped.

        ``initial_mean`` ``(n_variables,)`` is the start these settings give (as for the constructor); a state
        that started elsewhere belongs to other settings and is refused, as is one whose replay does not reproduce
        the saved mean and step size (ValueError).
        """
        if state.get("method", "cmaes") != "cmaes":
            raise ValueError(f"saved optimizer state is a {state.get('method')} state, not cmaes (optimizer.method "
                             "changed?)")
        optimizer = cls(n_variables, settings, lower, upper, clock, initial_mean)
        if not np.array_equal(optimizer.initial_mean, np.asarray(state["initial_mean"], dtype=np.float64)):
            raise ValueError("saved optimizer state does not match these settings (different initial mean)")
        optimizer._replay(state)
        if (not np.array_equal(np.asarray(optimizer._es.mean), np.asarray(state["mean"], dtype=np.float64))
                or float(optimizer._es.sigma) != float(state["sigma"])):
            raise ValueError("replaying the saved tells does not reproduce the saved CMA-ES state (mean, sigma or "
                             "counters differ): the checkpoint belongs to other settings or code")
        optimizer._resume_clock(state)
        return optimizer


def check_search_space(n_variables: int, settings: OptimizerSettings, lower: float, upper: float,
                       initial_mean: typing.Optional[npt.ArrayLike]
                       ) -> typing.Tuple[int, float, float, npt.NDArray[np.float64]]:
    """``(n_variables, lower, upper, initial_mean)`` checked and converted; ValueError naming what is wrong.

    ``initial_mean`` ``(n_variables,)`` heights, simulation units; None -> row 0 of :func:`random_initial_means`
    (the paper's random start).
    """
    if n_variables < 1:
        raise ValueError(f"n_variables must be >= 1, got {n_variables}")
    if not lower < upper:
        raise ValueError(f"need lower < upper, got [{lower}, {upper}]")
    n_variables, lower, upper = int(n_variables), float(lower), float(upper)
    if initial_mean is None:
        initial_mean = random_initial_means(settings, n_variables, lower, upper)[0]
    mean = np.array(initial_mean, dtype=np.float64)
    if mean.shape != (n_variables,) or not np.all(np.isfinite(mean)) or \
            np.any(mean < lower) or np.any(mean > upper):
        raise ValueError(f"initial_mean must be {n_variables} finite heights in [{lower}, {upper}]")
    return n_variables, lower, upper, mean


#: ``optimizer.method`` -> its :class:`IncumbentOptimizer` subclass (``"module:Class"``: imported when chosen).
#: A new method is one module with the subclass plus one entry here.
OPTIMIZER_METHODS: Registry[IncumbentOptimizer] = Registry("method", IncumbentOptimizer, {
    "cmaes": "rollability_ros.core.optimization.cmaes:ProfileOptimizer",
    "cma_mae": "rollability_ros.core.optimization.quality_diversity:QualityDiversityOptimizer",
})
