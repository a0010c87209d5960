"""The face of ``rollability_ros.core.sim``: the names code outside the subpackage imports, and where each
lives. Type checkers read this stub; at run time ``lazy_loader.attach_stub`` (``__init__.py``) reads the same
imports and loads a name's module when the name is first used."""
from .evaluation import (SETTINGS_SECTIONS, EvaluationCancelled, EvaluationResult, EvaluatorSettings, TrialBatchEngine,
                         TrialExecutor, evaluate_jobs, evaluate_mesh, evaluate_profile, load_settings, make_executor,
                         profile_job, request_problem, settings_at_fidelity, settings_from_parameters, trial_seed,
                         with_given_files, with_objective)
from .launch.placement import check_launcher
from .launch.results import LaunchResult
from .launch.settings import (TWIN_NAMESPACE, TWIN_SECTIONS, LaunchTwinSettings, launch_twin_settings_from_parameters,
                              load_launch_twin_settings, mecanum_wheels, twin_files, twin_value,
                              twin_with_values)
from .launch.twin import profile_body, simulate_launch, simulate_valid_launch
from .objectives import FIDELITIES, ObjectiveSettings, ResolvedLaunch, check_fidelity, resolve_launch, world_fidelity
from .rollout import rollout_distance_m
from .sensitivity import launch_sensitivity_rows, sensitivity_rows
from .stable_poses import ScreenSettings, profile_screener, robot_hull, screen_robot
from .engines import LAUNCH_ENGINES, TRIAL_ENGINES, engine_names, register_trial_engine
from .launch.contract import LaunchEngine
from .trial_engine import TrialEngine, TrialOutcome, make_trial_world
from .trials import TrialSettings
from .world import PhysicsParams
from .world_check import (WORLD_CHECK_COLUMNS, WorldSummary, local_world_evaluator, run_world_check, summarize_worlds,
                          world_check_lines, world_draws)
from ._worker_pool import WORKER_RSS_MB, available_memory_mb, spawn_pool, worker_memory_refusal

__all__ = [
    "FIDELITIES", "LAUNCH_ENGINES", "SETTINGS_SECTIONS", "TRIAL_ENGINES", "TWIN_NAMESPACE", "TWIN_SECTIONS",
    "WORKER_RSS_MB", "WORLD_CHECK_COLUMNS", "EvaluationCancelled", "EvaluationResult", "EvaluatorSettings", "LaunchEngine",
    "LaunchResult", "LaunchTwinSettings", "ObjectiveSettings", "PhysicsParams", "ResolvedLaunch", "ScreenSettings",
    "TrialBatchEngine", "TrialEngine", "TrialExecutor", "TrialOutcome", "TrialSettings", "WorldSummary",
    "available_memory_mb", "check_fidelity", "check_launcher", "engine_names", "evaluate_jobs", "evaluate_mesh", "evaluate_profile",
    "launch_sensitivity_rows", "launch_twin_settings_from_parameters", "load_launch_twin_settings", "load_settings",
    "local_world_evaluator", "make_executor", "make_trial_world", "mecanum_wheels", "profile_body", "profile_job",
    "profile_screener", "register_trial_engine", "request_problem", "resolve_launch", "robot_hull", "rollout_distance_m",
    "run_world_check", "screen_robot", "sensitivity_rows", "settings_at_fidelity", "settings_from_parameters",
    "simulate_launch", "simulate_valid_launch", "spawn_pool", "summarize_worlds", "trial_seed", "twin_files",
    "twin_value", "twin_with_values", "with_given_files", "with_objective", "worker_memory_refusal", "world_check_lines", "world_draws",
    "world_fidelity"
]
