"""`rollability calibrate`: fit the launch twin to recorded physical outcomes and write a calibrated parameter file."""
import argparse
import csv
import os
import typing

from rollability_ros.cli import Subparsers

if typing.TYPE_CHECKING:  # annotations only: the command imports its core modules when it runs
    from rollability_ros.core.campaign import CalibrationResult


def _write_csv(path, rows):
    """Write homogeneous dict ``rows`` to ``path``; return the path."""
    with open(path, "w", newline="", encoding="utf-8") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path


def _screen_rows(twin_settings, configurations, screen_settings):
    """The stable-pose screen of each configuration on ``twin_settings``' robot, the built-in chassis or a URDF
    robot (quasi-static cross-check)."""
    from rollability_ros.core.sim import profile_body, screen_robot

    robot_model = twin_settings.robot_model()
    return [{"configuration": configuration,
             **screen_robot(robot_model, profile_body(configuration, twin_settings), screen_settings).row()}
            for configuration in configurations]


def summary_lines(result: "CalibrationResult",
                  screen_rows: typing.Sequence[typing.Mapping[str, typing.Any]]) -> typing.List[str]:
    """The printed summary: likelihood, parameters with uncertainty, per-configuration rates, rank agreement."""
    trials = sum(c.trials for c in result.conditions)
    lines = [f"grouped conditions: {len(result.conditions)}, physical trials: {trials}, parameter sets simulated: "
             f"{result.evaluations} x {result.sim_repetitions} launches per condition",
             f"log-likelihood: before {result.before_log_likelihood:.2f}, after {result.after_log_likelihood:.2f}",
             f"{'parameter':<42} {'start':>10} {'fitted':>10} {'95% interval':>24} {'bootstrap sd':>13}"]
    lines += [f"{e.name:<42} {e.initial:>10.4g} {e.fitted:>10.4g} "
              f"{f'[{e.interval_low:.4g}, {e.interval_high:.4g}]':>24} {e.std:>13.3g}" for e in result.estimates]
    lines.append(f"{'configuration':<14} {'measured':>9} {'before':>7} {'after':>7}   (trial success rates)")
    lines += [f"{row['configuration']:<14} {row['measured_trial_rate']:>9.0%} {row['before_trial_rate']:>7.0%} "
              f"{row['after_trial_rate']:>7.0%}" for row in result.configuration_rows()]
    for label, agreement in (result.rank_agreement() if result.conditions else {}).items():
        lines.append(f"rank agreement {label}: "
                     f"{agreement.agreement_text()}")
    lines += [f"screen {row['configuration']}: quasi-static P(upright) {row['upright_probability']:.2f}, worst "
              f"barrier {row['worst_barrier_m'] * 1000:.1f} mm ({row['worst_barrier_j']:.3f} J)" for row in screen_rows]
    return lines


#: The rig node's parameter file written beside calibrated.yaml (``rig.twin_config`` naming it).
RIG_FILE = "calibrated_rig.yaml"


def run(args: argparse.Namespace) -> int:
    """Calibrate, write the outputs to ``--out`` and print the summary; return the exit code."""
    import yaml

    from rollability_ros.core.campaign import (TWIN_CONFIGS, LaunchPool, calibrate, calibrated_parameter_document,
                                               calibration_settings, check_fittable, load_characterisation,
                                               rig_parameter_document, twin_settings_with)
    from rollability_ros.core.optimization import atomic_write_bytes
    from rollability_ros.core.config import check_given_files, check_output_dir, from_mapping, load_parameters, section
    from rollability_ros.core.results import load_report_data
    from rollability_ros.core.sim import TWIN_SECTIONS, ScreenSettings

    check_output_dir(args.out, "--out", keeps=("calibrated.yaml", RIG_FILE))   # before minutes of fitting
    check_given_files(args.config, {*TWIN_SECTIONS, "calibration", "stable_poses"}, "rollability calibrate")
    parameters = load_parameters([*TWIN_CONFIGS, "calibration", *args.config])
    settings = calibration_settings(parameters)
    if args.fit:
        settings = settings.selected(args.fit)
    characterisation = load_characterisation(args.characterisation) if args.characterisation else None
    if args.physical is None and characterisation is None:
        raise ValueError("give --physical (launch outcomes) and/or --characterisation (bench readings)")
    if args.workers is not None:
        if args.workers < 1:
            raise ValueError(f"--workers must be >= 1, got {args.workers}")
        settings.workers = args.workers
    screen_settings = from_mapping(ScreenSettings, section(parameters, "stable_poses"), "stable_poses")
    outcomes = []
    sources = []
    if args.physical is not None:
        data = load_report_data(args.physical, args.run)
        outcomes = [o for o in data.outcomes if o.backend == "physical"]
        if not outcomes:
            raise ValueError(f"{data.source}: no physical launch outcomes to calibrate against")
        sources.append(str(data.source))
    if characterisation is not None:
        print(characterisation.summary())
        sources.append(characterisation.source)
    check_fittable(parameters, settings)   # before any launch
    with LaunchPool(settings.workers) as pool:
        result = calibrate(outcomes, parameters, settings, pool, on_progress=print,
                           characterisation=characterisation)
    os.makedirs(args.out, exist_ok=True)
    params_path = os.path.join(args.out, "calibrated.yaml")
    document = calibrated_parameter_document(result.fitted_values())
    header = (f"# Calibrated launch-twin parameters from {' and '.join(sources)} (rollability calibrate); load on top "
              f"of the\n# defaults: --config / --rig-config. Bootstrap uncertainty in parameters.csv beside this "
              f"file.\n")
    atomic_write_bytes(params_path, (header + yaml.safe_dump(document, sort_keys=True)).encode("utf-8"))
    rig_document = rig_parameter_document(os.path.abspath(params_path))
    atomic_write_bytes(os.path.join(args.out, RIG_FILE),
                       (f"# A rig node's twin on {params_path}: --params-file after config/rig.yaml\n"
                        + yaml.safe_dump(rig_document, sort_keys=True)).encode("utf-8"))
    calibrated_twin = twin_settings_with(parameters, settings.parameters, [e.fitted for e in result.estimates])
    configurations = sorted({c.configuration for c in result.conditions})
    screen_rows = _screen_rows(calibrated_twin, configurations, screen_settings)
    if result.conditions:   # a characterisation alone has no launch conditions to compare
        _write_csv(os.path.join(args.out, "conditions.csv"), result.condition_rows())
        _write_csv(os.path.join(args.out, "configurations.csv"), result.configuration_rows())
        _write_csv(os.path.join(args.out, "screen.csv"), screen_rows)
    _write_csv(os.path.join(args.out, "parameters.csv"), [e.row() for e in result.estimates])
    summary = "\n".join(summary_lines(result, screen_rows))
    with open(os.path.join(args.out, "summary.txt"), "w", encoding="utf-8") as stream:
        stream.write(summary + "\n")
    print(summary)
    print(f"calibrated parameter file: {params_path} (a rig node's: {os.path.join(args.out, RIG_FILE)})")
    return 0


def register(subparsers: Subparsers) -> None:
    """Add the ``calibrate`` verb."""
    parser = subparsers.add_parser(
        "calibrate", help="fit the simulated launch twin to recorded physical launch outcomes",
        description="Fit the launch twin's uncertain parameters (config/calibration.yaml: foam stiffness, damping, "
                    "friction, restitution, speed scatter, centre of mass, foam rolling friction, wheel drag, with "
                    "bounds) to physical outcomes and/or bench characterisation readings by "
                    "maximising the binomial likelihood of the observed successes per grouped condition with "
                    "CMA-ES; report before/after agreement and bootstrap uncertainty; write calibrated.yaml, a "
                    "parameter file the evaluator, optimizer and rig load on top of the defaults, and "
                    "calibrated_rig.yaml, which points a rig node's twin at it.")
    parser.add_argument("--physical", metavar="SOURCE",
                        help="physical launch outcomes: a store, a run directory, a bag or a CSV (docs/outcome-csv.md); "
                             "needed unless --characterisation is given")
    parser.add_argument("--characterisation", metavar="FILE",
                        help="bench readings (roll-out, slide angle) of docs/characterisation.md, fitted beside the "
                             "launch outcomes, or alone before the first launch")
    parser.add_argument("--fit", action="append", default=[], metavar="KEY",
                        help="fit only this declared parameter (a key of calibration.parameters, with its bounds and "
                             "scale; repeatable); the others stay at their loaded values")
    parser.add_argument("--run", help="campaign run id in SOURCE (needed when it holds several)")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="parameter file loaded over sim, robot, launch_twin and calibration (repeatable)")
    parser.add_argument("--out", default="calibration", metavar="DIR",
                        help="output directory (default: ./calibration); one that already holds a calibrated.yaml "
                             "is refused (an earlier calibration is never overwritten)")
    parser.add_argument("--workers", type=int, help="launch worker processes (default: calibration.workers)")
    parser.set_defaults(func=run)
