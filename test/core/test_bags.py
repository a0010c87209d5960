"""Bag core: definitions and type hashes, writer/reader round trips, splitting, info, errors, playback, convert, CLI."""
import glob
import json
import os
import struct
import subprocess
import sys

import pytest
import yaml

from rollability_ros.core.bags.convert import convert
from rollability_ros.core.bags.metadata import BagError, read_metadata
from rollability_ros.core.bags.qos import normalize_qos_profiles, qos_dict_from_profile, subscription_qos_for
from rollability_ros.core.bags.playback import clock_message_cdr, playback_schedule
from rollability_ros.core.bags.reader import BagMessage, BagReader, bag_info, format_bag_info
from rollability_ros.core.bags.recover import recover
from rollability_ros.core.bags.writer import BagWriter
from rollability_ros.core.bags.msg_definitions import SEPARATOR, definition_for, package_directories, rihs01_hash
from rollability_ros.cli import main as cli_main

T0_NS = 1_700_000_000_000_000_000


def string_cdr(text):
    """CDR of std_msgs/msg/String (little endian): header, length incl. NUL, bytes, NUL."""
    raw = text.encode() + b"\0"
    return b"\x00\x01\x00\x00" + struct.pack("<I", len(raw)) + raw


def write_string_bag(directory, count, period_ns=10_000_000, topics=("/a", "/b"), **writer_options):
    """Write ``count`` std_msgs/String messages round-robin over ``topics``; return the BagMessages written."""
    written = []
    with BagWriter(directory, custom_data={"campaign": "test"}, **writer_options) as writer:
        for topic in topics:
            writer.add_topic(topic, "std_msgs/msg/String", offered_qos_profiles=[{"depth": 5}])
        for index in range(count):
            topic = topics[index % len(topics)]
            message = BagMessage(topic, "std_msgs/msg/String", string_cdr(f"{topic} {index}"),
                                 T0_NS + index * period_ns)
            writer.write(message.topic, message.data, message.log_time_ns)
            written.append(message)
    return written


def installed_hash(type_name):
    """The RIHS01 hash rosidl generated for an installed type (from its .json), or skip the test."""
    package, kind, name = type_name.split("/")
    stem = name.split("_")[0] if kind != "msg" else name
    for directory in package_directories(package):
        path = os.path.join(directory, kind, f"{stem}.json")
        if os.path.isfile(path):
            with open(path, encoding="utf-8") as stream:
                hashes = {h["type_name"]: h["hash_string"] for h in json.load(stream)["type_hashes"]}
            return hashes[type_name]
    pytest.skip(f"{type_name}: no rosidl .json installed")


@pytest.mark.parametrize("type_name", [
    "std_msgs/msg/String", "std_msgs/msg/Char", "geometry_msgs/msg/PoseStamped", "sensor_msgs/msg/Imu",
    "visualization_msgs/msg/Marker", "diagnostic_msgs/msg/DiagnosticArray", "rosgraph_msgs/msg/Clock",
    "std_srvs/srv/SetBool_Request", "action_msgs/msg/GoalStatusArray",
])
def test_rihs01_hash_equals_rosidl_generated_hash(type_name):
    assert rihs01_hash(type_name, definition_for(type_name)) == installed_hash(type_name)


def test_definition_has_every_nested_type_once_in_rosbag2_layout():
    text = definition_for("rollability_ros/msg/LaunchOutcome")
    with open(os.path.join(next(package_directories("rollability_ros")), "msg", "LaunchOutcome.msg"),
              encoding="utf-8") as stream:
        assert text.startswith(stream.read())
    headers = [line[len("MSG: "):] for line in text.splitlines() if line.startswith("MSG: ")]
    assert headers == ["geometry_msgs/Quaternion", "rollability_ros/LaunchCondition", "rollability_ros/ValveAuth",
                       "std_msgs/Header", "builtin_interfaces/Time"]
    assert text.count(SEPARATOR + "\nMSG: ") == 5
    pose = definition_for("geometry_msgs/PoseStamped")
    assert [line for line in pose.splitlines() if line.startswith("MSG: ")] == [
        "MSG: geometry_msgs/Pose", "MSG: geometry_msgs/Point", "MSG: geometry_msgs/Quaternion",
        "MSG: std_msgs/Header", "MSG: builtin_interfaces/Time"]


def test_definition_errors_name_the_type():
    with pytest.raises(ValueError, match="nonexistent_pkg/msg/Nope"):
        definition_for("nonexistent_pkg/msg/Nope")
    with pytest.raises(ValueError, match="pkg/msg/Type"):
        definition_for("JustAName")


def test_qos_profiles_normalise_from_v8_strings_dicts_and_reject_unknown_keys():
    v8 = "- history: 1\n  depth: 3\n  reliability: 2\n  durability: 1\n  deadline: {sec: 0, nsec: 0}\n" \
         "  lifespan: {sec: 0, nsec: 0}\n  liveliness: 1\n  liveliness_lease_duration: {sec: 0, nsec: 0}\n" \
         "  avoid_ros_namespace_conventions: false\n"
    (profile,) = normalize_qos_profiles(v8)
    assert profile["history"] == "keep_last" and profile["reliability"] == "best_effort"
    assert profile["durability"] == "transient_local" and profile["depth"] == 3
    (profile,) = normalize_qos_profiles([{"durability": "transient_local", "deadline": 1_500_000_000}])
    assert profile["deadline"] == {"sec": 1, "nsec": 500_000_000} and profile["depth"] == 10
    with pytest.raises(ValueError, match="unknown QoS profile keys"):
        normalize_qos_profiles([{"dept": 1}])
    with pytest.raises(ValueError, match="reliability"):
        normalize_qos_profiles([{"reliability": "sometimes"}])


def test_subscription_qos_matches_every_publisher_and_reads_rclpy_like_profiles():
    class Duration:
        def __init__(self, nanoseconds):
            self.nanoseconds = nanoseconds

    class Policy:   # an rclpy policy enum: only .value matters
        def __init__(self, value):
            self.value = value

    class Profile:  # the attributes of rclpy's QoSProfile
        history, depth, reliability, durability = Policy(1), 7, Policy(2), Policy(1)
        deadline = lifespan = liveliness_lease_duration = Duration(9223372036854775807)
        liveliness, avoid_ros_namespace_conventions = Policy(1), False

    offered = qos_dict_from_profile(Profile())
    assert offered["reliability"] == "best_effort" and offered["durability"] == "transient_local"
    assert offered["deadline"] == {"sec": 9223372036, "nsec": 854775807} and offered["depth"] == 7
    latched_reliable = {"durability": "transient_local"}
    assert subscription_qos_for([latched_reliable, latched_reliable])["durability"] == "transient_local"
    mixed = subscription_qos_for([latched_reliable, offered, {}], depth=50)
    assert (mixed["reliability"], mixed["durability"], mixed["depth"]) == ("best_effort", "volatile", 50)
    assert subscription_qos_for([])["reliability"] == "reliable"
    with pytest.raises(ValueError, match="depth"):
        subscription_qos_for([], depth=0)


def test_round_trip_split_by_size_keeps_order_metadata_and_mcap_layout(tmp_path):
    from mcap.reader import make_reader

    bag = tmp_path / "run1"
    written = write_string_bag(bag, 3000, split_max_bytes=20_000, chunk_size_bytes=4096)
    assert list(BagReader(bag)) == written

    information = read_metadata(bag)
    assert information["version"] == 9 and information["storage_identifier"] == "mcap"
    assert information["ros_distro"] == "jazzy" and information["custom_data"] == {"campaign": "test"}
    assert information["compression_format"] == "" and information["compression_mode"] == ""
    names = information["relative_file_paths"]
    assert len(names) > 2 and names == [f"run1_{i}.mcap" for i in range(len(names))]
    assert sorted(os.listdir(bag)) == sorted(names + ["metadata.yaml"])   # sidecar removed by close
    assert [f["path"] for f in information["files"]] == names
    assert sum(f["message_count"] for f in information["files"]) == information["message_count"] == 3000
    assert information["starting_time"]["nanoseconds_since_epoch"] == T0_NS
    assert information["duration"]["nanoseconds"] == 2999 * 10_000_000
    topic = information["topics_with_message_count"][0]
    assert topic["message_count"] == 1500
    assert topic["topic_metadata"]["type_description_hash"] == installed_hash("std_msgs/msg/String")
    assert topic["topic_metadata"]["offered_qos_profiles"][0]["depth"] == 5

    for entry in information["files"]:
        with open(bag / entry["path"], "rb") as stream:
            reader = make_reader(stream)
            assert reader.get_header().profile == "ros2"
            summary = reader.get_summary()
            assert summary.statistics.message_count == entry["message_count"]
            assert {c.compression for c in summary.chunk_indexes} == {"zstd"}
            assert all(c.message_index_length > 0 for c in summary.chunk_indexes)
            (schema,) = summary.schemas.values()
            assert schema.encoding == "ros2msg" and schema.data.decode() == definition_for("std_msgs/msg/String")
            channel = summary.channels[1]
            assert channel.message_encoding == "cdr"
            assert yaml.safe_load(channel.metadata["offered_qos_profiles"])[0]["history"] == "keep_last"
            assert channel.metadata["topic_type_hash"].startswith("RIHS01_")
            (record,) = [m for m in reader.iter_metadata() if m.name == "rosbag2"]
            assert yaml.safe_load(record.metadata["serialized_metadata"])["custom_data"] == {"campaign": "test"}


def test_split_by_duration_and_filters(tmp_path):
    bag = tmp_path / "timed"
    written = write_string_bag(bag, 100, period_ns=100_000_000, split_max_duration_s=2.0)
    files = read_metadata(bag)["files"]
    assert [f["message_count"] for f in files] == [20, 20, 20, 20, 20]
    assert all(f["duration"]["nanoseconds"] == 19 * 100_000_000 for f in files)
    window = list(BagReader(bag, topics=["/b"], start_time_ns=T0_NS + 1_000_000_000,
                            end_time_ns=T0_NS + 3_000_000_000))
    assert window == [m for m in written if m.topic == "/b" and T0_NS + 1e9 <= m.log_time_ns < T0_NS + 3e9]
    with pytest.raises(ValueError, match="/c"):
        BagReader(bag, topics=["/c"])


def test_bag_info_reports_topics_counts_duration_size_compression(tmp_path):
    bag = tmp_path / "info"
    write_string_bag(bag, 10, period_ns=500_000_000, split_max_duration_s=2.0)
    info = bag_info(bag)
    assert info["message_count"] == 10 and info["duration_s"] == pytest.approx(4.5)
    assert {t["name"]: t["message_count"] for t in info["topics"]} == {"/a": 5, "/b": 5}
    assert info["compression"] == "zstd (mcap chunks)" and info["warnings"] == []
    assert info["size_bytes"] == sum(os.path.getsize(p) for p in glob.glob(str(bag / "*.mcap")))


def test_bag_info_tells_what_ros2_bag_info_tells_for_a_folder_or_one_mcap_file(tmp_path):
    bag = tmp_path / "rich"
    write_string_bag(bag, 10, period_ns=500_000_000, split_max_duration_s=2.0)
    info = bag_info(bag)
    # T0_NS = 1 700 000 000 s since the epoch = 2023-11-14 22:13:20 UTC; the last message 4.5 s later
    assert info["start_time"] == "2023-11-14 22:13:20.000000000 UTC"
    assert info["end_time"] == "2023-11-14 22:13:24.500000000 UTC"
    text = format_bag_info(info)
    assert "Start:             2023-11-14 22:13:20.000000000 UTC (1700000000.000000000 s)" in text
    for entry in info["files"]:
        assert f"  {entry['path']}  " in text and f"({entry['size_bytes']} bytes)" in text
    assert ("Topic: /a | Type: std_msgs/msg/String | Count: 5 | Serialization Format: cdr | "
            "QoS: reliable, volatile, keep_last 5") in text
    first = sorted(glob.glob(str(bag / "*.mcap")))[0]
    single = bag_info(first)       # one split file, summarised from its own records
    assert single["path"] == first and [f["path"] for f in single["files"]] == [os.path.basename(first)]
    assert single["message_count"] == info["files"][0]["message_count"] and single["warnings"] == []
    assert single["topics"][0]["offered_qos_profiles"][0]["depth"] == 5 and single["ros_distro"] == "jazzy"
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(BagError, match="not a bag: give a bag directory"):
        bag_info(tmp_path / "notes.txt")


def test_a_closed_pipe_ends_the_cli_quietly(tmp_path):
    """`rollability bag info --json | head`: the reader goes away first; no BrokenPipeError traceback."""
    write_string_bag(tmp_path / "pipe", 20)
    process = subprocess.Popen([sys.executable, "-m", "rollability_ros.cli", "bag", "info", "--json",
                                str(tmp_path / "pipe")], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    process.stdout.close()          # before the child writes: its first write meets a closed pipe
    stderr = process.stderr.read().decode()
    assert process.wait(timeout=60) == 141
    assert "Traceback" not in stderr and "BrokenPipeError" not in stderr, stderr


def test_corrupt_truncated_and_missing_files_raise_errors_naming_the_file(tmp_path):
    bag = tmp_path / "broken"
    write_string_bag(bag, 200, split_max_duration_s=1.0)
    first, second = bag / "broken_0.mcap", bag / "broken_1.mcap"
    second.write_bytes(second.read_bytes()[:-100])
    with pytest.raises(BagError, match="broken_1.mcap: truncated"):
        list(BagReader(bag))
    first.write_bytes(b"not an mcap file at all")
    with pytest.raises(BagError, match="broken_0.mcap: not an MCAP file"):
        bag_info(bag)
    first.unlink()
    with pytest.raises(BagError, match="broken_0.mcap: storage file listed in metadata.yaml is missing"):
        BagReader(bag)
    (bag / "metadata.yaml").unlink()
    with pytest.raises(BagError, match="metadata.yaml: missing"):
        bag_info(bag)


def test_writer_rejects_bad_input(tmp_path):
    with pytest.raises(ValueError, match="compression"):
        BagWriter(tmp_path / "x", compression="gzip")
    with pytest.raises(ValueError, match="storage"):
        BagWriter(tmp_path / "y", storage="sqlite3")
    with BagWriter(tmp_path / "z") as writer:
        writer.add_topic("/a", "std_msgs/String")
        with pytest.raises(ValueError, match="already recorded with type std_msgs/msg/String"):
            writer.add_topic("/a", "std_msgs/msg/Bool")
        with pytest.raises(ValueError, match="add_topic"):
            writer.write("/nope", b"", T0_NS)
    with pytest.raises(ValueError, match="not overwriting"):
        BagWriter(tmp_path / "z")


def test_flush_interval_bounds_what_an_unclosed_writer_loses(tmp_path):
    """A writer never closed (as after SIGKILL) keeps every message flushed by the interval, loses the rest."""
    import shutil

    now = [0.0]
    writer = BagWriter(tmp_path / "live", flush_interval_s=1.0, chunk_size_bytes=1 << 20, clock=lambda: now[0])
    writer.add_topic("/a", "std_msgs/msg/String")
    for index in range(5):
        writer.write("/a", string_cdr(str(index)), T0_NS + index)
    now[0] = 1.5
    writer.write("/a", string_cdr("5"), T0_NS + 5)          # interval passed: chunk of 6 messages written
    for index in range(6, 9):
        writer.write("/a", string_cdr(str(index)), T0_NS + index)   # still in the open chunk
    shutil.copytree(tmp_path / "live", tmp_path / "killed")
    report = recover(tmp_path / "killed")
    assert report["message_count"] == 6
    assert [m.data for m in BagReader(tmp_path / "killed")] == [string_cdr(str(i)) for i in range(6)]
    assert read_metadata(tmp_path / "killed")["topics_with_message_count"][0]["topic_metadata"][
        "type_description_hash"] == installed_hash("std_msgs/msg/String")
    writer.close()


def test_playback_schedule_rate_offset_selection_remap_and_loop():
    messages = [("/a", "t", b"0", T0_NS), ("/b", "t", b"1", T0_NS + 1_000_000_000),
                ("/a", "t", b"2", T0_NS + 2_000_000_000), ("/a", "t", b"3", T0_NS + 4_000_000_000)]
    items = list(playback_schedule(messages, rate=2.0, start_offset_s=1.5, topics=["/a"], remap={"/a": "/replay"}))
    assert [(i.wall_time_s, i.delay_s, i.topic, i.data) for i in items] == [
        (0.0, 0.0, "/replay", b"2"), (1.0, 1.0, "/replay", b"3")]
    looped = playback_schedule(messages, loop=True)
    first_two_passes = [next(looped) for _ in range(8)]
    assert [i.wall_time_s for i in first_two_passes] == [0.0, 1.0, 2.0, 4.0, 4.0, 5.0, 6.0, 8.0]
    assert [i.loop_index for i in first_two_passes] == [0] * 4 + [1] * 4
    with pytest.raises(ValueError, match="re-iterable"):
        list(playback_schedule(iter(messages), loop=True))
    with pytest.raises(ValueError, match="rate"):
        list(playback_schedule(messages, rate=0))


def test_clock_message_cdr_decodes_as_rosgraph_clock():
    from rosbags.typesys import Stores, get_typestore

    clock = get_typestore(Stores.ROS2_JAZZY).deserialize_cdr(clock_message_cdr(T0_NS + 123), "rosgraph_msgs/msg/Clock")
    assert (clock.clock.sec, clock.clock.nanosec) == (T0_NS // 1_000_000_000, 123)


def test_convert_mcap_sqlite3_mcap_keeps_messages_and_metadata(tmp_path):
    from rosbags.rosbag2 import Reader

    written = write_string_bag(tmp_path / "src", 50, split_max_duration_s=0.2)
    convert(tmp_path / "src", tmp_path / "db", storage="sqlite3")
    convert(tmp_path / "db", tmp_path / "back", storage="mcap")
    with Reader(tmp_path / "db") as reader:
        assert [c.digest for c in reader.connections] == [installed_hash("std_msgs/msg/String")] * 2
    for bag in ("db", "back"):
        information = read_metadata(tmp_path / bag)
        assert information["custom_data"] == {"campaign": "test"} and information["ros_distro"] == "jazzy"
        assert information["topics_with_message_count"][0]["topic_metadata"]["offered_qos_profiles"][0]["depth"] == 5
        assert list(BagReader(tmp_path / bag)) == written
        # each message comes with the definition its bag stores, from MCAP schemas and SQLite3 metadata alike
        assert {d for _, d in BagReader(tmp_path / bag).with_definitions()} == {definition_for("std_msgs/msg/String")}
    with pytest.raises(ValueError, match="storage"):
        convert(tmp_path / "src", tmp_path / "z", storage="rosbag1")


def test_cli_bag_info_recover_convert(tmp_path, capsys):
    write_string_bag(tmp_path / "cli", 20)
    assert cli_main(["bag", "info", str(tmp_path / "cli")]) == 0
    out = capsys.readouterr().out
    assert "/a" in out and "std_msgs/msg/String" in out and "zstd (mcap chunks)" in out
    assert cli_main(["bag", "info", "--json", str(tmp_path / "cli")]) == 0
    assert json.loads(capsys.readouterr().out)["message_count"] == 20
    assert cli_main(["bag", "recover", str(tmp_path / "cli")]) == 0
    assert "cli_0.mcap: intact" in capsys.readouterr().out
    assert cli_main(["bag", "convert", str(tmp_path / "cli"), str(tmp_path / "db"), "--storage", "sqlite3"]) == 0
    assert bag_info(tmp_path / "db")["message_count"] == 20
    assert cli_main(["bag", "info", str(tmp_path / "missing")]) == 2
    assert "not a bag directory" in capsys.readouterr().err


def test_playback_schedule_keeps_every_message_of_the_sample_bag():
    """Issue 17: the sample's first message was dropped when its epoch time in ns rounded up as a float."""
    from rollability_ros.core.bags.reader import BagReader

    sample = os.path.join(os.path.dirname(__file__), "..", "..", "bags", "sample")
    messages = list(BagReader(sample))
    items = list(playback_schedule(messages))
    assert len(items) == len(messages) == 2362
    assert [item.log_time_ns for item in items] == [m.log_time_ns for m in messages]
    # an offset of exactly the gap to the second message keeps the second message (integer ns arithmetic)
    offset_s = (messages[1].log_time_ns - messages[0].log_time_ns) / 1e9
    assert list(playback_schedule(messages, start_offset_s=offset_s))[0].log_time_ns == messages[1].log_time_ns
