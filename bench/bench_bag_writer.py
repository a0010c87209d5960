"""Bag writer throughput: a raw ``mcap`` writer (the disk-side limit) next to our BagWriter, same messages, one run.

Message sizes: outcome-sized (~200 B), pose-stream-sized (~100 B, many), and large (10 kB). Prints
messages/s, MB/s and the BagWriter / raw ratio. The recorder-node benchmark imports :func:`measure` to put
its own end-to-end numbers beside these.

    python bench/bench_bag_writer.py [--seconds-per-case 2]
"""
import argparse
import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from rollability_ros.core.bags.writer import DEFAULT_CHUNK_SIZE_BYTES, BagWriter  # noqa: E402

#: (case name, payload bytes) measured by default.
CASES = (("outcome", 200), ("pose_stream", 100), ("large", 10_000))

T0_NS = 1_700_000_000_000_000_000


def payloads(payload_bytes, count=64):
    """Return ``count`` distinct CDR-like payloads of ``payload_bytes`` bytes (varied so zstd cannot cheat)."""
    return [b"\x00\x01\x00\x00" + os.urandom(payload_bytes // 2) + bytes(payload_bytes - 4 - payload_bytes // 2)
            for _ in range(count)]


def _raw_mcap(path, data, message_count):
    """Write with a bare mcap Writer; return the seconds spent writing messages and finishing the file."""
    from mcap.writer import CompressionType, Writer

    with open(path, "wb") as stream:
        writer = Writer(stream, chunk_size=DEFAULT_CHUNK_SIZE_BYTES, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library="bench")
        schema_id = writer.register_schema("std_msgs/msg/ByteMultiArray", "ros2msg", b"uint8[] data\n")
        channel_id = writer.register_channel("/bench", "cdr", schema_id, {"offered_qos_profiles": ""})
        start = time.perf_counter()
        for index in range(message_count):
            writer.add_message(channel_id, T0_NS + index, data[index % len(data)], T0_NS + index)
        writer.finish()
    return time.perf_counter() - start


def _bag_writer(path, data, message_count):
    """Write with BagWriter; return the seconds spent writing messages and closing the bag."""
    writer = BagWriter(path)
    writer.add_topic("/bench", "std_msgs/msg/ByteMultiArray")
    start = time.perf_counter()
    for index in range(message_count):
        writer.write("/bench", data[index % len(data)], T0_NS + index)
    writer.close()
    return time.perf_counter() - start


WRITERS = {"raw_mcap": _raw_mcap, "bag_writer": _bag_writer}


def measure(writer_name, payload_bytes, message_count, directory):
    """Write ``message_count`` messages of ``payload_bytes`` with one writer; return its throughput.

    Setup (opening the file, registering the topic) is not timed; writing and closing are.

    Returns
    -------
    dict
        ``writer``, ``payload_bytes``, ``messages``, ``seconds``, ``messages_per_s``, ``mb_per_s`` (payload
        megabytes per second, 1 MB = 1e6 B), ``file_bytes`` (on disk).
    """
    data = payloads(payload_bytes)
    target = os.path.join(directory, f"{writer_name}_{payload_bytes}")
    seconds = WRITERS[writer_name](target, data, message_count)
    file_bytes = (sum(os.path.getsize(os.path.join(target, n)) for n in os.listdir(target))
                  if os.path.isdir(target) else os.path.getsize(target))
    shutil.rmtree(target) if os.path.isdir(target) else os.remove(target)
    return {"writer": writer_name, "payload_bytes": payload_bytes, "messages": message_count, "seconds": seconds,
            "messages_per_s": message_count / seconds, "mb_per_s": message_count * payload_bytes / seconds / 1e6,
            "file_bytes": file_bytes}


def run(seconds_per_case=2.0, cases=CASES, directory=None, probe_messages=20_000):
    """Measure every case with both writers; return ``{case: {writer name: measure() dict}}``.

    The message count of a case is calibrated so the raw writer runs about ``seconds_per_case``.
    """
    results = {}
    with tempfile.TemporaryDirectory(dir=directory) as scratch:
        for case, payload_bytes in cases:
            probe = measure("raw_mcap", payload_bytes, probe_messages, scratch)
            count = max(probe_messages, int(probe["messages_per_s"] * seconds_per_case))
            results[case] = {name: measure(name, payload_bytes, count, scratch) for name in WRITERS}
    return results


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds-per-case", type=float, default=2.0, help="target run time per writer, s")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    results = run(0.0, probe_messages=50) if args.smoke else run(args.seconds_per_case)
    print(f"{'case':<12} {'payload B':>9} {'writer':<11} {'messages':>9} {'msg/s':>10} {'MB/s':>8}  ratio")
    for case, by_writer in results.items():
        raw = by_writer["raw_mcap"]["messages_per_s"]
        for name, result in by_writer.items():
            print(f"{case:<12} {result['payload_bytes']:>9} {name:<11} {result['messages']:>9} "
                  f"{result['messages_per_s']:>10.0f} {result['mb_per_s']:>8.2f}  {result['messages_per_s'] / raw:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
