"""Optimization of profile heights: CMA-ES or CMA-MAE, the run loop with checkpoints, design selection.

- cmaes: ask / tell / stop / result around pycma
- quality_diversity: CMA-MAE (pyribs) filling a maximum height x sharpness archive
- optimization_run: generations through an injected evaluator, logged, checkpointed, resumable
- checkpoint: atomic checkpoints checked against the run's config
- evaluator_pool: a batch of evaluations spread over the available evaluators
- selection: designs A/B/C from a run's log or its archive (deciding), and the world check's recommendation
- recommendation: the rule naming the design to print first from the plausible-world check
- design_set: writing a selection (STL, 3MF, Table 3, designs.yaml, world_check.csv) and its record

The face below is what code outside ``core/optimization`` imports (``from rollability_ros.core.optimization import
OptimizerSettings``). It is lazy (``core/faces.py``): importing it loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller never pays for numpy, pycma or pyribs.
"""
import typing

from rollability_ros.core.faces import lazy_attribute

if typing.TYPE_CHECKING:   # imported when first used: lazy_attribute reads this block
    from rollability_ros.core.optimization import design_set, optimization_run, recommendation, selection
    from rollability_ros.core.optimization.checkpoint import atomic_write_bytes
    from rollability_ros.core.optimization.cmaes import (OPTIMIZER_METHODS, IncumbentOptimizer, OptimizerSettings,
                                                         ProfileOptimizer)
    from rollability_ros.core.optimization.evaluator_pool import (EvaluationFailed, EvaluatorPool, PoolClosed,
                                                                  PoolSettings)
    from rollability_ros.core.optimization.optimization_run import (OptimizationRun, make_optimizer, run_generations,
                                                                    run_target)
    from rollability_ros.core.optimization.quality_diversity import QualityDiversitySettings
    from rollability_ros.core.optimization.selection import GAIN_SOURCES, SelectionSettings

__all__ = [
    "GAIN_SOURCES", "OPTIMIZER_METHODS", "EvaluationFailed", "EvaluatorPool", "IncumbentOptimizer", "OptimizationRun",
    "OptimizerSettings", "PoolClosed", "PoolSettings", "ProfileOptimizer", "QualityDiversitySettings",
    "SelectionSettings", "atomic_write_bytes", "design_set", "make_optimizer", "optimization_run", "recommendation",
    "run_generations", "run_target", "selection",
]


def __getattr__(name: str) -> typing.Any:
    return lazy_attribute(__name__, name)
