"""`rollability record`: run the recorder node in this process until Ctrl-C / SIGTERM."""
from rollability_ros.cli import Subparsers, add_session_argument, join_session


def _record(args):
    join_session(args.session)   # a running session's own domain and discovery range, before ROS starts
    from rollability_ros.nodes import recorder
    from rollability_ros.nodes._bag_nodes import parameter_overrides

    values = {"recorder.output_dir": args.output, "recorder.topics": args.topics,
              "recorder.compression": args.compression, "recorder.split_max_bytes": args.split_max_bytes,
              "recorder.split_max_duration_s": args.split_max_duration_s}
    return recorder.main(args=[], parameter_overrides=parameter_overrides(values))


def register(subparsers: Subparsers) -> None:
    """Add the ``record`` verb."""
    parser = subparsers.add_parser(
        "record", help="record the project's topics (or chosen ones) into a rosbag2 MCAP bag",
        description="Record topics into bags/<date-time>/ (or --output) as a rosbag2 bag (metadata.yaml + "
                    "zstd-chunked MCAP) that ros2 bag, rosbags and mcap open. Default topics: every topic of the "
                    "project's graph plus /tf, /tf_static, /clock and /diagnostics, discovered while running. "
                    "Stop with Ctrl-C or SIGTERM; after kill -9 run `rollability bag recover`.")
    parser.add_argument("--topics", nargs="+", metavar="TOPIC", help="absolute topic names to record")
    parser.add_argument("--output", "-o", metavar="DIR", help="bag directory to create (must not exist)")
    parser.add_argument("--compression", choices=("zstd", "lz4", "none"), help="MCAP chunk compression (zstd)")
    parser.add_argument("--split-max-bytes", type=int, metavar="B", help="start a new storage file after B bytes")
    parser.add_argument("--split-max-duration-s", type=float, metavar="S",
                        help="start a new storage file after S seconds of recorded time")
    add_session_argument(parser)
    parser.set_defaults(func=_record)
