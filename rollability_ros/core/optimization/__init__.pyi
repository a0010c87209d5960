"""The face of ``rollability_ros.core.optimization``: the names code outside the subpackage imports, and where each
lives. Type checkers read this stub; at run time ``lazy_loader.attach_stub`` (``__init__.py``) reads the same
imports and loads a name's module when the name is first used."""
from .checkpoint import atomic_write_bytes
from .cmaes import OPTIMIZER_METHODS, IncumbentOptimizer, OptimizerSettings, ProfileOptimizer
from .evaluator_pool import EvaluationFailed, EvaluatorPool, PoolClosed, PoolSettings
from .optimization_run import (OptimizationRun, RunConfig, RunSettings, check_method_settings, fidelity_batch_evaluator,
                               load_run_parameters, make_optimizer, profile_batch_evaluator, profile_screen,
                               read_run_config, resolve_run_dir, run_config, run_generations, run_id_of, run_settings,
                               run_target, with_given_files)
from .quality_diversity import QualityDiversitySettings
from .selection import GAIN_SOURCES, SelectionSettings, design_set_folders, select_run, table_rows

__all__ = [
    "GAIN_SOURCES", "OPTIMIZER_METHODS", "EvaluationFailed", "EvaluatorPool", "IncumbentOptimizer", "OptimizationRun",
    "OptimizerSettings", "PoolClosed", "PoolSettings", "ProfileOptimizer", "QualityDiversitySettings", "RunConfig",
    "RunSettings", "SelectionSettings", "atomic_write_bytes", "check_method_settings", "design_set_folders",
    "fidelity_batch_evaluator", "load_run_parameters", "make_optimizer", "profile_batch_evaluator", "profile_screen",
    "read_run_config", "resolve_run_dir", "run_config", "run_generations", "run_id_of", "run_settings", "run_target",
    "select_run", "table_rows", "with_given_files"
]
