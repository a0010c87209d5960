"""The face of ``rollability_ros.core.optimization``: the names code outside the subpackage imports, and where each
lives. Type checkers read this stub; at run time ``lazy_loader.attach_stub`` (``__init__.py``) reads the same
imports and loads a name's module when the name is first used."""
from .checkpoint import CHECKPOINT_FILENAME, atomic_write_bytes, load_checkpoint
from .cmaes import ProfileOptimizer
from .evaluator_pool import EvaluationFailed, EvaluatorPool, PoolClosed, PoolSettings
from .batch_evaluation import fidelity_batch_evaluator, profile_batch_evaluator
from .optimization_run import (OptimizationRun, RunConfig, check_method_settings, make_optimizer, profile_screen,
                               run_config, run_generations, run_settings, with_given_files)
from .optimizer_contract import (OPTIMIZER_METHODS, IncumbentOptimizer, OptimizerSettings, QualityDiversitySettings,
                                 RunSettings)
from .design_set import design_set_folders, select_run, table_rows
from .run_directory import load_run_parameters, read_run_config, resolve_run_dir, run_id_of, run_target
from .recommendation import DEFAULT_WORLD_SHARE, Recommendation, recommend, with_campaign
from .selection import GAIN_SOURCES, SelectionSettings

__all__ = [
    "CHECKPOINT_FILENAME", "DEFAULT_WORLD_SHARE", "GAIN_SOURCES", "OPTIMIZER_METHODS", "EvaluationFailed",
    "EvaluatorPool", "IncumbentOptimizer", "OptimizationRun", "OptimizerSettings", "PoolClosed", "PoolSettings",
    "ProfileOptimizer", "QualityDiversitySettings", "Recommendation", "RunConfig", "RunSettings", "SelectionSettings",
    "atomic_write_bytes", "load_checkpoint", "check_method_settings", "design_set_folders", "fidelity_batch_evaluator",
    "load_run_parameters", "make_optimizer", "profile_batch_evaluator", "profile_screen", "read_run_config",
    "recommend", "resolve_run_dir", "run_config", "run_generations", "run_id_of", "run_settings", "run_target",
    "select_run", "table_rows", "with_campaign", "with_given_files"
]
