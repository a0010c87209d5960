"""Early trial decision: analytic barriers of a cube, and no outcome change against the full rest rule.

bench/verify_early_decision.py runs the large sample (thousands of trials, several robots and profiles).
"""
import dataclasses
import math

import numpy as np
import pytest

from rollability_ros.core.sim.early_decision import build_basin_map, tabulate_basin_map
from rollability_ros.core.sim.evaluation import evaluate_profile, load_settings, with_objective

pytest.importorskip("scipy")
pybullet = pytest.importorskip("pybullet")

SIDE_M = 0.1


def cube_map():
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * SIDE_M / 2
    return build_basin_map({-1: corners}, (), np.zeros(3), 1.0, (0.0, 0.0, 1.0), upright_tilt_deg=30.0,
                           min_wheels=0, contact_tolerance_m=0.001, margin_m=0.0)


def test_cube_barriers_match_analytic_heights():
    cube = cube_map()
    down, up = np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, 1.0])
    # resting on its bottom face (COM at side/2): the only other resting poses (its side faces, not upright)
    # are reached over an edge, with the COM at side / sqrt 2; upside down likewise to reach the bottom face
    over_edge_m = SIDE_M / math.sqrt(2)
    for start, outcome in ((down, True), (up, False)):
        nearest = np.argmax(cube.directions @ start)
        barrier = (cube.barrier_to_not_upright_m if outcome else cube.barrier_to_upright_m)[nearest]
        assert over_edge_m - 0.1 * SIDE_M < barrier <= over_edge_m  # lowered only by the lattice slack
        assert cube.decide(start, SIDE_M / 2 + 0.001) is outcome
        assert cube.decide(start, over_edge_m + 0.001) is None


def test_a_basin_map_is_tabulated_once_per_body_and_shared_read_only():
    """Every launch of one design rebuilds the same body: its map is tabulated once per process and shared, so it
    refuses writes; a body that differs in one input (here the COM, by 1 mm) gets its own, equal to a fresh one."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * SIDE_M / 2
    com = np.zeros(3)
    first = cube_map()
    assert cube_map() is first
    with pytest.raises(ValueError, match="read-only"):
        first.barrier_to_upright_m[0] = 0.0
    com[2] = 0.001
    kwargs = dict(upright_tilt_deg=30.0, min_wheels=0, contact_tolerance_m=0.001, margin_m=0.0)
    moved = build_basin_map({-1: corners}, (), com, 1.0, (0.0, 0.0, 1.0), **kwargs)
    assert moved is not first and not np.array_equal(moved.barrier_to_upright_m, first.barrier_to_upright_m)
    fresh = tabulate_basin_map({-1: corners}, (), com, 1.0, (0.0, 0.0, 1.0), **kwargs)
    for field in dataclasses.fields(fresh):
        assert np.array_equal(getattr(moved, field.name), getattr(fresh, field.name)), field.name
    com[2] = 0.0   # the caller's array was copied, not frozen: it stays the caller's
    assert cube_map() is first


def dome_heights(grid):
    from rollability_ros.core.profile.geometry import grid_xy
    xy = grid_xy(grid)
    ny, nx = xy[:, 1] / (grid.width_m / 2), xy[:, 0] / (grid.length_m / 2)
    return np.clip(grid.height_max * (1 - 0.5 * ny ** 2 - 0.5 * nx ** 2), 0.0, grid.height_max)


def early(settings, enabled):
    return dataclasses.replace(settings, trial=dataclasses.replace(settings.trial, early_decision=enabled))


@pytest.mark.parametrize("config,profile,trials", [
    (("sim", "robot", "evaluator"), "baseline", 40),
    (("sim", "robot", "evaluator"), "dome", 60),
    (("sim", "robot", "evaluator", "husky"), "dome", 12),
])
def test_early_decision_changes_no_outcome_and_saves_steps(config, profile, trials):
    settings = load_settings(config)
    heights = None if profile == "baseline" else dome_heights(settings.grid)
    full = evaluate_profile(heights, trials, 11, early(settings, False)).trial_results
    fast = evaluate_profile(heights, trials, 11, early(settings, True)).trial_results
    assert [o.upright for o in fast] == [o.upright for o in full]
    assert not any(o.decided for o in full)
    assert any(o.decided for o in fast)
    assert sum(o.steps for o in fast) < sum(o.steps for o in full)


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
@pytest.mark.parametrize("robot,profile,launches", [("chassis", "dome", 20), ("husky", "baseline", 8)])
def test_early_decision_of_launches_changes_no_outcome(engine, robot, profile, launches):
    """Launches on the twin under the paper's 20 conditions in turn, with and without the early decision (after
    the landing on the foam, once the plate has stopped): the same outcomes, fewer steps
    (bench/verify_early_decision.py --launches runs the large sample)."""
    if engine == "mujoco":
        pytest.importorskip("mujoco")
    extra = ("husky",) if robot == "husky" else ()
    settings = load_settings(("sim", "robot", "evaluator") + extra)
    objective = dataclasses.replace(settings.objective, kind="launch_twin",
                                    twin_config=["sim", "robot", "launch_twin", *extra])
    settings = dataclasses.replace(with_objective(settings, objective),
                                   physics=dataclasses.replace(settings.physics, engine=engine))
    heights = None if profile == "baseline" else dome_heights(settings.grid)
    full = evaluate_profile(heights, launches, 5, early(settings, False)).trial_results
    fast = evaluate_profile(heights, launches, 5, early(settings, True)).trial_results
    assert [o.upright for o in fast] == [o.upright for o in full]
    assert not any(o.decided for o in full) and any(o.decided for o in fast)
    assert sum(o.steps for o in fast) < sum(o.steps for o in full)
