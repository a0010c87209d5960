"""Does the foam pad's size change the twin's verdict? The rig's rule counts a robot upright wherever it rests.

    nice python bench/bench_pad_size.py [--config optimizer] [--launches 100] [--workers 2] [--engine pybullet]

Launches the bare robot, a tall and a low simple profile (bench/bench_shape_ceiling.py's family: a flat top at
the 0.45 bound, "H 0.45 a 0.0 b 0.0", and a low ridge across, "H 0.20 a 0.5 b 0.0") ``--launches`` times each
under the campaign's nominal conditions (its 20 launch conditions in turn, the launch fidelity's twin, no draw
of the unknowns) with the foam pad at the shipped 2.5 x 3 m and at 30 x 30 m, the same seeds for both. Prints the
upright counts, their difference (issue 40 asks for at most 6 of 100) and how many launches came to rest on the
floor beyond the small pad. All numbers are simulated.
"""
import argparse
import concurrent.futures
import dataclasses
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

from bench.bench_shape_ceiling import nominal_settings, shapes  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402

#: Base seed of the launches (not a seed the campaign or a study uses).
PAD_SEED = 777011
#: Pads (length along the launch, width along the edge; m): the shipped one and one no robot rolls off.
PADS = ((2.5, 3.0), (30.0, 30.0))
SHAPES = ("bare", "H 0.45 a 0.0 b 0.0", "H 0.20 a 0.5 b 0.0")
#: Largest difference of the upright counts of 100 launches that issue 40 accepts.
ACCEPTED_PER_100 = 6


def _launches(settings, heights, pad, launches, engine):
    """``(upright, on the floor, invalid)`` counts of ``launches`` nominal launches of ``heights`` on ``pad``."""
    from rollability_ros.core.sim import objectives
    from rollability_ros.core.sim.launch.twin import simulate_valid_launch

    objective = objectives.launch_objective(settings.objective, settings.resolved_launch, engine, early_decision=True)
    assert objective is not None, "the launch fidelity has a launch objective"
    twin = objective.twin
    foam = dataclasses.replace(twin.twin.foam, length_m=pad[0], width_m=pad[1])
    twin = dataclasses.replace(twin, twin=dataclasses.replace(twin.twin, foam=foam))
    profile = evaluation.profile_job(heights, settings).profile
    upright = floor = invalid = 0
    for index in range(launches):
        result = simulate_valid_launch(objective.condition(index), twin, PAD_SEED + index, profile=profile,
                                       use_profile=True)
        upright += bool(result.valid and result.upright)
        floor += result.rest_surface == "floor"
        invalid += not result.valid
    return upright, floor, invalid


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", action="append", help="parameter files (default: optimizer, the quick study)")
    parser.add_argument("--launches", type=int, default=100, help="launches per shape and pad")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--engine", default=None, help="sim.engine of the launches (default: the launch fidelity's)")
    parser.add_argument("--smoke", action="store_true",
                        help="tiny sizes: each step once, in seconds; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    if args.smoke:
        args.launches, args.workers = 1, 1
    settings = nominal_settings(args.config or ["optimizer"])
    engine = args.engine or settings.physics.engine
    family = shapes(settings.grid)
    jobs = [(name, pad) for name in SHAPES for pad in PADS]
    started = time.perf_counter()
    with concurrent.futures.ProcessPoolExecutor(args.workers) as pool:
        counts = dict(zip(jobs, pool.map(_launches, [settings] * len(jobs), [family[name] for name, _ in jobs],
                                         [pad for _, pad in jobs], [args.launches] * len(jobs),
                                         [engine] * len(jobs))))
    print(f"upright of {args.launches} nominal launches per shape, seeds {PAD_SEED}.., {engine} twin, pad "
          f"{PADS[0][0]} x {PADS[0][1]} m vs {PADS[1][0]} x {PADS[1][1]} m (simulated; "
          f"{time.perf_counter() - started:.0f} s)")
    allowed = ACCEPTED_PER_100 * args.launches / 100
    for name in SHAPES:
        (small, floor, invalid), (large, _, invalid_large) = counts[(name, PADS[0])], counts[(name, PADS[1])]
        verdict = "within" if abs(small - large) <= allowed else "OUTSIDE"
        print(f"  {name:<20} small pad {small:>4}  large pad {large:>4}  difference {small - large:+d} ({verdict} "
              f"{allowed:g}); at rest on the floor beyond the small pad: {floor}; invalid {invalid} / {invalid_large}")


if __name__ == "__main__":
    sys.exit(main())
