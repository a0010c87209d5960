"""Recorder throughput end to end (publisher process -> recorder -> disk) beside its two limits, in one run.

For outcome-sized (rollability_ros/LaunchOutcome) and pose-stream-sized (geometry_msgs/PoseStamped) messages, a
publisher in its own process sends N messages as fast as it can (reliable, keep-all: the consumer's speed paces
it, nothing may be dropped) to one consumer process at a time:

- ``bare_callback``: a bare rclpy subscription that only counts (deserialized messages, one executor callback
  per message, SingleThreadedExecutor: what plain ``rclpy.spin`` does);
- ``bare_drained``: a bare raw subscription that counts and takes queued messages in a loop, as the recorder does;
- ``recorder``: the recorder node (same executor as ``python -m rollability_ros.nodes.recorder``), writing the
  bag; its time runs until the bag is closed on disk.

and, without ROS, the raw ``mcap`` writer and our BagWriter over the same number of same-sized payloads
(``bench_bag_writer.measure``). Prints messages/s, MB/s (serialized payload), drops, and ratios; the target is
recorder >= 0.8 x bare_callback.

    python bench/bench_recorder.py [--outcomes 20000] [--poses 40000] [--smoke]

The processes run in a ROS domain of their own (``bench.smoke.isolated_ros``), their ROS logs in a temporary
folder. ``--smoke``: 20 messages of each case (bench/smoke.py).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
import typing

BENCH_DIR = os.path.dirname(os.path.abspath(__file__))
REPO_ROOT = os.path.dirname(BENCH_DIR)
sys.path.insert(0, REPO_ROOT)

TOPICS = {"outcome": "/launch_outcomes", "pose": "/rig/pose"}
CONSUMERS = ("bare_callback", "bare_drained", "recorder")


def message_type(case):
    if case == "outcome":
        from rollability_ros.msg import LaunchOutcome

        return LaunchOutcome
    from geometry_msgs.msg import PoseStamped

    return PoseStamped


def sample_message(case):
    """One message of the case, filled like a real one (so its serialized size is realistic)."""
    msg = message_type(case)()
    if case == "outcome":
        msg.run_id, msg.trial_id, msg.backend, msg.classified_by = "campaign-2026-11-22", "t00000", "sim", "sim"
        msg.condition.configuration, msg.condition.height_m, msg.condition.speed_mps = "B", 1.30, 1.5
        msg.note = "operator: clean launch, landed on the left wheel"
        msg.header.frame_id = "world"
    else:
        msg.header.frame_id = "world"
        msg.pose.position.x, msg.pose.orientation.w = 0.12, 1.0
    return msg


def reliable_keep_all():
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=1000, history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)


# --- roles run in their own processes ------------------------------------------------------------------------
def run_publisher(case, count):
    """Publish ``count`` messages as fast as possible once a subscriber matched; print JSON."""
    import rclpy
    from rclpy.duration import Duration

    rclpy.init()
    node = rclpy.create_node("bench_publisher")
    publisher = node.create_publisher(message_type(case), TOPICS[case], reliable_keep_all())
    _wait(lambda: publisher.get_subscription_count() > 0, 30, 0.02)   # this side of the match
    sys.stdin.readline()   # the consumer's side: measure_consumer says "go" once the consumer sees this publisher
    msg = sample_message(case)
    start = time.perf_counter()
    for index in range(count):
        if case == "outcome":
            msg.trial_id = f"t{index:05d}"
        else:
            msg.header.stamp.nanosec = index
        publisher.publish(msg)
    published_s = time.perf_counter() - start
    acked = publisher.wait_for_all_acked(Duration(seconds=60))
    print(json.dumps({"published": count, "publish_s": published_s, "acked": acked}), flush=True)
    node.destroy_node()
    rclpy.shutdown()


def _wait(predicate, timeout_s, period_s=0.01):
    deadline = time.monotonic() + timeout_s
    while not predicate() and time.monotonic() < deadline:
        time.sleep(period_s)
    return predicate()


def run_consumer(kind, case, count, bag_dir):
    """Receive ``count`` messages with consumer ``kind``; print JSON with the count and the seconds from the first
    message to the last one (recorder: to the bag closed on disk)."""
    import rclpy
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor

    rclpy.init()
    marks: typing.Dict[str, typing.Any] = {"first": None, "last": None, "count": 0}
    if kind == "recorder":
        from rclpy.parameter import Parameter

        from rollability_ros.nodes.recorder import RecorderNode

        node: typing.Any = RecorderNode([Parameter("recorder.output_dir", value=bag_dir),
                                         Parameter("recorder.topics", value=[TOPICS[case]]),
                                         Parameter("recorder.discovery_period_s", value=0.2)])
        executor: typing.Any = MultiThreadedExecutor(num_threads=4)   # as run_node spins every node

        def received():
            return node.counts().get(TOPICS[case], 0)
    else:
        node = rclpy.create_node("bench_" + kind)
        executor = SingleThreadedExecutor()
        raw = kind == "bare_drained"

        def on_message(msg):
            if marks["first"] is None:
                marks["first"] = time.perf_counter()
            marks["count"] += 1
            if raw:
                with subscription.handle:
                    while subscription.handle.take_message(subscription.msg_type, True) is not None:
                        marks["count"] += 1
            if marks["count"] >= count:
                marks["last"] = time.perf_counter()

        subscription = node.create_subscription(message_type(case), TOPICS[case], on_message, reliable_keep_all(),
                                                raw=raw)

        def received():
            return marks["count"]
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    print(json.dumps({"ready": True}), flush=True)
    matched = _wait(lambda: node.count_publishers(TOPICS[case]) > 0, 60)   # the publisher's side: it waits for us
    print(json.dumps({"matched": matched}), flush=True)
    if kind == "recorder":
        _wait(lambda: received() > 0, 60)
        marks["first"] = time.perf_counter()
    done = _wait(lambda: received() >= count, 120)
    if kind == "recorder":
        node.close()   # the bag is on disk: summary section, metadata.yaml
        marks["last"] = time.perf_counter()
    total = received() if kind != "recorder" else sum(node.counts().values())
    print(json.dumps({"received": total, "seconds": (marks["last"] or time.perf_counter()) - marks["first"],
                      "complete": done}), flush=True)
    # stay until the publisher left: it leaves once this side acknowledged every message, and a reader that left
    # first kept its publisher's wait_for_all_acked waiting ~20 s for the reader's lease to run out
    _wait(lambda: node.count_publishers(TOPICS[case]) == 0, 60)
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()


# --- orchestration --------------------------------------------------------------------------------------------
def _json_lines(text):
    return [json.loads(line) for line in text.splitlines() if line.startswith("{")]


def measure_consumer(kind, case, count, scratch):
    """Run one consumer process and one publisher process; return a result dict."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [REPO_ROOT, os.environ.get("PYTHONPATH")]))}
    bag_dir = os.path.join(scratch, f"{kind}_{case}")
    consumer = subprocess.Popen([sys.executable, __file__, "--role", "consumer", "--kind", kind, "--case", case,
                                 "--count", str(count), "--bag", bag_dir], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, env=env)
    assert consumer.stdout is not None
    consumer.stdout.readline()   # ready
    publisher = subprocess.Popen([sys.executable, __file__, "--role", "publisher", "--case", case, "--count",
                                  str(count)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 text=True, env=env)
    consumer.stdout.readline()   # matched (or the consumer's end): the publisher may go once it matched too
    published_out, published_err = publisher.communicate("go\n", timeout=300)
    out, err = consumer.communicate(timeout=300)
    results = [line for line in _json_lines(out) if "received" in line]
    published = _json_lines(published_out)
    if not results or not published:
        raise RuntimeError(f"{kind}/{case} failed:\n{err[-2000:]}\n{published_err[-2000:]}")
    result, sent = results[-1], published[-1]
    return {"consumer": kind, "messages": sent["published"], "received": result["received"],
            "drops": sent["published"] - result["received"], "seconds": result["seconds"],
            "publisher_per_s": sent["published"] / sent["publish_s"],
            "messages_per_s": result["received"] / result["seconds"]}


def serialized_size(case):
    from rclpy.serialization import serialize_message

    return len(serialize_message(sample_message(case)))


def run(counts):
    """Measure every case; return ``{case: {"payload_bytes": n, "rows": [result dicts]}}``."""
    from bench.bench_bag_writer import measure

    results = {}
    with tempfile.TemporaryDirectory() as scratch:
        for case, count in counts.items():
            size = serialized_size(case)
            rows = [measure_consumer(kind, case, count, scratch) for kind in CONSUMERS]
            for writer in ("raw_mcap", "bag_writer"):
                written = measure(writer, size, count, scratch)
                rows.append({"consumer": writer, "messages": count, "received": count, "drops": 0,
                             "seconds": written["seconds"], "publisher_per_s": float("nan"),
                             "messages_per_s": written["messages_per_s"]})
            for row in rows:
                row["mb_per_s"] = row["messages_per_s"] * size / 1e6
            results[case] = {"payload_bytes": size, "rows": rows}
    return results


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--outcomes", type=int, default=20000, help="outcome-sized messages per consumer")
    parser.add_argument("--poses", type=int, default=40000, help="pose-stream-sized messages per consumer")
    parser.add_argument("--role", choices=("publisher", "consumer"), help=argparse.SUPPRESS)
    parser.add_argument("--kind", choices=CONSUMERS, help=argparse.SUPPRESS)
    parser.add_argument("--case", choices=tuple(TOPICS), help=argparse.SUPPRESS)
    parser.add_argument("--count", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--bag", help=argparse.SUPPRESS)
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: 20 messages of each case; the numbers "
                                                             "mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    if args.role == "publisher":
        run_publisher(args.case, args.count)
        return 0
    if args.role == "consumer":
        run_consumer(args.kind, args.case, args.count, args.bag)
        return 0
    if args.smoke:
        args.outcomes = args.poses = 20
    from bench.smoke import isolated_ros

    scratch = tempfile.TemporaryDirectory(prefix="bench-recorder-")   # ROS logs; removed when main returns
    domain_lock = isolated_ros(scratch.name)   # noqa: F841 - held while the processes run
    results = run({"outcome": args.outcomes, "pose": args.poses})
    print(f"{'case':<8} {'size B':>6} {'consumer':<14} {'messages':>8} {'drops':>5} {'msg/s':>9} {'MB/s':>7} "
          f"{'pub msg/s':>9}  vs bare_callback  vs bare_drained")
    verdicts = []
    for case, result in results.items():
        by_name = {row["consumer"]: row for row in result["rows"]}
        bare, drained = by_name["bare_callback"]["messages_per_s"], by_name["bare_drained"]["messages_per_s"]
        for row in result["rows"]:
            print(f"{case:<8} {result['payload_bytes']:>6} {row['consumer']:<14} {row['messages']:>8} "
                  f"{row['drops']:>5} {row['messages_per_s']:>9.0f} {row['mb_per_s']:>7.2f} "
                  f"{row['publisher_per_s']:>9.0f}  {row['messages_per_s'] / bare:>15.2f}  "
                  f"{row['messages_per_s'] / drained:>13.2f}")
        recorder = by_name["recorder"]
        ok = recorder["drops"] == 0 and recorder["messages_per_s"] >= 0.8 * bare
        verdicts.append(f"{case}: recorder/bare_callback = {recorder['messages_per_s'] / bare:.2f}, "
                        f"drops {recorder['drops']} -> {'meets' if ok else 'MISSES'} the target (>= 0.80, 0 drops)")
    print("\n".join(verdicts))
    return 0


if __name__ == "__main__":
    sys.exit(main())
