"""Physics (PyBullet; MuJoCo as an option): worlds, disturbance trials, fitness evaluation, the stable-pose screen,
the launch twin.

- world: PhysicsParams and one DIRECT client per simulation
- trial_engine: the TrialEngine and LaunchEngine contracts, their tables and make_trial_world (picks sim.engine)
- _body_points: hull points, mass and centre of mass of a spawned PyBullet body's links
- trials: one disturbance trial (start, push, rest, upright test); TrialWorld, the pybullet engine
- mujoco_trials: the same trial in MuJoCo (sim.engine: mujoco)
- early_decision: ends a trial once energy fixes its outcome (barriers to the resting poses)
- evaluation: fitness = upright / trials, serial, process pool or Ray
- _worker_pool: spawned worker processes that never outlive their parent
- stable_poses: analytic stable-pose screen
- launch/: the simulated launch rig: settings, results, contract, placement, decision, loop, drive, twin (the entry)
  and one module per engine (pybullet_twin, mujoco_twin: the same rules in MuJoCo)

The face below is what code outside ``core/sim`` imports (``from rollability_ros.core.sim import
evaluate_profile``). It is lazy (``core/faces.py``): importing it loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller never pays for numpy, PyBullet or MuJoCo.
"""
import typing

from rollability_ros.core.faces import lazy_attribute

if typing.TYPE_CHECKING:   # imported when first used: lazy_attribute reads this block
    from rollability_ros.core.sim import evaluation, stable_poses
    from rollability_ros.core.sim.evaluation import (SETTINGS_SECTIONS, EvaluationCancelled, EvaluatorSettings,
                                                     TrialExecutor, evaluate_jobs, evaluate_mesh, evaluate_profile,
                                                     make_executor, profile_job, settings_at_fidelity,
                                                     settings_from_parameters, trial_seed, with_given_files)
    from rollability_ros.core.sim.launch.placement import check_launcher
    from rollability_ros.core.sim.launch.settings import (TWIN_NAMESPACE, TWIN_SECTIONS, LaunchTwinSettings,
                                                          launch_twin_settings_from_parameters,
                                                          load_launch_twin_settings, mecanum_wheels, twin_files)
    from rollability_ros.core.sim.launch.twin import profile_body, simulate_launch, simulate_valid_launch
    from rollability_ros.core.sim.objectives import FIDELITIES, ObjectiveSettings, check_fidelity, world_fidelity
    from rollability_ros.core.sim.rollout import rollout_distance_m
    from rollability_ros.core.sim.sensitivity import launch_sensitivity_rows, sensitivity_rows
    from rollability_ros.core.sim.stable_poses import ScreenSettings, screen_robot
    from rollability_ros.core.sim.trial_engine import (LAUNCH_ENGINES, TRIAL_ENGINES, LaunchEngine, TrialEngine,
                                                       TrialOutcome, engine_names, make_trial_world,
                                                       register_trial_engine)
    from rollability_ros.core.sim.trials import TrialSettings
    from rollability_ros.core.sim import world_check
    from rollability_ros.core.sim.world_check import WorldSummary, summarize_worlds
    from rollability_ros.core.sim._worker_pool import spawn_pool
    from rollability_ros.core.sim.world import PhysicsParams

__all__ = [
    "FIDELITIES", "LAUNCH_ENGINES", "SETTINGS_SECTIONS", "TRIAL_ENGINES", "TWIN_NAMESPACE", "TWIN_SECTIONS",
    "EvaluationCancelled", "EvaluatorSettings", "LaunchEngine", "LaunchTwinSettings", "ObjectiveSettings", "PhysicsParams",
    "ScreenSettings", "TrialEngine", "TrialExecutor", "TrialOutcome", "TrialSettings", "WorldSummary", "check_fidelity", "engine_names",
    "evaluate_jobs", "evaluate_mesh", "evaluate_profile", "evaluation", "launch_sensitivity_rows",
    "launch_twin_settings_from_parameters",
    "check_launcher", "load_launch_twin_settings", "make_executor", "make_trial_world", "mecanum_wheels", "rollout_distance_m", "profile_body", "profile_job", "register_trial_engine", "screen_robot",
    "sensitivity_rows", "settings_at_fidelity", "settings_from_parameters", "simulate_launch",
    "simulate_valid_launch", "spawn_pool", "stable_poses", "summarize_worlds", "trial_seed", "twin_files",
    "with_given_files", "world_check", "world_fidelity",
]


def __getattr__(name: str) -> typing.Any:
    return lazy_attribute(__name__, name)
