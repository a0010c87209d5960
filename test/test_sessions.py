"""Issue 42: every session isolated by default, nodes that talk only to their own session, and joining a session
by the name it printed (docs/sessions.md)."""
import importlib.util
import os
import re
import signal
import subprocess
import sys
import time

import pytest
import yaml

from conftest import REPO_ROOT
from test_outcome_logger import LoggerPeer, outcome

MINI = str(REPO_ROOT / "test" / "resources" / "mini_study.yaml")

#: Every process a test here started; none outlives its test.
_STARTED = []


@pytest.fixture(autouse=True)
def _nothing_outlives_its_test():
    yield
    while _STARTED:
        process = _STARTED.pop()
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout=30)


def _cli(tmp_path, name, *args, **kwargs):
    """``rollability <args>`` in ``tmp_path``, its output in ``<name>.log``; the Popen."""
    stream = open(tmp_path / f"{name}.log", "w")
    process = subprocess.Popen([sys.executable, "-m", "rollability_ros.cli", *args], cwd=tmp_path, stdout=stream,
                               stderr=subprocess.STDOUT, text=True, start_new_session=True, **kwargs)
    _STARTED.append(process)
    return process


def _log(tmp_path, name):
    return (tmp_path / f"{name}.log").read_text()


def _wait_for_line(tmp_path, name, pattern, process, timeout_s=120):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        match = re.search(pattern, _log(tmp_path, name))
        if match:
            return match
        assert process.poll() is None, _log(tmp_path, name)
        time.sleep(0.2)
    raise AssertionError(f"no {pattern!r} in:\n{_log(tmp_path, name)}")


def _study_records(study_dir):
    """(launch outcome run ids and count, candidates as comparable tuples) of a study's store and bag."""
    from rollability_ros.core.bags import read_records_from_bag
    from rollability_ros.core.store import Store

    with Store(study_dir / "outcomes.sqlite") as store:
        outcomes = store.launch_outcomes()
        candidates = store.candidates()
    bagged = read_records_from_bag(study_dir / "bag")[0]
    return ({o.run_id for o in outcomes}, len(outcomes), {o.run_id for o in bagged}, len(bagged),
            sorted((c.run_id, c.generation, c.index, tuple(c.heights), c.fitness) for c in candidates))


@pytest.mark.slow   # three miniature studies (one alone, two at once beside a physical bringup): minutes on 2 cores
def test_two_studies_5_s_apart_beside_a_physical_rig_each_equal_the_study_alone(tmp_path):
    """Issue 42's 'done when': same shell environment, same seed, started 5 s apart, both exit 0, each store and
    bag holds only its own run, and each one's candidates and campaign counts equal the same study run alone; a
    physical bringup on the shell's domain beside them is untouched."""
    alone = _cli(tmp_path, "alone", "study", "--config", MINI, "--study-id", "alone")
    assert alone.wait(timeout=900) == 0, _log(tmp_path, "alone")
    rig = _cli(tmp_path, "rig", "bringup", "--backend", "physical", "--no-optimizer", "--session-id", "rig")
    _wait_for_line(tmp_path, "rig", r"\[rig\] started", rig)
    first = _cli(tmp_path, "first", "study", "--config", MINI, "--study-id", "first")
    time.sleep(5)
    second = _cli(tmp_path, "second", "study", "--config", MINI, "--study-id", "second")
    assert first.wait(timeout=900) == 0, _log(tmp_path, "first")
    assert second.wait(timeout=900) == 0, _log(tmp_path, "second")
    os.killpg(rig.pid, signal.SIGINT)
    assert rig.wait(timeout=120) == 0, _log(tmp_path, "rig")

    runs = tmp_path / "runs"
    sessions = {name: yaml.safe_load((runs / name / "session.yaml").read_text())["session"]
                for name in ("alone", "first", "second", "rig")}
    domains = [sessions[name]["ros_domain_id"] for name in ("first", "second", "rig")]
    assert len(set(domains)) == 3 and domains[2] == int(os.environ["ROS_DOMAIN_ID"]), sessions
    assert len({sessions[name]["valve_key_file"] for name in sessions}) == 4
    for name in ("first", "second"):
        assert f"join: rollability rig --session {os.path.join('runs', name)}" in _log(tmp_path, name)
    reference = _study_records(runs / "alone")
    for name in ("first", "second"):
        stored_runs, stored, bagged_runs, bagged, candidates = _study_records(runs / name)
        assert stored_runs == bagged_runs == {name} and stored == bagged == reference[1], name
        assert len(candidates) == len(reference[4])
        assert [c[1:] for c in candidates] == [c[1:] for c in reference[4]], name   # same optimization, alone
    from rollability_ros.core.store import Store

    with Store(runs / "rig" / "outcomes.sqlite") as store:
        assert store.launch_outcomes() == [] and store.candidates() == []


def test_a_logger_of_a_session_stores_only_its_sessions_runs(tmp_path, ros_node, start_node):
    """A stored_trials request of another session is refused; a record of a run the session never announced is
    refused and logged once, never stored nor acknowledged; once the session's runner announces its run, its
    outcomes are stored, also by a restarted logger. Candidates and generations of another session (or none) are
    refused, logged once, even under the session's own run id; its own are stored."""
    from rollability_ros.core.records import CandidateRecord, GenerationRecord
    from rollability_ros.nodes import _convert

    params = {"store_path": "outcomes.sqlite", "session.id": "lab.1234"}
    logger = start_node("outcome_logger", params=params, cwd=str(tmp_path))
    peer = LoggerPeer(ros_node)
    peer.wait_connected(logger)
    for index in range(3):
        peer.outcomes.publish(_convert.outcome_to_msg(outcome(f"stray{index}", run_id="other-study")))
    stored_client, request = peer.stored_client, peer.stored_request
    assert stored_client.wait_for_service(timeout_sec=30)
    refused = stored_client.call(request(run_id="mine", session="other.9999"), timeout_sec=30)
    assert not refused.success and "session other.9999 refused" in refused.message, refused
    accepted = stored_client.call(request(run_id="mine", session="lab.1234"), timeout_sec=30)
    assert accepted.success and list(accepted.trial_ids) == []
    peer.outcomes.publish(_convert.outcome_to_msg(outcome("t0", run_id="mine")))
    peer.wait_trials(1, logger)
    # two sessions' optimizations, both run "optimization" (as two joined studies): the other's first, same keys
    for session in ("other.9999", "other.9999", "", "lab.1234"):
        peer.candidates.publish(_convert.candidate_to_msg(CandidateRecord(
            "optimization", 0, 0, (0.1, 0.2), 0.5, 1, 2, 7, 0.5, session=session)))
        peer.generations.publish(_convert.generation_to_msg(GenerationRecord(
            "optimization", 0, 0.5, 0.5, 0.5, 0.1, (0.1, 0.2), 1, 1.0, session=session)))
    assert ros_node.wait_for(lambda: "stored generation summary optimization/0" in logger.log()
                             and "stored candidate optimization/0/0" in logger.log(), 30), logger.log()
    log = logger.log()
    assert log.count("refused launch outcome other-study/") == 1, log       # logged once
    refusals = log.count("refused candidate optimization/0/0") + log.count("refused generation summary optimization/0")
    assert refusals == 1 and "optimization of session " in log, log                 # logged once
    assert "duplicate" not in log, log
    assert "stored launch outcome mine/t0" in log
    assert not any(ack.run_id == "other-study" for ack in peer.acknowledgements)
    logger.stop()
    logger = start_node("outcome_logger", params=params, cwd=str(tmp_path), name="outcome_logger_again")
    assert ros_node.wait_for(lambda: peer.outcomes.get_subscription_count() > 0, 30)
    peer.outcomes.publish(_convert.outcome_to_msg(outcome("t1", run_id="mine")))
    assert ros_node.wait_for(lambda: "stored launch outcome mine/t1" in logger.log(), 30), logger.log()
    from rollability_ros.core.store import Store

    with Store(tmp_path / "outcomes.sqlite") as store:
        assert {o.run_id for o in store.launch_outcomes()} == {"mine"} and len(store.launch_outcomes()) == 2
        assert [(c.session, c.index) for c in store.candidates()] == [("lab.1234", 0)]
        assert [g.session for g in store.generations()] == ["lab.1234"]


def test_ctrl_c_while_campaign_graph_waits_for_a_logger_is_a_clean_stop(tmp_path):
    """Issue 42: Ctrl-C during the 30 s wait printed an ExternalShutdownException traceback and exited 1."""
    (tmp_path / "campaign.yaml").write_text("/**:\n  ros__parameters:\n    campaign:\n      run_id: nowhere\n")
    process = _cli(tmp_path, "campaign", "campaign", "--backend", "sim", "--graph", "--namespace", "/nobody_here",
                   "--config", str(tmp_path / "campaign.yaml"), stdin=subprocess.DEVNULL)
    _wait_for_line(tmp_path, "campaign", r"campaign: through the graph on ROS domain \d+, namespace /nobody_here",
                   process, timeout_s=60)
    time.sleep(1.0)
    os.killpg(process.pid, signal.SIGINT)
    assert process.wait(timeout=30) == 130, _log(tmp_path, "campaign")
    output = _log(tmp_path, "campaign")
    assert "Traceback" not in output and "continue with --resume" in output, output


def test_joining_verbs_name_what_they_looked_for_and_where(tmp_path, monkeypatch, capsys):
    from rollability_ros.cli import main

    (tmp_path / "runs" / "empty").mkdir(parents=True)
    monkeypatch.chdir(tmp_path)
    environment = dict(os.environ)
    for args, expected in (
            (["rig", "--session", "lab", "estop"], "no session 'lab': neither a directory nor a file of that name, "
                                                   "and no runs/lab/session.yaml"),
            (["campaign", "--backend", "sim", "--graph", "--session", "runs/empty"], "no session.yaml in runs/empty"),
            (["campaign", "--backend", "sim", "--session", "lab"], "--session and --namespace are for --graph")):
        assert main(args) == 2, args
        error = capsys.readouterr().err
        assert expected in error and len(error.strip().splitlines()) == 1, (args, error)
    assert dict(os.environ) == environment      # nothing joined


@pytest.mark.slow   # a bringup session, a campaign, the live view and the operator's CLI through it: about 25 s
def test_campaign_graph_reaches_a_bringup_session_by_the_name_it_printed(tmp_path):
    """Issue 42 item 4 / issue 45 item 2: `campaign --graph` ran in the root namespace and never found bringup's
    logger; now it joins by the printed name (domain, namespace, session id) and the session's store holds it."""
    (tmp_path / "small.yaml").write_text("/**:\n  ros__parameters:\n    bringup:\n      evaluators: 0\n"
                                         "      poll_period_s: 0.2\n")
    (tmp_path / "campaign.yaml").write_text(
        "/**:\n  ros__parameters:\n    campaign:\n      run_id: joined\n      configurations: [baseline]\n"
        "      heights_m: [0.75]\n      speeds_mps: [0.8]\n      angles_deg: [0.0, 30.0]\n      repetitions: 1\n")
    bringup = _cli(tmp_path, "bringup", "bringup", "--config", str(tmp_path / "small.yaml"), "--no-optimizer",
                   "--session-id", "lab")
    _wait_for_line(tmp_path, "bringup", r"join: rollability rig --session runs/lab", bringup)
    _wait_for_line(tmp_path, "bringup", r"\[rig\] started", bringup)
    campaign = _cli(tmp_path, "campaign", "campaign", "--backend", "sim", "--graph", "--session", "lab", "--config",
                    str(tmp_path / "campaign.yaml"), stdin=subprocess.DEVNULL)
    assert campaign.wait(timeout=300) == 0, _log(tmp_path, "campaign") + _log(tmp_path, "bringup")
    assert "campaign complete: 2/2" in _log(tmp_path, "campaign")
    # the live view and the operator's CLI reach it with what it printed; without it, this shell's domain is not it
    stray = subprocess.run([sys.executable, "-m", "rollability_ros.cli", "rig", "estop", "--timeout-s", "3"],
                           cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert stray.returncode == 2 and "no valve controller subscribes" in stray.stderr, stray.stderr
    joined = subprocess.run([sys.executable, "-m", "rollability_ros.cli", "rig", "--session", "lab", "estop"],
                            cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert joined.returncode == 0 and "e-stop sent" in joined.stdout, joined.stdout + joined.stderr
    if importlib.util.find_spec("foxglove") is not None:
        view = _cli(tmp_path, "view", "view", "--session", "runs/lab", "--port", "0", stdin=subprocess.DEVNULL)
        _wait_for_line(tmp_path, "view", r"serving /rollability/summary", view, timeout_s=60)
        os.killpg(view.pid, signal.SIGINT)
        view.wait(timeout=30)
    os.killpg(bringup.pid, signal.SIGINT)
    assert bringup.wait(timeout=120) == 0, _log(tmp_path, "bringup")
    from rollability_ros.core.store import Store

    with Store(tmp_path / "runs" / "lab" / "outcomes.sqlite") as store:
        assert {o.run_id for o in store.launch_outcomes()} == {"joined"} and len(store.launch_outcomes()) == 2


def test_an_evaluator_and_a_rig_of_a_session_serve_only_that_session(ros_node, start_node):
    """An evaluator rejects another session's goal (logged once) and names its session in its result; a rig aborts
    another session's launch goal before it can hold the rig busy."""
    from action_msgs.msg import GoalStatus

    from rig_client import RigClient
    from rollability_ros.action import EvaluateProfile
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.nodes._support import ThreadSafeActionClient, send_goal_resending

    evaluator = start_node("sim_evaluator", params={"evaluator.workers": 1, "session.id": "lab.1"})
    rig = start_node("rig", params={"rig.backend": "sim", "session.id": "lab.1"})
    client = ThreadSafeActionClient(ros_node.node, EvaluateProfile, "/evaluate_profile")
    assert client.wait_for_server(timeout_sec=120), evaluator.log()

    def send(session):
        goal = EvaluateProfile.Goal(heights=[], trials=2, seed=1, session=session)
        handle = send_goal_resending(client, goal, ros_node.wait_for, 120)
        assert handle is not None, evaluator.log()
        return handle

    for session in ("other.2", "", "other.2"):
        assert not send(session).accepted
    log = evaluator.log()
    assert log.count("evaluate_profile goal of session other.2 refused") == 1, log    # logged once
    assert "evaluate_profile goal of session (none) refused: this node belongs to session lab.1" in log, log
    accepted = send("lab.1")
    assert accepted.accepted
    future = accepted.get_result_async()
    assert ros_node.wait_for(future.done, 120)
    assert future.result().status == GoalStatus.STATUS_SUCCEEDED and future.result().result.session == "lab.1"

    launcher = RigClient(ros_node, signed=False)
    refused = launcher.result(launcher.send("t0", LaunchCondition("baseline", 0.75, 0.8, 0.0, 0), []))
    assert refused.status == GoalStatus.STATUS_ABORTED, rig.log()
    assert "launch goal of session (none) refused: this node belongs to session lab.1" in refused.result.message
    assert launcher.outcomes == []


@pytest.mark.slow   # a physical bringup (dry-run valve) and a 4-launch campaign through it: about 15 s (suite budget)
def test_a_physical_campaign_joins_a_physical_bringup_by_name_and_signs_with_its_key(tmp_path):
    """Issue 45 item 1: campaign and bringup reach each other as shipped; the campaign signs with the session's own
    key file (from session.yaml), the session's logger verifies and stores every outcome."""
    from test_campaign_runner import CAMPAIGN_YAML, SPEC, operator_script

    from rollability_ros.core.campaign.plan import plan_trials
    from rollability_ros.core.store import Store

    (tmp_path / "small.yaml").write_text("/**:\n  ros__parameters:\n    bringup:\n      evaluators: 0\n"
                                         "      poll_period_s: 0.2\n    rig:\n      countdown_s: 0.6\n")
    (tmp_path / "campaign.yaml").write_text(CAMPAIGN_YAML)
    bringup = _cli(tmp_path, "bringup", "bringup", "--backend", "physical", "--config", str(tmp_path / "small.yaml"),
                   "--no-optimizer", "--session-id", "rig")
    _wait_for_line(tmp_path, "bringup", r"\[rig\] started", bringup)
    session = yaml.safe_load((tmp_path / "runs" / "rig" / "session.yaml").read_text())["session"]
    deadline = time.monotonic() + 60
    while not os.path.exists(session["valve_key_file"]) and time.monotonic() < deadline:
        time.sleep(0.2)
    done = subprocess.run([sys.executable, "-m", "rollability_ros.cli", "campaign", "--backend", "physical", "--graph",
                           "--session", "rig", "--config", str(tmp_path / "campaign.yaml")], cwd=tmp_path,
                          input=operator_script(plan_trials(SPEC)), capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr + _log(tmp_path, "bringup")
    assert "campaign complete: 4/4" in done.stdout
    os.killpg(bringup.pid, signal.SIGINT)
    assert bringup.wait(timeout=120) == 0, _log(tmp_path, "bringup")
    with Store(tmp_path / "runs" / "rig" / "outcomes.sqlite") as store:
        outcomes = store.launch_outcomes(SPEC.run_id)
    assert [o.trial_id for o in outcomes] == [t.trial_id for t in plan_trials(SPEC)]
    assert {o.backend for o in outcomes} == {"physical"}
