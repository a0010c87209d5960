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

    nice python bench/bench_design_space.py --designs <study>/optimization/designs/designs.yaml
                                            [--labels A C] [--mass-scales 0.1 1 2] [--launches 100] [--config FILE]

With ``--designs`` it asks instead where a chosen design's gain comes from: the bare robot and each design (by
label) at each ``--mass-scales`` multiplier on its printed mass (``robot.profile_mass_scale``; 0.1 is nearly the
bare geometry, 1 the print of ``--config``'s ``robot.profile_print``), ``--launches`` nominal launches each under
the campaign's conditions in turn (seed :data:`SPLIT_SEED`): each row's upright total and its gain over the bare
robot (Newcombe 95%), split by launch speed and where the failures came to rest (``bench_shape_ceiling.rest_mode``).
``--config gradual_print`` (or another print option) with ``--mass-scales 1`` launches the designs as that print.
"""
import argparse
import dataclasses
import os
import sys
import time
import typing

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

from bench.bench_shape_ceiling import nominal_settings, rest_mode, shapes  # noqa: E402

from rollability_ros.core.optimization import batch_evaluation  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402
from rollability_ros.core.stats import newcombe_interval, wilson_interval  # noqa: E402

#: Base seeds of the nominal and the robust launches (none is a seed the campaign or a study uses).
NOMINAL_SEED, ROBUST_SEED = 778001, 778003
#: Base seed of ``--designs``' launches (split by speed and rest mode).
SPLIT_SEED = 779001

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


def split_launches(settings, mesh, mass_scale, launches, seed):
    """``([(speed m/s, rest mode)] per launch, printed mass kg)`` of ``launches`` nominal launches of ``mesh``
    (None = the bare robot) with its printed mass times ``mass_scale``."""
    from rollability_ros.core.sim import objectives
    from rollability_ros.core.sim.launch.twin import simulate_valid_launch

    settings = dataclasses.replace(settings, robot=dataclasses.replace(settings.robot, profile_mass_scale=mass_scale))
    objective = objectives.launch_objective(settings.objective, settings.resolved_launch, settings.physics.engine,
                                           early_decision=False)
    assert objective is not None, "the launch fidelity has a launch objective"
    profile = None if mesh is None else evaluation.mesh_job(mesh, settings).profile
    rows = []
    for index in range(launches):
        condition = objective.condition(index)
        result = simulate_valid_launch(condition, objective.twin, seed + index, profile=profile, use_profile=True)
        rows.append((condition.speed_mps, rest_mode(result)))
    return rows, 0.0 if profile is None else profile.mass_kg


def mass_split(args):
    """The ``--designs`` mode (module docstring): print each design's rate by speed at each mass multiplier."""
    import collections
    import concurrent.futures

    from rollability_ros.core.profile.designs import DesignSources, configuration_ids, profile_mesh_for

    settings = nominal_settings(["optimizer", *args.config])
    sources = DesignSources(designs_file=args.designs)
    labels = [label for label in configuration_ids(sources)
              if label != "baseline" and (not args.labels or label in args.labels)]
    jobs = [("bare", None, 1.0)] + [(label, profile_mesh_for(label, sources), scale)
                                    for label in labels for scale in args.mass_scales]
    started = time.perf_counter()
    columns = ([settings] * len(jobs), [job[1] for job in jobs], [job[2] for job in jobs],
               [args.launches] * len(jobs), [SPLIT_SEED] * len(jobs))
    if args.workers:
        with concurrent.futures.ProcessPoolExecutor(args.workers) as pool:
            results = list(pool.map(split_launches, *columns))
    else:   # in this process
        results = list(map(split_launches, *columns))
    print(f"{args.designs}: {args.launches} nominal launches each under the campaign's conditions in turn (seed "
          f"{SPLIT_SEED}, {settings.physics.engine} twin, simulated), {time.perf_counter() - started:.0f} s")
    bare = (0, 0)
    for (label, _mesh, scale), (rows, mass_kg) in zip(jobs, results):   # the bare robot first
        by_speed: typing.Dict[float, typing.Counter[str]] = collections.defaultdict(collections.Counter)
        for speed, mode in rows:
            by_speed[speed][mode] += 1
        parts = []
        for speed in sorted(by_speed):
            count = by_speed[speed]
            sides = sum(n for mode, n in count.items() if mode.startswith("on its"))
            parts.append(f"{speed} m/s: upright {count['upright']}/{sum(count.values())} (at rest upside down "
                         f"{count['upside down']}, on a side or end {sides}, tilted {count['tilted on its wheels']}, "
                         f"invalid {count['invalid']})")
        upright = sum(1 for _speed, mode in rows if mode == "upright")
        if label == "bare":
            bare = (upright, len(rows))
        gain, low, high = newcombe_interval(upright, len(rows), *bare)
        print(f"  {label:<5} mass x{scale:<4g} {mass_kg * 1000:>5.0f} g  all {upright}/{len(rows)}, minus bare "
              f"{gain:+.2f} [{low:+.2f}, {high:+.2f}]; " + "; ".join(parts), flush=True)
    return 0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--option", action="append", default=[], metavar="NAME=FILE[,FILE...]",
                        help="an option: parameter files over the quick study's (repeat; default: the shipped one)")
    parser.add_argument("--shapes", nargs="+", default=list(DEFAULT_SHAPES))
    parser.add_argument("--launches", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2, help="worker processes (0: in this process)")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: one shape, one launch per measure, in this "
                                                             "process; the numbers mean nothing (bench/smoke.py)")
    parser.add_argument("--designs", help="a designs.yaml: launch its designs at --mass-scales, split by speed")
    parser.add_argument("--labels", nargs="+", default=[], help="--designs: these designs only (default: all)")
    parser.add_argument("--mass-scales", type=float, nargs="+", default=[0.1, 1.0, 2.0])
    parser.add_argument("--config", action="append", default=[], help="--designs: parameter files over optimizer's")
    args = parser.parse_args(argv)
    if args.smoke:
        args.shapes, args.launches, args.workers = args.shapes[:1], 1, 0
    if args.designs:
        return mass_split(args)
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
