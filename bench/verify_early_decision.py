"""Verify the early trial decision: the same trials with and without it must give the same outcomes.

    nice python bench/verify_early_decision.py [--trials-chassis 250] [--trials-husky 100] [--seed 7]
                                               [--engine pybullet|mujoco] [--launches]

Runs every trial twice in one process, once under the full rule (rest hold or time cap) and once ending at the
early decision, over several profiles on the built-in chassis (baseline, dome, ridge, random) and on the URDF
Husky from pybullet_data (``config/husky.yaml``: baseline, dome, random). Prints per case: trials, outcome
changes, upright counts, steps per trial with and without the decision and the share decided early; exits 1
if any outcome changed. With ``--launches`` every trial is a launch on the launch twin of ``--engine``
(``objective.kind: launch_twin``) under the paper's 20 launch conditions in turn (heights 0.75 / 1.30 m, speeds
0.8 / 1.5 m/s, angles -60 ... 60 deg; ``config/campaign.yaml``), with its speed and angle scatter; the counts are
then launches (the outcome compared is valid and upright, as the objective scores it).
"""
import argparse
import dataclasses
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from rollability_ros.core.profile.geometry import grid_xy  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402


def dome_heights(grid, peak=1.0):
    """A dome over the footprint, ``peak`` x height_max at the centre (simulation units)."""
    xy = grid_xy(grid)
    ny, nx = xy[:, 1] / (grid.width_m / 2), xy[:, 0] / (grid.length_m / 2)
    return np.clip(peak * grid.height_max * (1 - 0.5 * ny ** 2 - 0.5 * nx ** 2), 0.0, grid.height_max)


def ridge_heights(grid):
    """A lengthwise ridge on the centre line, falling off across (simulation units)."""
    xy = grid_xy(grid)
    return np.clip(grid.height_max * (1 - np.abs(xy[:, 1]) / (grid.width_m / 2)), 0.0, grid.height_max)


def with_engine(settings, engine):
    """A copy of ``settings`` with ``physics.engine`` set."""
    return dataclasses.replace(settings, physics=dataclasses.replace(settings.physics, engine=engine))


def as_launches(settings, twin_config):
    """A copy of ``settings`` whose trials are launches on the twin of ``twin_config`` (the paper's conditions)."""
    objective = dataclasses.replace(settings.objective, kind="launch_twin", campaign_config=["campaign"],
                                    twin_config=list(twin_config))
    return evaluation.with_objective(settings, objective)


def cases(seed, engine="pybullet", launches=False):
    """(name, settings, heights) of every verified robot + profile."""
    rng = np.random.default_rng(seed)
    chassis = with_engine(evaluation.load_settings(("sim", "robot", "evaluator")), engine)
    husky = with_engine(evaluation.load_settings(("sim", "robot", "evaluator", "husky")), engine)
    if launches:
        chassis = as_launches(chassis, ("sim", "robot", "launch_twin"))
        husky = as_launches(husky, ("sim", "robot", "launch_twin", "husky"))
    out = [("chassis baseline", chassis, None), ("chassis dome", chassis, dome_heights(chassis.grid)),
           ("chassis low dome", chassis, dome_heights(chassis.grid, 0.4)),
           ("chassis ridge", chassis, ridge_heights(chassis.grid))]
    out += [(f"chassis random {k}", chassis, rng.uniform(0, chassis.grid.height_max, chassis.grid.n_variables))
            for k in range(3)]
    out += [("husky baseline", husky, None), ("husky dome", husky, dome_heights(husky.grid)),
            ("husky random", husky, rng.uniform(0, husky.grid.height_max, husky.grid.n_variables))]
    return out


def with_early_decision(settings, enabled):
    """A copy of ``settings`` with ``trial.early_decision`` set."""
    return dataclasses.replace(settings, trial=dataclasses.replace(settings.trial, early_decision=enabled))


def compare(settings, heights, trials, seed):
    """Outcomes of the same trials under the full rule and with the early decision: (full, early, s, s)."""
    started = time.perf_counter()
    full = evaluation.evaluate_profile(heights, trials, seed, with_early_decision(settings, False)).trial_results
    full_s = time.perf_counter() - started
    started = time.perf_counter()
    early = evaluation.evaluate_profile(heights, trials, seed, with_early_decision(settings, True)).trial_results
    return full, early, full_s, time.perf_counter() - started


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials-chassis", type=int, default=250)
    parser.add_argument("--trials-husky", type=int, default=100)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--engine", choices=("pybullet", "mujoco"), default="pybullet")
    parser.add_argument("--launches", action="store_true", help="verify launches on the launch twin instead")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    if args.smoke:
        args.trials_chassis = args.trials_husky = 2
    print(f"engine: {args.engine}   kind: {'launches on the twin' if args.launches else 'disturbance trials'}")
    total = changed = 0
    full_steps, early_steps = [], []
    print(f"{'case':20s} {'trials':>6s} {'changed':>7s} {'upright':>7s} {'steps full':>10s} {'steps early':>11s} "
          f"{'decided':>7s} {'time ratio':>10s}")
    verified = cases(args.seed, args.engine, args.launches)
    for name, settings, heights in [verified[1], verified[-3]] if args.smoke else verified:
        trials = args.trials_husky if name.startswith("husky") else args.trials_chassis
        full, early, full_s, early_s = compare(settings, heights, trials, args.seed)
        diffs = [(a.index, a.upright, b.upright) for a, b in zip(full, early) if a.upright != b.upright]
        total += trials
        changed += len(diffs)
        full_steps += [o.steps for o in full]
        early_steps += [o.steps for o in early]
        print(f"{name:20s} {trials:6d} {len(diffs):7d} {sum(o.upright for o in full):7d} "
              f"{np.mean([o.steps for o in full]):10.1f} {np.mean([o.steps for o in early]):11.1f} "
              f"{np.mean([o.decided for o in early]):7.0%} {full_s / early_s:9.2f}x")
        for index, was, now in diffs:
            print(f"    trial {index}: full rule upright={was}, early decision upright={now}")
    print(f"total: {total} trials, {changed} outcome changes; steps/trial {np.mean(full_steps):.1f} -> "
          f"{np.mean(early_steps):.1f} ({np.mean(full_steps) / np.mean(early_steps):.2f}x fewer); "
          f"load average {os.getloadavg()[0]:.2f}")
    return 1 if changed else 0


if __name__ == "__main__":
    sys.exit(main())
