"""`rollability bringup`: the lab session's node graph as supervised processes, until Ctrl-C."""
import argparse
import os
import signal
import time

from rollability_ros.cli import Subparsers


def run(args: argparse.Namespace) -> int:
    from rollability_ros.core.graph import (PROGRESS_PERIOD_S, ProgressDisplay, Supervisor, add_twin_files,
                                            join_nodes, load_graph_settings, new_study_id, parameter_files,
                                            refuse_bad_session, session_nodes, session_progress, start_session)
    from rollability_ros.core.config import check_path_component
    from rollability_ros.core.rig import launch_backend_class

    param_files = parameter_files(["bringup", *args.config])
    settings = load_graph_settings(param_files)
    if args.view:
        settings.view = True
    session_id = (check_path_component(args.session_id, "--session-id") if args.session_id is not None
                  else new_study_id().replace("study", "session"))
    run_dir = os.path.join(settings.output_dir, session_id)
    if os.path.lexists(run_dir):   # its closed bag and store belong to an earlier session: never written into
        raise ValueError(f"session folder {run_dir} already exists; choose another --session-id")
    nodes = session_nodes(settings, run_dir, rig_backend=args.backend, optimizer=not args.no_optimizer)
    add_twin_files(nodes, param_files, args.config)   # every twin reads the given files that set twin parameters
    # before anything is made or started: a key of a given file no node applies, or a value a node would refuse
    refuse_bad_session(param_files, args.config, {node.module: node.params for node in nodes}, "rollability bringup")
    os.makedirs(run_dir)
    physical = launch_backend_class(args.backend).authenticated   # a backend that moves hardware
    if physical:
        _isolate_physical_rig()
    # its own domain (the physical rig: its own, 73 unless set) and localhost discovery; nodes inherit the variables
    session, _domain_lock = start_session("bringup", run_dir, settings.namespace, os.environ, own_domain=not physical,
                                          rig_backend=args.backend)
    join_nodes(nodes, session.id, session.valve_key_file)
    supervisor = Supervisor([node.process_spec(param_files, run_dir) for node in nodes], os.path.join(run_dir, "logs"))
    stop = []
    signal.signal(signal.SIGINT, lambda *_: stop.append("Ctrl-C"))
    signal.signal(signal.SIGTERM, lambda *_: stop.append("SIGTERM"))
    print(f"bringup: session {run_dir} ({len(nodes)} nodes, rig backend {args.backend}) on ROS domain "
          f"{session.ros_domain_id} ({session.discovery_range} discovery), namespace {session.namespace}; Ctrl-C stops "
          "everything")
    for line in session.join_lines():
        print(f"bringup: {line}")
    started, last_shown = time.monotonic(), 0.0
    from rollability_ros.nodes._graph_observer import RosGraphObserver

    # a live line on a terminal, a plain line per change in a pipe or log; the progress comes over ROS
    with ProgressDisplay() as display, RosGraphObserver(settings.namespace) as observer:
        try:
            supervisor.start()
            while not stop and supervisor.poll():
                if time.monotonic() - last_shown >= PROGRESS_PERIOD_S:
                    last_shown = time.monotonic()
                    try:
                        display.update(session_progress(observer, len(nodes), last_shown - started))
                    except Exception as exc:  # informative only: it must not end the session
                        display.update(f"(progress unavailable: {exc})")
                time.sleep(settings.poll_period_s)
        finally:
            supervisor.stop()
    if supervisor.failed:
        print(f"bringup: stopped because {supervisor.failed}")
        return 1
    print(f"bringup: stopped ({stop[0] if stop else 'done'}); outcomes and bag in {run_dir}")
    return 0


def _isolate_physical_rig():
    """The physical rig's graph defaults to its own domain and localhost discovery (the children inherit them)."""
    from rollability_ros.core.rig import exposure_warnings, physical_rig_environment

    added = physical_rig_environment(os.environ)
    os.environ.update(added)
    print(f"bringup: physical rig on ROS domain {os.environ['ROS_DOMAIN_ID']}, discovery "
          f"{os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE') or 'ROS_LOCALHOST_ONLY'}"
          + (" (defaults; the operator's shells need: " + " ".join(f"export {k}={v};" for k, v in added.items())
             + ")" if added else ""))
    for warning in exposure_warnings(os.environ):
        print(f"bringup: warning: {warning}")


def register(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "bringup", help="start the whole node graph as supervised processes (Ctrl-C stops it cleanly)",
        description="Start recorder, outcome_logger, valve_controller, the sim_evaluator nodes, the rig and the "
        "optimizer (which waits for its 'start' service) as separate processes. A node that dies is restarted "
        "(up to 3 times) or the whole graph is stopped cleanly; Ctrl-C stops every node in reverse order, the "
        "recorder last, so the bag is complete and closed.")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="extra ROS 2 parameter file(s) on top of the defaults; repeatable, later files win")
    parser.add_argument("--backend", choices=("sim", "physical"), default="sim",
                        help="the rig's backend; physical runs on ROS domain 73 with localhost-only discovery unless "
                             "ROS_DOMAIN_ID / ROS_AUTOMATIC_DISCOVERY_RANGE are set")
    parser.add_argument("--no-optimizer", action="store_true", help="leave the optimizer out (rig-only session)")
    parser.add_argument("--view", action="store_true", help="also serve the live topics to the Foxglove app")
    parser.add_argument("--session-id", default=None, help="name of the new session directory under "
                                                         "bringup.output_dir (one folder name; must not exist)")
    parser.set_defaults(func=run)
