"""optimizer.initial_mean_screen: the run starts from the best of several random means by the stable-pose screen."""
import os
import types

import numpy as np
import pytest

pytest.importorskip("cma")

from rollability_ros.core.config import ConfigError  # noqa: E402
from rollability_ros.core.profile.geometry import ProfileGrid  # noqa: E402
from doubles import SyntheticEvaluator  # noqa: E402
from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config, profile_screen  # noqa: E402
from rollability_ros.core.optimization.optimizer_contract import random_initial_means  # noqa: E402
from rollability_ros.core.optimization.optimization_run import run_settings  # noqa: E402

GRID = ProfileGrid(rows=3, cols=3)
OPTIMUM = np.linspace(0.05, 0.4, GRID.n_variables)


def parameters(screen, **overrides):
    return {"optimizer.max_generations": 3, "optimizer.seed": 5, "optimizer.trials": 30, "optimizer.popsize": 6,
            "optimizer.initial_mean_screen": screen, **overrides}


def fake_screen(calls):
    """A screen scoring a profile by its mean height (taller = more upright), ties broken by the barrier."""
    def screen(heights_list):
        calls.append([np.array(h) for h in heights_list])
        return [types.SimpleNamespace(upright_probability=round(float(np.mean(h)), 1),
                                      worst_barrier_m=float(h[0])) for h in heights_list]
    return screen


def test_without_the_screen_the_run_starts_from_the_papers_random_mean(tmp_path):
    run = OptimizationRun(os.path.join(tmp_path, "run"), run_config(parameters(0)), GRID, SyntheticEvaluator(OPTIMUM, 30))
    expected = random_initial_means(run_settings(parameters(0)).optimizer, GRID.n_variables)[0]
    assert np.array_equal(run.optimizer.initial_mean, expected)
    assert run.initial_mean_screen is None
    assert "initial_mean_screen" not in run.store.run_info(run.run_id)["info"]
    run.close()
    with pytest.raises(ValueError, match=r"^optimizer.initial_mean_screen out of range: -1 is not in \[0, 10000\]$"):
        OptimizationRun(os.path.join(tmp_path, "bad"), run_config(parameters(-1)), GRID, SyntheticEvaluator(OPTIMUM, 30))


def test_the_screened_start_is_the_best_candidate_recorded_and_kept_on_resume(tmp_path):
    run_dir = os.path.join(tmp_path, "run")
    calls = []
    run = OptimizationRun(run_dir, run_config(parameters(8)), GRID, SyntheticEvaluator(OPTIMUM, 30),
                          screen_profiles=fake_screen(calls))
    means = random_initial_means(run_settings(parameters(8)).optimizer, GRID.n_variables)
    assert len(calls) == 1 and np.array_equal(np.array(calls[0]), means)
    keys = [(round(float(np.mean(m)), 1), -float(m[0])) for m in means]
    chosen = max(range(8), key=keys.__getitem__)
    assert np.array_equal(run.optimizer.initial_mean, means[chosen])
    info = run.store.run_info(run.run_id)["info"]["initial_mean_screen"]
    assert info["chosen"] == chosen and len(info["upright_probability"]) == 8
    assert run.initial_mean_text().startswith(f"initial mean: #{chosen} of 8 random means by the stable-pose screen")
    run.step()
    run.close()

    resumed = OptimizationRun(run_dir, run_config(parameters(8)), GRID, SyntheticEvaluator(OPTIMUM, 30), resume=True,
                              screen_profiles=fake_screen(calls))
    assert resumed.optimizer.generation == 1
    assert np.array_equal(resumed.optimizer.initial_mean, means[chosen])
    resumed.close()

    with pytest.raises(ValueError, match="different initial mean"):      # the screen changed under the run
        OptimizationRun(run_dir, run_config(parameters(8)), GRID, SyntheticEvaluator(OPTIMUM, 30), resume=True,
                        screen_profiles=lambda heights: [types.SimpleNamespace(upright_probability=0.0,
                                                                               worst_barrier_m=float(h[1]))
                                                         for h in heights])


def test_the_edge_screens_the_robot_its_parameters_describe(tmp_path):
    """The run reads no flat parameters: the screen of the robot they describe is built at the edge (as the CLI
    does), and a run asked to screen without one is refused before anything is written."""
    pytest.importorskip("pybullet")
    pytest.importorskip("trimesh")
    from rollability_ros.core.sim.evaluation import settings_from_parameters

    params = parameters(4, **{"profile.rows": 3, "profile.cols": 3, "stable_poses.com_sigma_m": 0.0})
    with pytest.raises(ValueError, match="initial_mean_screen 4 needs the stable-pose screen"):
        OptimizationRun(os.path.join(tmp_path, "none"), run_config(params), GRID, SyntheticEvaluator(OPTIMUM, 30))
    assert not os.path.exists(os.path.join(tmp_path, "none"))
    run = OptimizationRun(os.path.join(tmp_path, "run"), run_config(params), GRID, SyntheticEvaluator(OPTIMUM, 30),
                          screen_profiles=profile_screen(run_settings(params), settings_from_parameters(params)))
    expected = [s.upright_probability for s in profile_screen(run_settings(params), settings_from_parameters(params))(
        list(random_initial_means(run_settings(params).optimizer, GRID.n_variables)))]
    assert run.initial_mean_screen["upright_probability"] == [round(p, 4) for p in expected]
    run.close()


def test_the_real_screen_ranks_random_means_on_the_robot_in_use():
    pytest.importorskip("pybullet")
    pytest.importorskip("trimesh")
    from rollability_ros.core.sim.evaluation import EvaluatorSettings

    settings = EvaluatorSettings(grid=GRID)
    params = parameters(4, **{"stable_poses.com_sigma_m": 0.0})
    screen = profile_screen(run_settings(params), settings)
    means = random_initial_means(run_settings(params).optimizer, GRID.n_variables)
    screens = screen(list(means))
    probabilities = [s.upright_probability for s in screens]
    assert all(0.0 <= p <= 1.0 for p in probabilities) and len(set(probabilities)) > 1
    assert all(s.worst_barrier_m >= 0 for s in screens)
    assert profile_screen(run_settings(parameters(0)), settings) is None
    with pytest.raises(ConfigError, match=r"^stable_poses.com_sigma_m out of range: 0.5 is not in \[0.0, 0.05\)$"):
        run_settings(parameters(4, **{"stable_poses.com_sigma_m": 0.5}))     # refused where it is parsed


class Counting:
    """``evaluate_batch`` that counts the profiles it evaluates."""

    def __init__(self, evaluate):
        self.evaluate, self.profiles = evaluate, 0

    def __call__(self, heights_list, seed):
        self.profiles += len(heights_list)
        return self.evaluate(heights_list, seed)


def test_the_start_ranked_on_the_searchs_own_measure_can_be_a_simple_profile_and_is_kept_on_resume(tmp_path):
    """initial_mean_measure objective with initial_mean_shapes: the random means and the 27 simple profiles are each
    evaluated once by the run's own evaluator, the one with the most successes starts (here the simple profile at the
    evaluator's optimum), the ranking is recorded and a resumed run reads it back without evaluating them again."""
    from rollability_ros.core.profile.geometry import simple_profiles

    shapes = simple_profiles(GRID)
    assert len(shapes) == 27 and all(GRID.height_min <= h.min() and h.max() <= GRID.height_max for h in shapes.values())
    assert np.allclose(shapes["H 0.45 a 0.0 b 0.0"], GRID.height_max)         # the flat top at the bound
    target = "H 0.32 a 1.0 b 0.5"
    params = parameters(4, **{"optimizer.initial_mean_measure": "objective", "optimizer.initial_mean_shapes": True})
    run_dir = os.path.join(tmp_path, "run")
    evaluate = Counting(SyntheticEvaluator(shapes[target], 30, width=0.02))
    run = OptimizationRun(run_dir, run_config(params), GRID, evaluate)
    assert evaluate.profiles == 4 + 27
    assert np.array_equal(run.optimizer.initial_mean, shapes[target])
    screen = run.store.run_info(run.run_id)["info"]["initial_mean_screen"]
    assert screen["names"][screen["chosen"]] == target and screen["measure"] == "objective"
    assert screen["successes"][screen["chosen"]] == max(screen["successes"]) and set(screen["trials"]) == {30}
    assert run.initial_mean_text().startswith(f"initial mean: {target}, the best of 31 candidate means")
    run.step()
    run.close()
    evaluate.profiles = 0
    resumed = OptimizationRun(run_dir, run_config(params), GRID, evaluate, resume=True)
    assert np.array_equal(resumed.optimizer.initial_mean, shapes[target])
    assert evaluate.profiles == 0      # read back, not launched again
    resumed.close()


def test_an_unknown_start_measure_is_refused_and_without_a_screen_the_papers_mean_starts_whatever_the_shapes(
        tmp_path):
    with pytest.raises(ValueError, match="initial_mean_measure must be one of stable_poses, objective"):
        OptimizationRun(os.path.join(tmp_path, "bad"), run_config(parameters(4, **{
            "optimizer.initial_mean_measure": "launches"})), GRID, SyntheticEvaluator(OPTIMUM, 30))
    assert not os.path.exists(os.path.join(tmp_path, "bad"))
    params = parameters(0, **{"optimizer.initial_mean_measure": "objective", "optimizer.initial_mean_shapes": True})
    evaluate = Counting(SyntheticEvaluator(OPTIMUM, 30))
    run = OptimizationRun(os.path.join(tmp_path, "run"), run_config(params), GRID, evaluate)
    expected = random_initial_means(run_settings(params).optimizer, GRID.n_variables)[0]
    assert np.array_equal(run.optimizer.initial_mean, expected) and evaluate.profiles == 0
    assert run.initial_mean_screen is None
    run.close()
