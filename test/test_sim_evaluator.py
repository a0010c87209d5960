"""sim_evaluator over real DDS: results equal the in-process core, bad goals rejected, cancel honoured,
two evaluators side by side in their own namespaces."""
import math

import pytest
from action_msgs.msg import GoalStatus

from rollability_ros.action import EvaluateProfile
from rollability_ros.nodes._support import ThreadSafeActionClient, send_goal_resending


def _wait(ros_node, future, timeout_s=180):
    assert ros_node.wait_for(future.done, timeout_s), "timed out waiting for the action server"
    return future.result()


def _client(ros_node, name):
    client = ThreadSafeActionClient(ros_node.node, EvaluateProfile, name)   # sent here, spun in another thread
    assert client.wait_for_server(timeout_sec=120), f"no action server {name}"
    return client


def _send(ros_node, client, heights, trials, seed, feedback=None, fidelity="", printed_with="", first_trial=0):
    goal = EvaluateProfile.Goal(heights=list(heights), trials=trials, seed=seed, fidelity=fidelity,
                                printed_with=printed_with, first_trial=first_trial)
    handle = send_goal_resending(client, goal, ros_node.wait_for, 180, feedback_callback=feedback)
    assert handle is not None, "the evaluator did not answer the goal"
    return handle


@pytest.fixture(scope="module")
def evaluator(tmp_path_factory):
    """One sim_evaluator (2 workers) for the goals of this module: each test's goals run on the node the earlier
    ones left (a rejected goal, a cancel must leave it serving), and 8 node starts shrink to one."""
    import sys

    from ros_fixtures import NodeProcess

    process = NodeProcess([sys.executable, "-m", "rollability_ros.nodes.sim_evaluator", "--ros-args",
                           "-p", "evaluator.workers:=2"], tmp_path_factory.mktemp("evaluator") / "sim_evaluator.log")
    yield process
    assert process.stop() == 0, process.log()


def _ridge(n_rows=10, n_cols=10, height=0.4):
    heights = [0.0] * (n_rows * n_cols)
    for row in range(n_rows):
        heights[row * n_cols] = height       # the column on the centre line, all along the length
    return heights


def test_results_equal_the_core_and_carry_feedback(ros_node, evaluator):
    from rollability_ros.core.sim.evaluation import evaluate_profile, load_settings

    client = _client(ros_node, "/evaluate_profile")
    feedback = []
    handle = _send(ros_node, client, _ridge(), 10, 1234, lambda fb: feedback.append(fb.feedback.trials_done))
    assert handle.accepted
    response = _wait(ros_node, handle.get_result_async())
    assert response.status == GoalStatus.STATUS_SUCCEEDED, response.result.message
    result = response.result
    expected = evaluate_profile(_ridge(), 10, 1234, load_settings())
    assert (result.successes, result.trials) == (expected.successes, expected.trials)
    assert [t.upright for t in result.trial_results] == [t.upright for t in expected.trial_results]
    assert [t.steps for t in result.trial_results] == [t.steps for t in expected.trial_results]
    assert math.isclose(result.fitness, expected.fitness) and result.ci_low <= result.fitness <= result.ci_high
    assert result.evaluator == "/sim_evaluator"
    # rclpy's ActionClient drops feedback that arrives after the result, so the last values may be missing
    assert feedback and feedback == sorted(set(feedback)) and feedback[-1] <= 10, feedback

    baseline = _wait(ros_node, _send(ros_node, client, [], 4, 1).get_result_async())
    assert baseline.status == GoalStatus.STATUS_SUCCEEDED and baseline.result.trials == 4


def test_a_launch_fidelity_goal_runs_robust_twin_launches_and_an_unknown_one_is_rejected(ros_node, evaluator):
    from rollability_ros.core.sim.evaluation import evaluate_profile, load_settings, settings_at_fidelity

    client = _client(ros_node, "/evaluate_profile")
    response = _wait(ros_node, _send(ros_node, client, [], 2, 77, fidelity="launch").get_result_async())
    assert response.status == GoalStatus.STATUS_SUCCEEDED, response.result.message
    expected = evaluate_profile(None, 2, 77, settings_at_fidelity(load_settings(), "launch"))
    assert [t.steps for t in response.result.trial_results] == [t.steps for t in expected.trial_results]
    assert not _send(ros_node, client, [], 2, 1, fidelity="campaign").accepted
    assert ros_node.wait_for(lambda: "unknown evaluation fidelity 'campaign'" in evaluator.log(), 10), evaluator.log()


def test_the_node_reads_a_changed_objective_file_and_refuses_one_it_cannot_read(ros_node, evaluator, tmp_path):
    """The node reads the files its objective names (the edge): a new objective.campaign_config is read when it is
    set, and its launches are those of that file; a file that cannot be read refuses the change, naming it."""
    import dataclasses

    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    from rollability_ros.core.sim.evaluation import evaluate_profile, load_settings, settings_at_fidelity, with_objective

    campaign = tmp_path / "one_condition.yaml"
    campaign.write_text("/**:\n  ros__parameters:\n    campaign:\n      heights_m: [1.30]\n      speeds_mps: [1.5]\n"
                        "      angles_deg: [45.0]\n")
    service = ros_node.node.create_client(SetParameters, "/sim_evaluator/set_parameters")
    assert service.wait_for_service(timeout_sec=30)

    def set_campaign(files):
        request = SetParameters.Request(parameters=[
            Parameter("objective.campaign_config", value=files).to_parameter_msg()])
        return service.call(request, timeout_sec=30).results[0]

    missing = str(tmp_path / "missing.yaml")
    refused = set_campaign([missing])
    assert not refused.successful and missing in refused.reason, refused.reason
    try:
        assert set_campaign([str(campaign)]).successful
        client = _client(ros_node, "/evaluate_profile")
        response = _wait(ros_node, _send(ros_node, client, [], 2, 77, fidelity="launch").get_result_async())
        assert response.status == GoalStatus.STATUS_SUCCEEDED, response.result.message
        settings = load_settings()
        settings = with_objective(settings, dataclasses.replace(settings.objective, campaign_config=[str(campaign)]))
        expected = evaluate_profile(None, 2, 77, settings_at_fidelity(settings, "launch"))
        assert [t.steps for t in response.result.trial_results] == [t.steps for t in expected.trial_results]
    finally:
        assert set_campaign(["campaign"]).successful   # the module's other goals run on the shipped campaign


@pytest.mark.parametrize("heights, trials, why", [
    ([0.1] * 99, 4, "wrong length"),
    ([float("nan")] + [0.1] * 99, 4, "NaN"),
    ([0.9] * 100, 4, "out of bounds"),
    ([-0.1] * 100, 4, "negative"),
    ([0.1] * 100, 0, "no trials"),
    ([0.1] * 100, 10_000_000, "absurdly many trials"),
])
def test_bad_goals_are_rejected_and_the_node_survives(ros_node, evaluator, heights, trials, why):
    client = _client(ros_node, "/evaluate_profile")
    rejected = evaluator.log().count("rejected evaluate_profile goal")
    handle = _send(ros_node, client, heights, trials, 1)
    assert not handle.accepted, why
    assert ros_node.wait_for(lambda: evaluator.log().count("rejected evaluate_profile goal") > rejected, 10), \
        evaluator.log()
    good = _send(ros_node, client, [], 2, 1)
    assert good.accepted and evaluator.alive()
    assert _wait(ros_node, good.get_result_async()).status == GoalStatus.STATUS_SUCCEEDED


def test_a_trial_range_past_max_trials_is_rejected_naming_it(ros_node, evaluator):
    """first_trial + trials may not pass evaluator.max_trials (10000): a part runs no trial its whole evaluation
    could not; the goal is rejected with the reason in one line and the node goes on serving."""
    client = _client(ros_node, "/evaluate_profile")
    rejected = evaluator.log().count("rejected evaluate_profile goal")
    assert not _send(ros_node, client, [], 3, 1, first_trial=9998).accepted
    assert ros_node.wait_for(lambda: evaluator.log().count("rejected evaluate_profile goal") > rejected, 10)
    line = evaluator.log().split("rejected evaluate_profile goal: ")[-1].splitlines()[0]
    assert line == ("first_trial + trials must be at most max_trials 10000 (trials 9998..10000), got first_trial "
                    "9998, trials 3"), line
    handle = _send(ros_node, client, [], 2, 1, first_trial=9998)   # the last two trials: accepted
    assert handle.accepted
    response = _wait(ros_node, handle.get_result_async())
    assert [t.index for t in response.result.trial_results] == [9998, 9999]


def test_a_goal_of_another_print_is_rejected_naming_the_difference(ros_node, evaluator):
    """An optimizer that will tell the lab to print otherwise than this evaluator weighs the profile gets no
    fitness from it: the goal is rejected and the log names the setting; the same print, or none stated, runs."""
    import json

    from rollability_ros.core.sim.evaluation import load_settings

    mine = load_settings().print_instructions()   # the node runs on the shipped files, as load_settings reads
    client = _client(ros_node, "/evaluate_profile")
    for printed_with, named in ((json.dumps({**mine, "infill_fraction": 0.35}), "infill_fraction"),
                                ("{not json", "printed_with: print instructions are not JSON"),
                                ("[" * 100_000, "nested too deep")):   # was a RecursionError: the node died
        rejected = evaluator.log().count("rejected evaluate_profile goal")
        assert not _send(ros_node, client, _ridge(), 2, 1, printed_with=printed_with).accepted
        assert ros_node.wait_for(lambda: evaluator.log().count("rejected evaluate_profile goal") > rejected, 10)
        assert named in evaluator.log().split("rejected evaluate_profile goal")[-1].splitlines()[0]
    for printed_with in (json.dumps(mine), ""):
        handle = _send(ros_node, client, _ridge(), 2, 1, printed_with=printed_with)
        assert handle.accepted
        assert _wait(ros_node, handle.get_result_async()).status == GoalStatus.STATUS_SUCCEEDED


def test_cancel_is_honoured(ros_node, evaluator):
    client = _client(ros_node, "/evaluate_profile")
    feedback = []
    handle = _send(ros_node, client, _ridge(), 2000, 5, lambda fb: feedback.append(fb.feedback.trials_done))
    assert handle.accepted
    assert ros_node.wait_for(lambda: feedback, 60)
    _wait(ros_node, handle.cancel_goal_async())
    response = _wait(ros_node, handle.get_result_async())
    assert response.status == GoalStatus.STATUS_CANCELED
    assert 0 < response.result.trials < 2000 and "cancelled" in response.result.message


def _trials(result):
    return [(t.index, t.seed, t.upright, t.settled, t.steps, t.tilt_deg) for t in result.trial_results]


def test_two_evaluators_side_by_side_and_an_evaluation_split_over_them_equals_the_unsplit_one(ros_node, start_node):
    """Two evaluators give the same trials; an evaluation split as the optimizer's pool splits it (trials 0..1 on
    one evaluator, 2..4 on the other, first_trial, sent at once) joins into the unsplit evaluation: the same
    successes and trial results (index, seed, outcome, steps, tilt)."""
    for namespace in ("eval_a", "eval_b"):
        start_node("sim_evaluator", params={"evaluator.workers": 1}, ros_args=["-r", f"__ns:=/{namespace}"],
                   name=namespace)
    clients = {namespace: _client(ros_node, f"/{namespace}/evaluate_profile") for namespace in ("eval_a", "eval_b")}
    results = {}
    for namespace in ("eval_a", "eval_b"):
        response = _wait(ros_node, _send(ros_node, clients[namespace], [], 3, 9).get_result_async())
        results[namespace] = response.result
    assert results["eval_a"].evaluator == "/eval_a/sim_evaluator"
    assert results["eval_b"].evaluator == "/eval_b/sim_evaluator"
    assert [t.upright for t in results["eval_a"].trial_results] == [t.upright for t in results["eval_b"].trial_results]

    unsplit = _wait(ros_node, _send(ros_node, clients["eval_a"], _ridge(), 5, 31).get_result_async()).result
    handles = [_send(ros_node, clients["eval_a"], _ridge(), 2, 31, first_trial=0),
               _send(ros_node, clients["eval_b"], _ridge(), 3, 31, first_trial=2)]
    head, tail = (_wait(ros_node, handle.get_result_async()).result for handle in handles)
    assert (head.evaluator, tail.evaluator) == ("/eval_a/sim_evaluator", "/eval_b/sim_evaluator")
    assert (head.trials, tail.trials) == (2, 3)
    assert head.successes + tail.successes == unsplit.successes
    assert _trials(head) + _trials(tail) == _trials(unsplit) and [t[0] for t in _trials(tail)] == [2, 3, 4]


def test_invalid_parameters_are_refused(start_node):
    node = start_node("sim_evaluator", params={"sim.time_step_s": -1.0})
    assert node.process.wait(timeout=60) == 2
    assert "time_step_s" in node.log()


def test_more_workers_than_the_memory_holds_are_refused_at_start(start_node):
    """evaluator.workers 1024 is in its declared range but about 290 MB x 1024 of workers: refused in one line
    before any worker starts."""
    from rollability_ros.core.sim import WORKER_RSS_MB, available_memory_mb

    available_mb = available_memory_mb()
    if available_mb is None or available_mb >= 1024 * WORKER_RSS_MB:
        pytest.skip("this machine holds 1024 workers, or says nothing of its memory")
    node = start_node("sim_evaluator", params={"evaluator.workers": 1024})
    assert node.process.wait(timeout=60) == 2
    errors = [line for line in node.log().splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and errors[0].startswith("error: evaluator.workers: 1024 worker processes need about "
                                                     "296960 MB (290 MB each"), node.log()


def test_a_replacement_pool_the_memory_refuses_aborts_the_goal_and_the_node_keeps_serving(ros_node, monkeypatch,
                                                                                            tmp_path):
    """A broken worker pool (its worker killed) is replaced through spawn_pool, which refuses a count the available
    memory (a fake meminfo) does not hold. That refusal escaped the execute callback (the goal aborted with no
    reason) and left the closed pool for every later goal; now the goal is aborted naming the shortfall, the next one
    too while the memory is short, and once it is not the configured pool (1 worker, never fewer) starts again."""
    import functools
    import os
    import signal
    import threading

    import rclpy
    from rclpy.executors import MultiThreadedExecutor

    from rollability_ros.core.sim import evaluation, spawn_pool
    from rollability_ros.nodes.sim_evaluator import SimEvaluator

    meminfo = tmp_path / "meminfo"

    def available(mb):
        meminfo.write_text(f"MemTotal:       16384000 kB\nMemAvailable:   {mb * 1024} kB\n")

    available(8000)
    monkeypatch.setattr(evaluation, "spawn_pool", functools.partial(spawn_pool, meminfo_path=str(meminfo)))
    rclpy.init(args=["--ros-args", "-p", "evaluator.workers:=1", "-r", "__ns:=/memory_short"])
    node = SimEvaluator()
    executor = MultiThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        (worker,) = node._pool.warm()
        os.kill(worker, signal.SIGKILL)   # the pool is broken
        available(100)                    # and its replacement does not fit
        client = _client(ros_node, "/memory_short/evaluate_profile")
        shortfall = ("no worker pool: evaluator.workers: 1 worker processes need about 290 MB (290 MB each: a trial "
                     "worker's RSS plateau, bench/bench_worker_memory.py), more than the 100 MB available "
                     "(MemAvailable, /proc/meminfo): free memory first")
        broken = _wait(ros_node, _send(ros_node, client, [], 2, 1).get_result_async())
        assert broken.status == GoalStatus.STATUS_ABORTED
        assert broken.result.message.startswith("evaluation failed: ") and broken.result.message.endswith(
            "; " + shortfall) and "\n" not in broken.result.message, broken.result.message
        short = _wait(ros_node, _send(ros_node, client, [], 2, 1).get_result_async())
        assert short.status == GoalStatus.STATUS_ABORTED
        assert short.result.message == "evaluation not started: " + shortfall
        available(8000)
        served = _wait(ros_node, _send(ros_node, client, [], 2, 1).get_result_async())
        assert served.status == GoalStatus.STATUS_SUCCEEDED, served.result.message
        assert served.result.trials == 2 and node._pool.workers == 1
    finally:
        node.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
        spinner.join(timeout=5)
