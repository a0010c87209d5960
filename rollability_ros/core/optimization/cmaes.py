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
import copy
import pickle
import time
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core import config
from rollability_ros.core.optional import require
from rollability_ros.core.optimization.optimizer_contract import (IncumbentOptimizer, OptimizerResult,
                                                                  OptimizerSettings, RunSettings,
                                                                  random_initial_means)
from rollability_ros.core.profile import ProfileGrid

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


