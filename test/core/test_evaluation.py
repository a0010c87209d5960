"""Evaluation: seeds, reproducibility across executors, streaming, cancel, request checks, settings, URDF, Ray."""
import dataclasses
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import xml.etree.ElementTree as ElementTree

import numpy as np
import pytest

from conftest import pid_running
from rollability_ros.core.config import ConfigError
from rollability_ros.core.sim.evaluation import (EvaluationCancelled, EvaluatorSettings, LocalExecutor, RayExecutor,
                                             evaluate_mesh, evaluate_profile, load_settings, mesh_job, profile_job,
                                             run_batch, trial_seed)
from rollability_ros.core.profile.geometry import export_mesh, grid_xy, load_profile_mesh, profile_mesh
from rollability_ros.core.sim import load_launch_twin_settings
from rollability_ros.core.sim.trial_engine import run_trial

pybullet = pytest.importorskip("pybullet")

SETTINGS = EvaluatorSettings()


def ridge_heights(grid, height=0.4):
    """A roof: tall along the centre line, falling linearly to zero at the side edges."""
    return height * (1.0 - grid_xy(grid)[:, 1] / (grid.width_m / 2))


def test_trial_seeds_are_reproducible_distinct_and_in_range():
    seeds = [trial_seed(42, i) for i in range(200)]
    assert seeds == [trial_seed(42, i) for i in range(200)]
    assert len(set(seeds)) == 200 and all(0 <= s < 2**63 for s in seeds)
    assert trial_seed(43, 0) != trial_seed(42, 0)
    assert trial_seed(2**64 - 1, 5) >= 0
    for bad in (-1, 2**64, 1.5, True, "7"):
        with pytest.raises(ValueError, match="seed"):
            trial_seed(bad, 0)


def test_a_trial_depends_only_on_profile_seed_and_settings():
    """The reused, restored world gives exactly what a freshly built world gives, whatever ran before: another
    profile's batch, or a world built in the engine's client outside the evaluation (run_trial), which empties the
    client under the evaluation's kept world (that world builds itself again)."""
    settings = SETTINGS
    ridge = profile_job(ridge_heights(settings.grid), settings)
    bare = profile_job(None, settings)
    seeds = [(i, trial_seed(5, i)) for i in range(4)]
    fresh = [run_trial(settings.robot_model(), ridge.profile, i, s, settings.trial, settings.physics)
             for i, s in seeds]
    together = run_batch(ridge, seeds)
    run_trial(settings.robot_model(), None, *seeds[0], settings.trial, settings.physics)
    after_outside_build = run_batch(ridge, seeds)
    run_batch(bare, seeds[:2])  # another profile in between rebuilds this process's world
    alone_reversed = [run_batch(ridge, [pair])[0] for pair in reversed(seeds)][::-1]
    assert together == fresh and after_outside_build == fresh and alone_reversed == fresh


def test_a_generation_runs_each_candidate_whole_when_there_are_two_per_worker():
    """profile_batch_evaluator hands a candidate's trials to one worker as one task once a generation has at least
    two candidates per worker (one world build each); fewer candidates are split into batch_trials tasks. The
    outcomes are the serial ones either way."""
    from rollability_ros.core.optimization.batch_evaluation import profile_batch_evaluator
    from rollability_ros.core.sim.evaluation import SerialExecutor

    class TwoWorkers(SerialExecutor):
        """Counts the tasks of each evaluation; runs them in this process, one thread at a time (one client)."""
        workers = 2

        def __init__(self):
            self.tasks, self.lock = [], threading.Lock()

        def iter_batches(self, job, batches, should_stop):
            with self.lock:
                self.tasks.append(len(batches))
                return list(super().iter_batches(job, batches, should_stop))

    candidates = [ridge_heights(SETTINGS.grid, height) for height in (0.2, 0.3, 0.4, 0.45)]
    serial = [(r.successes, r.trials) for r in (evaluate_profile(h, 12, 5, SETTINGS) for h in candidates)]
    executor = TwoWorkers()
    evaluate = profile_batch_evaluator(SETTINGS, 12, executor)
    assert [r[:2] for r in evaluate(candidates, 5)] == serial
    assert executor.tasks == [1, 1, 1, 1]
    executor.tasks.clear()
    assert [r[:2] for r in evaluate(candidates[:3], 5)] == serial[:3]
    assert executor.tasks == [-(-12 // SETTINGS.evaluator.batch_trials)] * 3


def test_executors_agree_with_serial_and_stream_every_trial():
    heights = ridge_heights(SETTINGS.grid)
    serial = evaluate_profile(heights, 12, 11, SETTINGS)
    streamed = []
    with LocalExecutor(workers=2) as pool:
        pooled = evaluate_profile(heights, 12, 11, SETTINGS, executor=pool, on_trial=streamed.append)
    assert pooled.trial_results == serial.trial_results
    assert (pooled.fitness, pooled.successes, pooled.ci_low, pooled.ci_high) == \
        (serial.fitness, serial.successes, serial.ci_low, serial.ci_high)
    assert sorted(o.index for o in streamed) == list(range(12))
    assert [o.seed for o in serial.trial_results] == [trial_seed(11, i) for i in range(12)]


def test_cancel_stops_early_and_raises():
    cancel = threading.Event()
    seen = []

    def on_trial(outcome):
        seen.append(outcome)
        cancel.set()

    with pytest.raises(EvaluationCancelled) as raised:
        evaluate_profile(None, 50, 1, SETTINGS, on_trial=on_trial, cancel_event=cancel)
    assert 0 < len(raised.value.outcomes) < 50 and len(seen) == len(raised.value.outcomes)


@pytest.mark.parametrize("heights, trials, seed, message", [
    (np.full(100, 0.5), 10, 1, "outside"),
    (np.full(7, 0.1), 10, 1, "needs 100"),
    (None, 0, 1, "trials"),
    (None, 10001, 1, "trials"),
    (None, 10, -3, "seed"),
])
def test_bad_requests_are_refused(heights, trials, seed, message):
    with pytest.raises(ValueError, match=message):
        evaluate_profile(heights, trials, seed, SETTINGS)


@pytest.mark.parametrize("first_trial, trials, message", [
    (-1, 4, "first_trial must be an integer >= 0"),
    (9998, 3, "first_trial \\+ trials must be at most max_trials 10000"),
])
def test_a_trial_range_past_max_trials_is_refused(first_trial, trials, message):
    with pytest.raises(ValueError, match=message):
        evaluate_profile(None, trials, 1, SETTINGS, first_trial=first_trial)


@pytest.mark.parametrize("fidelity", ["screen", "mix", "launch", "world:3"])
def test_a_trial_range_run_alone_is_those_trials_of_the_whole_evaluation(fidelity):
    """What splitting an evaluation over evaluators rests on (core/optimization/evaluator_pool.py): trial i's
    kind, launch condition and draws depend on i and trial_seed(seed, i) only, at every fidelity; so the parts
    first_trial 0 and k of one evaluation, joined, are the whole evaluation's trials (seeds, outcomes, steps).
    "mix" alternates disturbance trials and launches by index (objective.launch_weight 0.5)."""
    from rollability_ros.core.sim.evaluation import settings_at_fidelity, with_objective

    settings = load_settings()
    if fidelity == "mix":
        settings = with_objective(settings, dataclasses.replace(settings.objective, kind="mix", launch_weight=0.5))
    settings = settings_at_fidelity(settings, "" if fidelity == "mix" else fidelity)
    heights = ridge_heights(settings.grid)
    trials, first = (4, 1) if fidelity != "screen" else (6, 2)
    whole = evaluate_profile(heights, trials, 21, settings)
    head = evaluate_profile(heights, first, 21, settings)
    tail = evaluate_profile(heights, trials - first, 21, settings, first_trial=first)
    assert [o.index for o in tail.trial_results] == list(range(first, trials))
    assert head.trial_results + tail.trial_results == whole.trial_results
    assert head.successes + tail.successes == whole.successes and tail.trials == trials - first


def test_baseline_forms_are_equivalent():
    assert profile_job(None, SETTINGS).profile is None
    assert profile_job([], SETTINGS).profile is None
    assert profile_job(np.zeros(100), SETTINGS).profile is None
    assert profile_job(np.full(100, 1e-4), SETTINGS).profile is None   # within flat_tolerance


def test_stl_profile_evaluates_like_its_heights(tmp_path):
    heights = ridge_heights(SETTINGS.grid)
    path = tmp_path / "ridge.stl"
    export_mesh(profile_mesh(heights, SETTINGS.grid), path)
    from_heights = evaluate_profile(heights, 6, 3, SETTINGS)
    from_file = evaluate_mesh(load_profile_mesh(str(path)), 6, 3, SETTINGS)
    assert [o.upright for o in from_file.trial_results] == [o.upright for o in from_heights.trial_results]
    np.testing.assert_allclose([o.tilt_deg for o in from_file.trial_results],
                               [o.tilt_deg for o in from_heights.trial_results], atol=0.5)


def test_shipped_config_files_load_and_match_the_documented_defaults(tmp_path):
    shipped = load_settings()
    # the files' values are the dataclasses' defaults; the edge also read the twin and campaign the objective names
    assert dataclasses.replace(shipped, resolved_launch=None) == EvaluatorSettings()
    assert shipped.resolved_launch.twin == load_launch_twin_settings(["sim", "robot", "launch_twin"])
    assert len(shipped.resolved_launch.conditions) == 20   # the paper's 2 heights x 2 speeds x 5 angles
    override = tmp_path / "fast.yaml"
    override.write_text("/**:\n  ros__parameters:\n    evaluator: {trials: 8}\n    sim: {contact_model: per_body}\n")
    settings = load_settings(("sim", "robot", "evaluator", str(override)))
    assert settings.evaluator.trials == 8 and settings.physics.contact_model == "per_body"
    bad = tmp_path / "bad.yaml"
    bad.write_text("/**:\n  ros__parameters:\n    sim: {frictoin: 0.3}\n")
    with pytest.raises(ConfigError, match="frictoin"):
        load_settings(("sim", str(bad)))
    bad.write_text("/**:\n  ros__parameters:\n    sim: {contact_model: sticky}\n")
    with pytest.raises(ConfigError, match="contact_model"):
        load_settings(("sim", str(bad)))


def test_urdf_export_loads_in_pybullet_with_the_profile(tmp_path):
    mesh = profile_mesh(ridge_heights(SETTINGS.grid), SETTINGS.grid)
    export_mesh(mesh, tmp_path / "profile.stl", units="m")   # URDF meshes are in metres
    job = mesh_job(mesh, SETTINGS)
    urdf = SETTINGS.robot_model().to_urdf("profile.stl", job.profile)
    ElementTree.fromstring(urdf)
    (tmp_path / "chassis.urdf").write_text(urdf)
    client = pybullet.connect(pybullet.DIRECT)
    try:
        body = pybullet.loadURDF(str(tmp_path / "chassis.urdf"), physicsClientId=client)
        names = [pybullet.getJointInfo(body, j, physicsClientId=client)[12].decode()
                 for j in range(pybullet.getNumJoints(body, physicsClientId=client))]
        assert names == ["profile_link", "front_left_wheel", "front_right_wheel", "rear_left_wheel", "rear_right_wheel"]
        masses = [pybullet.getDynamicsInfo(body, link, physicsClientId=client)[0] for link in range(-1, 5)]
        spec = SETTINGS.robot
        assert masses == pytest.approx([spec.body_mass_kg, job.profile.mass_kg] + [spec.wheel_mass_kg] * 4, rel=1e-5)
        low, high = pybullet.getAABB(body, 0, physicsClientId=client)
        assert mesh.extents[2] <= high[2] - low[2] <= mesh.extents[2] + 0.01  # AABB adds the collision margin
    finally:
        pybullet.disconnect(client)


def _free_port():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture(scope="module")
def ray_head():
    """A Ray head on loopback, started by this test and stopped (SIGTERM to ``ray start --block``) after it."""
    pytest.importorskip("ray")
    ray_cli = shutil.which("ray", path=os.path.dirname(sys.executable)) or shutil.which("ray")
    if ray_cli is None:
        pytest.skip("the ray command is not installed")
    port = _free_port()
    environment = dict(os.environ, RAY_AUTH_MODE="disabled")  # a throwaway local cluster needs no token
    head = subprocess.Popen([ray_cli, "start", "--head", "--block", "--node-ip-address", "127.0.0.1",
                             "--port", str(port), "--num-cpus", "2", "--include-dashboard", "false",
                             "--disable-usage-stats"], env=environment, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    previous = os.environ.get("RAY_AUTH_MODE")
    os.environ["RAY_AUTH_MODE"] = "disabled"
    try:
        yield f"127.0.0.1:{port}"
    finally:
        if previous is None:
            os.environ.pop("RAY_AUTH_MODE", None)
        else:
            os.environ["RAY_AUTH_MODE"] = previous
        head.send_signal(signal.SIGTERM)
        try:
            head.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(head.pid, signal.SIGKILL)
            head.wait()


def _connect(address, deadline_s=60.0):
    start = time.monotonic()
    while True:
        try:
            return RayExecutor(address)
        except ConnectionError:
            if time.monotonic() - start > deadline_s:
                raise
            time.sleep(1.0)


@pytest.mark.slow   # a local ray head starts in about 8 s: CI's --slow step runs it
def test_ray_executor_matches_the_local_executor(ray_head):
    heights = ridge_heights(SETTINGS.grid)
    local = evaluate_profile(heights, 10, 21, SETTINGS)
    with _connect(ray_head) as cluster:
        remote = evaluate_profile(heights, 10, 21, SETTINGS, executor=cluster)
    assert remote.trial_results == local.trial_results
    assert (remote.fitness, remote.ci_low, remote.ci_high) == (local.fitness, local.ci_low, local.ci_high)


ORPHAN_PARENT = """
import sys, time
from rollability_ros.core.sim.evaluation import LocalExecutor
executor = LocalExecutor(workers=2)
print(" ".join(map(str, executor.warm())), flush=True)
time.sleep(600)
"""


def test_workers_exit_when_their_parent_is_killed():
    """kill -9 of a process with a LocalExecutor (a CLI run, an evaluator node) leaves no worker behind."""
    parent = subprocess.Popen([sys.executable, "-c", ORPHAN_PARENT], stdout=subprocess.PIPE, text=True)
    try:
        pids = [int(pid) for pid in parent.stdout.readline().split()]
        assert len(pids) == 2 and parent.pid not in pids
        assert all(os.path.exists(f"/proc/{pid}") for pid in pids)
    finally:
        parent.kill()
        parent.wait()

    deadline = time.monotonic() + 30
    while any(pid_running(pid) for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not any(pid_running(pid) for pid in pids), f"orphaned workers still running: {pids}"


def test_batched_engine_seam_gives_the_executors_outcomes_and_plugs_into_the_optimizer_evaluator():
    """The TrialBatchEngine seam: the CPU engine over an executor gives evaluate_profile's outcomes; an engine
    that takes a whole generation's (profile, trial) pairs in one call plugs into the optimizer's evaluate_batch."""
    from rollability_ros.core.optimization.batch_evaluation import profile_batch_evaluator
    from rollability_ros.core.sim.evaluation import ExecutorEngine, TrialBatchEngine, evaluate_jobs

    heights_list = [None, ridge_heights(SETTINGS.grid)]
    expected = [evaluate_profile(heights, 6, 3, SETTINGS) for heights in heights_list]
    jobs = [profile_job(heights, SETTINGS) for heights in heights_list]
    for engine in (ExecutorEngine(), ExecutorEngine(whole=True)):
        results = evaluate_jobs(jobs, 6, 3, engine)
        assert [r.trial_results for r in results] == [e.trial_results for e in expected]
        assert [r.successes for r in results] == [e.successes for e in expected]

    class WholeBatch(TrialBatchEngine):
        """Stands in for a many-worlds engine: one call per generation, outcomes in the pairs' order."""
        name = "batched"

        def __init__(self):
            self.calls = []

        def run_trials(self, jobs, pairs):
            self.calls.append(len(pairs))
            return [run_batch(jobs[job], [(index, seed)])[0] for job, index, seed in reversed(pairs)][::-1]

    batched = WholeBatch()
    evaluate_batch = profile_batch_evaluator(SETTINGS, 6, None, engine=batched)
    with LocalExecutor(workers=1) as executor:
        plain = profile_batch_evaluator(SETTINGS, 6, executor)(heights_list, 3)
    assert batched.calls == [] and [r[:2] for r in evaluate_batch(heights_list, 3)] == \
        [(e.successes, e.trials) for e in expected] == [r[:2] for r in plain]
    assert batched.calls == [12] and evaluate_batch(heights_list, 3)[0][3] == "batched"
