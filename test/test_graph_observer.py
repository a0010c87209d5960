"""The orchestrators learn the graph's progress over ROS, never from a node's store: a study's campaign count and a
bringup's stored launches come from a real outcome_logger whose store is in a directory the orchestrator never
opens (any SQLite open in this process fails), through RosGraphObserver over real DDS.

The optimizer's side (``optimizer_progress`` from a real run) is checked in test_optimizer_node.py."""
import sqlite3

import pytest

from test_outcome_logger import LoggerPeer, outcome


@pytest.fixture
def no_store_here(monkeypatch):
    """Every SQLite open in the test process (the orchestrator's) fails loudly."""
    def refuse(*_args, **_kwargs):
        raise AssertionError("the orchestrator opened a store")

    monkeypatch.setattr(sqlite3, "connect", refuse)
    from rollability_ros.core import store

    monkeypatch.setattr(store.Store, "__init__", refuse)


def test_study_and_bringup_progress_come_from_the_logger_over_ros(tmp_path, ros_node, start_node, no_store_here):
    from rollability_ros.core.graph.progress import ProgressDisplay, session_progress
    from rollability_ros.core.graph.study import Study, study_config
    from rollability_ros.nodes import _convert
    from rollability_ros.nodes._graph_observer import RosGraphObserver

    logger_dir = tmp_path / "logger-computer"
    logger_dir.mkdir()
    logger = start_node("outcome_logger", params={"store_path": "outcomes.sqlite"}, cwd=str(logger_dir))
    peer = LoggerPeer(ros_node)
    peer.wait_connected(logger)
    study = Study(study_config(study_id="obs"), display=ProgressDisplay(live=False))
    study.study_dir = str(tmp_path / "orchestrator")       # no store there: the logger writes elsewhere

    with RosGraphObserver("/", node_name="test_observer") as observer:
        study.observer = observer
        assert study._progress_campaign(6)[0].trials_stored == 0      # no answer yet: "starting"
        for index in range(3):
            peer.outcomes.publish(_convert.outcome_to_msg(outcome(f"t{index}", run_id="obs")))
        peer.outcomes.publish(_convert.outcome_to_msg(outcome("t0", run_id="another-run")))
        peer.wait_trials(4, logger)

        def campaign_count():
            return study._progress_campaign(6)[0].trials_stored

        assert ros_node.wait_for(lambda: campaign_count() == 3, 30), (campaign_count(), logger.log())
        shown = study._progress_campaign(6)[0]
        assert shown.text().startswith("launch campaign (simulated rig) | 3/6 trials stored")
        assert ros_node.wait_for(lambda: observer.stored_launches() == 4, 30), observer.stored_launches()
        session = session_progress(observer, 5, 12.0)
        assert session.trials_stored == 4 and session.generation is None   # no optimizer in this graph
        assert "4 trials stored" in session.text()
    assert (logger_dir / "outcomes.sqlite").is_file() and not (tmp_path / "orchestrator").exists()


def test_the_campaign_count_goes_on_through_a_kill_9_of_the_logger(tmp_path, ros_node, start_node, no_store_here):
    """Issue 42: a request the killed logger never answers must not freeze the count (it did, at "44/400", while
    the campaign finished): it times out and is asked again of the restarted logger."""
    import signal

    from rollability_ros.nodes import _convert
    from rollability_ros.nodes._graph_observer import RosGraphObserver

    logger_dir = tmp_path / "logger-computer"
    logger_dir.mkdir()
    logger = start_node("outcome_logger", params={"store_path": "outcomes.sqlite"}, cwd=str(logger_dir))
    peer = LoggerPeer(ros_node)
    peer.wait_connected(logger)
    with RosGraphObserver("/", node_name="test_observer", request_timeout_s=1.0) as observer:
        for index in range(3):
            peer.outcomes.publish(_convert.outcome_to_msg(outcome(f"t{index}", run_id="soak")))
        peer.wait_trials(3, logger)
        assert ros_node.wait_for(lambda: observer.stored_trials("soak") == 3, 30), logger.log()
        assert ros_node.wait_for(lambda: observer._pending.done(), 10)
        logger.signal(signal.SIGKILL)
        logger.process.wait(timeout=10)
        observer.stored_trials("soak")   # a request to the dead logger: never answered
        assert observer._pending is not None and not observer._pending.done()
        logger = start_node("outcome_logger", params={"store_path": "outcomes.sqlite"}, cwd=str(logger_dir),
                            name="outcome_logger_restarted")
        peer.wait_connected(logger)
        for index in range(3, 5):
            peer.outcomes.publish(_convert.outcome_to_msg(outcome(f"t{index}", run_id="soak")))
        peer.wait_trials(5, logger)
        assert ros_node.wait_for(lambda: observer.stored_trials("soak") == 5, 60), (observer.stored_trials("soak"),
                                                                                   logger.log())
