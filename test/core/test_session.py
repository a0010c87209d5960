"""Sessions isolated by default and joined by name (core/graph/session.py), without ROS: the domain a session claims,
its session.yaml, and what a joining verb resolves from what the session printed."""
import dataclasses
import os
import subprocess

import pytest
import yaml

from rollability_ros.core.graph.session import SESSION_DOMAINS, SESSION_FILE, load_session, start_session
from rollability_ros.core.rig import RIG_DOMAIN_ID


def test_two_sessions_from_one_shell_get_different_domains_never_the_shells_nor_the_rigs(tmp_path):
    shell = {"ROS_DOMAIN_ID": "42", "ROS_LOCALHOST_ONLY": "1", "ROS_STATIC_PEERS": "10.0.0.9"}
    first_env, second_env = dict(shell), dict(shell)
    first, first_lock = start_session("study", str(tmp_path / "runs" / "a"), "/rollability", first_env)
    second, second_lock = start_session("study", str(tmp_path / "runs" / "b"), "/rollability", second_env)
    try:
        assert first.ros_domain_id != second.ros_domain_id
        for info, environ in ((first, first_env), (second, second_env)):
            assert SESSION_DOMAINS[0] <= info.ros_domain_id <= SESSION_DOMAINS[1]
            assert info.ros_domain_id not in (42, RIG_DOMAIN_ID)
            assert environ["ROS_DOMAIN_ID"] == str(info.ros_domain_id)
            assert environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" == info.discovery_range
            assert "ROS_STATIC_PEERS" not in environ and "ROS_LOCALHOST_ONLY" not in environ
        assert first.valve_key_file != second.valve_key_file
        assert first.store_path == os.path.join(str(tmp_path / "runs" / "a"), "outcomes.sqlite")
    finally:
        first_lock.close()
        second_lock.close()


def test_a_claim_skips_the_domains_it_must_not_take():
    from rollability_ros.core.graph import claim_domain

    first, first_lock = claim_domain(224, 226, start=224, skip={225})
    second, second_lock = claim_domain(224, 226, start=224, skip={225})
    try:
        assert (first, second) == (224, 226)
        with pytest.raises(RuntimeError, match="no free ROS_DOMAIN_ID"):
            claim_domain(224, 226, skip={225})
    finally:
        first_lock.close()
        second_lock.close()


def test_the_physical_rig_stays_on_its_domain(tmp_path):
    environ = {"ROS_DOMAIN_ID": str(RIG_DOMAIN_ID), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    info, lock = start_session("bringup", str(tmp_path / "lab"), "/rollability", environ, own_domain=False,
                               rig_backend="physical")
    try:
        assert info.ros_domain_id == RIG_DOMAIN_ID and environ["ROS_DOMAIN_ID"] == str(RIG_DOMAIN_ID)
        assert load_session(str(tmp_path / "lab")).rig_backend == "physical"
    finally:
        if lock is not None:
            lock.close()


def test_a_session_is_joined_by_directory_file_or_printed_name_and_sets_the_environment(tmp_path):
    directory = tmp_path / "runs" / "lab"
    info, lock = start_session("bringup", str(directory), "/rollability", {})
    lock.close()
    document = yaml.safe_load((directory / SESSION_FILE).read_text())["session"]
    assert {"name", "ros_domain_id", "discovery_range", "namespace", "valve_key_file", "store_path"} <= set(document)
    for argument in (str(directory), str(directory / SESSION_FILE)):
        assert load_session(argument) == info
    assert load_session("lab", str(tmp_path / "runs")) == info
    assert info.running()                       # this process wrote it
    assert not dataclasses.replace(info, pid=_ended_pid()).running()   # its process has ended
    environ = {"ROS_DOMAIN_ID": "0", "ROS_STATIC_PEERS": "10.0.0.9"}
    info.apply(environ)
    assert environ == {"ROS_DOMAIN_ID": str(info.ros_domain_id), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    join, raw = info.join_lines()
    assert f"rollability rig --session {directory}" in join and "campaign --graph --session" in join
    assert f"ROS_DOMAIN_ID={info.ros_domain_id} ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST" in raw
    assert "namespace /rollability" in raw


def _ended_pid():
    process = subprocess.Popen(["true"])
    process.wait()
    return process.pid


def test_errors_name_what_was_looked_for_and_where(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match=f"no {SESSION_FILE} in {tmp_path / 'empty'}"):
        load_session(str(tmp_path / "empty"))
    with pytest.raises(ValueError, match=r"no session 'lab'.*" + str(tmp_path / "runs" / "lab" / SESSION_FILE)):
        load_session("lab", str(tmp_path / "runs"))
    broken = tmp_path / "broken.yaml"
    broken.write_text("session: {name: x, ros_domain_id: 999}\n")
    with pytest.raises(ValueError, match=f"{broken} is not a session file"):
        load_session(str(broken))


def test_a_node_of_a_session_takes_only_its_own_sessions_and_a_node_outside_takes_all(tmp_path):
    from rollability_ros.core.config import SessionSettings
    from rollability_ros.core.records import CandidateRecord, LaunchCondition, LaunchOutcome
    from rollability_ros.core.results import SessionGate
    from rollability_ros.core.store import Store

    member, outsider = SessionSettings(id="lab.1"), SessionSettings()
    assert member.refusal("lab.1", "result") == "" and outsider.refusal("other.2", "result") == ""
    assert member.refusal("other.2", "result") == "result of session other.2 refused: this node belongs to session " \
                                                  "lab.1"
    assert "of session (none) refused" in member.refusal("", "launch goal")

    def launch(run_id):
        return LaunchOutcome(run_id=run_id, trial_id="t0", condition=LaunchCondition("A", 0.75, 0.8, 0.0, 0),
                             backend="sim", upright=True)

    def candidate(run_id, session):
        return CandidateRecord(run_id=run_id, generation=1, index=0, heights=(0.0,), fitness=1.0, successes=1,
                               trials=1, seed=1, eval_time_s=0.1, session=session)

    with Store(tmp_path / "store.sqlite") as store:
        study = SessionGate("study-1.ab", ["study-1"], store)
        assert study.refusal(launch("study-1")) == "" and study.refusal(candidate("optimization", "study-1.ab")) == ""
        assert study.refusal(launch("study-2"))
        # candidates are the optimizer's session's, whatever their run id (two studies' runs share "optimization")
        assert "run optimization of session study-2.ef is not of session study-1.ab" == study.refusal(
            candidate("optimization", "study-2.ef"))
        assert "of session (none)" in study.refusal(candidate("optimization", ""))
        bringup = SessionGate("lab.cd", [], store)
        assert bringup.refusal(launch("campaign-1")) and bringup.refusal(candidate("opt-1", "lab.cd")) == ""
        assert bringup.refusal(candidate("opt-1", "study-1.ab")) and SessionGate("", [], store).refusal(
            candidate("opt-1", "study-1.ab")) == ""
        assert "session other.ef refused" in bringup.announce("other.ef", "campaign-1")
        assert bringup.announce("lab.cd", "campaign-1") == "" and bringup.refusal(launch("campaign-1")) == ""
        assert SessionGate("lab.cd", [], store).refusal(launch("campaign-1")) == ""   # a restarted logger knows it
        assert SessionGate("", [], store).refusal(launch("anything")) == ""
        assert bringup.first_refusal("x") and not bringup.first_refusal("x")
