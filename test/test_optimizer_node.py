"""optimizer node over real DDS with sim_evaluator nodes in separate processes: the stored run equals the
in-process run for the same config and seed, whether the candidates are spread over two evaluators, wait for a
late evaluator, survive a SIGKILLed evaluator, or are interrupted by SIGINT and resumed; pause / resume / stop.

Evaluations are deterministic in (heights, seed), so equal runs store equal candidate sequences.
"""
import signal
import sys

import pytest
from action_msgs.msg import GoalStatus, GoalStatusArray
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_action_status_default
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker

from conftest import REPO_ROOT
from rollability_ros.action import EvaluateProfile
from rollability_ros.msg import CandidateResult, GenerationSummary
from rollability_ros.nodes._support import RECORD_QOS
from ros_fixtures import NodeProcess

#: A tiny real run: 3 x 3 half grid, popsize 6, 6 trials, 4 generations, one random initial mean (the 16-mean
#: stable-pose screen, test/core/test_initial_mean_screen.py, took most of a minute per start at load average 16).
RUN = {"profile.rows": 3, "profile.cols": 3, "optimizer.popsize": 6, "optimizer.trials": 6,
       "optimizer.max_generations": 4, "optimizer.stagnation_generations": 0, "optimizer.seed": 1,
       "optimizer.initial_mean_screen": 0}
#: The evaluators below run the objective's defaults (the paper's disturbance trial on sim.engine): so does the
#: in-process reference (the quick default's launch objective runs through the graph in test_study.py).
PAPER_OBJECTIVE = {"objective.kind": "disturbance", "objective.robust.enabled": False, "objective.screen_engine": ""}
GRID = {"profile.rows": 3, "profile.cols": 3}
OPTIMIZER_CONFIG = str(REPO_ROOT / "config" / "optimizer.yaml")
ALL_GENERATIONS_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                                 durability=DurabilityPolicy.TRANSIENT_LOCAL)


def evaluator_params():
    """An evaluator's parameters for these runs: the 3 x 3 grid and the print config/optimizer.yaml states (the
    robot's ``profile_print``: bringup gives every node the same files; the in-process reference weighs the profiles
    by that print, so an evaluator on robot.yaml's 20 % print would launch heavier profiles)."""
    from rollability_ros.core.optimization import run_directory

    printed = {key: value for key, value in run_directory.load_run_parameters("optimizer").items()
               if key.startswith("robot.profile_print.")}
    assert printed, "config/optimizer.yaml states the quick study's print"
    return {**GRID, **printed}


def stored_generations(store_dir, run_id):
    """How many generations the run's store holds: what the optimizer completed (its summaries on ``/generations``
    may still be on their way to a listener)."""
    from rollability_ros.core.store import Store

    with Store(store_dir) as store:
        return len(store.generations(run_id=run_id))


def candidate_rows(store_dir, run_id):
    from rollability_ros.core.store import Store

    with Store(store_dir) as store:
        return [(c.generation, c.index, c.heights, c.successes, c.trials, c.seed)
                for c in sorted(store.candidates(run_id=run_id), key=lambda c: (c.generation, c.index))]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The same run in this process (no ROS graph): stored candidates and generation summaries."""
    from rollability_ros.core.sim import evaluation
    from rollability_ros.core.optimization import optimization_run as optimization_run
    from rollability_ros.core.optimization import batch_evaluation, run_directory
    from rollability_ros.core.store import Store

    parameters = run_directory.load_run_parameters("optimizer")
    parameters.update({**RUN, **PAPER_OBJECTIVE})
    settings = evaluation.settings_from_parameters(parameters)
    executor = evaluation.make_executor(settings.evaluator, 2)
    run_dir = tmp_path_factory.mktemp("reference") / "ref"
    try:
        evaluate_batch = batch_evaluation.profile_batch_evaluator(settings, RUN["optimizer.trials"], executor)
        run = optimization_run.OptimizationRun(run_dir, optimization_run.run_config(parameters), settings.grid, evaluate_batch)
        run.run()
        run.close()
    finally:
        executor.close()
    with Store(run_dir) as store:
        generations = store.generations(run_id="ref")
    candidates = candidate_rows(run_dir, "ref")
    assert len({row[3] for row in candidates}) >= 3, "the reference run must not be all failures (a weak test)"
    return {"candidates": candidates, "generations": generations}


@pytest.fixture(scope="module")
def evaluators(tmp_path_factory):
    """Two sim_evaluator processes, /eval_a and /eval_b, one worker each, on the 3 x 3 grid, printing the profile as
    config/optimizer.yaml says (the robot's ``profile_print``: what bringup gives every node, and what the in-process
    reference weighs the profiles by)."""
    logs = tmp_path_factory.mktemp("evaluators")
    processes = {}
    for namespace in ("eval_a", "eval_b"):
        args = ["--ros-args", "-r", f"__ns:=/{namespace}", "-p", "evaluator.workers:=1"]
        for key, value in evaluator_params().items():
            args += ["-p", f"{key}:={value}"]
        processes[namespace] = NodeProcess([sys.executable, "-m", "rollability_ros.nodes.sim_evaluator", *args],
                                           logs / f"{namespace}.log")
    yield processes
    for process in processes.values():
        process.stop()


def start_optimizer(start_node, tmp_path, run_id, name="optimizer", **params):
    """Start the node on config/optimizer.yaml with :data:`RUN` and ``params`` on top (-p after the file wins)."""
    values = {**RUN, "optimizer.output_dir": str(tmp_path / "runs"), "run_id": run_id,
              "evaluator_discovery_period_s": 0.5, "evaluator_timeout_s": 10.0, **params}
    args = ["--params-file", OPTIMIZER_CONFIG]
    for key, value in values.items():
        args += ["-p", f"{key}:={str(value).lower() if isinstance(value, bool) else value}"]
    return start_node("optimizer", ros_args=args, name=name)


class Listener:
    """The optimizer's topics, collected in the test node."""

    def __init__(self, ros_node):
        self.candidates, self.generations, self.markers = [], [], []
        node = ros_node.node
        node.create_subscription(CandidateResult, "/candidates", self.candidates.append, RECORD_QOS)
        node.create_subscription(GenerationSummary, "/generations", self.generations.append, ALL_GENERATIONS_QOS)
        node.create_subscription(Marker, "/best_profile_marker", self.markers.append, ALL_GENERATIONS_QOS)


def start_listened(ros_node, start_node, tmp_path, run_id, **params):
    """Start the optimizer with ``autostart`` off, subscribe to its topics, and start the run by service."""
    listener = Listener(ros_node)
    optimizer = start_optimizer(start_node, tmp_path, run_id, autostart=False, **params)
    node = ros_node.node
    assert ros_node.wait_for(lambda: all(node.count_publishers(topic) for topic in
                                         ("/candidates", "/generations", "/best_profile_marker")), 60), optimizer.log()
    response = call(ros_node, "/start")
    assert response.success and run_id in response.message, response.message
    return listener, optimizer


def wait_for_log(ros_node, process, text, timeout_s=120):
    assert ros_node.wait_for(lambda: text in process.log() or not process.alive(), timeout_s), process.log()
    assert text in process.log(), process.log()


def call(ros_node, name):
    client = ros_node.node.create_client(Trigger, name)
    assert client.wait_for_service(timeout_sec=30), name
    future = client.call_async(Trigger.Request())
    assert ros_node.wait_for(future.done, 30)
    return future.result()


# The slow tier (about 25 s: a late evaluator, the race and a 2 x 2 world check over ROS); the README's command keeps
# two evaluators equal to the in-process run and pause/resume/stop through the same node.
@pytest.mark.slow
def test_with_no_evaluator_it_says_so_and_waits_then_proceeds(ros_node, start_node, tmp_path, reference):
    optimizer = start_optimizer(start_node, tmp_path, "late", exit_on_finish=True, select_designs=True,
                                **{"selection.reevaluate_trials": 2, "selection.min_distance": 0.01,
                                   "selection.race_launches": "[2]", "selection.race_elites": 3,
                                   "selection.launch_trials": 2, "selection.world_count": 2,
                                   "selection.world_launches": 2})
    wait_for_log(ros_node, optimizer, "no evaluator available", 60)
    assert "generation 1:" not in optimizer.log() and optimizer.alive()
    start_node("sim_evaluator", params={"evaluator.workers": 2, **evaluator_params()}, ros_args=["-r", "__ns:=/eval_late"],
               name="eval_late")
    wait_for_log(ros_node, optimizer, "ended after 4 generation(s)")
    assert optimizer.process.wait(timeout=60) == 0, optimizer.log()   # exit_on_finish, after the selection
    assert candidate_rows(tmp_path / "runs" / "late", "late") == reference["candidates"]
    designs = tmp_path / "runs" / "late" / "designs"
    assert (designs / "table3.csv").read_text().startswith("configuration,") and (designs / "mesh_A.stl").is_file()
    assert "selected" in optimizer.log()
    # the race and the gain ran as launch-fidelity goals on the graph's evaluator
    assert "minus the bare robot on fresh robust launches on the twin" in optimizer.log(), optimizer.log()
    # and the world check as world:<seed> goals: its rows and the recommendation it gives
    assert (designs / "selection_world_check.csv").is_file()
    assert "recommendation (simulated world check): " in optimizer.log(), optimizer.log()


@pytest.mark.slow   # about 30 s; test_sim_evaluator checks the rejection itself in the README's command
def test_an_evaluator_that_prints_otherwise_gets_no_candidate(ros_node, start_node, tmp_path):
    """The optimizer's goals carry its print (config/optimizer.yaml's gradual print): an evaluator started on
    robot.yaml's 20 % print alone rejects them naming the difference, and no candidate is scored."""
    wrong = start_node("sim_evaluator", params={"evaluator.workers": 1, **GRID}, ros_args=["-r", "__ns:=/eval_20"],
                       name="eval_20")
    optimizer = start_optimizer(start_node, tmp_path, "print", evaluator_max_attempts=2,
                                evaluator_retry_delay_s=0.1)
    wait_for_log(ros_node, wrong, "rejected evaluate_profile goal: the optimizer prints the profile otherwise")
    refusal = wrong.log().split("rejected evaluate_profile goal: ")[1].splitlines()[0]
    assert "gradual_infill_steps 5 (optimizer) vs 0 (this evaluator)" in refusal, refusal
    wait_for_log(ros_node, optimizer, "goal rejected (that evaluator's log says why")
    assert candidate_rows(tmp_path / "runs" / "print", "print") == []


def test_two_evaluators_share_the_run_and_it_equals_the_in_process_run(ros_node, start_node, evaluators, tmp_path,
                                                                         reference):
    from rollability_ros.nodes._graph_observer import RosGraphObserver

    with RosGraphObserver("/", node_name="progress_observer") as observer:   # what study / bringup see
        listener, optimizer = start_listened(ros_node, start_node, tmp_path, "two")
        wait_for_log(ros_node, optimizer, "ended after 4 generation(s)")
        assert ros_node.wait_for(lambda: [p.generation for p in observer.optimizer_progress()] == [0, 1, 2, 3, 4],
                                 10), observer.optimizer_progress()
        progress = observer.optimizer_progress()
    assert candidate_rows(tmp_path / "runs" / "two", "two") == reference["candidates"]
    assert {(p.run_id, p.max_generations) for p in progress} == {("two", 4)}
    assert progress[-1].trials == sum(row[4] for row in reference["candidates"])       # the store's, over ROS
    assert [p.best_so_far for p in progress[1:]] == [g.best_so_far for g in reference["generations"]]

    stored = len(reference["candidates"])
    assert ros_node.wait_for(lambda: len(listener.candidates) == stored and len(listener.generations) == 4, 10)
    # the incumbent's re-evaluation, a lone request, was split over both evaluators (trials 0..2 on eval_a, 3..5
    # on eval_b) and merged: the stored candidates above equal the in-process run's all the same
    split = "/eval_a/sim_evaluator+/eval_b/sim_evaluator"
    assert {c.evaluator for c in listener.candidates} == {"/eval_a/sim_evaluator", "/eval_b/sim_evaluator", split}
    assert {c.evaluator for c in listener.candidates if c.index == RUN["optimizer.popsize"]} == {split}
    assert [(c.generation, c.index, c.successes) for c in listener.candidates] == \
        [(row[0], row[1], row[3]) for row in reference["candidates"]]
    published = [(g.generation, g.best_fitness, g.best_so_far, g.sigma) for g in listener.generations]
    assert published == [(g.generation, g.best_fitness, g.best_so_far, g.sigma) for g in reference["generations"]]
    # best_so_far is the pooled estimate of the incumbent (it drops when a lucky estimate is corrected), so the
    # evidence is improvement, not monotonicity: this seed's run ends better than its first generation
    assert published[-1][2] > published[0][2]

    marker = listener.markers[-1]
    assert marker.type == Marker.TRIANGLE_LIST and marker.header.frame_id == "base_link"
    assert marker.action == Marker.ADD and len(marker.points) >= 12 and len(marker.points) % 3 == 0
    assert max(p.z for p in marker.points) > 0 and marker.pose.position.z > 0


@pytest.mark.slow   # about 20 s, most of it the killed reader's DDS lease; the test above checks two evaluators
#                     equal the in-process run in the README's command
def test_a_killed_evaluator_is_replaced_and_the_results_do_not_change(ros_node, start_node, evaluators, tmp_path,
                                                                     reference):
    victim = start_node("sim_evaluator", params={"evaluator.workers": 1, **evaluator_params()}, ros_args=["-r", "__ns:=/eval_k"],
                        name="eval_k")
    started = {"gen": False}
    killed = []

    def on_feedback(_message):
        if started["gen"] and not killed:   # eval_k is mid-goal in generation >= 1
            victim.signal(signal.SIGKILL)
            killed.append(True)

    ros_node.node.create_subscription(EvaluateProfile.Impl.FeedbackMessage, "/eval_k/evaluate_profile/_action/feedback",
                                      on_feedback, 10)
    ros_node.node.create_subscription(GenerationSummary, "/generations",
                                      lambda _msg: started.update(gen=True), ALL_GENERATIONS_QOS)
    optimizer = start_optimizer(start_node, tmp_path, "kill", evaluator_timeout_s=2.0)
    wait_for_log(ros_node, optimizer, "ended after 4 generation(s)")
    assert killed, "eval_k never got a goal after the first generation"
    assert "on /eval_k/evaluate_profile failed" in optimizer.log()
    assert candidate_rows(tmp_path / "runs" / "kill", "kill") == reference["candidates"]


class GoalWatch:
    """The goals the evaluators' action servers report (``/<ns>/evaluate_profile/_action/status``): the goal ids
    seen on each, and whether any goal is still pending or running."""

    ACTIVE = (GoalStatus.STATUS_ACCEPTED, GoalStatus.STATUS_EXECUTING, GoalStatus.STATUS_CANCELING)

    def __init__(self, ros_node, namespaces):
        self.latest = {namespace: [] for namespace in namespaces}
        self.seen = {namespace: set() for namespace in namespaces}
        for namespace in namespaces:
            ros_node.node.create_subscription(GoalStatusArray, f"/{namespace}/evaluate_profile/_action/status",
                                              lambda msg, ns=namespace: self._on_status(ns, msg),
                                              qos_profile_action_status_default)

    def _on_status(self, namespace, msg):
        self.latest[namespace] = msg.status_list
        self.seen[namespace].update(bytes(status.goal_info.goal_id.uuid) for status in msg.status_list)

    def idle(self):
        return not any(status.status in self.ACTIVE for statuses in self.latest.values() for status in statuses)

    def new_since(self, snapshot):
        """Per evaluator, how many goals it got after ``snapshot`` (a copy of :attr:`seen`)."""
        return {namespace: len(ids - snapshot[namespace]) for namespace, ids in self.seen.items()}


def test_pause_resume_and_stop(ros_node, start_node, evaluators, tmp_path):
    goals = GoalWatch(ros_node, evaluators)
    listener, optimizer = start_listened(ros_node, start_node, tmp_path, "pause", **{"optimizer.max_generations": 200})
    assert ros_node.wait_for(lambda: listener.generations, 60), optimizer.log()
    assert call(ros_node, "/pause").success
    at_pause = {ns: set(ids) for ns, ids in goals.seen.items()}
    # counted in the store, not from the summaries received: one published just before the pause may arrive after it
    run_dir = tmp_path / "runs" / "pause"
    paused_at = stored_generations(run_dir, "pause")
    # the goals in flight finish (at most their generation completes), events rather than a fixed wait; a goal sent
    # just before the pause may reach its evaluator after it (the pool sends one goal per evaluator at a time), so
    # each evaluator may start at most one goal after the pause, and none once they are all idle
    assert ros_node.wait_for(goals.idle, 60), optimizer.log()
    ros_node.wait_for(lambda: max(goals.new_since(at_pause).values()) > 1, 1.5)
    assert ros_node.wait_for(goals.idle, 60), optimizer.log()
    assert max(goals.new_since(at_pause).values()) <= 1, f"a paused run went on evaluating: {goals.new_since(at_pause)}"
    settled = stored_generations(run_dir, "pause")
    assert settled <= paused_at + 1, f"{settled - paused_at} generations completed after the pause"
    assert call(ros_node, "/resume").success
    assert ros_node.wait_for(lambda: stored_generations(run_dir, "pause") >= settled + 2, 60)
    stop = call(ros_node, "/stop")
    assert stop.success and "current generation" in stop.message
    wait_for_log(ros_node, optimizer, "(stop service)")
    from rollability_ros.core.optimization import checkpoint

    saved = checkpoint.load_checkpoint(tmp_path / "runs" / "pause" / checkpoint.CHECKPOINT_FILENAME)
    assert saved["generation"] < 200
    assert ros_node.wait_for(lambda: listener.generations[-1].generation == saved["generation"], 10)
    assert optimizer.alive() and not call(ros_node, "/pause").success   # no run in progress any more


@pytest.mark.slow   # the node's checkpoint and resume; the core's are tested in test/core/test_resume.py
def test_sigint_keeps_a_valid_checkpoint_and_resume_continues(ros_node, start_node, evaluators, tmp_path,
                                                              reference):
    from rollability_ros.core.optimization import checkpoint

    listener = Listener(ros_node)
    first = start_optimizer(start_node, tmp_path, "sig", name="first")
    assert ros_node.wait_for(lambda: listener.generations, 60), first.log()
    first.signal(signal.SIGINT)
    assert first.process.wait(timeout=30) == 0, first.log()
    assert "interrupted; its checkpoint holds" in first.log() and "Error" not in first.log(), first.log()
    saved = checkpoint.load_checkpoint(tmp_path / "runs" / "sig" / checkpoint.CHECKPOINT_FILENAME)
    assert 1 <= saved["generation"] < 4, first.log()

    second = start_optimizer(start_node, tmp_path, "sig", name="second", resume=True)
    wait_for_log(ros_node, second, "ended after 4 generation(s)")
    assert f"resuming after generation {saved['generation']}" in second.log()
    assert candidate_rows(tmp_path / "runs" / "sig", "sig") == reference["candidates"]


def test_invalid_parameters_are_refused(start_node, tmp_path):
    optimizer = start_optimizer(start_node, tmp_path, "bad", **{"optimizer.popsize": 1})
    assert optimizer.process.wait(timeout=60) == 2
    assert "popsize" in optimizer.log()
