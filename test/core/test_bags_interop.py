"""Our bags open in other readers, and other writers' bags open in ours.

The decoding runs in an isolated interpreter (``python -I`` in an empty directory: no repo on the path, no
AMENT_PREFIX_PATH), so custom types must decode from the definitions stored in the bag alone.
"""
import glob
import json
import os
import subprocess
import sys
import textwrap

import pytest

from rollability_ros.core.bags.reader import BagReader, bag_info
from rollability_ros.core.bags.writer import BagWriter
from test_bags import T0_NS, string_cdr

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

#: Reads the bag given as argv[1] with rosbags (typestore from stored definitions) and with mcap + mcap_ros2.
DECODE_SCRIPT = textwrap.dedent("""
    import glob, json, sys
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg

    def plain(value):
        if hasattr(value, "__dataclass_fields__"):
            return {k: plain(getattr(value, k)) for k in value.__dataclass_fields__ if k != "__msgtype__"}
        if hasattr(value, "__slots__") and not isinstance(value, (str, bytes)):
            return {k: plain(getattr(value, k)) for k in value.__slots__}
        return value

    out = {"rosbags": [], "mcap_ros2": []}
    typestore = get_typestore(Stores.EMPTY)
    with Reader(sys.argv[1]) as reader:
        for connection in reader.connections:
            typestore.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        for connection, log_time_ns, data in reader.messages():
            out["rosbags"].append([connection.topic, plain(typestore.deserialize_cdr(data, connection.msgtype))])
    for path in sorted(glob.glob(sys.argv[1] + "/*.mcap")):
        with open(path, "rb") as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=True):
                out["mcap_ros2"].append([channel.topic, plain(decoded)])
    print(json.dumps(out))
""")


def custom_typestore():
    """A rosbags typestore with Jazzy's standard types and our msg/*.msg registered file by file."""
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg

    typestore = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for path in glob.glob(os.path.join(REPO_ROOT, "msg", "*.msg")):
        with open(path, encoding="utf-8") as stream:
            name = f"rollability_ros/msg/{os.path.splitext(os.path.basename(path))[0]}"
            types.update(get_types_from_msg(stream.read(), name))
    typestore.register(types)
    return typestore


def launch_outcome_cdr(typestore, trial_id, upright):
    """CDR of a rollability_ros/msg/LaunchOutcome built with rosbags from our .msg files."""
    new = typestore.types
    stamp = new["builtin_interfaces/msg/Time"](sec=1_700_000_000, nanosec=5)
    condition = new["rollability_ros/msg/LaunchCondition"](
        configuration="A", height_m=0.75, speed_mps=0.8, angle_deg=-30.0, repetition=2)
    outcome_type = new["rollability_ros/msg/LaunchOutcome"]
    values = dict(
        header=new["std_msgs/msg/Header"](stamp=stamp, frame_id="rig"), run_id="run1", trial_id=trial_id,
        condition=condition, backend="sim", upright=upright, travel_time_s=0.42, measured_speed_mps=0.81,
        speed_out_of_tolerance=False, final_orientation=new["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0,
                                                                                            w=1.0),
        classified_by="sim", note="", seed=123_456_789, final_tilt_deg=178.5, rest_distance_m=0.42,
        time_to_rest_s=float("nan"), peak_deceleration_mps2=96.0,
        auth=new["rollability_ros/msg/ValveAuth"](session="0123456789abcdef", counter=2**63 + 5, mac="ab" * 32),
        twin='{"no_twin":"physical"}')
    missing = set(outcome_type.__dataclass_fields__) - set(values) - {"__msgtype__"}
    assert not missing, f"LaunchOutcome.msg has fields this test does not fill: {missing}"
    return typestore.serialize_cdr(outcome_type(**values), "rollability_ros/msg/LaunchOutcome")


def test_bag_decodes_in_rosbags_and_mcap_ros2_from_stored_definitions_alone(tmp_path):
    serialization = pytest.importorskip("rclpy.serialization")
    from geometry_msgs.msg import PoseStamped
    from std_msgs.msg import String

    pose = PoseStamped()
    pose.header.frame_id = "world"
    pose.header.stamp.sec = 12
    pose.pose.position.x = 1.5
    pose.pose.orientation.w = 1.0
    typestore = custom_typestore()
    bag = tmp_path / "interop"
    with BagWriter(bag, split_max_duration_s=1.0) as writer:
        writer.add_topic("/chatter", "std_msgs/msg/String")
        writer.add_topic("/pose", "geometry_msgs/msg/PoseStamped")
        writer.add_topic("/rollability/launch_outcomes", "rollability_ros/msg/LaunchOutcome")
        for index in range(6):
            log_time_ns = T0_NS + index * 400_000_000
            writer.write("/chatter", serialization.serialize_message(String(data=f"hello {index}")), log_time_ns)
            writer.write("/pose", serialization.serialize_message(pose), log_time_ns + 1)
            writer.write("/rollability/launch_outcomes", launch_outcome_cdr(typestore, f"t{index}", index % 2 == 0),
                         log_time_ns + 2)
    assert len(glob.glob(str(bag / "*.mcap"))) > 1

    clean_env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "AMENT_PREFIX_PATH")}
    result = subprocess.run([sys.executable, "-I", "-c", DECODE_SCRIPT, str(bag)], cwd=tmp_path, env=clean_env,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    decoded = json.loads(result.stdout)
    for reader_name in ("rosbags", "mcap_ros2"):
        messages = decoded[reader_name]
        assert [topic for topic, _ in messages] == ["/chatter", "/pose", "/rollability/launch_outcomes"] * 6
        assert [m["data"] for topic, m in messages if topic == "/chatter"] == [f"hello {i}" for i in range(6)]
        poses = [m for topic, m in messages if topic == "/pose"]
        assert poses[0]["header"]["frame_id"] == "world" and poses[0]["header"]["stamp"]["sec"] == 12
        assert poses[0]["pose"]["position"]["x"] == 1.5 and poses[0]["pose"]["orientation"]["w"] == 1.0
        outcomes = [m for topic, m in messages if topic == "/rollability/launch_outcomes"]
        assert [o["trial_id"] for o in outcomes] == [f"t{i}" for i in range(6)]
        assert [o["upright"] for o in outcomes] == [True, False] * 3
        assert outcomes[0]["condition"]["height_m"] == 0.75 and outcomes[0]["header"]["frame_id"] == "rig"
        assert outcomes[0]["seed"] == 123_456_789
        assert outcomes[0]["auth"]["counter"] == 2**63 + 5 and outcomes[0]["auth"]["mac"] == "ab" * 32

    # and rclpy reads back exactly what it wrote
    first_pose = next(iter(BagReader(bag, topics=["/pose"])))
    assert serialization.deserialize_message(first_pose.data, PoseStamped) == pose


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_bags_written_by_rosbags_open_in_our_reader(tmp_path, storage):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_JAZZY)
    bag = tmp_path / f"rosbags_{storage}"
    writer = Writer(bag, version=9, storage_plugin=StoragePlugin[storage.upper()])
    with writer:
        connection = writer.add_connection("/chatter", "std_msgs/msg/String", typestore=typestore)
        for index in range(5):
            writer.write(connection, T0_NS + index, string_cdr(f"m{index}"))
    assert [m.data for m in BagReader(bag)] == [string_cdr(f"m{i}") for i in range(5)]
    info = bag_info(bag)
    assert info["message_count"] == 5 and info["topics"][0]["type"] == "std_msgs/msg/String"
