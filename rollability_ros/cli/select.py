"""`rollability select RUN`: choose the designs to fabricate (Mesh A, B, C) from an optimization run."""
import argparse
import os
import sys
import typing

if typing.TYPE_CHECKING:
    import numpy

from rollability_ros.cli import Subparsers


#: ``selection`` settings a command-line option overrides (same names).
OVERRIDES = ("count", "min_distance", "reevaluate_trials", "mesh_units", "top_fraction", "launch_trials",
             "race_launches", "world_count", "world_launches")


def _print_table(rows):
    stream = sys.stdout   # looked up when called: sys.stdout may be replaced after import
    stream.write(f"{'design':<10}{'length m':>10}{'width m':>10}{'max h m':>10}{'mass g':>8}  {'fitness [95% CI]':<22}"
                 f"{'trials':>7}  {'source':<13}  {'in-run [95% CI]':<22}{'trials':>7}  bias\n")
    for row in rows:
        fitness = ("-" if not row["trials"] else
                   f"{row['simulated_fitness']:.3f} [{row['ci_low']:.3f}, {row['ci_high']:.3f}]")
        in_run = ("-" if not row["in_run_trials"] else
                  f"{row['in_run_fitness']:.3f} [{row['in_run_ci_low']:.3f}, {row['in_run_ci_high']:.3f}]")
        bias = "-" if row["selection_bias"] != row["selection_bias"] else f"{row['selection_bias']:+.3f}"
        mass = "-" if row["printed_mass_g"] == "" else f"{row['printed_mass_g']:.0f}"
        stream.write(f"{row['configuration']:<10}{row['length_m']:>10.4f}{row['width_m']:>10.4f}"
                     f"{row['max_height_m']:>10.4f}{mass:>8}  {fitness:<22}{row['trials']:>7}  "
                     f"{row['fitness_source']:<13}  "
                     f"{in_run:<22}{row['in_run_trials']:>7}  {bias}\n")


def _world_launch(evaluator_settings, executor):
    """``(world_launch, describe_world)`` of the selection's world check in this process (fidelity world:<seed>)."""
    from rollability_ros.core.optimization import fidelity_batch_evaluator
    from rollability_ros.core.sim import world_draws, world_fidelity

    def world_launch(heights_list: "typing.List[numpy.ndarray]", world_seed: int, launch_seed: int,
                     launches: int) -> typing.Sequence[typing.Tuple[int, int, float, str]]:
        evaluate = fidelity_batch_evaluator(evaluator_settings, executor, world_fidelity(world_seed))
        return evaluate(heights_list, launch_seed, launches)
    return world_launch, world_draws(evaluator_settings)


def _print_recommendation(result):
    """The world check per design and the recommendation, when the selection ran one (simulated)."""
    from rollability_ros.core.sim import summarize_worlds, world_check_lines

    if result.recommendation is None:
        return
    for line in world_check_lines(summarize_worlds(result.world_rows or [])):
        print(line)
    print(f"recommendation: {result.recommendation.headline()}")


def run(args: argparse.Namespace) -> int:
    """Select, export and report the designs; exit code 1 when fewer than requested qualify."""
    from rollability_ros.core.sim import make_executor, settings_from_parameters
    from rollability_ros.core.optimization import (GAIN_SOURCES, SelectionSettings, design_set_folders,
                                                   fidelity_batch_evaluator, profile_batch_evaluator, read_run_config,
                                                   resolve_run_dir, run_id_of, run_settings, select_run, table_rows,
                                                   with_given_files)
    from rollability_ros.core.config import from_mapping, section
    from rollability_ros.core.store import Store

    run_dir = resolve_run_dir(args.run, args.output_dir)
    parameters = read_run_config(run_dir)
    # later files win over the run's own config.yaml, key by key; a key no run applies is refused
    parameters = with_given_files(parameters, list(args.config), "rollability select")
    mapping = section(parameters, "selection")
    for name in OVERRIDES:
        if getattr(args, name) is not None:
            mapping[name] = getattr(args, name)
    settings = from_mapping(SelectionSettings, mapping, "selection")
    evaluator_settings = settings_from_parameters(parameters)
    run_id = run_id_of(run_dir)
    launches = bool(settings.race_rounds or settings.launch_trials or settings.world_count)
    executor = make_executor(evaluator_settings.evaluator, args.workers) \
        if settings.reevaluate_trials or launches else None
    try:
        evaluate_batch = profile_batch_evaluator(evaluator_settings, settings.reevaluate_trials, executor) \
            if executor is not None and settings.reevaluate_trials else None
        launch_batch = fidelity_batch_evaluator(evaluator_settings, executor, "launch") \
            if executor is not None and launches else None
        world_launch, describe_world = _world_launch(evaluator_settings, executor) \
            if executor is not None and settings.world_count else (None, None)
        with Store(run_dir) as store:
            result, folder = select_run(store, run_id, run_dir, evaluator_settings.grid,
                                        evaluator_settings.printer, settings, evaluate_batch,
                                        run_settings(parameters).optimizer.seed,
                                        launch_batch, weigh=lambda mesh: evaluator_settings.profile_body(mesh).mass_kg,
                                        world_launch=world_launch, describe_world=describe_world,
                                        printed_with=evaluator_settings.print_instructions())
    finally:
        if executor is not None:
            executor.close()
    if result.race is not None:
        race = result.race
        print(f"{len(result.designs)} design(s) from a race of {len(race.totals)} designs (the best by the screen) "
              f"on robust twin launches of run {run_id}: rounds of "
              f"{', '.join(str(r['trials']) for r in race.rounds)} launches, {len(race.survivors)} survived, "
              f"{race.trials_spent} launches spent"
              + (f"; bare robot {race.reference[0]}/{race.reference[1]}" if race.reference is not None else ""))
    elif result.top_threshold is None:
        print(f"{len(result.designs)} design(s) from {result.considered} distinct logged designs of run {run_id} "
              f"(min RMS distance {settings.min_distance} units)")
    else:
        print(f"{len(result.designs)} design(s) from the {result.considered} elites of run {run_id}'s height x "
              f"sharpness archive (top {settings.top_fraction:.0%}: fitness >= {result.top_threshold:.3f})")
    _print_table(table_rows(result))
    for design in result.designs:
        print(f"{design.label}: {design.reason}")
    for gain in result.gains():
        if gain is not None:
            print(f"{gain.label} minus the bare robot on {GAIN_SOURCES[gain.source]}: {gain.text()} "
                  f"(95% Newcombe){'' if gain.beats else '; does NOT beat the bare robot'}")
    print(f"wrote {folder}/: table3.csv, designs.yaml, {len(result.designs)} STL file(s) in "
          f"{'millimetres' if settings.mesh_units == 'mm' else 'metres'} and as many 3MF files")
    earlier = [os.path.basename(path) for path in design_set_folders(run_dir)
               if os.path.abspath(path) != os.path.abspath(folder)]
    if earlier:
        print(f"earlier design set(s) kept unchanged ({', '.join(earlier)}: stored outcomes and printed parts may "
              f"refer to them); a campaign on this set needs launch_twin.designs.designs_file: {folder}/designs.yaml")
    _print_recommendation(result)
    if result.no_design_helps():
        print(f"rollability select: warning: {result.no_design_helps()}; designs.yaml marks each design "
              f"beats_baseline: false", file=sys.stderr)
    if result.shortfall:
        print(f"rollability select: {result.shortfall}", file=sys.stderr)
        return 1
    return 0


def register(subparsers: Subparsers) -> None:
    """Add the ``select`` verb."""
    parser = subparsers.add_parser(
        "select", help="choose high-fitness, printable, diverse designs (Mesh A, B, C) from an optimization run",
        description="Pool every logged evaluation of the run per design, rank by the lower Wilson bound of the "
                    "fitness, and take the best designs that pass the printability checks and lie at least "
                    "--min-distance (RMS height difference, simulation units) from each other; optionally "
                    "re-evaluate them and the baseline with fresh trials. A quality-diversity run (optimizer.method "
                    "cma_mae) is selected from its height x sharpness archive instead: every elite screened on fresh "
                    "trials, A the best of the top decile (--top-fraction), B and C the top-decile elites farthest "
                    "from the designs already taken. Each design's reason is printed. Writes a new design set, "
                    "<run>/designs/ (or designs-2/, designs-3/, ... when the run has one: a written set is never "
                    "changed): mesh_<X>.stl "
                    "(millimetres unless --mesh-units m; the unit is in the STL header), mesh_<X>.3mf, "
                    "table3.csv (the paper's Table 3 with fitness and Wilson interval) and designs.yaml. "
                    "Defaults come from the run's config.yaml (section selection).")
    parser.add_argument("run", metavar="RUN", help="run id under --output-dir, or a run directory")
    parser.add_argument("--count", type=int, help="designs to choose (default: selection.count, 3)")
    parser.add_argument("--min-distance", type=float, help="minimum RMS height distance between designs, "
                                                           "simulation units (default: selection.min_distance)")
    parser.add_argument("--reevaluate-trials", type=int, help="fresh trials per design and the baseline; 0 = "
                                                              "report the logged estimate")
    parser.add_argument("--top-fraction", type=float, help="archive runs: choose among the elites in this top "
                                                           "fraction of fitness (default: selection.top_fraction, 0.1)")
    parser.add_argument("--race-launches", type=lambda text: [int(n) for n in text.split(",")], metavar="N,N,...",
                        help="rank designs by a race on robust twin launches: launches per design in each round "
                             "(default: selection.race_launches; 0 = no race, rank by the screen)")
    parser.add_argument("--launch-trials", type=int, help="fresh robust twin launches per chosen design and the "
                                                          "bare robot for the gain over it (default: "
                                                          "selection.launch_trials; 0 = none)")
    parser.add_argument("--world-count", type=int, help="worlds of the plausible-world check behind the "
                                                        "recommendation (default: selection.world_count; 0 = none)")
    parser.add_argument("--world-launches", type=int, help="paired launches per configuration in each world "
                                                           "(default: selection.world_launches)")
    parser.add_argument("--workers", type=int, help="worker processes for the re-evaluation")
    parser.add_argument("--mesh-units", choices=("mm", "m"), help="length unit of the STL files (default: "
                        "selection.mesh_units, mm as slicers expect)")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="a ROS 2 parameter file (or shipped name) whose keys override the run's config.yaml, "
                             "e.g. another printer section; repeatable, later files win")
    parser.add_argument("--output-dir", default="runs", help="root of run directories (default: runs)")
    parser.set_defaults(func=run)
