"""`rollability sensitivity`: the simulated fitness of the bare chassis and of profiles against each uncertain
factor (disturbance scale, start pose, contact reading, centre of mass) and robustly, with intervals; with
``--launches``, launches on the twin against each of its unknowns (both ends of each range) and robustly."""
import argparse
import csv
import os
import typing

from rollability_ros.cli import Subparsers

if typing.TYPE_CHECKING:  # annotations only: the command imports its core modules when it runs
    from rollability_ros.core.profile import Mesh


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


def run(args: argparse.Namespace) -> int:
    """Run the sensitivity study, write ``sensitivity.csv`` and ``sensitivity.png`` to ``--out``; exit code."""
    from rollability_ros.core.config import check_output_dir
    from rollability_ros.core.optional import MissingDependency
    from rollability_ros.core.results import sensitivity_figure
    from rollability_ros.core.sim import load_settings, make_executor, with_given_files
    from rollability_ros.core.results import gain_lines
    from rollability_ros.core.sim import launch_sensitivity_rows, sensitivity_rows

    check_output_dir(args.out, "--out", keeps=("sensitivity.csv", "sensitivity.png"))
    settings = with_given_files(load_settings(["sim", "robot", "evaluator", *args.config]),
                                args.config, "rollability sensitivity")
    if args.trials < 1:
        raise ValueError(f"--trials must be >= 1, got {args.trials}")
    profiles = _profiles(args)
    varied = _varied(args.vary)
    if varied and not args.launches:
        raise ValueError("--vary needs --launches (it varies a launch twin setting)")
    os.makedirs(args.out, exist_ok=True)

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
                    "random numbers); prints each fitness with its Wilson 95%% interval and writes "
                    "sensitivity.csv and sensitivity.png. With --launches: launches on the twin under the "
                    "campaign's conditions, each of the twin's unknowns (contact reading, centre of mass, foam "
                    "stiffness, restitution, friction and rolling friction, wheel drag) at both ends of its "
                    "range (objective.robust) and all drawn at once; each design minus the bare robot with its "
                    "Newcombe 95%% interval. See docs/optimization.md and docs/twin-model.md.")
    parser.add_argument("--mesh", action="append", default=[], metavar="LABEL=FILE",
                        help="a profile solid (STL/OBJ, metres, base on z = 0) under a label (repeatable)")
    parser.add_argument("--designs-file", metavar="FILE", help="designs.yaml of `rollability select`")
    parser.add_argument("--launches", action="store_true",
                        help="vary the launch twin's unknowns on launches (the rig's measure) instead of the "
                             "disturbance trial's factors")
    parser.add_argument("--vary", action="append", default=[], metavar="NAME=LOW,HIGH",
                        help="with --launches: also a row per level of this numeric launch twin setting, by its "
                             "dotted settings name (e.g. twin.wheel_side_friction_factor=0.03,0.5; repeatable)")
    parser.add_argument("--trials", type=int, default=60, help="trials (or launches) per evaluation (default 60)")
    parser.add_argument("--seed", type=int, default=0, help="the one base seed of every evaluation (default 0)")
    parser.add_argument("--workers", type=int, help="worker processes (default: evaluator.workers)")
    parser.add_argument("--out", default="sensitivity", help="output folder (default ./sensitivity); one that "
                                                             "already holds sensitivity results is refused")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="extra parameter file loaded over sim, robot and evaluator (repeatable)")
    parser.set_defaults(func=run)
