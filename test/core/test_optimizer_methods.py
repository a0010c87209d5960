"""The optimizer-method seam (core/optimization/cmaes.py): the IncumbentOptimizer contract, the OPTIMIZER_METHODS
table, make_optimizer / check_method_settings its only lookups. A new method is one class plus one registration
line, and it runs, checkpoints and resumes through the same OptimizationRun as CMA-ES and CMA-MAE."""
import numpy as np
import pytest

from rollability_ros.core.optimization import cmaes
from rollability_ros.core.optimization.cmaes import OPTIMIZER_METHODS, IncumbentOptimizer, OptimizerResult


class RandomSearch(IncumbentOptimizer):
    """``optimizer.method: random``: uniform heights in the grid's bounds, from the run's seed and generation."""

    @classmethod
    def create(cls, grid, settings, clock, initial_mean=None, state=None):
        optimizer = cls(grid, settings.optimizer, clock)
        if state is not None:
            optimizer._replay(state)
            optimizer._resume_clock(state)
        return optimizer

    def __init__(self, grid, settings, clock):
        self.grid = grid
        self._init_bookkeeping(settings, clock)

    def _ask(self):
        rng = np.random.default_rng([self.settings.seed, self.generation])
        return list(rng.uniform(self.grid.height_min, self.grid.height_max, (self.settings.popsize,
                                                                              self.grid.n_variables)))

    def _tell(self, population, fitness, trials):
        pass

    @property
    def sigma(self):
        return 0.0

    @property
    def result(self):
        return OptimizerResult(best=self._incumbent, generations=self.generation, evaluations=self.evaluations,
                               elapsed_s=self.elapsed_s, mean=None, sigma=0.0, stop=self.stop())

    def state_dict(self):
        return {**self._bookkeeping_state(), "method": "random"}


@pytest.fixture
def methods(monkeypatch):
    monkeypatch.setattr(OPTIMIZER_METHODS, "_entries", dict(OPTIMIZER_METHODS._entries))
    return OPTIMIZER_METHODS


def test_a_new_method_is_one_class_and_one_registration_line(methods, tmp_path):
    pytest.importorskip("cma")
    from doubles import SyntheticEvaluator
    from rollability_ros.core.optimization.optimization_run import (OptimizationRun, run_config, check_method_settings,
                                                                        run_settings)
    from rollability_ros.core.profile.geometry import ProfileGrid

    methods.register("random", RandomSearch)        # the one registration line
    parameters = {"optimizer.method": "random", "optimizer.max_generations": 3, "optimizer.trials": 10,
                  "optimizer.popsize": 4, "optimizer.stagnation_generations": 0}
    check_method_settings(run_settings(parameters))
    grid = ProfileGrid(rows=3, cols=3)
    evaluator = SyntheticEvaluator(np.full(9, 0.2), trials=10)
    run = OptimizationRun(tmp_path / "opt", run_config(parameters), grid, evaluator)
    assert isinstance(run.optimizer, RandomSearch)
    run.step()
    run.step()                                     # then the run is "killed": it resumes from its checkpoint
    first = [c.heights for c in run.store.candidates()]
    run.close()
    again = OptimizationRun(tmp_path / "opt", run_config(parameters), grid, evaluator, resume=True)   # from its checkpoint
    assert isinstance(again.optimizer, RandomSearch) and again.optimizer.generation == 2
    again.run()
    assert again.optimizer.generation == 3 and [c.heights for c in again.store.candidates()][:len(first)] == first
    again.close()


def test_unknown_methods_and_incomplete_contracts_are_refused(methods):
    from rollability_ros.core.optimization.optimization_run import run_settings

    with pytest.raises(ValueError, match=r"^optimizer: method must be one of \('cmaes', 'cma_mae'\), got 'random'$"):
        run_settings({"optimizer.method": "random"})       # refused where the parameters are parsed
    with pytest.raises(TypeError, match="abstract methods? .*_ask"):   # the contract declares what a method needs
        type("Incomplete", (IncumbentOptimizer,), {})()
    assert methods.get("cmaes") is cmaes.ProfileOptimizer


def test_the_built_in_methods_are_on_the_contract():
    pytest.importorskip("ribs")
    from rollability_ros.core.optimization.quality_diversity import QualityDiversityOptimizer

    assert OPTIMIZER_METHODS.get("cma_mae") is QualityDiversityOptimizer
    assert OPTIMIZER_METHODS.names() == ("cmaes", "cma_mae")
