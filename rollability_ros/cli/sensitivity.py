"""`rollability sensitivity`: the simulated fitness of the bare chassis and of profiles against each uncertain
factor (disturbance scale, start pose, contact reading, centre of mass) and robustly, with intervals; with
``--launches``, launches on the twin against each of its unknowns (both ends of each range) and robustly; with
``--worlds N``, the plausible-world check (``core/sim/world_check.py``): the bare robot and every design launched
in each of N fixed draws of all unknowns on the same seeds."""
import argparse
import csv
import os
import sys
import typing

from rollability_ros.cli import Subparsers

if typing.TYPE_CHECKING:  # annotations only: the command imports its core modules when it runs
    from rollability_ros.core.profile import Mesh

#: ``--launches-per-world`` default: the campaign's 20 conditions twice.
DEFAULT_LAUNCHES_PER_WORLD = 40


def _profiles(args):
    """``{label: mesh or None}``: the bare chassis, then every ``--mesh LABEL=FILE`` and ``--designs-file`` design."""
    from rollability_ros.core.profile import load_profile_mesh
    from rollability_ros.core.profile import DesignSources, configuration_ids, profile_mesh_for

    profiles: typing.Dict[str, typing.Optional["Mesh"]] = {"baseline": None}
    for item in args.mesh:
        label, _, path = item.partition("=")
        if not label or not path:
            raise ValueError(f"--mesh takes LABEL=FILE, got {item!r}")
        profiles[label] = load_profile_mesh(path)
    if args.designs_file:
        sources = DesignSources(designs_file=args.designs_file)
        for label in configuration_ids(sources):
            if label != "baseline":
                profiles[label] = profile_mesh_for(label, sources)
    return profiles


def _varied(items: typing.Sequence[str]) -> typing.Dict[str, typing.Tuple[float, ...]]:
    """``{dotted setting: levels}`` of ``--vary NAME=LOW,HIGH`` items; ``ValueError`` naming a malformed one."""
    import math

    varied = {}
    for item in items:
        name, _, values = item.partition("=")
        try:
            levels = tuple(float(v) for v in values.split(","))
        except ValueError:
            levels = ()
        if not name or len(levels) < 2 or not all(math.isfinite(v) for v in levels):
            raise ValueError(f"--vary takes NAME=LOW,HIGH (two or more finite numbers), got {item!r}")
        varied[name] = levels
    return varied


#: Files the world check writes into ``--out``.
WORLD_FILES = ("world_check.csv", "world_summary.yaml")


def run_worlds(args: argparse.Namespace, settings: typing.Any, profiles: typing.Mapping[str, typing.Any]) -> int:
    """The plausible-world check: print it, write :data:`WORLD_FILES` to ``--out``; exit code."""
    import dataclasses

    import yaml

    from rollability_ros.core.optimization import SelectionSettings, recommend
    from rollability_ros.core.sim import (WORLD_CHECK_COLUMNS, local_world_evaluator, make_executor,
                                          run_world_check, settings_at_fidelity, summarize_worlds,
                                          world_check_lines, world_draws)

    if args.engine:
        settings = dataclasses.replace(settings, objective=dataclasses.replace(settings.objective,
                                                                               launch_engine=args.engine))
    engine = settings_at_fidelity(settings, "launch").physics.engine

    csv_path = os.path.join(args.out, WORLD_FILES[0])
    # each row written as it comes: a check stopped after hours keeps the worlds it ran (they were lost at Ctrl-C)
    with open(csv_path, "w", newline="", encoding="utf-8") as stream, \
            make_executor(settings.evaluator, args.workers) as executor:
        writer = csv.DictWriter(stream, fieldnames=list(WORLD_CHECK_COLUMNS))
        writer.writeheader()

        def show(row: typing.Mapping[str, typing.Any]) -> None:
            writer.writerow(row)
            stream.flush()
            print(f"world {row['world']:>3} {row['configuration']:<10} {row['successes']:>4}/{row['trials']:<4}",
                  flush=True)

        try:
            rows = run_world_check(local_world_evaluator(profiles, settings, executor), args.worlds,
                                   args.launches_per_world, args.seed, world_draws(settings), show)
        except KeyboardInterrupt:
            print(f"{csv_path} keeps the rows of the worlds done (no summary written)", file=sys.stderr)
            raise
    summaries = summarize_worlds(rows)
    verdict = recommend(summaries, SelectionSettings().recommend_world_share)
    document = {"simulated": True, "engine": engine, "worlds": args.worlds,
                "launches_per_world": args.launches_per_world, "seed": args.seed,
                "wins_mean": "a design wins a world when its point gain over the bare robot there is > 0",
                "designs": {s.configuration: s.as_dict() for s in summaries},
                "recommendation": verdict.as_dict()}
    yaml_path = os.path.join(args.out, WORLD_FILES[1])
    with open(yaml_path, "w", encoding="utf-8") as stream:
        yaml.safe_dump(document, stream, sort_keys=False)
    for line in world_check_lines(summaries, engine):
        print(line)
    print(f"recommendation (the selection's rule, selection.recommend_world_share): {verdict.headline()}")
    print(f"wrote {csv_path} and {yaml_path}")
    return 0


def _check_world_arguments(args: argparse.Namespace, profiles: typing.Mapping[str, typing.Any],
                           varied: typing.Mapping[str, typing.Any]) -> None:
    """``ValueError`` for world-check flags without ``--worlds``, with a flag of the factor study, or unusable."""
    if args.worlds is not None and (args.launches or varied):
        raise ValueError("--worlds runs the world check: it takes neither --launches nor --vary")
    if args.worlds is None and (args.engine or args.launches_per_world != DEFAULT_LAUNCHES_PER_WORLD):
        raise ValueError("--engine and --launches-per-world belong to the world check: give --worlds N")
    if args.worlds is not None and (args.worlds < 1 or args.launches_per_world < 1):
        raise ValueError(f"--worlds and --launches-per-world must be >= 1, got {args.worlds} and "
                         f"{args.launches_per_world}")
    if args.worlds is not None and len(profiles) < 2:
        raise ValueError("the world check needs designs: give --designs-file or --mesh")


def run(args: argparse.Namespace) -> int:
    """Run the sensitivity study, write ``sensitivity.csv`` and ``sensitivity.png`` to ``--out`` (the world check:
    :data:`WORLD_FILES`); exit code."""
    from rollability_ros.core.config import check_output_dir
    from rollability_ros.core.optional import MissingDependency
    from rollability_ros.core.results import sensitivity_figure
    from rollability_ros.core.sim import load_settings, make_executor, with_given_files
    from rollability_ros.core.results import gain_lines
    from rollability_ros.core.sim import launch_sensitivity_rows, sensitivity_rows

    check_output_dir(args.out, "--out", keeps=WORLD_FILES if args.worlds is not None else
                     ("sensitivity.csv", "sensitivity.png"))
    settings = with_given_files(load_settings(["sim", "robot", "evaluator", *args.config]),
                                args.config, "rollability sensitivity")
    if args.trials < 1:
        raise ValueError(f"--trials must be >= 1, got {args.trials}")
    if args.designs_file:
        from rollability_ros.core.profile import check_printed_with
        check_printed_with(args.designs_file, settings.print_instructions())   # the designs' masses assume it
    profiles = _profiles(args)
    varied = _varied(args.vary)
    if varied and not args.launches:
        raise ValueError("--vary needs --launches (it varies a launch twin setting)")
    _check_world_arguments(args, profiles, varied)
    os.makedirs(args.out, exist_ok=True)
    if args.worlds is not None:
        return run_worlds(args, settings, profiles)

    def show(row: typing.Mapping[str, typing.Any]) -> None:
        print(f"{row['configuration']:<10} {row['factor']:<18} {str(row['level']):<18} {row['successes']:>4}/"
              f"{row['trials']:<4} {row['fitness']:.2f} [{row['ci_low']:.2f}, {row['ci_high']:.2f}]", flush=True)

    with make_executor(settings.evaluator, args.workers) as executor:
        if args.launches:
            rows = launch_sensitivity_rows(profiles, settings, args.trials, args.seed, executor, on_row=show,
                                           settings_levels=varied)
        else:
            rows = sensitivity_rows(profiles, settings, args.trials, args.seed, executor, on_row=show)
    csv_path = os.path.join(args.out, "sensitivity.csv")
    with open(csv_path, "w", newline="", encoding="utf-8") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    try:
        figure = sensitivity_figure(os.path.join(args.out, "sensitivity.png"), rows)
    except MissingDependency:
        figure = None
    for line in gain_lines(rows):
        print(line)
    print(f"wrote {csv_path}" + (f" and {figure}" if figure else ""))
    return 0


def register(subparsers: Subparsers) -> None:
    """Add the ``sensitivity`` verb."""
    parser = subparsers.add_parser(
        "sensitivity", help="fitness of the bare chassis and profiles against each uncertain factor, with intervals",
        description="Evaluate the bare chassis and the given profiles with the disturbance trial, varying one "
                    "uncertain factor at a time (disturbance scale, start pose, contact reading, centre of mass) "
                    "and all of them at once (the robust fitness), every evaluation from one seed (common "
                    "random numbers); prints each fitness with its Wilson 95% interval and writes "
                    "sensitivity.csv and sensitivity.png. With --launches: launches on the twin under the "
                    "campaign's conditions, each of the twin's unknowns (contact reading, centre of mass, foam "
                    "stiffness, restitution, friction and rolling friction, wheel drag) at both ends of its "
                    "range (objective.robust) and all drawn at once; each design minus the bare robot with its "
                    "Newcombe 95% interval. With --worlds N: the plausible-world check (N fixed draws of all "
                    "unknowns; the bare robot and every design on the same seeds in each; simulated). See "
                    "docs/optimization.md and docs/twin-model.md.")
    parser.add_argument("--mesh", action="append", default=[], metavar="LABEL=FILE",
                        help="a profile solid (STL/OBJ, metres, base on z = 0) under a label (repeatable)")
    parser.add_argument("--designs-file", metavar="FILE", help="designs.yaml of `rollability select`")
    parser.add_argument("--launches", action="store_true",
                        help="vary the launch twin's unknowns on launches (the rig's measure) instead of the "
                             "disturbance trial's factors")
    parser.add_argument("--vary", action="append", default=[], metavar="NAME=LOW,HIGH",
                        help="with --launches: also a row per level of this numeric launch twin setting, by its "
                             "dotted settings name (e.g. twin.wheel_side_friction_factor=0.03,0.5; repeatable)")
    parser.add_argument("--worlds", type=int, metavar="N",
                        help="the plausible-world check: N fixed draws of all unknowns, the bare robot and every "
                             "design launched in each on the same seeds; per design the share of worlds it wins, "
                             "the worst world and the pooled gain (writes world_check.csv, world_summary.yaml)")
    parser.add_argument("--launches-per-world", type=int, default=DEFAULT_LAUNCHES_PER_WORLD, metavar="K",
                        help=f"with --worlds: paired launches per configuration in each world (default "
                             f"{DEFAULT_LAUNCHES_PER_WORLD}: the campaign's 20 conditions twice)")
    parser.add_argument("--engine", metavar="ENGINE",
                        help="with --worlds: the launch engine, pybullet | mujoco (default: objective.launch_engine, else sim.engine)")
    parser.add_argument("--trials", type=int, default=60, help="trials (or launches) per evaluation (default 60)")
    parser.add_argument("--seed", type=int, default=0, help="the one base seed of every evaluation (default 0)")
    parser.add_argument("--workers", type=int, help="worker processes (default: evaluator.workers)")
    parser.add_argument("--out", default="sensitivity", help="output folder (default ./sensitivity); one that "
                                                             "already holds sensitivity results is refused")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="extra parameter file loaded over sim, robot and evaluator (repeatable)")
    parser.set_defaults(func=run)
