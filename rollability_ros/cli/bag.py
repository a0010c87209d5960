"""`rollability bag info|recover|convert`: inspect, repair and convert rosbag2 bags without ``ros2 bag``."""
import json
import sys

from rollability_ros.cli import Subparsers


def _info(args):
    from rollability_ros.core.bags import bag_info, format_bag_info

    info = bag_info(args.bag, verify_chunks=not args.no_verify)
    print(json.dumps(info, indent=2) if args.json else format_bag_info(info))
    if info["corrupt_chunks"]:   # the summary above is what the undamaged records say; the data is not all there
        print(f"rollability bag info: error: {args.bag}: {info['chunk_check']}", file=sys.stderr)
        return 1
    return 0


def _recover(args):
    from rollability_ros.core.bags import recover

    report = recover(args.bag)
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    for entry in report["files"]:
        if entry["status"] == "intact":
            print(f"{entry['path']}: intact")
        else:
            print(f"{entry['path']}: recovered {entry['messages']} messages from {entry['chunks_recovered']} "
                  f"chunks; discarded {entry['chunks_discarded']} corrupt chunks, {entry['bytes_discarded']} "
                  f"bytes of cut tail, {entry['messages_without_channel']} messages without a channel"
                  + (f"; the damaged original is kept as {entry['backup']}" if entry.get("backup") else ""))
    if report["metadata_rewritten"]:
        kept = f" (the previous one kept as {report['metadata_backup']})" if report["metadata_backup"] else ""
        print(f"{args.bag}: metadata.yaml rewritten{kept}, {report['message_count']} messages")
    else:
        print(f"{args.bag}: metadata.yaml already matched the files, {report['message_count']} messages")
    return 0


def _convert(args):
    from rollability_ros.core.bags import convert

    convert(args.src, args.dst, storage=args.storage)
    print(f"{args.src} -> {args.dst} ({args.storage})")
    return 0


def register(subparsers: Subparsers) -> None:
    """Add the ``bag`` verb with its ``info``, ``recover`` and ``convert`` sub-verbs."""
    parser = subparsers.add_parser(
        "bag", help="inspect, recover and convert rosbag2 bags (MCAP / SQLite3)",
        description="Work on rosbag2 bag directories (metadata.yaml + storage files) without ros2 bag.")
    verbs = parser.add_subparsers(dest="bag_verb", metavar="BAG_VERB")
    verbs.required = True

    info = verbs.add_parser("info", help="topics (type, count, serialization, QoS), start/end times, duration, "
                                         "files and sizes of a bag",
                            description="Summarise a bag from its metadata and its storage files' summaries, as "
                                        "`ros2 bag info` does, plus per-topic offered QoS and per-file sizes. "
                                        "Every MCAP chunk is read and checked against its CRC (reads the whole "
                                        "bag; --no-verify skips it and says so): a corrupt chunk is listed and "
                                        "the exit code is 1.")
    info.add_argument("bag", help="bag directory, or one .mcap file")
    info.add_argument("--no-verify", action="store_true",
                      help="do not read the chunks to check their CRCs (fast; the output says they were not verified)")
    info.add_argument("--json", action="store_true", help="print the summary as JSON")
    info.set_defaults(func=_info)

    recover = verbs.add_parser(
        "recover", help="repair a bag whose recorder was killed",
        description="Rebuild cut or damaged MCAP storage files from every intact (CRC-checked) chunk, found by "
                    "scanning past damaged records, and rewrite metadata.yaml keeping storage id, ROS distro, custom "
                    "data, QoS and type hashes. A file is replaced only after its rebuilt copy verifies; the damaged "
                    "original stays as <file>.before-recover, the old metadata.yaml as metadata.yaml.before-recover "
                    "(-2, -3, ... after an earlier recovery). When nothing can be saved (no intact message) the bag "
                    "is left untouched and the exit code is 2.")
    recover.add_argument("bag", help="bag directory")
    recover.add_argument("--json", action="store_true", help="print the recovery report as JSON")
    recover.set_defaults(func=_recover)

    convert = verbs.add_parser("convert", help="copy a bag into MCAP or SQLite3 storage",
                               description="Write a new bag DST with the messages, topics, QoS, type hashes "
                                           "and custom data of SRC in the chosen storage.")
    convert.add_argument("src", help="source bag directory")
    convert.add_argument("dst", help="new bag directory (must not exist)")
    convert.add_argument("--storage", choices=("mcap", "sqlite3"), default="sqlite3",
                         help="storage of the new bag (default: sqlite3)")
    convert.set_defaults(func=_convert)
