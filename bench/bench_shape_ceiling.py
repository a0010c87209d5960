"""How high can a simple profile go on the campaign's measure? A ceiling check for the search's designs.

    nice python bench/bench_shape_ceiling.py [--config optimizer] [--screen 100] [--fresh 200] [--top 3] [--workers 2]
                                             [--modes 100]

The quick study's designs land near 0.5 on the campaign's launches (docs/optimization.md, "What the race had to
choose from"). Is that the search's limit or the twin's? This bench launches simple parametric profiles on the
study's own grid, ``h(x, y) = H (1 - a |x| / (L/2)) (1 - b |y| / (W/2))`` for H in {0.2, 0.32, 0.45} (simulation
units, of the 0.45 bound), a and b in {0, 0.5, 1} (a flat top, ridges along and across, a pyramid), and the bare
robot, ``--screen`` times each under the campaign's nominal conditions on the launch fidelity's engine (the
campaign's measure: its 20 launch conditions in turn, no draw of the unknowns; the PyBullet twin in the shipped
configs). The best of a screen is a maximum of noisy estimates, so the ``--top`` shapes and the bare robot are then
launched ``--fresh`` more times on other seeds, and those fresh counts are the result: each shape's rate with its
Wilson 95% interval and its gain over the bare robot with Newcombe's 95% interval. All numbers are simulated.

``--modes N`` then launches the fresh shapes N more times each (same conditions, other seeds, full rest rule) and
says where they came to rest: upright, or resting upside down, on a side or on an end (the axis of the robot's
base frame nearest world up), or tilted on its wheels beyond the upright test. That says what a profile would have
to remove. ``--config FILE`` with ``robot.profile.unit_m`` tries another height scale (taller profiles).
"""
import argparse
import collections
import concurrent.futures
import dataclasses
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

import numpy as np  # noqa: E402

from rollability_ros.core.optimization import batch_evaluation, run_directory  # noqa: E402
from rollability_ros.core.profile import geometry  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402
from rollability_ros.core.stats import newcombe_interval, wilson_interval  # noqa: E402

#: Base seeds of the screen, the fresh launches and the rest modes (none is a seed the campaign or a study uses).
SCREEN_SEED, FRESH_SEED, MODES_SEED = 777001, 777003, 777005


def nominal_settings(configs):
    """The launch fidelity's settings of ``configs`` with the unknowns not drawn: the campaign's measure."""
    launch = evaluation.settings_at_fidelity(
        evaluation.settings_from_parameters(run_directory.load_run_parameters(configs)), "launch")
    objective = dataclasses.replace(launch.objective, screen_engine=launch.physics.engine,
                                    robust=dataclasses.replace(launch.objective.robust, enabled=False))
    return dataclasses.replace(launch, objective=objective)


def shapes(grid):
    """``{name: heights}``: the bare robot and the parametric family (see the module docstring;
    ``geometry.simple_profiles``)."""
    return {"bare": np.zeros(grid.n_variables), **geometry.simple_profiles(grid)}


#: Rest modes by the base-frame axis nearest world up (index, sign): the robot's own x forward, y left, z up.
#: World up along the base's +y (its left) means it lies on its right side; along +x (its front), on its rear end.
MODES = {(2, 1): "tilted on its wheels", (2, -1): "upside down", (1, 1): "on its right side",
         (1, -1): "on its left side", (0, 1): "on its rear end", (0, -1): "on its front end"}


def rest_mode(result) -> str:
    """Where the launch ``result`` (a LaunchResult) ended: ``upright``, one of :data:`MODES`, or ``invalid``."""
    from scipy.spatial.transform import Rotation

    if not result.valid:
        return "invalid"
    if result.upright:
        return "upright"
    up = Rotation.from_quat(result.final_orientation).inv().apply([0.0, 0.0, 1.0])  # world up in the base frame
    axis = int(np.argmax(np.abs(up)))
    return MODES[(axis, int(np.sign(up[axis])))]


def _modes_of(settings, heights, launches, seed):
    """``Counter`` of :func:`rest_mode` over ``launches`` nominal launches of ``heights`` (full rest rule)."""
    from rollability_ros.core.sim import objectives
    from rollability_ros.core.sim.launch.twin import simulate_valid_launch

    objective = objectives.launch_objective(settings.objective, settings.resolved_launch, settings.physics.engine,
                                           early_decision=False)
    assert objective is not None, "the launch fidelity has a launch objective"
    profile = evaluation.profile_job(heights, settings).profile
    return collections.Counter(rest_mode(simulate_valid_launch(objective.condition(index), objective.twin,
                                                               seed + index, profile=profile, use_profile=True))
                               for index in range(launches))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", action="append", help="parameter files (default: optimizer, the quick study)")
    parser.add_argument("--screen", type=int, default=100, help="nominal launches per shape in the screen")
    parser.add_argument("--fresh", type=int, default=200, help="fresh nominal launches of the best and the bare robot")
    parser.add_argument("--top", type=int, default=3, help="shapes launched afresh")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--modes", type=int, default=0, help="launches of each fresh shape classified by rest mode")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    if args.smoke:   # one launch per shape in each step (the rest modes too), the best shape only, one worker
        args.screen, args.fresh, args.top, args.modes, args.workers = 1, 1, 1, 1, 1
    settings = nominal_settings(args.config or ["optimizer"])
    family = shapes(settings.grid)
    names = list(family)
    started = time.perf_counter()
    with evaluation.LocalExecutor(args.workers) as pool:
        evaluate = batch_evaluation.fidelity_batch_evaluator(settings, pool, "screen")
        screen = {name: (int(r[0]), int(r[1])) for name, r in
                  zip(names, evaluate([family[name] for name in names], SCREEN_SEED, args.screen))}
        best = sorted((name for name in names if name != "bare"), key=lambda name: -screen[name][0])[:args.top]
        fresh_names = best + ["bare"]
        fresh = {name: (int(r[0]), int(r[1])) for name, r in
                 zip(fresh_names, evaluate([family[name] for name in fresh_names], FRESH_SEED, args.fresh))}
    grid = settings.grid
    print(f"simple profiles on the {grid.rows} x {grid.cols} half grid, nominal launches on the "
          f"{settings.physics.engine} twin under the campaign's conditions (simulated); {time.perf_counter() - started:.0f} s")
    print(f"screen ({args.screen} launches each, seed {SCREEN_SEED}; the best is biased upward):")
    for name in sorted(names, key=lambda name: -screen[name][0]):
        print(f"  {name:<22} {screen[name][0]:>4}/{screen[name][1]}")
    bare = fresh["bare"]
    low, high = wilson_interval(*bare)
    print(f"fresh ({args.fresh} launches each, seed {FRESH_SEED}): bare robot {bare[0]}/{bare[1]} "
          f"[{low:.2f}, {high:.2f}]")
    for name in best:
        s, n = fresh[name]
        low, high = wilson_interval(s, n)
        gain, gain_low, gain_high = newcombe_interval(s, n, *bare)
        print(f"  {name:<22} {s:>4}/{n} = {s / n:.2f} [{low:.2f}, {high:.2f}]; minus bare "
              f"{gain:+.2f} [{gain_low:+.2f}, {gain_high:+.2f}]")
    if args.modes:
        with concurrent.futures.ProcessPoolExecutor(args.workers) as pool:
            modes = dict(zip(fresh_names, pool.map(_modes_of, [settings] * len(fresh_names),
                                                   [family[name] for name in fresh_names],
                                                   [args.modes] * len(fresh_names), [MODES_SEED] * len(fresh_names))))
        print(f"where {args.modes} more launches each came to rest (seed {MODES_SEED}, full rest rule):")
        for name in fresh_names:
            print(f"  {name:<22} " + ", ".join(f"{mode} {count}" for mode, count in modes[name].most_common()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
