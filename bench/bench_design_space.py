"""What does each option of the design space buy? Simple profiles under each option, on both measures.

    nice python bench/bench_design_space.py [--option NAME=FILE[,FILE...] ...] [--launches 100] [--workers 2]
                                            [--shapes "H 0.45 a 1.0 b 1.0" ...] [--smoke]

An *option* is a set of parameter files laid over the quick study's (``optimizer``): a taller height bound
(``profile.unit_m``), another print (``robot.profile_print``), another footprint (``profile.length_m`` /
``width_m``). For each option the bench launches the bare robot and the simple parametric profiles of
``bench/bench_shape_ceiling.py`` (``--shapes``, by name; default four of its best) ``--launches`` times each

- under the campaign's **nominal** conditions (the campaign's measure: its 20 conditions in turn, no unknown
  drawn) on the launch fidelity's engine, and
- under **robust** draws of every unknown (``objective.robust``, the search's measure), on the same engine,

all on one base seed per measure, so within a measure every shape and the bare robot meet the same launches. It
prints each shape's printed mass (``core/profile/print_mass.py``), its rate on both measures with Wilson 95%
intervals and its gain over the bare robot with Newcombe's 95% interval. All numbers are simulated.
"""
import argparse
import dataclasses
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

from bench.bench_shape_ceiling import nominal_settings, shapes  # noqa: E402

from rollability_ros.core.optimization import batch_evaluation  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402
from rollability_ros.core.stats import newcombe_interval, wilson_interval  # noqa: E402

#: Base seeds of the nominal and the robust launches (none is a seed the campaign or a study uses).
NOMINAL_SEED, ROBUST_SEED = 778001, 778003

#: Four of bench_shape_ceiling's best shapes at the shipped and the doubled height scale (printed mass).
DEFAULT_SHAPES = ("H 0.45 a 1.0 b 1.0", "H 0.45 a 0.5 b 1.0", "H 0.32 a 0.5 b 0.5", "H 0.20 a 1.0 b 0.5")


def robust_settings(configs):
    """The launch fidelity's settings with every unknown drawn (the search's measure) on the launch engine."""
    nominal = nominal_settings(configs)
    objective = dataclasses.replace(nominal.objective,
                                    robust=dataclasses.replace(nominal.objective.robust, enabled=True))
    return dataclasses.replace(nominal, objective=objective)


def printed_mass_g(settings, heights) -> float:
    """The printed profile's mass, g (0 for the bare robot)."""
    job = evaluation.profile_job(heights, settings)
    return 0.0 if job.profile is None else 1000.0 * job.profile.mass_kg


def measure(configs, names, launches, workers):
    """``{measure: {name: (upright, launches)}}`` and ``{name: mass g}`` for ``names`` under ``configs`` (``workers``
    0: in this process)."""
    counts, masses = {}, {}
    for label, settings, seed in (("nominal", nominal_settings(configs), NOMINAL_SEED),
                                  ("robust", robust_settings(configs), ROBUST_SEED)):
        family = shapes(settings.grid)
        masses = {name: printed_mass_g(settings, family[name]) for name in names}
        with evaluation.LocalExecutor(workers) if workers else evaluation.SerialExecutor() as pool:
            evaluate = batch_evaluation.fidelity_batch_evaluator(settings, pool, "screen")
            counts[label] = {name: (int(r[0]), int(r[1])) for name, r in
                             zip(names, evaluate([family[name] for name in names], seed, launches))}
    return counts, masses


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--option", action="append", default=[], metavar="NAME=FILE[,FILE...]",
                        help="an option: parameter files over the quick study's (repeat; default: the shipped one)")
    parser.add_argument("--shapes", nargs="+", default=list(DEFAULT_SHAPES))
    parser.add_argument("--launches", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2, help="worker processes (0: in this process)")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: one shape, one launch per measure, in this "
                                                             "process; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    if args.smoke:
        args.shapes, args.launches, args.workers = args.shapes[:1], 1, 0
    options = [("shipped", [])] + [(text.split("=", 1)[0], text.split("=", 1)[1].split(","))
                                   for text in args.option]
    names = ["bare", *args.shapes]
    for name, files in options:
        started = time.perf_counter()
        counts, masses = measure(["optimizer", *files], names, args.launches, args.workers)
        grid = nominal_settings(["optimizer", *files]).grid
        print(f"\noption {name} ({', '.join(files) or 'the quick study as shipped'}): heights up to "
              f"{grid.height_max * grid.unit_m:.3f} m, footprint {grid.length_m:.3f} x {grid.width_m:.3f} m; "
              f"{args.launches} launches per shape and measure (simulated), {time.perf_counter() - started:.0f} s",
              flush=True)
        for measure_name in ("nominal", "robust"):
            bare = counts[measure_name]["bare"]
            low, high = wilson_interval(*bare)
            print(f"  {measure_name}: bare robot {bare[0]}/{bare[1]} [{low:.2f}, {high:.2f}]")
            for shape in args.shapes:
                s, n = counts[measure_name][shape]
                low, high = wilson_interval(s, n)
                gain, gain_low, gain_high = newcombe_interval(s, n, *bare)
                print(f"    {shape:<20} {masses[shape]:>6.0f} g  {s:>4}/{n} = {s / n:.2f} [{low:.2f}, {high:.2f}]; "
                      f"minus bare {gain:+.2f} [{gain_low:+.2f}, {gain_high:+.2f}]", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
