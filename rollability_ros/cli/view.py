"""`rollability view`: serve the project's live ROS topics to the Foxglove app (no ROS install on the viewer)."""
import argparse
import typing

from rollability_ros.cli import Subparsers, add_session_argument, join_session


def register(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "view", help="live view of the project's topics in the Foxglove app (WebSocket)",
        description="Run the view_bridge node: every topic of the project's graph (or --topics) is served over "
                    "the Foxglove WebSocket protocol with its ros2msg schema, so the Foxglove app decodes our "
                    "custom types. Open the app, 'Open connection' -> Foxglove WebSocket -> ws://HOST:PORT, then "
                    "import config/foxglove_layout.json (see docs/live-view.md). Ctrl-C stops it.")
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to listen on (default 127.0.0.1: this machine only; 0.0.0.0: every interface)")
    parser.add_argument("--port", type=int, default=8765, help="TCP port (default 8765; 0 = any free port)")
    parser.add_argument("--topics", nargs="+", default=[], metavar="TOPIC",
                        help="absolute topic names to serve (default: the project's graph)")
    parser.add_argument("--discovery-period", type=float, default=2.0, metavar="S",
                        help="how often to look for new topics, s (default 2)")
    add_session_argument(parser)
    parser.set_defaults(func=run)


def bridge_arguments(host: str = "127.0.0.1", port: int = 8765, topics: typing.Sequence[str] = (),
                     discovery_period_s: float = 2.0) -> typing.List[str]:
    """``--ros-args`` for ``python -m rollability_ros.nodes.view_bridge`` (what ``bringup --view`` starts)."""
    args = ["--ros-args", "-p", f"host:={host}", "-p", f"port:={int(port)}",
            "-p", f"discovery_period_s:={float(discovery_period_s)}"]
    if topics:
        args += ["-p", "topics:=[" + ",".join(f"'{t}'" for t in topics) + "]"]
    return args


def run(args: argparse.Namespace) -> int:
    from rollability_ros.core.optional import require

    require("foxglove", feature="rollability view")
    session = join_session(args.session)   # its domain and discovery range, before ROS starts
    if session is not None:
        print(f"view: session {session.name} on ROS domain {session.ros_domain_id}, namespace {session.namespace}",
              flush=True)
    from rollability_ros.nodes import view_bridge

    return view_bridge.main(bridge_arguments(args.host, args.port, args.topics, args.discovery_period))
