"""player over real DDS, in its own process: replayed outcomes reach the logger like live ones; timing and options."""
import threading

import pytest

from rollability_ros.core.bags.writer import BagWriter
from rollability_ros.core.records import CandidateRecord, LaunchCondition, LaunchOutcome
from rollability_ros.core.store import Store
from test_recorder import stopped_cleanly

T0_NS = 1_700_000_000_000_000_000
SPACING_NS = 50_000_000   # 50 ms between recorded outcomes


def outcome(index):
    condition = LaunchCondition("AB"[index % 2], 1.30, 1.5, 30.0 * (index % 3), index // 6)
    return LaunchOutcome(run_id="campaign1", trial_id=f"t{index:03d}", condition=condition, backend="sim",
                         upright=index % 4 != 0, travel_time_s=0.23, measured_speed_mps=1.48,
                         final_orientation=(0.0, 0.0, 0.0, 1.0), classified_by="sim", stamp_s=1700000000.0 + index)


@pytest.fixture
def campaign_bag(tmp_path):
    """A bag of 30 launch outcomes 50 ms apart and 5 candidates, written as the recorder writes them."""
    from rclpy.serialization import serialize_message

    from rollability_ros.nodes import _convert
    from rollability_ros.nodes._support import RECORD_QOS
    from rollability_ros.core.bags.qos import qos_dict_from_profile

    outcomes = [outcome(i) for i in range(30)]
    bag = tmp_path / "campaign"
    offered = [qos_dict_from_profile(RECORD_QOS)]
    with BagWriter(bag) as writer:
        writer.add_topic("/launch_outcomes", "rollability_ros/msg/LaunchOutcome", offered_qos_profiles=offered)
        writer.add_topic("/candidates", "rollability_ros/msg/CandidateResult", offered_qos_profiles=offered)
        for index, record in enumerate(outcomes):
            writer.write("/launch_outcomes", serialize_message(_convert.outcome_to_msg(record)),
                         T0_NS + index * SPACING_NS)
        for index in range(5):
            candidate = CandidateRecord("opt1", 0, index, (0.1,), 0.5, 1, 2, 3, 0.1)
            writer.write("/candidates", serialize_message(_convert.candidate_to_msg(candidate)),
                         T0_NS + index * SPACING_NS + 1)
    return bag, outcomes


def test_replayed_outcomes_are_stored_by_the_logger_like_live_ones(tmp_path, campaign_bag, ros_node, start_node,
                                                                   start_process):
    from rollability_ros.srv import GetSummary

    from rollability_ros.msg import LaunchOutcome as OutcomeMsg
    from rollability_ros.nodes._support import RECORD_QOS

    bag, outcomes = campaign_bag
    store_path = tmp_path / "replayed.sqlite"
    logger = start_node("outcome_logger", params={"store_path": str(store_path)})
    client = ros_node.node.create_client(GetSummary, "/get_summary")
    assert client.wait_for_service(timeout_sec=30), logger.log()

    def play(name):
        player = start_process("rollability_ros.cli", "play", str(bag), "--rate", "2", "--topics",
                               "/launch_outcomes", name=name)
        player.process.wait(timeout=60)
        assert player.process.returncode == 0, player.log()
        assert "played 30 messages" in player.log()

    # The player starts once every played topic has *a* subscriber. The logger is the only one on the first play:
    # with a second subscriber the player may start once that one matched and before the logger did (seen in a
    # fresh-clone run: 30 played, 0 stored). Once the player's writer has matched a reliable reader, it keeps every
    # message for it until acknowledged, and it waits for the acknowledgements before exiting.
    play("play0")
    summary = client.call(GetSummary.Request(), timeout_sec=30).summary
    assert (summary.trials, summary.candidates) == (30, 0), logger.log()   # /candidates was not selected

    sent_ns = []      # when the player published each outcome (the DDS source timestamp, ns)
    ros_node.node.create_subscription(OutcomeMsg, "/launch_outcomes",
                                      lambda msg, info: sent_ns.append(info["source_timestamp"]), RECORD_QOS)
    for attempt in range(1, 4):
        sent_ns.clear()
        play(f"play{attempt}")
        # the logger (matched since the first play) lets the player start before this test's observer matched it;
        # the volatile messages then went out before it: play again (the logger stores each outcome once)
        if ros_node.wait_for(lambda: len(sent_ns) == 30, 10):
            break
    # the player published them with the recorded spacing divided by the rate: 29 x 50 ms / 2 = 0.725 s from the
    # first to the last (never sooner; a starved player may be late). Timed where they were sent: a consumer
    # starved of CPU would see them bunched.
    assert len(sent_ns) == 30, sent_ns
    assert 0.7 <= (max(sent_ns) - min(sent_ns)) / 1e9 < 1.4, sent_ns            # rate 1 would take 1.45 s
    assert stopped_cleanly(logger, logger.stop())
    with Store(store_path) as store:
        assert store.launch_outcomes() == outcomes


def test_remap_clock_start_offset_and_loop(campaign_bag, ros_node, start_process):
    from rosgraph_msgs.msg import Clock

    from rollability_ros.msg import LaunchOutcome as OutcomeMsg
    from rollability_ros.nodes._support import RECORD_QOS

    bag, outcomes = campaign_bag
    replayed, clocks = [], []
    lock = threading.Lock()

    def on_outcome(msg):
        with lock:
            replayed.append(msg.trial_id)

    ros_node.node.create_subscription(OutcomeMsg, "/replayed", on_outcome, RECORD_QOS)
    ros_node.node.create_subscription(Clock, "/clock", lambda m: clocks.append(m.clock.sec * 10**9 + m.clock.nanosec),
                                      100)
    player = start_process("rollability_ros.cli", "play", str(bag), "--topics", "/launch_outcomes",
                           "--remap", "/launch_outcomes:=/replayed", "--clock", "--start-offset", "1.0", name="play")
    player.process.wait(timeout=60)
    assert player.process.returncode == 0, player.log()
    assert ros_node.wait_for(lambda: len(replayed) == 10, 10), (replayed, player.log())
    assert replayed == [o.trial_id for o in outcomes[20:]]          # the first second (20 outcomes) skipped
    # /clock is volatile (a late subscriber must not get old time): the outcomes above are acknowledged, but on a
    # loaded machine this node can match the player's /clock writer a few ticks late and miss the first ones. So:
    # every tick received is a played message's recorded time, in order, ending with the last played one
    expected = [T0_NS + i * SPACING_NS for i in range(20, 30)]
    assert ros_node.wait_for(lambda: clocks and clocks[-1] == expected[-1], 10), clocks
    assert clocks == expected[-len(clocks):]

    replayed.clear()
    looping = start_process("rollability_ros.cli", "play", str(bag), "--topics", "/launch_outcomes", "--remap",
                            "/launch_outcomes:=/replayed", "--loop", "--rate", "10", name="loop")
    assert ros_node.wait_for(lambda: len(replayed) >= 75, 30), looping.log()
    assert looping.alive()
    assert stopped_cleanly(looping, looping.stop()), looping.log()
    with lock:
        passes = replayed[:60]
    assert passes == [o.trial_id for o in outcomes] * 2


def test_bad_bag_and_options_exit_with_a_reason(tmp_path, campaign_bag, start_process):
    bag, _ = campaign_bag
    cases = [((str(tmp_path / "missing"),), "not a directory"),
             ((str(bag), "--rate", "-1"), "player.rate out of range"),
             ((str(bag), "--topics", "/nope"), "not in bag"),
             ((str(bag), "--remap", "/launch_outcomes"), "must look like")]
    for args, reason in cases:
        process = start_process("rollability_ros.cli", "play", *args, name="bad_play")
        process.process.wait(timeout=30)
        assert process.process.returncode == 2 and reason in process.log(), process.log()


def _corrupt_variants(bag):
    """Yield (name, damage) pairs: each damage function spoils a copy of ``bag`` in another way."""
    from mcap.reader import make_reader

    def storage(directory):
        (path,) = directory.glob("*.mcap")
        return path

    def chunk_offsets(path):
        with open(path, "rb") as stream:
            return [(c.chunk_start_offset, c.chunk_length) for c in make_reader(stream).get_summary().chunk_indexes]

    def flip_in_chunk(directory):
        path = storage(directory)
        start, length = chunk_offsets(path)[0]
        data = bytearray(path.read_bytes())
        for offset in range(start + length // 2, start + length // 2 + 16):
            data[offset] ^= 0xFF
        path.write_bytes(bytes(data))

    def cut(directory):
        path = storage(directory)
        path.write_bytes(path.read_bytes()[:len(path.read_bytes()) // 2])

    def garbage(directory):
        path = storage(directory)
        path.write_bytes(b"\x00" * path.stat().st_size)

    def missing_file(directory):
        storage(directory).unlink()

    def bad_metadata(directory):
        (directory / "metadata.yaml").write_text("rosbag2_bagfile_information: [")

    return [("flip_in_chunk", flip_in_chunk), ("cut", cut), ("garbage", garbage), ("missing_file", missing_file),
            ("bad_metadata", bad_metadata)]


def test_play_of_a_corrupt_bag_exits_non_zero_with_the_reason(tmp_path, campaign_bag, start_process):
    """Issue 17: five kinds of damaged bag each give a non-zero exit naming the problem (was: ERROR, exit 0)."""
    import shutil

    bag, _ = campaign_bag
    for name, damage in _corrupt_variants(bag):
        copy = tmp_path / f"corrupt_{name}"
        shutil.copytree(bag, copy)
        damage(copy)
        process = start_process("rollability_ros.cli", "play", str(copy), "--wait-for-subscribers", "0",
                                name=f"corrupt_play_{name}")
        process.process.wait(timeout=60)
        assert process.process.returncode != 0, (name, process.log())
        assert "error" in process.log().lower(), (name, process.log())


FROZEN_SUBSCRIBER = """
import os, signal, sys
import rclpy
from rollability_ros.msg import LaunchOutcome
from rollability_ros.nodes._support import RECORD_QOS
rclpy.init()
node = rclpy.create_node("frozen_subscriber")
def first(_msg):
    print("got one: freezing", flush=True)
    os.kill(os.getpid(), signal.SIGSTOP)   # every thread stops: the player's later messages are never acknowledged
node.create_subscription(LaunchOutcome, "/launch_outcomes", first, RECORD_QOS)
rclpy.spin(node)
"""


def test_player_stops_at_once_while_a_subscriber_never_acknowledges(campaign_bag, start_process, tmp_path):
    """Issue 30: a reliable subscriber that froze after the first message never acknowledges the rest. The player
    waits for acknowledgements up to ACK_TIMEOUT_S, but a stop signal must end it at once: rclpy's
    wait_for_all_acked holds the GIL while it waits, and a player that called it with the whole timeout froze
    every Python thread, the signal check too (the installed player once ignored SIGINT for 60 s)."""
    import signal
    import sys
    import time

    from ros_fixtures import NodeProcess
    from rollability_ros.nodes.player import ACK_TIMEOUT_S

    bag, _ = campaign_bag
    subscriber = NodeProcess([sys.executable, "-c", FROZEN_SUBSCRIBER], tmp_path / "frozen.log")
    try:
        player = start_process("rollability_ros.cli", "play", str(bag), "--topics", "/launch_outcomes",
                               "--rate", "10")
        deadline = time.monotonic() + 60
        while "freezing" not in subscriber.log():
            assert time.monotonic() < deadline and player.alive(), player.log() + subscriber.log()
            time.sleep(0.05)
        time.sleep(1.5)   # the rest of the bag (29 x 5 ms) is out: the player waits for acknowledgements now
        assert player.alive(), player.log()
        player.signal(signal.SIGINT)
        sent = time.monotonic()
        try:
            code = player.process.wait(timeout=ACK_TIMEOUT_S + 10)
        except Exception:
            code = None
        took_s = time.monotonic() - sent
        assert took_s < 3.0, f"the player took {took_s:.1f} s to exit after SIGINT (code {code})\n{player.log()}"
        assert code == 0, player.log()
    finally:
        subscriber.signal(signal.SIGKILL)
        subscriber.stop()
