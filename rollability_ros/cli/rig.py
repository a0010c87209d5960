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
    parser.add_argument("--namespace", default="", help="ROS namespace of the rig nodes (default: none)")
    parser.epilog = ("Unless ROS_DOMAIN_ID / ROS_AUTOMATIC_DISCOVERY_RANGE are set, this joins the physical rig's "
                     "defaults: domain 73, localhost discovery (as `rollability bringup --backend physical`).")
    parser.add_argument("--session-key-file", default="",
                        help="for arm / disarm: the valve_controller's session key (default: valve.session_key_file's "
                             "default for this ROS domain and namespace)")
    parser.add_argument("--timeout-s", type=float, default=10.0, help="longest wait for the nodes, s (default 10)")
    parser.set_defaults(func=run)


def _request(args):
    """``(service or topic type, name, request or message)`` for the action."""
    from std_msgs.msg import Bool
    from std_srvs.srv import Trigger

    from rollability_ros.core.rig import valve_auth
    from rollability_ros.nodes.valve_controller import auth_msg
    from rollability_ros.srv import ArmValve, RecordOutcome

    if args.action in ("arm", "disarm"):
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


def run(args):
    import os
    import time

    import rclpy
    from rclpy.node import Node

    from rollability_ros.core.rig.rig_network import physical_rig_environment

    os.environ.update(physical_rig_environment(os.environ))  # the physical bringup's defaults, unless set
    kind, name, payload = _request(args)
    rclpy.init(args=[])
    node = Node("rig_operator", namespace=args.namespace or None)
    try:
        if args.action == "estop":
            publisher = node.create_publisher(kind, name, 10)
            deadline = time.monotonic() + args.timeout_s
            while publisher.get_subscription_count() == 0:
                if time.monotonic() > deadline:
                    raise ValueError(f"no valve controller subscribes to {name}")
                time.sleep(0.05)
            publisher.publish(payload)
            time.sleep(0.2)  # let the reliable message leave before the node goes
            print("e-stop sent")
            return 0
        client = node.create_client(kind, name)
        if not client.wait_for_service(timeout_sec=args.timeout_s):
            raise ValueError(f"service {name} is not available (is the node running in this ROS domain?)")
        if args.action in ("arm", "disarm"):
            payload = _request(args)[2]  # signed now: the signature is fresh for a few seconds only
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
