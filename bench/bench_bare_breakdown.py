"""The bare chassis on the twin, condition by condition, beside the paper's stated baseline facts (reported, not
tuned).

    nice python bench/bench_bare_breakdown.py [--repetitions 10] [--workers 2] [--engine pybullet]

Launches the bare chassis ``--repetitions`` times at each of the paper's 20 conditions (heights 0.75 / 1.30 m,
speeds 0.8 / 1.5 m/s, angles -60 .. +60 deg) on the shipped twin (config/launch_twin.yaml, its scatter drawn per
seed) and prints the upright rate by speed, by angle, by height and overall with Wilson 95% intervals, and how many
conditions the paper's majority rule (3 of 5) would call successes. The paper (section 3) says of its baseline:
success mainly near 0 deg, lower at 1.5 m/s than at 0.8 m/s, limited at negative angles, and about 30% overall
(Figure 12d). All numbers are simulated.
"""
import argparse
import collections
import concurrent.futures
import itertools
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

from rollability_ros.core.stats import wilson_interval  # noqa: E402

HEIGHTS_M, SPEEDS_MPS, ANGLES_DEG = (0.75, 1.30), (0.8, 1.5), (-60.0, -30.0, 0.0, 30.0, 60.0)
#: Base seed of the launches (not one the campaign or a study uses).
BARE_SEED = 777021


def _condition(height_m, speed_mps, angle_deg, repetitions, engine):
    """Upright count of ``repetitions`` valid-launch retries of the bare chassis at one condition."""
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.sim.launch.settings import load_launch_twin_settings
    from rollability_ros.core.sim.launch.twin import simulate_valid_launch

    settings = load_launch_twin_settings(overrides={"physics.engine": engine})
    condition = LaunchCondition("baseline", height_m, speed_mps, angle_deg)
    return sum(bool(r.valid and r.upright) for r in (simulate_valid_launch(condition, settings, BARE_SEED + k)
                                                    for k in range(repetitions)))


def _line(label, upright, launches):
    low, high = wilson_interval(upright, launches)
    return f"  {label:<14} {upright:>4}/{launches:<4} = {upright / launches:.2f} [{low:.2f}, {high:.2f}]"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repetitions", type=int, default=10, help="launches per condition")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--engine", default="pybullet")
    args = parser.parse_args()
    conditions = list(itertools.product(HEIGHTS_M, SPEEDS_MPS, ANGLES_DEG))
    started = time.perf_counter()
    with concurrent.futures.ProcessPoolExecutor(args.workers) as pool:
        counts = dict(zip(conditions, pool.map(_condition, *zip(*conditions), [args.repetitions] * len(conditions),
                                                [args.engine] * len(conditions))))
    n = args.repetitions
    print(f"bare chassis, {n} launches per condition, seeds {BARE_SEED}.., {args.engine} twin (simulated; "
          f"{time.perf_counter() - started:.0f} s)")
    for name, index, values in (("speed m/s", 1, SPEEDS_MPS), ("angle deg", 2, ANGLES_DEG), ("height m", 0, HEIGHTS_M)):
        print(f"by {name}:")
        for value in values:
            upright = sum(c for condition, c in counts.items() if condition[index] == value)
            launches = n * sum(1 for condition in counts if condition[index] == value)
            print(_line(f"{value:+g}" if index == 2 else f"{value:g}", upright, launches))
    print("overall:")
    print(_line("all", sum(counts.values()), n * len(counts)))
    majority = collections.Counter(c / n > 0.5 for c in counts.values())
    print(f"conditions with a majority upright: {majority[True]} of {len(counts)}; per condition (height, speed, "
          "angle: upright):")
    for condition, count in counts.items():
        print(f"  {condition[0]:.2f} m {condition[1]:.1f} m/s {condition[2]:+4.0f} deg: {count}/{n}")


if __name__ == "__main__":
    main()
