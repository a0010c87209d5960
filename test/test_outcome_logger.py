"""outcome_logger over real DDS, in its own process: stores, deduplicates, skips bad messages, survives kill -9."""
import dataclasses
import math
import os
import re
import signal
import sqlite3
import threading
import time

from rollability_ros.core.records import CandidateRecord, GenerationRecord, LaunchCondition, LaunchOutcome
from rollability_ros.core.store import Store
from ros_fixtures import transitions_qos
from test_recorder import stopped_cleanly

STORED = re.compile(r"stored launch outcome (\S+)/(\S+)")


def outcome(trial_id, configuration="A", upright=True, run_id="run1", **fields):
    condition = LaunchCondition(configuration, 0.75, 0.8, -30.0, 1)
    return LaunchOutcome(run_id=run_id, trial_id=trial_id, condition=condition, backend="sim", upright=upright,
                         travel_time_s=0.41, measured_speed_mps=0.83, stamp_s=1700000000.5, note="from the test",
                         **fields)


class LoggerPeer:
    """The test's side of the logger: publishers of every record topic, the latched summary, the service."""

    def __init__(self, spun):
        from rollability_ros.msg import CandidateResult, GenerationSummary, LaunchOutcome, OutcomeSummary
        from rollability_ros.nodes._support import RECORD_QOS
        from rollability_ros.srv import GetSummary

        self.spun = spun
        node = spun.node
        self.outcomes = node.create_publisher(LaunchOutcome, "/launch_outcomes", RECORD_QOS)
        self.candidates = node.create_publisher(CandidateResult, "/candidates", RECORD_QOS)
        self.generations = node.create_publisher(GenerationSummary, "/generations", RECORD_QOS)
        self.summaries = []
        self.summary_sent_ns = []     # source timestamp of each summary (wall clock of its publisher, ns)
        # deeper than the publisher's 1 (still compatible): a burst of summaries is not squeezed into one slot
        node.create_subscription(OutcomeSummary, "/summary", self._on_summary, transitions_qos())
        self.client = node.create_client(GetSummary, "/get_summary")
        self.request_type = GetSummary.Request
        from rollability_ros.msg import OutcomeStored
        from rollability_ros.srv import GetStoredTrials

        self.acknowledgements = []
        node.create_subscription(OutcomeStored, "/outcomes_stored", self.acknowledgements.append, RECORD_QOS)
        self.stored_client = node.create_client(GetStoredTrials, "/stored_trials")
        self.stored_request = GetStoredTrials.Request

    def _on_summary(self, msg, info):
        self.summaries.append(msg)
        self.summary_sent_ns.append(info["source_timestamp"])

    def summaries_sent_after(self, ns):
        """The summaries published after wall-clock time ``ns`` (a late delivery from a killed logger is not)."""
        return [msg for msg, sent in zip(self.summaries, self.summary_sent_ns) if sent > ns]

    def wait_connected(self, logger):
        publishers = (self.outcomes, self.candidates, self.generations)
        assert self.spun.wait_for(lambda: all(p.get_subscription_count() > 0 for p in publishers), 30), logger.log()
        assert self.spun.wait_for(lambda: self.summaries, 30), logger.log()

    def wait_trials(self, trials, logger, timeout_s=30):
        """Wait until the logger acknowledged ``trials`` outcomes (its summary topic or its log says so)."""
        def acknowledged():
            from_topic = max((s.trials for s in self.summaries), default=0)
            return max(from_topic, len(STORED.findall(logger.log()))) >= trials

        assert self.spun.wait_for(acknowledged, timeout_s, period_s=0.02), (self.summaries[-1:], logger.log())

    def stored_trials(self, run_id):
        assert self.stored_client.wait_for_service(timeout_sec=30)
        return self.stored_client.call(self.stored_request(run_id=run_id), timeout_sec=30)

    def get_summary(self, run_id=""):
        assert self.client.wait_for_service(timeout_sec=30)
        return self.client.call(self.request_type(run_id=run_id), timeout_sec=30).summary


def test_stores_outcomes_once_skips_malformed_and_answers_summary(tmp_path, ros_node, start_node):
    from rollability_ros.nodes import _convert

    store_path = tmp_path / "outcomes.sqlite"
    logger = start_node("outcome_logger", params={"store_path": str(store_path)})
    peer = LoggerPeer(ros_node)
    peer.wait_connected(logger)
    assert peer.summaries[-1].trials == 0

    good = [outcome("t1", "A", True), outcome("t2", "B", False), outcome("t3", "A", False)]
    nan_height = _convert.outcome_to_msg(outcome("bad-height"))
    nan_height.condition.height_m = math.nan
    empty_run = _convert.outcome_to_msg(outcome("bad-run", run_id=""))
    catapult = _convert.outcome_to_msg(outcome("bad-backend"))
    catapult.backend = "catapult"
    duplicate = _convert.outcome_to_msg(dataclasses.replace(good[0], upright=False, note="resent"))
    too_many = _convert.candidate_to_msg(CandidateRecord("opt1", 0, 0, (0.1, 0.2), 1.0, 5, 2, 7, 0.5))
    candidate = CandidateRecord("opt1", 0, 1, (0.1, 0.2), 0.5, 1, 2, 7, 0.5)
    generation = GenerationRecord("opt1", 0, 0.5, 0.5, 0.5, 0.1, (0.1, 0.2), 2, 1.0)

    for msg in (nan_height, _convert.outcome_to_msg(good[0]), empty_run, catapult, duplicate,
                _convert.outcome_to_msg(good[1]), _convert.outcome_to_msg(good[2])):
        peer.outcomes.publish(msg)
    peer.candidates.publish(too_many)
    peer.candidates.publish(_convert.candidate_to_msg(candidate))
    peer.generations.publish(_convert.generation_to_msg(generation))

    peer.wait_trials(3, logger)
    assert ros_node.wait_for(lambda: peer.summaries[-1].trials == 3 and peer.summaries[-1].candidates == 1, 30), \
        logger.log()
    assert ros_node.wait_for(lambda: "stored generation summary opt1/0" in logger.log(), 10), logger.log()
    log = logger.log()
    assert "skipped malformed launch outcome: height_m must be a finite number" in log
    assert "skipped malformed launch outcome: run_id and trial_id must be non-empty" in log
    assert "skipped malformed launch outcome: backend must be one of" in log
    assert "skipped malformed candidate: successes 5 > trials 2" in log
    assert "duplicate launch outcome run1/t1: already stored, ignored" in log
    assert logger.alive() and "Traceback" not in log

    latest = peer.summaries[-1]
    assert [(c.configuration, c.trials, c.successes) for c in latest.configurations] == [("A", 2, 1), ("B", 1, 0)]
    assert latest.configurations[0].success_rate == 0.5
    assert 0.0 < latest.configurations[0].ci_low < 0.5 < latest.configurations[0].ci_high < 1.0
    assert latest.header.stamp.sec == 1700000000

    answered = peer.get_summary()
    assert (answered.trials, answered.candidates) == (3, 1)
    assert [c.configuration for c in answered.configurations] == ["A", "B"]
    assert (peer.get_summary("opt1").trials, peer.get_summary("opt1").candidates) == (0, 1)
    nothing = peer.get_summary("no-such-run")
    assert (nothing.trials, nothing.candidates, list(nothing.configurations)) == (0, 0, [])

    # acknowledgements over ROS: one per stored outcome, the duplicate acknowledged as such, malformed ones not
    assert ros_node.wait_for(lambda: len(peer.acknowledgements) == 4, 10), peer.acknowledgements
    assert [(a.run_id, a.trial_id, a.duplicate) for a in peer.acknowledgements] == [
        ("run1", "t1", False), ("run1", "t1", True), ("run1", "t2", False), ("run1", "t3", False)]
    stored = peer.stored_trials("run1")
    assert stored.success and list(stored.trial_ids) == ["t1", "t2", "t3"]
    assert peer.stored_trials("no-such-run").trial_ids == [] and not peer.stored_trials("").success

    assert stopped_cleanly(logger, logger.stop())
    with Store(store_path) as store:
        assert store.launch_outcomes() == good           # every field round-trips; the resent t1 did not win
        assert store.candidates() == [candidate] and store.generations() == [generation]


def test_invalid_store_path_exits_with_a_reason(tmp_path, start_node):
    junk = tmp_path / "junk.sqlite"
    junk.write_bytes(b"not a database, just some bytes in a file " * 8)
    logger = start_node("outcome_logger", params={"store_path": str(junk)})
    logger.process.wait(timeout=30)
    assert logger.process.returncode == 2
    assert "store_path" in logger.log() and "not a usable rollability store" in logger.log()


def test_acknowledged_outcomes_survive_sigkill(tmp_path, ros_node, start_node):
    from rollability_ros.nodes import _convert

    store_path = tmp_path / "outcomes.sqlite"
    # unbuffered log: every "stored" line written before the kill is in the log file
    env = {**os.environ, "RCUTILS_LOGGING_BUFFERED_STREAM": "0"}
    logger = start_node("outcome_logger", params={"store_path": str(store_path)}, env=env)
    peer = LoggerPeer(ros_node)
    peer.wait_connected(logger)

    stream = [outcome(f"t{i:04d}", "AB"[i % 2], i % 3 != 0) for i in range(600)]
    stop = threading.Event()
    published = []

    def publish_stream():
        for record in stream:
            if stop.is_set():
                return
            peer.outcomes.publish(_convert.outcome_to_msg(record))
            published.append(record.trial_id)
            stop.wait(0.001)

    publisher = threading.Thread(target=publish_stream, daemon=True)
    publisher.start()
    peer.wait_trials(60, logger)
    logger.signal(signal.SIGKILL)                 # mid-stream: the publisher is still sending
    logger.process.wait(timeout=10)
    acknowledged_by_summary = max(s.trials for s in peer.summaries)
    acknowledged_by_log = {trial for run, trial in STORED.findall(logger.log())}
    stop.set()
    publisher.join(timeout=10)
    assert logger.process.returncode == -signal.SIGKILL
    assert 60 <= len(acknowledged_by_log) < len(stream), "the kill must land mid-stream"
    assert len(acknowledged_by_log) >= acknowledged_by_summary   # a summary follows its log line

    # the store opens cleanly and holds every acknowledged outcome, exactly as sent
    with sqlite3.connect(store_path) as raw:
        assert raw.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    with Store(store_path) as store:
        stored = {o.trial_id: o for o in store.launch_outcomes("run1")}
    assert acknowledged_by_log <= set(stored)
    # one publisher, reliable, one writer: the summary count is the first N outcomes of the stream
    assert {r.trial_id for r in stream[:acknowledged_by_summary]} <= set(stored)
    assert all(stored[r.trial_id] == r for r in stream if r.trial_id in stored)

    # restarted on the same store: it starts from what was stored, then catches up by itself from the
    # publisher's transient-local history (RECORD_QOS) without a resend; a full resend then adds nothing
    restarted_ns = time.time_ns()
    restarted = start_node("outcome_logger", params={"store_path": str(store_path)}, name="outcome_logger_again")
    peer.wait_connected(restarted)
    assert ros_node.wait_for(lambda: peer.summaries_sent_after(restarted_ns), 30), restarted.log()
    assert peer.summaries_sent_after(restarted_ns)[0].trials >= len(stored)
    peer.wait_trials(len(published), restarted)
    assert peer.get_summary("run1").trials == len(published)
    for record in stream:
        peer.outcomes.publish(_convert.outcome_to_msg(record))
    peer.wait_trials(len(stream), restarted)
    assert peer.get_summary("run1").trials == len(stream)
    assert stopped_cleanly(restarted, restarted.stop())
    with Store(store_path) as store:
        final = store.launch_outcomes("run1")
    assert len(final) == len(stream) and sorted(final, key=lambda o: o.trial_id) == stream
