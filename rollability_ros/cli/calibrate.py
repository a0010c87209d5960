"""`rollability calibrate`: fit the launch twin to recorded physical outcomes and write a calibrated parameter file."""
import argparse
import csv
import os
import typing

from rollability_ros.cli import Subparsers

if typing.TYPE_CHECKING:  # annotations only: the command imports its core modules when it runs
    from rollability_ros.core.campaign import CalibrationResult, CalibrationSettings, LearntLikelihood
    from rollability_ros.core.sim import LaunchTwinSettings


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
             f"{'parameter':<42} {'start':>10} {'fitted':>10} {'95% interval':>24}"
             + (f" {'bootstrap sd':>13}" if any(e.bootstrap for e in result.estimates) else "")]
    lines += [f"{e.name:<42} {e.initial:>10.4g} {e.fitted:>10.4g} "
              f"{f'[{e.interval_low:.4g}, {e.interval_high:.4g}]':>24}"
              + (f" {e.std:>13.3g}" if e.bootstrap else "") + f"  ({e.interval_method})" for e in result.estimates]
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


def _header(sources: typing.Sequence[str], method: str, note: str = "") -> str:
    """The comment at the top of calibrated.yaml: where the values come from and where their uncertainty is
    (``note``: a further line, e.g. the learnt likelihood's temperature and the coverage measured at it)."""
    return (f"# Calibrated launch-twin parameters from {' and '.join(sources)} (rollability calibrate); load on top "
            f"of the\n# defaults: --config / --rig-config. Each value's 95% {method} is in parameters.csv beside "
            f"this file.\n" + (f"# {note}\n" if note else ""))


def _write_outputs(args: argparse.Namespace, sources: typing.Sequence[str], method: str,
                   fitted: typing.Mapping[str, float], note: str = "") -> str:
    """Write calibrated.yaml and calibrated_rig.yaml into ``args.out``; return calibrated.yaml's path."""
    import yaml

    from rollability_ros.core.campaign import calibrated_parameter_document, rig_parameter_document
    from rollability_ros.core.optimization import atomic_write_bytes

    os.makedirs(args.out, exist_ok=True)
    params_path = os.path.join(args.out, "calibrated.yaml")
    document = calibrated_parameter_document(fitted)
    atomic_write_bytes(params_path, (_header(sources, method, note) + yaml.safe_dump(document, sort_keys=True)).encode())
    rig_document = rig_parameter_document(os.path.abspath(params_path))
    atomic_write_bytes(os.path.join(args.out, RIG_FILE),
                       (f"# A rig node's twin on {params_path}: --params-file after config/rig.yaml\n"
                        + yaml.safe_dump(rig_document, sort_keys=True)).encode("utf-8"))
    return params_path


#: The most launches ``--prepare`` simulates: 125 times the default 8000 (sized for 15 minutes on 2 cores). Its draws
#: are made before the first launch: 10^11 launches asked numpy for 11 TiB at once.
MAX_PREPARE_LAUNCHES = 1_000_000
#: The most steps of ``--sampler-steps``: its chains are allocated whole (steps x walkers x unknowns per member).
MAX_SAMPLER_STEPS = 100_000


def prepare(args: argparse.Namespace, parameters: typing.Mapping[str, typing.Any], twin: "LaunchTwinSettings",
            settings: "CalibrationSettings") -> int:
    """``--prepare FILE``: simulate the training launches and learn the likelihood of the fitted unknowns over the
    loaded twin's configurations (the bare robot and ``launch_twin.designs``) and the campaign's levels."""
    import time

    from rollability_ros.core.campaign import (CampaignSpec, ConditionLevels, Unknowns, learn,
                                               simulate_training_set, twin_fingerprint)
    from rollability_ros.core.config import from_mapping, section
    from rollability_ros.core.sim import spawn_pool

    if os.path.exists(args.prepare):
        raise ValueError(f"--prepare {args.prepare}: the file exists; a prepared likelihood is never overwritten")
    if not 200 <= args.prepare_launches <= MAX_PREPARE_LAUNCHES:   # 10^11 was an 11 TiB MemoryError traceback
        raise ValueError(f"--prepare-launches must be in [200, {MAX_PREPARE_LAUNCHES}], got {args.prepare_launches}")
    spec = from_mapping(CampaignSpec, section(parameters, "campaign"), "campaign")
    levels = ConditionLevels(tuple(spec.heights_m), tuple(spec.speeds_mps), tuple(spec.angles_deg))
    configurations = ["baseline", *(label for label in parameters.get("launch_twin.designs.mesh_labels", []) if label)]
    unknowns = Unknowns(tuple(settings.parameters), tuple(settings.lower), tuple(settings.upper),
                               tuple(settings.log_scale))
    fingerprint = twin_fingerprint(parameters, unknowns.names)
    print(f"preparing the likelihood of {', '.join(unknowns.names)} over {', '.join(configurations)} from "
          f"{args.prepare_launches} twin launches")
    started = time.perf_counter()
    workers = settings.workers or os.cpu_count() or 1
    pool = spawn_pool(workers)
    try:
        def progress(done: int, total: int) -> None:
            if done == total or done % 1000 < 25:
                print(f"  {done}/{total} launches, {time.perf_counter() - started:.0f} s", flush=True)
        training = simulate_training_set(twin, unknowns, configurations, levels,
                                         args.prepare_launches, settings.seed, pool, on_progress=progress)
        likelihood = learn(training, unknowns, configurations, levels, fingerprint, settings.seed,
                           on_progress=print, pool=pool)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    likelihood.info["prepare_s"] = time.perf_counter() - started
    likelihood.save(args.prepare)
    print(f"prepared likelihood: {args.prepare} ({likelihood.info['prepare_s']:.0f} s on {workers} workers); "
          f"its calibrations' temperature {likelihood.temperature:g} ({likelihood.temperature_source})")
    return 0


def outcome_names(which: str) -> typing.Optional[typing.Tuple[str, ...]]:
    """``--outcomes``: ``none`` -> () (the verdicts only), ``all`` -> None (every one), else the comma-separated
    names, each one of ``likelihood.OUTCOMES`` (``ValueError`` naming an unknown one)."""
    from rollability_ros.core.campaign import OUTCOMES

    if which == "none":
        return ()
    if which == "all":
        return None
    names = tuple(name.strip() for name in which.split(","))
    unknown = [name for name in names if name not in OUTCOMES]
    if unknown:
        raise ValueError(f"--outcomes: unknown outcome {unknown[0]!r} (known: none, all, {', '.join(OUTCOMES)})")
    return names


def _temperature(args: argparse.Namespace, likelihood: "LearntLikelihood") -> typing.Tuple[float, str]:
    """The launches' temperature (``--temperature``, else the prepared file's) and the report's line on it: where
    it came from and the coverage measured at it, or that none was."""
    from rollability_ros.core.campaign import temperature_statement

    if args.temperature is None:
        return likelihood.temperature, temperature_statement(
            likelihood.temperature, f"the file's; {likelihood.temperature_source}")
    return args.temperature, temperature_statement(args.temperature, "given by --temperature")


def _check_sampler_flags(args: argparse.Namespace) -> None:
    """``ValueError`` naming a ``--sampler-steps`` or ``--seed`` the posterior sampler cannot take."""
    if not 20 <= args.sampler_steps <= MAX_SAMPLER_STEPS:   # 10^11 was a 23 TiB MemoryError traceback
        raise ValueError(f"--sampler-steps must be in [20, {MAX_SAMPLER_STEPS}], got {args.sampler_steps}")
    if args.seed < 0:   # numpy's own refusal named neither the flag nor the value
        raise ValueError(f"--seed must be >= 0, got {args.seed}")


def run_learnt(args: argparse.Namespace, parameters: typing.Mapping[str, typing.Any], twin: "LaunchTwinSettings",
               outcomes: typing.Sequence[typing.Any], characterisation: typing.Any,
               sources: typing.Sequence[str]) -> int:
    """``--likelihood FILE``: the posterior of the ``--fit`` unknowns (default: all the file's) from the prepared
    likelihood, the file's other unknowns held at their loaded values; write the outputs and print the summary."""
    import numpy as np

    from rollability_ros.core.campaign import (OUTCOMES, characterisation_term, format_set, gate_term,
                                               load_likelihood, observations_from_outcomes, sample_posterior,
                                               shot_observations, twin_fingerprint)
    from rollability_ros.core.results import group_conditions

    _check_sampler_flags(args)
    likelihood = load_likelihood(args.likelihood)
    unknowns = likelihood.unknowns
    if likelihood.fingerprint != twin_fingerprint(parameters, unknowns.names):
        raise ValueError(f"{args.likelihood}: prepared for another twin or design set than the loaded parameter "
                         f"files (a setting, a design mesh or the twin's code differs): prepare it again (--prepare)")
    sampled = list(dict.fromkeys(args.fit)) or list(unknowns.names)
    fixed = {name: float(parameters[name]) for name in unknowns.names if name not in sampled}
    observations = observations_from_outcomes(outcomes)
    chosen = outcome_names(args.outcomes)
    terms = ([characterisation_term(characterisation, twin, unknowns, gate_shots=not args.gate, sampled=sampled)]
             if characterisation is not None else [])
    if args.gate:   # the gate's reading weighed once, by its exact term; the launcher's shots in the same groups
        shots = shot_observations(characterisation.gate_shots) if characterisation is not None else []
        terms.append(gate_term([*shots, *observations], twin, unknowns, sampled=sampled))
        chosen = tuple(n for n in (OUTCOMES if chosen is None else chosen) if n != "measured_speed_mps")

    def extra(u: np.ndarray) -> np.ndarray:
        """The exact terms' log-likelihood (s,): characterisation, gate."""
        return np.sum([term(u) for term in terms], axis=0)
    temperature, tempered = _temperature(args, likelihood)
    posterior = sample_posterior(likelihood, observations, sampled, fixed, extra if terms else None, seed=args.seed,
                                 steps=args.sampler_steps, temperature=temperature, outcomes=chosen)
    fitted = posterior.best()
    method = "highest-density set of the learnt likelihood's posterior"
    params_path = _write_outputs(args, sources, f"credible set ({method})", fitted, tempered)
    rows = []
    for i, name in enumerate(posterior.names):
        j = unknowns.names.index(name)
        sets = posterior.credible_set(name)
        rows.append({"parameter": name, "initial": float(parameters[name]), "fitted": fitted[name],
                     "median": posterior.median(name), "set": format_set(sets),
                     "set_low": sets[0][0], "set_high": sets[-1][1],
                     "set_width_fraction": posterior.set_width_fraction(name), "split": len(sets) > 1,
                     "lower": unknowns.lower[j], "upper": unknowns.upper[j], "method": method,
                     "temperature": temperature})
    _write_csv(os.path.join(args.out, "parameters.csv"), rows)
    full = {**fixed, **fitted}
    before = {**fixed, **{n: float(parameters[n]) for n in sampled}}
    conditions = group_conditions(outcomes)
    condition_rows = []
    for c in conditions:
        cell = (c.height_m, c.speed_mps, c.angle_deg)
        predicted = [float(likelihood.predict_upright_probability(
            np.array([[values[n] for n in unknowns.names]]), c.configuration, cell)[0]) for values in (before, full)]
        condition_rows.append({"configuration": c.configuration, "height_m": c.height_m, "speed_mps": c.speed_mps,
                               "angle_deg": c.angle_deg, "trials": c.trials, "successes": c.successes,
                               "measured_rate": c.successes / c.trials, "before_probability": predicted[0],
                               "after_probability": predicted[1]})
    if condition_rows:
        _write_csv(os.path.join(args.out, "conditions.csv"), condition_rows)
    lines = [f"physical launches: {len(observations)} valid; posterior of {len(sampled)} unknown(s) from the prepared "
             f"likelihood {args.likelihood} ({len(posterior.samples)} samples pooled over its "
             f"{likelihood.ensemble_size} ensemble members, {posterior.wall_s:.1f} s)"
             + (f"; held at their loaded values: {', '.join(f'{n} = {v:.4g}' for n, v in fixed.items())}"
                if fixed else ""),
             tempered,
             f"{'parameter':<42} {'start':>10} {'fitted':>10}   95% set (a split set is a union of intervals)"]
    lines += [f"{r['parameter']:<42} {r['initial']:>10.4g} {r['fitted']:>10.4g}   {r['set']} "
              f"({r['set_width_fraction']:.0%} of the range{', split' if r['split'] else ''})" for r in rows]
    summary = "\n".join(lines)
    with open(os.path.join(args.out, "summary.txt"), "w", encoding="utf-8") as stream:
        stream.write(summary + "\n")
    print(summary)
    print(f"calibrated parameter file: {params_path} (a rig node's: {os.path.join(args.out, RIG_FILE)})")
    return 0


def run(args: argparse.Namespace) -> int:
    """Calibrate, write the outputs to ``--out`` and print the summary; return the exit code."""
    from rollability_ros.core.campaign import (TWIN_CONFIGS, LaunchPool, calibrate, calibration_settings,
                                               check_designs_print, check_fittable, load_characterisation,
                                               load_twin_files, twin_settings_with)
    from rollability_ros.core.config import check_output_dir, from_mapping, section
    from rollability_ros.core.results import load_report_data
    from rollability_ros.core.sim import TWIN_SECTIONS, ScreenSettings, launch_twin_settings_from_parameters

    if args.prepare and args.likelihood:
        raise ValueError("give --prepare FILE (learn a likelihood) or --likelihood FILE (calibrate with one), not both")
    if args.temperature is not None and not args.likelihood:
        raise ValueError("--temperature tempers a prepared likelihood: give it with --likelihood FILE")
    if args.gate and not args.likelihood:
        raise ValueError("--gate adds the speed gate's term to a prepared likelihood: give it with --likelihood FILE")
    if args.outcomes != "none" and not args.likelihood:
        raise ValueError("--outcomes chooses a prepared likelihood's continuous outcomes: give it with --likelihood "
                         "FILE")
    if not args.prepare:
        check_output_dir(args.out, "--out", keeps=("calibrated.yaml", RIG_FILE))   # before minutes of fitting
    parameters, unread = load_twin_files([*TWIN_CONFIGS, "calibration", "campaign"], args.config,
                                         {*TWIN_SECTIONS, "calibration", "stable_poses", "campaign"},
                                         "rollability calibrate")
    settings = calibration_settings(parameters)
    if args.fit and not args.likelihood:
        settings = settings.selected(args.fit)
    if args.workers is not None:
        if args.workers < 1:
            raise ValueError(f"--workers must be >= 1, got {args.workers}")
        settings.workers = args.workers
    twin = launch_twin_settings_from_parameters(parameters)   # the twin parsed once; the core is handed it typed
    check_designs_print(twin, "--config")   # every path weighs or launches the designs: under their print only
    if unread:
        print(unread)
    if args.prepare:
        check_fittable(twin, settings)
        return prepare(args, parameters, twin, settings)
    characterisation = load_characterisation(args.characterisation) if args.characterisation else None
    if args.physical is None and characterisation is None:
        raise ValueError("give --physical (launch outcomes) and/or --characterisation (bench readings)")
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
    if args.likelihood:
        return run_learnt(args, parameters, twin, outcomes, characterisation, sources)
    check_fittable(twin, settings)   # before any launch
    with LaunchPool(settings.workers) as pool:
        result = calibrate(outcomes, twin, settings, pool, on_progress=print,
                                       characterisation=characterisation)
    params_path = _write_outputs(args, sources, f"interval ({settings.interval})", result.fitted_values())
    calibrated_twin = twin_settings_with(twin, settings.parameters,
                                                     [e.fitted for e in result.estimates])
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
                    "friction, restitution, speed scatter, centre of mass, foam rolling friction, wheel drag, "
                    "profile mass, launcher, with bounds) to physical outcomes and/or bench characterisation "
                    "readings. With --likelihood FILE (made once by --prepare FILE): the posterior of the unknowns "
                    "from a likelihood learnt on simulated launches, over the verdicts and the measured outcomes "
                    "(gate speed, final tilt, peak deceleration, time to rest, rest distance), in minutes, with 95% "
                    "highest-density sets (a split set printed as a union of intervals). Without it: CMA-ES on the "
                    "twin simulated afresh for every parameter set, with a likelihood-ratio 95% interval per "
                    "parameter (calibration.interval). Writes calibrated.yaml, a parameter file the evaluator, "
                    "optimizer and rig load on top of the defaults, calibrated_rig.yaml, which points a rig node's "
                    "twin at it, and parameters.csv with each value's 95% interval or set.")
    parser.add_argument("--physical", metavar="SOURCE",
                        help="physical launch outcomes: a store, a run directory, a bag or a CSV (docs/outcome-csv.md); "
                             "needed unless --characterisation is given")
    parser.add_argument("--characterisation", metavar="FILE",
                        help="bench readings (roll-out, slide angle, tip angle) of docs/characterisation.md, fitted "
                             "beside the launch outcomes, or alone before the first launch")
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
    parser.add_argument("--prepare", metavar="FILE",
                        help="learn the likelihood of the --fit unknowns (default: all declared) over the loaded "
                             "twin's configurations and the campaign's levels from simulated launches, and write it "
                             "to FILE (.npz; never overwritten), with the temperature a calibration with it uses "
                             "(0.25, chosen on held-out truths: --temperature); once per robot and design set")
    parser.add_argument("--prepare-launches", type=int, default=8000, metavar="N",
                        help="simulated launches of --prepare, 200 to 1000000 (default 8000: sized for 15 minutes on 2 quiet "
                             "cores)")
    parser.add_argument("--likelihood", metavar="FILE",
                        help="calibrate with a likelihood made by --prepare (its twin and designs must be the loaded "
                             "ones): the posterior of the --fit unknowns, the file's others held at their loaded "
                             "values")
    parser.add_argument("--seed", type=int, default=1, help="seed of the posterior sampler (--likelihood)")
    parser.add_argument("--sampler-steps", type=int, default=300, metavar="N",
                        help="steps of the posterior sampler per ensemble member (--likelihood; the first half is "
                             "discarded; 20 to 100000)")
    parser.add_argument("--outcomes", default="none", metavar="WHICH",
                        help="the continuous outcomes the learnt likelihood weighs beside the verdicts (--likelihood): "
                             "none (default: the verdicts only), all (every one the records carry) or NAME,NAME of "
                             "measured_speed_mps, final_tilt_deg, ... (measured: the learnt continuous outcomes are "
                             "biased, sets from them missed their truths; docs/calibration.md)")
    parser.add_argument("--temperature", type=float, metavar="T",
                        help="raise the launches' learnt log-likelihood to T in (0, 1] (--likelihood; default: the "
                             "file's, which --prepare records as 0.25, the temperature chosen on held-out truths; a "
                             "file prepared earlier gets 0.25 too): below 1 widens the sets for an emulator less "
                             "accurate than its ensemble says. The report states the temperature used and the "
                             "coverage measured at it (at 1: 80%%, under the 90%% target), or that none was measured "
                             "(docs/calibration.md)")
    parser.add_argument("--gate", action="store_true",
                        help="weigh each launch's speed-gate reading through the twin's launcher model, tabulated "
                             "(exact, never tempered) (--likelihood, with the speed bias among the fitted unknowns): "
                             "it pins launch_twin.launcher.speed_bias_fraction; the learnt gate outcome is then not "
                             "weighed (docs/calibration.md, \"The speed gate's term\")")
    parser.set_defaults(func=run)
