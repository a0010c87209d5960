"""`rollability evaluate`: the simulated rollability of one profile, with its Wilson 95% interval."""
import argparse
import sys
import typing

from rollability_ros.cli import Subparsers

if typing.TYPE_CHECKING:  # annotations only: the command imports its core modules when it runs
    from rollability_ros.core.profile import Mesh
    from rollability_ros.core.sim import TrialOutcome


def parse_heights(text: str, source: str = "--heights") -> typing.List[float]:
    """Parse profile heights (simulation units) separated by commas and/or whitespace; ValueError naming the
    problem for an empty list, an empty field (``1,,2``), a non-number or a non-finite value."""
    import math
    import re

    stripped = text.strip()
    if not stripped:
        raise ValueError(f"{source} is empty: give the rows*cols heights (or --baseline for the chassis alone)")
    heights = []
    for position, token in enumerate(re.split(r"\s*,\s*|\s+", stripped), start=1):
        if not token:
            raise ValueError(f"{source}: value {position} is empty (two separators in a row or a trailing comma)")
        try:
            value = float(token)
        except ValueError:
            raise ValueError(f"{source}: value {position} ({token!r}) is not a number") from None
        if not math.isfinite(value):
            raise ValueError(f"{source}: value {position} ({token!r}) is not finite")
        heights.append(value)
    return heights


def _read_heights(args):
    """The heights the arguments name (list of float), or None for the baseline / an STL."""
    if args.heights is not None:
        return parse_heights(args.heights)
    if args.heights_file is not None:
        with open(args.heights_file, encoding="utf-8") as stream:
            try:
                text = stream.read()
            except UnicodeDecodeError:   # its own message names neither the flag nor the file
                raise ValueError(f"--heights-file {args.heights_file}: not a text file of heights (UTF-8)") from None
        return parse_heights(text, source=f"--heights-file {args.heights_file}")
    return None


def run(args: argparse.Namespace) -> int:
    """Evaluate the profile the arguments name and print fitness, interval and timing; return the exit code."""
    from rollability_ros.core.sim import (evaluate_mesh, load_settings, make_executor, profile_job,
                                          settings_at_fidelity, with_given_files)
    from rollability_ros.core.profile import load_profile_mesh, profile_mesh

    # the objective and engine of the fidelity (objective.screen_engine / launch_engine; --engines names its own)
    settings = settings_at_fidelity(load_settings(["sim", "robot", "evaluator", *args.config]),
                                    args.fidelity)
    settings = with_given_files(settings, args.config, f"rollability evaluate --fidelity {args.fidelity}")
    trials = args.trials if args.trials is not None else settings.evaluator.trials
    if args.designs is not None:
        if args.engines is None:
            raise ValueError("--designs compares engines: give --engines too (e.g. --engines pybullet,mujoco)")
        return _compare_designs(args, settings, trials)
    mesh: typing.Optional["Mesh"]
    if args.stl is not None:
        mesh = load_profile_mesh(args.stl, units=args.stl_units)
        label = args.stl
    else:
        heights = _read_heights(args)
        job = profile_job(heights, settings)  # validates before any worker starts
        mesh = None if job.profile is None else profile_mesh(heights, settings.grid)
        label = "baseline (no profile)" if mesh is None else f"{len(heights)} heights"
    if args.engines is not None:   # `--engines ''` is refused (_engine_list), never one engine
        return _compare_engines(args, settings, mesh, trials, label)
    executor = make_executor(settings.evaluator, args.workers)
    done = []

    def progress(outcome: "TrialOutcome") -> None:
        done.append(outcome)
        if sys.stderr.isatty():
            sys.stderr.write(f"\r  {len(done)}/{trials} trials, {sum(o.upright for o in done)} upright ")
            sys.stderr.flush()

    try:
        result = evaluate_mesh(mesh, trials, args.seed, settings, executor=executor, on_trial=progress)
    finally:
        executor.close()
        if sys.stderr.isatty():
            sys.stderr.write("\n")
    mean_steps = sum(o.steps for o in result.trial_results) / result.trials
    print(f"profile   {label}")
    print(f"fitness   {result.fitness:.3f}  ({result.successes}/{result.trials} upright)  "
          f"95% CI [{result.ci_low:.3f}, {result.ci_high:.3f}] (Wilson)")
    print(f"seed      {args.seed}   steps/trial {mean_steps:.0f}   wall time {result.eval_time_s:.2f} s   "
          f"engine {settings.physics.engine}   fidelity {args.fidelity} (simulated)")
    return 0


def _engine_list(text):
    """The engines of ``--engines`` (comma separated), checked against the known ones."""
    from rollability_ros.core.sim import engine_names
    engines = [name.strip() for name in text.split(",") if name.strip()]
    unknown = [name for name in engines if name not in engine_names()]
    if unknown or len(engines) != 2 or engines[0] == engines[1]:
        raise ValueError(f"--engines needs two different engines of {', '.join(engine_names())}, got {text!r}")
    return engines


def _compare_engines(args, settings, mesh, trials, label):
    """Evaluate the same trials in two engines; print fitness per engine and trial-by-trial agreement."""
    import dataclasses
    from rollability_ros.core.results import trial_agreement
    from rollability_ros.core.sim import evaluate_mesh, make_executor

    engines = _engine_list(args.engines)
    results = {}
    for engine in engines:
        engine_settings = dataclasses.replace(settings, physics=dataclasses.replace(settings.physics, engine=engine))
        executor = make_executor(settings.evaluator, args.workers)
        try:
            results[engine] = evaluate_mesh(mesh, trials, args.seed, engine_settings, executor=executor)
        finally:
            executor.close()
    print(f"profile   {label}   seed {args.seed}   (simulated)")
    for engine, result in results.items():
        mean_steps = sum(o.steps for o in result.trial_results) / result.trials
        print(f"{engine:9s} fitness {result.fitness:.3f}  ({result.successes}/{result.trials} upright)  "
              f"95% CI [{result.ci_low:.3f}, {result.ci_high:.3f}]   steps/trial {mean_steps:.0f}   "
              f"wall time {result.eval_time_s:.2f} s")
    agreement = trial_agreement(*(result.trial_results for result in results.values()))
    print(f"agreement {agreement.agreed}/{agreement.trials} trials same outcome ({agreement.fraction:.3f}, 95% CI "
          f"[{agreement.ci_low:.3f}, {agreement.ci_high:.3f}]); upright in both {agreement.both_upright}, only "
          f"{engines[0]} {agreement.only_first_upright}, only {engines[1]} {agreement.only_second_upright}")
    return 0


def _compare_designs(args, settings, trials):
    """The baseline and every design of a designs.yaml in two engines on the same seeds: print the agreement
    summary and write it next to the designs file (``engine_agreement.csv``, read by ``rollability report``)."""
    import dataclasses
    import os
    from rollability_ros.core.profile import DesignSources, check_printed_with, configuration_ids, profile_mesh_for
    from rollability_ros.core.results import TABLE_FILENAME, summary_lines, table_rows, write_table
    from rollability_ros.core.sim import evaluate_mesh, make_executor

    engines = _engine_list(args.engines)
    sources = DesignSources(designs_file=args.designs)
    check_printed_with(args.designs, settings.print_instructions())   # the designs' masses assume their print
    table = os.path.join(os.path.dirname(os.path.abspath(args.designs)), TABLE_FILENAME)
    if os.path.lexists(table):   # before minutes of trials: an earlier comparison is a result, never overwritten
        raise ValueError(f"{table} already holds an earlier engine comparison of these designs; move it aside to "
                         "keep it, then run again")
    results: typing.Dict[str, typing.Dict[str, typing.Any]] = {}
    executor = make_executor(settings.evaluator, args.workers)   # one worker pool for every evaluation
    try:
        for design in configuration_ids(sources):
            mesh = profile_mesh_for(design, sources)
            results[design] = {}
            for engine in engines:
                engine_settings = dataclasses.replace(settings, physics=dataclasses.replace(settings.physics,
                                                                                            engine=engine))
                results[design][engine] = evaluate_mesh(mesh, trials, args.seed, engine_settings,
                                                        executor=executor)
    finally:
        executor.close()
    rows = table_rows(results, args.seed)
    path = write_table(table, rows)
    print("\n".join(summary_lines(rows)))
    print(f"wrote {path} (rollability report shows it)")
    return 0


def register(subparsers: Subparsers) -> None:
    """Add the ``evaluate`` verb."""
    parser = subparsers.add_parser(
        "evaluate", help="simulate one profile's self-righting rate (fitness) with its confidence interval",
        description="Run disturbance trials of one profile in PyBullet (paper 2.1.3) and print its fitness "
                    "(upright trials / trials) with the Wilson 95% interval. The profile is a list of half-grid "
                    "heights, a file of them, an STL/OBJ solid in metres, or the baseline (no profile).")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--heights", metavar="H1,H2,...",
                        help="rows*cols half-grid vertex heights in simulation units, comma separated")
    source.add_argument("--heights-file", metavar="FILE", help="a text file of heights (commas or whitespace)")
    source.add_argument("--stl", metavar="FILE", help="a profile solid (STL, OBJ or 3MF, base on z = 0; units "
                        "from the file's header, else --stl-units)")
    source.add_argument("--baseline", action="store_true", help="the chassis without a profile")
    source.add_argument("--designs", metavar="DESIGNS_YAML",
                        help="the baseline and every design of a designs.yaml (written by select); with --engines: "
                             "writes engine_agreement.csv beside it for the report")
    parser.add_argument("--stl-units", choices=("mm", "m"), help="length unit of --stl when the file does not "
                        "declare one (default: the file's own, else m)")
    parser.add_argument("--trials", type=int, help="number of trials (default: evaluator.trials, 60)")
    parser.add_argument("--seed", type=int, default=0, help="base seed of the trials' disturbances (default 0)")
    parser.add_argument("--workers", type=int,
                        help="worker processes (default: evaluator.workers; 0 = one per core)")
    parser.add_argument("--engines", metavar="A,B",
                        help="run the same trials in two engines (e.g. pybullet,mujoco) and print the fitness of "
                             "each and their trial-by-trial agreement")
    parser.add_argument("--fidelity", choices=("screen", "launch"), default="screen",
                        help="screen: the configured objective on objective.screen_engine (default); launch: robust "
                             "twin launches on objective.launch_engine, as the selection's race (empty engine = "
                             "sim.engine)")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="extra parameter file loaded over sim, robot and evaluator (repeatable)")
    parser.set_defaults(func=run)
