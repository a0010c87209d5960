"""`rollability rig`: operator commands to a running launch rig (valve_controller and rig nodes) over ROS 2."""
import argparse
import typing

from rollability_ros.cli import Subparsers, add_session_argument, join_session

ACTIONS = ("arm", "disarm", "estop", "confirm", "outcome", "console")
#: Keys of ``rollability rig console`` -> what they do.
CONSOLE_KEYS = {"e": "estop", " ": "estop", "c": "cancel", "d": "disarm", "q": "quit"}
#: The console's line once it can stop the valve (a script may wait for it).
CONSOLE_READY = "console ready: "
# whether the rig's launch feedback publisher is matched: the countdown reaches the console only once it is
CONSOLE_RIG_FOUND = "rig: connected (its launch steps show here)"
CONSOLE_RIG_MISSING = "rig: none in this namespace yet (its launch steps show here once one starts)"
#: Longest --timeout-s, s (a day: longer is a typo).
MAX_TIMEOUT_S = 86400.0


def register(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "rig", help="operator commands to the running rig: arm, disarm (acknowledge a fault), e-stop, confirm, outcome, "
                    "console (one key stops the valve)",
        description="Talk to the running valve_controller and rig nodes (same ROS domain). arm, disarm, confirm "
                    "and outcome are signed with the valve_controller's session key, so they work only on the rig "
                    "computer, as the user running the valve_controller; disarm also acknowledges a latched valve "
                    "fault (e-stop, watchdog). estop needs no key: anyone may stop. confirm answers the rig's "
                    "regulator question; outcome records the result of the launch the rig waits on. console stays "
                    "open beside the campaign: it shows the valve and the rig's launch (the countdown), and one key "
                    "acts at once: e or space = e-stop, c = cancel the running launch (before the fire), d = disarm "
                    "(acknowledge a stop), q = quit. Start it before the campaign: an `estop` command takes a second "
                    "or two to start, longer than the countdown.")
    parser.add_argument("action", choices=ACTIONS, help="what to do")
    parser.add_argument("verdict", nargs="?", choices=("upright", "tipped"),
                        help="for outcome: upright (on its wheels) or tipped")
    parser.add_argument("--trial-id", default="",
                        help="for confirm and outcome: the trial (default: the one the rig waits on)")
    parser.add_argument("--travel-time-s", type=float, default=None,
                        help="for outcome: travel time over the run, s, > 0 (when the light gates missed it)")
    parser.add_argument("--note", default="", help="for outcome: free text")
    parser.add_argument("--rolled-m", type=float, default=None,
                        help="for outcome: distance from the ledge's edge to where the chassis came to rest, m, >= 0, "
                             "as measured (stored as the outcome's rest_distance_m; left out: not measured)")
    parser.add_argument("--namespace", default=None,
                        help="ROS namespace of the rig nodes (default: bringup.namespace of the parameter files, "
                             "/rollability as shipped: where `rollability bringup` and the launch files start them)")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="extra ROS 2 parameter file(s), as given to bringup, for the default namespace")
    add_session_argument(parser)
    parser.epilog = ("With --session, this joins that session (its domain, namespace and key). Otherwise, unless "
                     "ROS_DOMAIN_ID / ROS_AUTOMATIC_DISCOVERY_RANGE are set, it joins the physical rig's defaults: "
                     "domain 73, localhost discovery (as `rollability bringup --backend physical`).")
    parser.add_argument("--session-key-file", default="",
                        help="for arm, disarm, confirm, outcome: the valve_controller's session key (default: "
                             "valve.session_key_file's default for this ROS domain and namespace)")
    parser.add_argument("--timeout-s", type=float, default=10.0,
                        help=f"longest wait for the nodes, s, in (0, {MAX_TIMEOUT_S:g}] (default 10)")
    parser.set_defaults(func=run)


def check_arguments(args: argparse.Namespace) -> None:
    """Refuse unusable arguments before anything starts (``ValueError``, one line): the namespace (normalized in
    place), the numbers (NaN, sign, range), a verdict where one is needed and only there."""
    import math

    from rollability_ros.core.rig import check_namespace

    if args.namespace is not None:
        args.namespace = check_namespace(args.namespace)
    if not 0 < args.timeout_s <= MAX_TIMEOUT_S:   # NaN fails every comparison
        raise ValueError(f"--timeout-s must be a number of seconds in (0, {MAX_TIMEOUT_S:g}], got {args.timeout_s}")
    if args.travel_time_s is not None:
        if args.action != "outcome":
            raise ValueError("--travel-time-s is for outcome only")
        if not 0 < args.travel_time_s < math.inf:
            raise ValueError(f"--travel-time-s must be a number of seconds > 0, got {args.travel_time_s} (leave it out "
                             "when the run was not timed)")
    if args.rolled_m is not None:
        if args.action != "outcome":
            raise ValueError("--rolled-m is for outcome only")
        from rollability_ros.core.rig import check_rest_distance

        check_rest_distance(args.rolled_m)
    if args.action == "outcome" and args.verdict is None:
        raise ValueError("outcome needs a verdict: upright or tipped")
    if args.action != "outcome" and args.verdict is not None:
        raise ValueError(f"a verdict ({args.verdict}) is for outcome only, not {args.action}")
    if args.action not in ("confirm", "outcome") and args.trial_id:
        raise ValueError("--trial-id is for confirm and outcome only")
    if args.action not in ("outcome",) and args.note:
        raise ValueError("--note is for outcome only")


def _request(args, sign=False):
    """``(service or topic type, name, request or message)`` for the action; the signed actions are built only
    when ``sign`` (the signature is fresh for a few seconds: sign once the service is there), else the request is
    None."""
    import math

    from std_msgs.msg import Bool

    from rollability_ros.core.rig import AuthError, KeyFileSigner, RequestSigner, default_key_path, load_session_key
    from rollability_ros.nodes._convert import auth_msg
    from rollability_ros.srv import ArmValve, ConfirmRegulator, RecordOutcome

    kind, name = {"arm": (ArmValve, "valve/arm"), "disarm": (ArmValve, "valve/arm"),
                  "confirm": (ConfirmRegulator, "rig/confirm"), "outcome": (RecordOutcome, "record_outcome"),
                  "estop": (Bool, "valve/estop")}[args.action]
    if args.action == "estop":
        return kind, name, Bool(data=True)
    if not sign:
        return kind, name, None
    key_file = args.session_key_file or default_key_path(args.namespace)
    try:
        if args.action in ("arm", "disarm"):
            signature = RequestSigner(load_session_key(key_file)).sign(args.action)
            return kind, name, ArmValve.Request(arm=args.action == "arm", auth=auth_msg(signature))
        signer = KeyFileSigner(key_file)
        if args.action == "confirm":
            return kind, name, ConfirmRegulator.Request(trial_id=args.trial_id,
                                                        auth=auth_msg(signer.confirm(args.trial_id)))
        travel_time_s = math.nan if args.travel_time_s is None else args.travel_time_s
        rolled_m = -1.0 if args.rolled_m is None else args.rolled_m   # the service's "not measured"
        upright = args.verdict == "upright"
        return kind, name, RecordOutcome.Request(
            trial_id=args.trial_id, upright=upright, travel_time_s=travel_time_s, note=args.note,
            rest_distance_m=rolled_m,
            auth=auth_msg(signer.outcome(args.trial_id, upright, travel_time_s, args.note, rolled_m)))
    except AuthError as exc:
        hint = "" if args.session else " (a session keeps its key where its session.yaml says: pass --session SESSION)"
        raise ValueError(f"{exc}{hint}") from exc


def default_namespace(config_files: typing.Sequence[str] = ()) -> str:
    """The namespace ``rollability bringup`` puts the graph in: ``bringup.namespace`` of the parameter files (the
    files as given to bringup: one bringup would refuse is refused here too)."""
    from rollability_ros.core.config import check_given_files
    from rollability_ros.core.graph import graph_namespaces, load_graph_settings, parameter_files

    check_given_files(config_files, graph_namespaces(), "rollability rig")
    return load_graph_settings(parameter_files(["bringup", *config_files])).namespace


def namespaces_offering(names: typing.Iterable[str], relative_name: str) -> typing.List[str]:
    """The namespaces in which one of the fully qualified ``names`` is ``relative_name`` (sorted, "/" for root)."""
    suffix = "/" + relative_name
    return sorted({name[:-len(suffix)] or "/" for name in names if name.endswith(suffix)})


def _missing(problem, name, elsewhere):
    """The error for ``name`` missing from the chosen namespace: ``problem``, and the namespaces where it is."""
    import os

    domain = os.environ.get("ROS_DOMAIN_ID") or "0"
    if not elsewhere:
        return f"{problem}, nor in any other namespace of ROS domain {domain} (is the node running, with the same " \
               f"ROS_DOMAIN_ID? a session's own domain: pass --session SESSION)"
    return f"{problem}; {name} is in {', '.join(elsewhere)}: use " + " or ".join(f"--namespace {ns}" for ns in elsewhere)


def _estop_publisher(node, timeout_s):
    """A ``valve/estop`` publisher matched by a valve controller within ``timeout_s`` (``ValueError`` otherwise,
    naming the namespaces where one listens)."""
    import time

    from std_msgs.msg import Bool

    publisher = node.create_publisher(Bool, "valve/estop", 10)
    deadline = time.monotonic() + timeout_s
    while publisher.get_subscription_count() == 0:
        if time.monotonic() > deadline:
            topics = [topic for topic, _types in node.get_topic_names_and_types() if node.count_subscribers(topic)]
            raise ValueError(_missing(f"no valve controller subscribes to {node.resolve_topic_name('valve/estop')}",
                                      "valve/estop", namespaces_offering(topics, "valve/estop")))
        time.sleep(0.05)
    return publisher


def _valve_line(msg):
    """The console's line for a valve state."""
    if msg.fault:
        return f"valve: STOPPED ({msg.fault_reason}); d acknowledges it (disarm)"
    return f"valve: {'ARMED' if msg.armed else 'disarmed'}{', OPEN' if msg.open else ''} (pulses {msg.pulses})"


def _console(args, node):
    """``rollability rig console``: one key stops the valve (see the parser's description). Messages arrive on a
    thread of their own; keys are read here and an e-stop is published from here at once (its publisher is matched
    before the ready line)."""
    import os
    import select
    import sys
    import termios
    import time
    import tty

    from action_msgs.srv import CancelGoal
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import Bool

    from rollability_ros.action import Launch
    from rollability_ros.msg import ValveState
    from rollability_ros.nodes._support import LATCHED_QOS, ExecutorThread

    estop = _estop_publisher(node, args.timeout_s)
    cancel = node.create_client(CancelGoal, "launch/_action/cancel_goal")
    shown: typing.Dict[str, str] = {}

    def show(key: str, text: str) -> None:
        if shown.get(key) != text:
            shown[key] = text
            print(text, flush=True)

    node.create_subscription(ValveState, "valve/state", lambda msg: show("valve", _valve_line(msg)), LATCHED_QOS)
    feedback = node.create_subscription(Launch.Impl.FeedbackMessage, "launch/_action/feedback",
                                        lambda msg: show("rig", f"rig: {msg.feedback.phase}: {msg.feedback.detail}"),
                                        10)
    started = time.monotonic()

    def link() -> None:   # "none" only after discovery has had its usual second or two
        if feedback.get_publisher_count():
            show("link", CONSOLE_RIG_FOUND)
        elif "link" in shown or time.monotonic() - started > 3.0:
            show("link", CONSOLE_RIG_MISSING)

    node.create_timer(0.25, link)
    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd) if os.isatty(fd) else None
    print(f"{CONSOLE_READY}e or space = E-STOP, c = cancel the running launch, d = disarm (acknowledge a stop), "
          f"q = quit (rig namespace {node.get_namespace()})", flush=True)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = ExecutorThread(executor, name="console-spin").start()
    try:
        if saved is not None:
            tty.setcbreak(fd)   # one key, no Enter
        while True:
            readable, _, _ = select.select([fd], [], [], 0.2)
            if not readable:
                continue
            data = os.read(fd, 64)
            if not data:
                return 0
            for key in data.decode("utf-8", "replace").lower():
                what = CONSOLE_KEYS.get(key)
                if what == "estop":
                    estop.publish(Bool(data=True))
                    print("E-STOP sent", flush=True)
                elif what == "cancel":
                    # a zero goal id and stamp cancels every goal of the launch action (action_msgs/CancelGoal)
                    if cancel.wait_for_service(timeout_sec=1.0):   # a rig started after the console: found now
                        cancel.call_async(CancelGoal.Request())
                        print("cancel sent: the rig stops the launch at its next wait (before the fire)", flush=True)
                    else:
                        print("no rig serves the launch action here", flush=True)
                elif what == "disarm":
                    _console_disarm(args, node)
                elif what == "quit":
                    return 0
    finally:
        if saved is not None:
            termios.tcsetattr(fd, termios.TCSADRAIN, saved)
        spinner.stop(timeout_s=1.0)


def _console_disarm(args, node):
    """The console's d: a signed disarm (acknowledges a stop); its answer arrives on the spinning thread."""
    import time

    from rollability_ros.srv import ArmValve

    client = node.create_client(ArmValve, "valve/arm")
    try:
        if not client.wait_for_service(timeout_sec=args.timeout_s):
            print("disarm: valve/arm is not available", flush=True)
            return
        request = _request(argparse.Namespace(**{**vars(args), "action": "disarm"}), sign=True)[2]
        future = client.call_async(request)
        deadline = time.monotonic() + args.timeout_s
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.02)
        response = future.result() if future.done() else None
        print(f"disarm: {'ok' if response is not None and response.success else 'refused'}: "
              f"{response.message if response is not None else 'no answer'}", flush=True)
    except ValueError as exc:
        print(f"disarm: {exc}", flush=True)
    finally:
        node.destroy_client(client)


def run(args: argparse.Namespace) -> int:
    import os
    import time

    from rollability_ros.core.rig import check_namespace, physical_rig_environment

    check_arguments(args)   # before ROS starts: a bad argument is one line, never a traceback or a hang
    import rclpy
    from rclpy.node import Node

    from rollability_ros.nodes._support import init_ros

    session = join_session(args.session, args.config)   # its domain, discovery range, namespace and key
    if session is None:
        os.environ.update(physical_rig_environment(os.environ))  # the physical bringup's defaults, unless set
    else:
        args.session_key_file = args.session_key_file or session.valve_key_file
    if args.namespace is None:
        args.namespace = check_namespace(session.namespace if session else default_namespace(args.config))
    namespace = args.namespace
    if args.action == "console":
        init_ros([])
        node = Node("rig_console", namespace=namespace or None)
        try:
            return _console(args, node)
        finally:
            node.destroy_node()
            rclpy.try_shutdown()
    kind, name, payload = _request(args)
    init_ros([])
    node = Node("rig_operator", namespace=namespace or None)
    try:
        if args.action == "estop":
            publisher = _estop_publisher(node, args.timeout_s)
            publisher.publish(payload)
            time.sleep(0.2)  # let the reliable message leave before the node goes
            print("e-stop sent")
            return 0
        client = node.create_client(kind, name)
        if not client.wait_for_service(timeout_sec=args.timeout_s):
            services = [service for service, _types in node.get_service_names_and_types()
                        if node.count_services(service)]   # the graph lists clients' service names too
            raise ValueError(_missing(f"service {node.resolve_service_name(name)} is not available", name,
                                      namespaces_offering(services, name)))
        payload = _request(args, sign=True)[2]  # signed now: the signature is fresh for a few seconds only
        future = client.call_async(payload)
        rclpy.spin_until_future_complete(node, future, timeout_sec=args.timeout_s)
        if not future.done():
            raise ValueError(f"{name} did not answer within {args.timeout_s:g} s")
        response = future.result()
        ok = response.accepted if args.action == "outcome" else response.success
        print(f"{args.action}: {'ok' if ok else 'refused'}: {response.message}")
        return 0 if ok else 1
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
