"""The bare chassis on the twin, condition by condition, beside the paper's stated baseline facts (reported, not
tuned).

    nice python bench/bench_bare_breakdown.py [--repetitions 10] [--workers 2] [--engine pybullet]
                                              [--engines pybullet,mujoco] [--set [ENGINE:]NAME=VALUE ...]

Launches the bare chassis ``--repetitions`` times at each of the paper's 20 conditions (heights 0.75 / 1.30 m,
speeds 0.8 / 1.5 m/s, angles -60 .. +60 deg) on the shipped twin (config/launch_twin.yaml, its scatter drawn per
seed) and prints the upright rate by speed, by angle, by height and overall with Wilson 95% intervals, and how many
conditions the paper's majority rule (3 of 5) would call successes. The paper (section 3) says of its baseline:
success mainly near 0 deg, lower at 1.5 m/s than at 0.8 m/s, limited at negative angles, and about 30% overall
(Figure 12d). All numbers are simulated.

``--engines a,b`` launches the same seeds on each engine and adds, per condition, both engines' counts and how
many launches ended alike (the engines' agreement on the bare robot, docs/optimization.md). ``--set NAME=VALUE``
overrides one twin setting (a dotted settings name, e.g. ``physics.restitution=0`` or
``twin.foam.contact_stiffness_npm=40000``) on every engine, ``--set ENGINE:NAME=VALUE`` on that engine only: one
modelling choice varied at a time.
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


def _condition(height_m, speed_mps, angle_deg, repetitions, engine, overrides=()):
    """Outcomes (upright, per launch) of ``repetitions`` valid-launch retries of the bare chassis at one condition."""
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.sim.launch.settings import load_launch_twin_settings
    from rollability_ros.core.sim.launch.twin import simulate_valid_launch

    settings = load_launch_twin_settings(overrides={"physics.engine": engine, **dict(overrides)})
    condition = LaunchCondition("baseline", height_m, speed_mps, angle_deg)
    return tuple(bool(r.valid and r.upright) for r in (simulate_valid_launch(condition, settings, BARE_SEED + k)
                                                      for k in range(repetitions)))


def _overrides(settings, engine):
    """``--set`` values for ``engine``: ``[(dotted name, value)]``, numbers as floats."""
    chosen = []
    for text in settings:
        scope, _, assignment = text.rpartition(":") if ":" in text.split("=", 1)[0] else ("", "", text)
        name, equals, value = assignment.partition("=")
        if not equals or not name:
            raise SystemExit(f"--set {text!r}: expected [ENGINE:]NAME=VALUE")
        if scope in ("", engine):
            try:
                chosen.append((name, float(value)))
            except ValueError:
                chosen.append((name, value))
    return tuple(chosen)


def _line(label, upright, launches):
    if not launches:   # a value no launched condition has (a --smoke run's few conditions)
        return f"  {label:<14} no launches"
    low, high = wilson_interval(upright, launches)
    return f"  {label:<14} {upright:>4}/{launches:<4} = {upright / launches:.2f} [{low:.2f}, {high:.2f}]"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repetitions", type=int, default=10, help="launches per condition")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--engine", default="pybullet")
    parser.add_argument("--engines", help="comma-separated engines launched on the same seeds (overrides --engine)")
    parser.add_argument("--set", action="append", default=[], metavar="[ENGINE:]NAME=VALUE",
                        help="one twin setting overridden (on ENGINE only when named)")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    conditions = list(itertools.product(HEIGHTS_M, SPEEDS_MPS, ANGLES_DEG))
    if args.smoke:   # two conditions, one launch each, one worker
        conditions, args.repetitions, args.workers = conditions[:2], 1, 1
    engines = args.engines.split(",") if args.engines else [args.engine]
    outcomes = {}
    for engine in engines:
        overrides = _overrides(args.set, engine)
        started = time.perf_counter()
        with concurrent.futures.ProcessPoolExecutor(args.workers) as pool:
            outcomes[engine] = dict(zip(conditions, pool.map(
                _condition, *zip(*conditions), [args.repetitions] * len(conditions), [engine] * len(conditions),
                [overrides] * len(conditions))))
        _print_engine(engine, outcomes[engine], args.repetitions, time.perf_counter() - started, overrides)
    if len(engines) > 1:
        first, *others = engines
        for other in others:
            same = {c: sum(a == b for a, b in zip(outcomes[first][c], outcomes[other][c])) for c in conditions}
            print(f"{first} vs {other}, per condition (height, speed, angle: upright {first} / {other}, same outcome "
                  f"of {args.repetitions}); overall same outcome {sum(same.values())}/{args.repetitions * len(conditions)}:")
            for condition in conditions:
                print(f"  {condition[0]:.2f} m {condition[1]:.1f} m/s {condition[2]:+4.0f} deg: "
                      f"{sum(outcomes[first][condition])} / {sum(outcomes[other][condition])}, same {same[condition]}")
    print(f"load average {' '.join(f'{v:.1f}' for v in os.getloadavg())} (2 shared cores)")
    return 0


def _print_engine(engine, outcomes, n, elapsed_s, overrides):
    counts = {condition: sum(upright) for condition, upright in outcomes.items()}
    varied = f"; {', '.join(f'{k}={v}' for k, v in overrides)}" if overrides else ""
    print(f"bare chassis, {n} launches per condition, seeds {BARE_SEED}.., {engine} twin{varied} (simulated; "
          f"{elapsed_s:.0f} s)")
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
    sys.exit(main())
