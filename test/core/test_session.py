"""Sessions isolated by default and joined by name (core/graph/session.py), without ROS: the domain a session claims,
its session.yaml, and what a joining verb resolves from what the session printed."""
import os

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
    environ = {"ROS_DOMAIN_ID": "0", "ROS_STATIC_PEERS": "10.0.0.9"}
    info.apply(environ)
    assert environ == {"ROS_DOMAIN_ID": str(info.ros_domain_id), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    join, raw = info.join_lines()
    assert f"rollability rig --session {directory}" in join and "campaign --graph --session" in join
    assert f"ROS_DOMAIN_ID={info.ros_domain_id} ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST" in raw
    assert "namespace /rollability" in raw


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
