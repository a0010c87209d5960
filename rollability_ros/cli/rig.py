"""`rollability rig`: operator commands to a running launch rig (valve_controller and rig nodes) over ROS 2."""

ACTIONS = ("arm", "disarm", "estop", "confirm", "outcome")


def register(subparsers):
    parser = subparsers.add_parser(
        "rig", help="operator commands to the running rig: arm, disarm (acknowledge a fault), e-stop, confirm, outcome",
        description="Talk to the running valve_controller and rig nodes (same ROS domain). arm and disarm are "
                    "signed with the valve_controller's session key, so they work only on the rig computer, as the "
                    "user running the valve_controller; disarm also acknowledges a latched valve fault (e-stop, "
                    "watchdog). estop needs no key: anyone may stop. confirm answers the rig's regulator "
                    "question; outcome records the result of the launch the rig waits on.")
    parser.add_argument("action", choices=ACTIONS, help="what to do")
    parser.add_argument("verdict", nargs="?", choices=("upright", "tipped"),
                        help="for outcome: upright (on its wheels) or tipped")
    parser.add_argument("--trial-id", default="", help="for outcome: the trial (default: the one the rig waits on)")
    parser.add_argument("--travel-time-s", type=float, default=float("nan"),
                        help="for outcome: travel time over the run, s (when the light gates missed it)")
    parser.add_argument("--note", default="", help="for outcome: free text")
    parser.add_argument("--namespace", default=None,
                        help="ROS namespace of the rig nodes (default: bringup.namespace of the parameter files, "
                             "/rollability as shipped: where `rollability bringup` and the launch files start them)")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="extra ROS 2 parameter file(s), as given to bringup, for the default namespace")
    parser.epilog = ("Unless ROS_DOMAIN_ID / ROS_AUTOMATIC_DISCOVERY_RANGE are set, this joins the physical rig's "
                     "defaults: domain 73, localhost discovery (as `rollability bringup --backend physical`).")
    parser.add_argument("--session-key-file", default="",
                        help="for arm / disarm: the valve_controller's session key (default: valve.session_key_file's "
                             "default for this ROS domain and namespace)")
    parser.add_argument("--timeout-s", type=float, default=10.0, help="longest wait for the nodes, s (default 10)")
    parser.set_defaults(func=run)


def _request(args, sign=False):
    """``(service or topic type, name, request or message)`` for the action; arm / disarm are signed only when
    ``sign`` (the signature is fresh for a few seconds: sign once the service is there), else the request is None."""
    from std_msgs.msg import Bool
    from std_srvs.srv import Trigger

    from rollability_ros.core.rig import valve_auth
    from rollability_ros.nodes._convert import auth_msg
    from rollability_ros.srv import ArmValve, RecordOutcome

    if args.action in ("arm", "disarm"):
        if not sign:
            return ArmValve, "valve/arm", None
        key_file = args.session_key_file or valve_auth.default_key_path(args.namespace)
        try:
            signature = valve_auth.RequestSigner(valve_auth.load_session_key(key_file)).sign(args.action)
        except valve_auth.AuthError as exc:
            raise ValueError(str(exc)) from exc
        return ArmValve, "valve/arm", ArmValve.Request(arm=args.action == "arm", auth=auth_msg(signature))
    if args.action == "estop":
        return Bool, "valve/estop", Bool(data=True)
    if args.action == "confirm":
        return Trigger, "rig/confirm", Trigger.Request()
    if args.verdict is None:
        raise ValueError("outcome needs a verdict: upright or tipped")
    return RecordOutcome, "record_outcome", RecordOutcome.Request(
        trial_id=args.trial_id, upright=args.verdict == "upright", travel_time_s=args.travel_time_s, note=args.note)


def default_namespace(config_files=()):
    """The namespace ``rollability bringup`` puts the graph in: ``bringup.namespace`` of the parameter files."""
    from rollability_ros.core.graph.bringup import load_graph_settings, parameter_files

    return load_graph_settings(parameter_files(["bringup", *config_files])).namespace


def namespaces_offering(names, relative_name):
    """The namespaces in which one of the fully qualified ``names`` is ``relative_name`` (sorted, "/" for root)."""
    suffix = "/" + relative_name
    return sorted({name[:-len(suffix)] or "/" for name in names if name.endswith(suffix)})


def _missing(problem, name, elsewhere):
    """The error for ``name`` missing from the chosen namespace: ``problem``, and the namespaces where it is."""
    if not elsewhere:
        return f"{problem}, nor in any other namespace of this ROS domain (is the node running, with the same " \
               f"ROS_DOMAIN_ID?)"
    return f"{problem}; {name} is in {', '.join(elsewhere)}: use " + " or ".join(f"--namespace {ns}" for ns in elsewhere)


def run(args):
    import os
    import time

    import rclpy
    from rclpy.node import Node

    from rollability_ros.core.rig.rig_network import physical_rig_environment
    from rollability_ros.nodes._support import init_ros

    os.environ.update(physical_rig_environment(os.environ))  # the physical bringup's defaults, unless set
    if args.namespace is None:
        args.namespace = default_namespace(args.config)
    namespace = args.namespace
    kind, name, payload = _request(args)
    init_ros([])
    node = Node("rig_operator", namespace=namespace or None)
    try:
        if args.action == "estop":
            publisher = node.create_publisher(kind, name, 10)
            deadline = time.monotonic() + args.timeout_s
            while publisher.get_subscription_count() == 0:
                if time.monotonic() > deadline:
                    topics = [topic for topic, _types in node.get_topic_names_and_types()
                              if node.count_subscribers(topic)]
                    raise ValueError(_missing(f"no valve controller subscribes to {node.resolve_topic_name(name)}",
                                              name, namespaces_offering(topics, name)))
                time.sleep(0.05)
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
        if args.action in ("arm", "disarm"):
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
