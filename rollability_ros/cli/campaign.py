"""`rollability campaign`: run the launch campaign (paper 2.2.6) in this process or through the node graph."""
import argparse

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
                        help="with --backend sim and --seed: run only this one launch on the launch twin of "
                             "--rig-config and print its outcome (the report's drill-down shows this command for "
                             "every simulated launch); stores nothing")
    parser.add_argument("--seed", type=int,
                        help="with --resimulate: the twin seed of the launch (the stored outcome's seed)")
    parser.set_defaults(func=run)


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
    ask = input if launch_backend_class(args.backend).attended else None
    if (args.session is not None or args.namespace is not None) and not args.graph:
        raise ValueError("--session and --namespace are for --graph (a campaign through a running graph)")
    if args.graph:
        if args.store:
            raise ValueError("--store is for the in-process campaign; with --graph the outcome_logger owns the store")
        if args.rig_config:   # never dropped: the rig node of the graph was started with its own files
            raise ValueError("--rig-config is for the in-process rig; with --graph the rig node reads the files it "
                             "was started with")
        return _run_graph(args, spec, ask)
    if not args.store:
        raise ValueError("--store is required (the store file or run directory this command writes)")
    return _run_local(args, spec, ask)


def _resimulate(args):
    from rollability_ros.core.campaign import LocalRig, local_rig_settings_from_files
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
    rig = LocalRig(local_rig_settings_from_files(args.backend, args.rig_config, RIG_CONFIG))
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
    return 0


def _run_local(args, spec, ask):
    import sys

    from rollability_ros.core.campaign import (LocalRig, local_rig_settings_from_files, plan_refusal, plan_trials,
                                               record_campaign_run, report_exit_code, resume_command, resume_refusal,
                                               run_campaign, store_writer)
    from rollability_ros.core.store import Store

    settings, plan = local_rig_settings_from_files(args.backend, args.rig_config, RIG_CONFIG), plan_trials(spec)

    def checked_rig() -> LocalRig:
        rig = LocalRig(settings, ask or input)
        refusal = plan_refusal(rig.backend, spec.run_id, plan)
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
            rig = rig or checked_rig()
            record_campaign_run(store, spec.run_id, args.backend, rig.backend.design_sources())
            report = run_campaign(plan, spec.run_id, stored, lambda trial: rig.launch(spec.run_id, trial),
                                  store_writer(store), ask=ask)
    finally:
        if rig is not None:
            rig.close()
    return report_exit_code(report, resume=resume_command(getattr(args, "argv", None) or sys.argv[1:]))


def _run_graph(args, spec, ask):
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
        return report_exit_code(run_graph_campaign(node, spec, settings, ask, session=session.id if session else ""),
                                resume=resume_command(getattr(args, "argv", None) or sys.argv[1:]))
    except (KeyboardInterrupt, ExternalShutdownException):
        print("campaign: stopped (Ctrl-C); stored trials are kept: continue with --resume", flush=True)
        return 130
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
