"""The committed sample bag (bags/sample): independent readers open it, its report equals the live store's, and
it replays into an outcome_logger exactly like the live run."""
import json
import subprocess
import sys
import time

from conftest import REPO_ROOT

SAMPLE = REPO_ROOT / "bags" / "sample"

# Runs in an isolated interpreter (-I: no checkout, no PYTHONPATH): only mcap + mcap_ros2 and the file itself.
DECODE_WITH_MCAP_ONLY = """
import json, sys
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
with open(sys.argv[1], "rb") as stream:
    reader = make_reader(stream, decoder_factories=[DecoderFactory()])
    outcomes = [(m.trial_id, m.condition.configuration, bool(m.upright))
                for _, channel, _, m in reader.iter_decoded_messages(topics=["/rollability/launch_outcomes"])]
print(json.dumps(outcomes))
"""


def test_sample_opens_in_mcap_and_rosbags_without_the_package(tmp_path):
    decoded = subprocess.run([sys.executable, "-I", "-c", DECODE_WITH_MCAP_ONLY, str(SAMPLE / "bag_0.mcap")],
                             capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert decoded.returncode == 0, decoded.stderr
    outcomes = json.loads(decoded.stdout)
    assert len(outcomes) == 36 and {c for _, c, _ in outcomes} == {"baseline", "A", "B"}

    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    with Reader(SAMPLE) as reader:
        for connection in reader.connections:
            store.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        connection = next(c for c in reader.connections if c.topic == "/rollability/launch_outcomes")
        upright = [store.deserialize_cdr(raw, connection.msgtype).upright
                   for _, _, raw in reader.messages(connections=[connection])]
    assert len(upright) == 36 and upright.count(True) == sum(u for _, _, u in outcomes)


def test_report_from_the_sample_equals_the_live_store(tmp_path):
    from rollability_ros.cli import main

    assert main(["report", str(SAMPLE), "--out", str(tmp_path)]) == 0
    # by_configuration.csv of the report the live run wrote from its outcome store
    expected = (REPO_ROOT / "test" / "resources" / "sample_by_configuration.csv").read_text()
    assert (tmp_path / "by_configuration.csv").read_text() == expected


def test_sample_replays_into_the_logger_like_the_live_run(tmp_path, ros_node, start_node, start_process):
    from rollability_ros.core.bags.messages import read_records_from_bag
    from rollability_ros.core.store import Store
    from rollability_ros.srv import GetSummary

    store_path = tmp_path / "replayed.sqlite"
    logger = start_node("outcome_logger", params={"store_path": str(store_path)},
                        ros_args=["-r", "__ns:=/rollability"])
    # the logger is up before the player starts, and the player waits (up to 60 s, not the default 3 s) until it
    # has matched the logger: on a loaded machine discovery can take longer than 3 s
    client = ros_node.node.create_client(GetSummary, "/rollability/get_summary")
    assert client.wait_for_service(timeout_sec=30), logger.log()
    player = start_process("rollability_ros.cli", "play", str(SAMPLE), "--rate", "20", "--wait-for-subscribers", "60",
                           "--topics", "/rollability/launch_outcomes", "/rollability/candidates",
                           "/rollability/generations")
    assert player.process.wait(timeout=180) == 0, player.log()
    recorded = read_records_from_bag(SAMPLE)[0]
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        with Store(store_path) as store:
            replayed = store.launch_outcomes()
        if len(replayed) == len(recorded):
            break
        time.sleep(0.2)
    assert sorted(replayed, key=lambda o: o.trial_id) == sorted(recorded, key=lambda o: o.trial_id), logger.log()
