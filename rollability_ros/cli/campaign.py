"""`rollability campaign`: run the launch campaign (paper 2.2.6) in this process or through the node graph."""
import argparse
import typing

from rollability_ros.cli import Subparsers, add_session_argument, join_session


def register(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "campaign", help="run the launch campaign on the launch twin or the physical rig, resumably",
        description="Run every trial of the campaign matrix not yet stored. Without --graph the rig runs in this "
                    "process (sim: the launch twin; physical: the valve, speed gate and your answers at the "
                    "terminal) and this command writes the store. With --graph it sends Launch goals to a running "
                    "rig node and waits until the outcome_logger acknowledges storing each outcome over ROS (one "
                    "writer; for a sim campaign its store may be on another computer; physical goals and answers are "
                    "signed with the valve's session key, so a physical --graph campaign runs on the rig computer). "
                    "Physical runs tell you what to change before each trial and wait for Enter; sim runs "
                    "unattended. Exit code 0 when complete, 3 when stopped early (rerun with --resume), 4 when more "
                    "than half of the launches are invalid (the message names the setting to change).")
    parser.add_argument("--backend", choices=("sim", "physical"), required=True,
                        help="sim: unattended launch twin; physical: the pneumatic launcher with an operator")
    parser.add_argument("--config", action="append", default=None,
                        help="campaign parameter file(s) (default: the shipped config/campaign.yaml)")
    parser.add_argument("--rig-config", action="append", default=None,
                        help="rig parameter file(s) for the in-process rig (default: config/rig.yaml)")
    parser.add_argument("--store",
                        help="store file or run directory (in process; with --graph the outcome_logger's own "
                             "store is used, over ROS)")
    parser.add_argument("--run-id", help="override campaign.run_id (the store key of the campaign)")
    parser.add_argument("--resume", action="store_true", help="continue a run that already has stored trials")
    parser.add_argument("--graph", action="store_true",
                        help="launch through the rig node (ROS 2) instead of in this process")
    parser.add_argument("--store-timeout-s", type=float, default=10.0,
                        help="with --graph: longest wait for the logger to acknowledge an outcome, s (default 10)")
    parser.add_argument("--session-key-file", default="",
                        help="with --graph --backend physical: the valve_controller's session key, to sign the goals "
                             "and answers (default: valve.session_key_file's default for this ROS domain)")
    add_session_argument(parser)
    parser.add_argument("--namespace", default=None,
                        help="with --graph: ROS namespace of the rig and outcome_logger (default: the session's with "
                             "--session, else bringup.namespace, /rollability as shipped: where `rollability bringup` "
                             "starts them)")
    parser.add_argument("--resimulate", nargs=4, metavar=("CONFIGURATION", "HEIGHT_M", "SPEED_MPS", "ANGLE_DEG"),
                        help="with --backend sim and --seed: run only this one launch on the launch twin and "
                             "print its outcome (the report's drill-down shows this command for every simulated "
                             "launch); with --store and --run-id on the twin files recorded for that run (refused "
                             "when one is missing or changed), else, or with --rig-config, on --rig-config's; "
                             "stores nothing")
    parser.add_argument("--seed", type=int,
                        help="with --resimulate: the twin seed of the launch (the stored outcome's seed)")
    _add_adaptive_arguments(parser)
    parser.set_defaults(func=run)


def _add_adaptive_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of the adaptive plan and of a comparison that stops once decided."""
    adaptive = parser.add_argument_group(
        "which launch next (docs/calibration.md, 'Which launch next')",
        "An adaptive plan launches, each time, the (configuration, condition) of the campaign matrix whose outcome "
        "tells most about the twin's unknowns (the expected information over samples of the unknowns weighted by the "
        "stored outcomes of the run). With --likelihood FILE (made once by `rollability calibrate --prepare`) the "
        "predictions are the learnt likelihood's, verdicts and continuous outcomes; without it P(upright) of each "
        "sample comes from --sim-repetitions twin launches, made once at the start. --propose-next prints that "
        "launch, as the technician sets it up, and why; it stores nothing.")
    adaptive.add_argument("--plan", choices=("matrix", "adaptive"), default="matrix",
                          help="matrix: every trial of the campaign matrix (default); adaptive: --budget launches, "
                               "each the one with the most expected information (in process only)")
    adaptive.add_argument("--propose-next", action="store_true",
                          help="print the next launch the adaptive plan would make from the run's stored outcomes "
                               "(--store) and why; launch nothing")
    adaptive.add_argument("--budget", type=int, default=150,
                          help="with --plan adaptive: launches this session (default 150)")
    adaptive.add_argument("--fit", action="append", default=[], metavar="KEY",
                          help="an unknown to learn about (a key of calibration.parameters, its declared bounds and "
                               "scale; repeatable; default: robot.com_offset_z_m and "
                               "launch_twin.foam.lateral_friction)")
    adaptive.add_argument("--likelihood", metavar="FILE",
                          help="a likelihood prepared by `rollability calibrate --prepare` for this twin and these "
                               "designs: the proposal weighs the stored verdicts and continuous outcomes (gate speed, "
                               "IMU, tape) by it and scores the information of both; its unknowns are the ones "
                               "learnt about (--fit is refused with it)")
    adaptive.add_argument("--twin-config", action="append", default=[], metavar="FILE",
                          help="parameter file over sim, robot, launch_twin and calibration for the predictions (e.g. "
                               "the launch_twin.designs naming the profiles, or a calibrated.yaml); repeatable")
    adaptive.add_argument("--prior-samples", type=int, default=None,
                          help="prior samples of the unknowns (default 32 on the twin, where more describe the "
                               "posterior better and cost prior-samples x conditions x sim-repetitions twin launches "
                               "once; 1000 with --likelihood, renewed as the outcomes narrow them)")
    adaptive.add_argument("--sim-repetitions", type=int, default=4,
                          help="twin launches per sample and condition for P(upright) (default 4)")
    adaptive.add_argument("--workers", type=int, default=None,
                          help="launch worker processes for the predictions (default: one per core)")
    adaptive.add_argument("--about", metavar="FIRST,SECOND",
                          help="with --propose-next / --plan adaptive: choose the launch that tells most about which "
                               "of two configurations rights the robot more often (under the plausible unknowns), "
                               "instead of about the unknowns themselves")
    adaptive.add_argument("--stop-when-decided", metavar="FIRST,SECOND",
                          help="compare two configurations launched in pairs (the same condition and repetition, "
                               "FIRST then SECOND; the plan is reordered so) and end the campaign as soon as the "
                               "always-valid test decides which rights the robot more often (exit 0)")
    adaptive.add_argument("--alpha", type=float, default=0.05,
                          help="with --stop-when-decided: the error rate, the chance that a decision is wrong "
                               "(default 0.05)")


#: How the commands name the campaign's rig files in a refusal.
RIG_CONFIG = "rollability campaign --rig-config"


def _spec(args):
    import dataclasses

    from rollability_ros.core.campaign import load_campaign_spec
    from rollability_ros.core.config import check_given_files, check_settings

    check_given_files(args.config or [], {"campaign"}, "rollability campaign --config")
    spec = load_campaign_spec(args.config or ["campaign"])
    if args.run_id is not None:   # given, even empty: then validate() refuses it
        spec = dataclasses.replace(spec, run_id=args.run_id)
        check_settings(spec, "campaign")
    return spec


def run(args: argparse.Namespace) -> int:
    from rollability_ros.core.rig import launch_backend_class

    if args.resimulate or args.seed is not None:
        return _resimulate(args)
    spec = _spec(args)
    _check_adaptive_arguments(args, spec)
    if args.propose_next:
        return _propose_next(args, spec)
    ask = input if launch_backend_class(args.backend).attended else None
    if (args.session is not None or args.namespace is not None) and not args.graph:
        raise ValueError("--session and --namespace are for --graph (a campaign through a running graph)")
    if args.graph:
        if args.store:
            raise ValueError("--store is for the in-process campaign; with --graph the outcome_logger owns the store")
        if args.rig_config:   # never dropped: the rig node of the graph was started with its own files
            raise ValueError("--rig-config is for the in-process rig; with --graph the rig node reads the files it "
                             "was started with")
        return _run_graph(args, spec, ask, _comparison(args))
    if not args.store:
        raise ValueError("--store is required (the store file or run directory this command writes)")
    return _run_local(args, spec, ask)


def _comparison(args: argparse.Namespace, text: typing.Optional[str] = None) -> typing.Optional[typing.Tuple[str, str]]:
    """``(first, second)`` of ``--stop-when-decided`` (or of ``text``), or None."""
    text = args.stop_when_decided if text is None else text
    if not text:
        return None
    first, second = text.split(",")
    return first.strip(), second.strip()


def _check_adaptive_arguments(args, spec):
    """Refuse unusable adaptive-plan arguments in one line, before anything starts."""
    import math

    for option, text in (("--stop-when-decided", args.stop_when_decided), ("--about", args.about)):
        if text is None:
            continue
        names = [name.strip() for name in text.split(",")]
        if len(names) != 2 or names[0] == names[1] or not all(names):
            raise ValueError(f"{option} needs two different configurations as FIRST,SECOND, got {text!r}")
        missing = [name for name in names if name not in spec.configurations]
        if missing:
            raise ValueError(f"{option}: {', '.join(missing)} not in campaign.configurations "
                             f"({', '.join(spec.configurations)})")
    if args.stop_when_decided is not None:
        if args.plan == "adaptive":
            raise ValueError("--stop-when-decided compares two configurations on the matrix plan, not --plan adaptive")
    if not 0 < args.alpha < 0.5 or math.isnan(args.alpha):
        raise ValueError(f"--alpha must be in (0, 0.5), got {args.alpha}")
    adaptive = args.plan == "adaptive" or args.propose_next
    if not adaptive and (args.fit or args.twin_config or args.about or args.likelihood):
        raise ValueError("--fit, --twin-config, --likelihood and --about are for --plan adaptive and --propose-next")
    if args.likelihood and args.fit:
        raise ValueError("--fit is for the twin's predictions: with --likelihood the unknowns are the prepared file's")
    if adaptive:
        if args.graph:
            raise ValueError("--plan adaptive and --propose-next run in process (--store), not with --graph")
        if not args.store:
            raise ValueError("--plan adaptive and --propose-next need --store (the run's stored outcomes)")
        if args.prior_samples is None:
            args.prior_samples = LEARNT_PRIOR_SAMPLES if args.likelihood else TWIN_PRIOR_SAMPLES
        for name, value, low in (("--budget", args.budget, 1), ("--prior-samples", args.prior_samples, 2),
                                 ("--sim-repetitions", args.sim_repetitions, 1)):
            if value < low:
                raise ValueError(f"{name} must be >= {low}, got {value}")
        if args.workers is not None and args.workers < 1:
            raise ValueError(f"--workers must be >= 1, got {args.workers}")
        _twin_parameters(args, say=False)   # its files and designs' print refused before the store is opened


#: Default prior samples of the adaptive plan on the twin's launches and on a learnt likelihood.
TWIN_PRIOR_SAMPLES, LEARNT_PRIOR_SAMPLES = 32, 1000


def _twin_parameters(args, say=True):
    """The flat parameters of the twin's files and ``--twin-config`` (each key applied or refused; a print file's
    search keys named as not read when ``say``), after refusing designs chosen for another print than the loaded
    one."""
    from rollability_ros.core.campaign import TWIN_CONFIGS, check_designs_print, load_twin_files
    from rollability_ros.core.sim import TWIN_SECTIONS, launch_twin_settings_from_parameters

    parameters, unread = load_twin_files([*TWIN_CONFIGS, "calibration"], args.twin_config,
                                         {*TWIN_SECTIONS, "calibration"}, "rollability campaign --twin-config")
    check_designs_print(launch_twin_settings_from_parameters(parameters), "--twin-config")
    if unread and say:
        print(unread, flush=True)
    return parameters


def _learnt_posterior(args, spec, outcomes):
    """The adaptive plan's weighted samples over the prepared likelihood ``--likelihood`` (its unknowns, verdicts
    and continuous outcomes), weighed by ``outcomes``; a file that is not one, or was prepared for another twin,
    other designs or other condition levels, is refused in one line naming it."""
    import numpy as np

    from rollability_ros.core.campaign import (LearntTable, OutcomePosterior, candidate_conditions, load_likelihood,
                                               twin_fingerprint)

    parameters = _twin_parameters(args)
    likelihood = load_likelihood(args.likelihood)
    if likelihood.fingerprint != twin_fingerprint(parameters, likelihood.unknowns.names):
        raise ValueError(f"{args.likelihood}: prepared for another twin or design set than the loaded parameter files "
                         "(--twin-config) or the twin's code: prepare it again for these")
    candidates = candidate_conditions(spec.configurations, spec.heights_m, spec.speeds_mps, spec.angles_deg)
    try:
        table = LearntTable(likelihood, candidates)
    except ValueError as error:
        raise ValueError(f"{args.likelihood}: {error}") from None
    print(f"adaptive plan: the learnt likelihood {args.likelihood} over {', '.join(likelihood.unknowns.names)}, "
          f"verdicts and {', '.join(table.outcomes) or 'no continuous outcome'}; {args.prior_samples} prior samples "
          f"at {len(candidates)} conditions, renewed as the outcomes narrow them", flush=True)
    posterior = OutcomePosterior.from_prior(table, args.prior_samples, np.random.default_rng(1))
    return _weighed(posterior, outcomes, spec)


def _weighed(posterior, outcomes, spec):
    used = posterior.observe_outcomes(outcomes)
    left_out = len(outcomes) - used
    why = f" ({left_out} left out: invalid launches, or conditions outside the campaign matrix)" if left_out else ""
    print(f"adaptive plan: weighed by {used} stored launches of run {spec.run_id}{why}", flush=True)
    return posterior


def _adaptive_posterior(args, spec, outcomes):
    """The weighted posterior of the adaptive plan: prior samples of the unknowns, the twin's P(upright) of each at
    every grouped condition of the matrix (launched now), weighed by ``outcomes``; with ``--likelihood``, the learnt
    likelihood's (:func:`_learnt_posterior`)."""
    import numpy as np

    if args.likelihood:
        return _learnt_posterior(args, spec, outcomes)

    from rollability_ros.core.campaign import (DEFAULT_UNKNOWNS, LaunchPool, TwinPredictor, Unknowns,
                                               WeightedPosterior, calibration_settings, candidate_conditions,
                                               check_fittable)
    from rollability_ros.core.profile import configuration_ids
    from rollability_ros.core.sim import launch_twin_settings_from_parameters

    parameters = _twin_parameters(args)
    settings = calibration_settings(parameters).selected(args.fit or DEFAULT_UNKNOWNS)
    twin = launch_twin_settings_from_parameters(parameters)   # parsed once, handed to the core typed
    check_fittable(twin, settings)
    known = configuration_ids(twin.twin.designs)
    unknown = [c for c in spec.configurations if c not in known]
    if unknown:
        raise ValueError(f"the twin has no profile for {', '.join(unknown)} (it knows {', '.join(known)}): give the "
                         "campaign's designs with --twin-config (launch_twin.designs)")
    unknowns = Unknowns.from_settings(settings)
    candidates = candidate_conditions(spec.configurations, spec.heights_m, spec.speeds_mps, spec.angles_deg)
    launches = args.prior_samples * len(candidates) * args.sim_repetitions
    print(f"adaptive plan: P(upright) of {args.prior_samples} prior samples of {', '.join(unknowns.names)} at "
          f"{len(candidates)} conditions, {args.sim_repetitions} twin launches each ({launches} launches, about "
          f"{launches * 0.05 / 60:.0f} min on one core)", flush=True)
    with LaunchPool(args.workers) as pool:
        predictor = TwinPredictor(twin, unknowns, pool, args.sim_repetitions, settings.seed)
        posterior = WeightedPosterior.from_predictor(unknowns, predictor, candidates, args.prior_samples,
                                                              np.random.default_rng(settings.seed))
    return _weighed(posterior, outcomes, spec)


def _pressures(args):
    """``{speed m/s: regulator psi}`` of the rig files (to name the pressure in the instructions)."""
    from rollability_ros.core.campaign import local_rig_settings_from_files

    regulator = local_rig_settings_from_files(args.backend, args.rig_config, RIG_CONFIG).valve.regulator
    return dict(zip(regulator.speeds_mps, regulator.pressures_psi))


def _stored_outcomes(args, spec):
    """The run's stored outcomes in ``--store``; a store that does not exist is refused (never created here)."""
    import os

    from rollability_ros.core.store import Store, store_path

    path = store_path(args.store)
    if not os.path.isfile(path):
        raise ValueError(f"no store at {path}: --propose-next reads the run's stored outcomes")
    with Store(path) as store:
        return store.launch_outcomes(spec.run_id)


def _propose_next(args, spec):
    from rollability_ros.core.campaign import proposal_lines

    outcomes = _stored_outcomes(args, spec)
    pressures = _pressures(args)
    posterior = _adaptive_posterior(args, spec, outcomes)
    previous = outcomes[-1].condition if outcomes else None
    proposal = posterior.propose(comparison=_comparison(args, args.about or ""))
    for line in proposal_lines(posterior, proposal, previous, pressures):
        print(line)
    return 0


def _read_twin(twin_config):
    """The launch twin of the files ``rig.twin_config`` names, parsed here, at the command (the edge); the in-process
    rig's simulated backend asks for it once (a physical one never does, so the rig computer needs no physics)."""
    from rollability_ros.core.sim import load_launch_twin_settings

    return load_launch_twin_settings(twin_config)


def _recorded_twin(args):
    """The twin recorded for run ``--run-id`` of ``--store`` (:mod:`~rollability_ros.core.campaign.twin_record`),
    checked; None without ``--store``, with ``--rig-config`` (which overrides it, as a note says) or for a run
    stored before twins were recorded (a note says so); a run of the physical rig is refused (it has no twin)."""
    import os
    import sys

    from rollability_ros.core.campaign import recorded_twin
    from rollability_ros.core.results import directory_store
    from rollability_ros.core.store import Store

    if args.store is None and args.run_id is None:
        return None
    if args.store is None or args.run_id is None:
        raise ValueError("--resimulate reads the campaign's twin from --store and --run-id together (the stored "
                         "outcome's store and run)")
    path = directory_store(args.store) if os.path.isdir(args.store) else args.store
    if not path or not os.path.isfile(path):
        raise ValueError(f"--store {args.store}: no store there")
    with Store(path) as store:
        described = store.run_info(args.run_id)
    if described is None:
        raise ValueError(f"--run-id {args.run_id}: store {path} holds no run of that id")
    folder = os.path.dirname(os.path.abspath(path))
    if args.rig_config:
        print(f"note: --rig-config given: re-simulating on its files, not on the twin files recorded for run "
              f"{args.run_id}", file=sys.stderr)
        return None
    twin = recorded_twin(described["info"], folder, args.run_id)
    if twin is None:
        print(f"note: run {args.run_id}'s twin files were not recorded (a run stored before they were, or by a rig "
              "that could not read them): re-simulating on the shipped rig files (a design's launch needs the "
              "campaign's --rig-config files)", file=sys.stderr)
    return twin


def _resimulate(args):
    import dataclasses
    import functools

    from rollability_ros.core.campaign import LocalRig, local_rig_settings_from_files
    from rollability_ros.core.sim import load_launch_twin_settings
    from rollability_ros.core.records import LaunchCondition, check_twin_seed
    from rollability_ros.core.rig import LAUNCH_BACKENDS, launch_backend_class

    refusal = launch_backend_class(args.backend).resimulate_refusal()
    if refusal or not args.resimulate or args.seed is None:
        able = " or ".join(name for name in LAUNCH_BACKENDS.names()
                           if not launch_backend_class(name).resimulate_refusal())
        raise ValueError(f"--resimulate needs --backend {able} and --seed" + (f" ({refusal})" if refusal else ""))
    configuration, *numbers = args.resimulate
    try:
        height_m, speed_mps, angle_deg = (float(text) for text in numbers)
    except ValueError:
        raise ValueError(f"--resimulate: HEIGHT_M, SPEED_MPS and ANGLE_DEG must be numbers, got {numbers}") from None
    condition = LaunchCondition(configuration, height_m, speed_mps, angle_deg)
    condition.validate()   # the campaign's own bounds (records.HEIGHT_RANGE_M ...): no stored launch lies outside
    check_twin_seed(args.seed)
    settings = local_rig_settings_from_files(args.backend, args.rig_config, RIG_CONFIG)
    twin = _recorded_twin(args)
    read_twin = _read_twin
    if twin is not None:   # the campaign's own twin: its files, and its designs file wherever the store now is
        settings = dataclasses.replace(settings, rig=dataclasses.replace(settings.rig, twin_config=twin.twin_config))
        overrides = {"twin.designs.designs_file": twin.designs_file} if twin.designs_file else None
        read_twin = functools.partial(load_launch_twin_settings, overrides=overrides)
    rig = LocalRig(settings, read_twin=read_twin)
    try:
        result = rig.backend.resimulate(condition, args.seed)
    finally:
        rig.close()
    print(f"upright: {str(bool(result.upright) and result.valid).lower()}")
    print("final_orientation (x, y, z, w): " + " ".join(repr(float(v)) for v in result.final_orientation))
    print(f"travel_time_s: {float(result.travel_time_s)!r}")
    print(f"launch_speed_mps: {float(result.launch_speed_mps)!r}")
    print(f"launch_angle_deg: {float(result.launch_angle_deg)!r}")
    print(f"invalid_reason: {result.invalid_reason or '(valid launch)'}")
    from rollability_ros.core.rig import simulated_continuous_outcomes

    for name, value in simulated_continuous_outcomes(result).items():   # as the stored outcome carries them
        print(f"{name}: {value!r}")
    return 0


def _run_local(args, spec, ask):
    import sys

    from rollability_ros.core.campaign import (LocalRig, local_rig_settings_from_files, plan_refusal, plan_trials,
                                               record_campaign_run, report_exit_code, resume_command, resume_refusal,
                                               run_campaign, store_writer)
    from rollability_ros.core.campaign import (adaptive_next_trial, budget_placeholders, comparison_stop_rule,
                                               paired_order)
    from rollability_ros.core.store import Store

    settings, plan = local_rig_settings_from_files(args.backend, args.rig_config, RIG_CONFIG), plan_trials(spec)

    matrix = list(plan)

    def checked_rig() -> LocalRig:
        rig = LocalRig(settings, ask or input, read_twin=_read_twin)
        refusal = plan_refusal(rig.backend, spec.run_id, matrix)   # every trial of the matrix, whichever plan runs
        if refusal:
            rig.close()
            raise ValueError(refusal)
        return rig

    # the twin opens no port: every trial is checked before the store is made; a physical rig opens its valve, so
    # it waits until the store has accepted the run
    rig = None if ask else checked_rig()
    try:
        with Store(args.store) as store:
            stored = store.trial_ids(spec.run_id)
            refusal = resume_refusal(len(stored), args.resume, spec.run_id)
            if refusal:
                raise ValueError(refusal)
            stop_rule, next_trial = None, None
            comparison = _comparison(args)
            if comparison is not None:
                plan = paired_order(plan, *comparison)
                first, second = comparison
                stop_rule = comparison_stop_rule(store.launch_outcomes(spec.run_id), first, second, args.alpha)
            if args.plan == "adaptive":   # minutes of twin launches: before a physical rig opens its valve
                posterior = _adaptive_posterior(args, spec, store.launch_outcomes(spec.run_id))
                next_trial = adaptive_next_trial(posterior, stored, comparison=_comparison(args, args.about or ""))
                plan = budget_placeholders(args.budget, plan[0].condition)
            rig = rig or checked_rig()
            record_campaign_run(store, spec.run_id, args.backend, rig.backend.design_sources(),
                                rig.backend.twin_config())
            report = run_campaign(plan, spec.run_id, stored, lambda trial: rig.launch(spec.run_id, trial),
                                  store_writer(store), ask=ask, pressure_psi_by_speed=_pressures(args),
                                  stop_rule=stop_rule, next_trial=next_trial)
    finally:
        if rig is not None:
            rig.close()
    return report_exit_code(report, resume=resume_command(getattr(args, "argv", None) or sys.argv[1:]))


def _run_graph(args, spec, ask, comparison=None):
    import os
    import signal
    import sys

    from rollability_ros.core.campaign import RunnerSettings, TerminalAsk, report_exit_code, resume_command
    from rollability_ros.core.config import check_settings
    from rollability_ros.core.rig import check_namespace

    if ask is not None:   # a prompt that stops waiting when the rig CLI answered first
        ask = TerminalAsk()

    session = join_session(args.session)   # its domain, discovery range, namespace and key, before ROS starts
    if args.namespace is not None:
        namespace = check_namespace(args.namespace)
    elif session is not None:
        namespace = session.namespace
    else:
        from rollability_ros.cli.rig import default_namespace

        namespace = check_namespace(default_namespace())
    settings = RunnerSettings(backend=args.backend, resume=args.resume, store_timeout_s=args.store_timeout_s,
                              session_key_file=args.session_key_file or (session.valve_key_file if session else ""))
    check_settings(settings, "runner")
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.node import Node

    from rollability_ros.nodes._support import init_ros
    from rollability_ros.nodes.campaign_runner import run_graph_campaign

    init_ros([])   # no rclpy signal handlers: Ctrl-C is a KeyboardInterrupt here (the running goal is cancelled)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    node = None
    try:
        node = Node("campaign_runner", namespace=namespace)
        print(f"campaign: through the graph on ROS domain {os.environ.get('ROS_DOMAIN_ID') or '0'}, namespace "
              f"{namespace}", flush=True)
        return report_exit_code(run_graph_campaign(node, spec, settings, ask, session=session.id if session else "",
                                                   comparison=comparison, alpha=args.alpha),
                                resume=resume_command(getattr(args, "argv", None) or sys.argv[1:]))
    except (KeyboardInterrupt, ExternalShutdownException):
        print("campaign: stopped (Ctrl-C); stored trials are kept: continue with --resume", flush=True)
        return 130
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
