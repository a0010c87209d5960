"""`rollability play BAG`: run the player node in this process until the bag is played (or Ctrl-C)."""
from rollability_ros.cli import Subparsers, add_session_argument, join_session


def _play(args):
    join_session(args.session)   # a running session's own domain and discovery range, before ROS starts
    from rollability_ros.nodes import player
    from rollability_ros.nodes._bag_nodes import parameter_overrides

    values = {"player.bag": args.bag, "player.rate": args.rate, "player.start_offset_s": args.start_offset,
              "player.loop": args.loop, "player.clock": args.clock, "player.topics": args.topics,
              "player.remap": args.remap, "player.wait_for_subscribers_s": args.wait_for_subscribers}
    return player.main(args=[], parameter_overrides=parameter_overrides(values))


def register(subparsers: Subparsers) -> None:
    """Add the ``play`` verb."""
    parser = subparsers.add_parser(
        "play", help="replay a recorded bag with its original timing",
        description="Publish a bag's messages (MCAP or SQLite3 storage) with their recorded spacing, types and "
                    "QoS, so the running graph (outcome logger, report) consumes them like live ones.")
    parser.add_argument("bag", help="bag directory")
    parser.add_argument("--rate", "-r", type=float, help="speed factor (default 1.0; 2 = twice as fast)")
    parser.add_argument("--start-offset", type=float, metavar="S", help="skip the first S seconds of the bag")
    parser.add_argument("--loop", "-l", action="store_true", default=None, help="play again from the start, forever")
    parser.add_argument("--topics", nargs="+", metavar="TOPIC", help="recorded topics to play (default all)")
    parser.add_argument("--remap", nargs="+", metavar="FROM:=TO", help="publish recorded topic FROM on TO")
    parser.add_argument("--clock", action="store_true", default=None,
                        help="publish /clock with each message's recorded time")
    parser.add_argument("--wait-for-subscribers", type=float, metavar="S",
                        help="wait up to S seconds for subscribers before the first message (default 3)")
    add_session_argument(parser)
    parser.set_defaults(func=_play)
