"""Checkpoint and resume: a run SIGKILLed mid-generation and resumed equals an uninterrupted run."""
import dataclasses
import os
import pickle
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

pytest.importorskip("cma")

from rollability_ros.core.optimization import checkpoint as checkpoints  # noqa: E402
from rollability_ros.core.config import ConfigError  # noqa: E402
from rollability_ros.core.profile.geometry import ProfileGrid  # noqa: E402
from doubles import SyntheticEvaluator  # noqa: E402
from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config  # noqa: E402
from rollability_ros.core.optimization.run_directory import read_run_config  # noqa: E402
from rollability_ros.core.store import Store  # noqa: E402

GRID = ProfileGrid(rows=3, cols=3)
OPTIMUM = np.linspace(0.05, 0.4, GRID.n_variables)
GENERATIONS = 8
KILL_GENERATION = 4

# A run in a child process whose evaluator blocks on its n-th call (after announcing it), so the test can
# SIGKILL it at a known point in the middle of a generation.
CHILD = textwrap.dedent("""
    import os, sys, time
    import numpy as np
    from rollability_ros.core.profile.geometry import ProfileGrid
    sys.path.insert(0, sys.argv[4])   # test/, for the test doubles
    from doubles import SyntheticEvaluator
    from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config
    run_dir, block_at, crn, method = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "True", sys.argv[5]
    evaluator = SyntheticEvaluator(np.linspace(0.05, 0.4, 9), trials=30)
    calls = []
    def evaluate_batch(heights_list, seed):
        calls.append(seed)
        if len(calls) == block_at:
            open(run_dir + ".blocked", "w").close()
            time.sleep(600)
        return evaluator(heights_list, seed)
    parameters = {"optimizer.max_generations": %d, "optimizer.seed": 5, "optimizer.trials": 30,
                  "optimizer.popsize": 6, "optimizer.common_random_numbers": crn, "optimizer.method": method}
    OptimizationRun(run_dir, run_config(parameters), ProfileGrid(rows=3, cols=3), evaluate_batch).run()
""" % GENERATIONS)


def parameters(common_random_numbers=True, method="cmaes", **overrides):
    values = {"optimizer.max_generations": GENERATIONS, "optimizer.seed": 5, "optimizer.trials": 30,
              "optimizer.popsize": 6, "optimizer.common_random_numbers": common_random_numbers,
              "optimizer.method": method}
    values.update(overrides)
    return values


def comparable(store_path):
    """Everything a run decides, without its id and wall-clock fields (timings, stamps)."""
    with Store(store_path) as store:
        candidates = [dataclasses.replace(c, run_id="", eval_time_s=0.0, stamp_s=0.0) for c in store.candidates()]
        generations = [dataclasses.replace(g, run_id="", elapsed_s=0.0, stamp_s=0.0) for g in store.generations()]
    return candidates, generations


def uninterrupted(tmp_path, common_random_numbers, method="cmaes"):
    run_dir = os.path.join(tmp_path, "straight", "run")
    run = OptimizationRun(run_dir, run_config(parameters(common_random_numbers, method)), GRID,
                          SyntheticEvaluator(OPTIMUM, trials=30))
    result = run.run()
    run.close()
    return run_dir, result


# calls per generation: CRN: population + re-evaluation = 2; independent seeds: 6 candidates + 1 = 7
@pytest.mark.parametrize("common_random_numbers, block_at, stored_in_killed_generation, method", [
    (True, 2 * KILL_GENERATION + 1, 0, "cmaes"),   # killed while the population is evaluated
    (True, 2 * KILL_GENERATION + 2, 6, "cmaes"),   # killed during the incumbent re-evaluation: population stored
    (False, 7 * KILL_GENERATION + 4, 3, "cmaes"),  # independent seeds, killed after 3 of 6 candidates
    (True, 2 * KILL_GENERATION + 2, 6, "cma_mae"),  # quality diversity: archive and emitters rebuilt exactly
])
def test_sigkill_mid_generation_then_resume_equals_uninterrupted(tmp_path, common_random_numbers, block_at,
                                                                 stored_in_killed_generation, method):
    if method == "cma_mae":
        pytest.importorskip("ribs")
    run_dir = os.path.join(tmp_path, "killed", "run")
    os.makedirs(os.path.dirname(run_dir))
    child = subprocess.Popen([sys.executable, "-c", CHILD, run_dir, str(block_at), str(common_random_numbers),
                              os.path.dirname(os.path.dirname(os.path.abspath(__file__))), method])
    try:
        deadline = time.monotonic() + 60
        while not os.path.exists(run_dir + ".blocked"):
            assert child.poll() is None, "child run ended before reaching the kill point"
            assert time.monotonic() < deadline, "child run never reached the kill point"
            time.sleep(0.02)
        child.send_signal(signal.SIGKILL)
    finally:
        child.kill()
        child.wait()
    assert child.returncode == -signal.SIGKILL

    with Store(run_dir) as store:
        assert len(store.generations()) == KILL_GENERATION
        # generations are numbered from 1: the killed one (index KILL_GENERATION) is number KILL_GENERATION + 1
        assert len(store.candidates(generation=KILL_GENERATION + 1)) == stored_in_killed_generation
    assert checkpoints.load_checkpoint(os.path.join(run_dir, checkpoints.CHECKPOINT_FILENAME))["generation"] == \
        KILL_GENERATION

    resumed = OptimizationRun(run_dir, run_config(read_run_config(run_dir)), GRID, SyntheticEvaluator(OPTIMUM, trials=30),
                              resume=True)
    assert resumed.optimizer.generation == KILL_GENERATION
    result = resumed.run()
    resumed.close()

    straight_dir, straight = uninterrupted(tmp_path, common_random_numbers, method)
    assert comparable(run_dir) == comparable(straight_dir)
    with Store(run_dir) as killed, Store(straight_dir) as straight_store:
        archive = killed.run_info("run")["info"].get("archive")
        assert archive == straight_store.run_info("run")["info"].get("archive")
        assert (archive is not None) == (method == "cma_mae")
    assert result.generations == straight.generations == GENERATIONS
    np.testing.assert_array_equal(result.best.heights, straight.best.heights)
    assert result.best.fitness == straight.best.fitness
    np.testing.assert_array_equal(result.mean, straight.mean)


def test_killed_in_generation_zero_resumes_from_scratch(tmp_path):
    run_dir = os.path.join(tmp_path, "run")

    def failing(heights_list, seed):
        raise RuntimeError("evaluator died")

    with pytest.raises(RuntimeError):
        OptimizationRun(run_dir, run_config(parameters()), GRID, failing).run()
    assert not os.path.exists(os.path.join(run_dir, checkpoints.CHECKPOINT_FILENAME))
    resumed = OptimizationRun(run_dir, run_config(parameters()), GRID, SyntheticEvaluator(OPTIMUM, trials=30), resume=True)
    resumed.run()
    resumed.close()
    assert comparable(run_dir) == comparable(uninterrupted(tmp_path, True)[0])


def test_after_an_evaluator_error_the_same_run_object_continues_identically(tmp_path):
    """The node's case: an evaluation fails mid-generation (no evaluator left); step() again later."""
    run_dir = os.path.join(tmp_path, "run")
    healthy = SyntheticEvaluator(OPTIMUM, trials=30)
    calls = []

    def flaky(heights_list, seed):
        calls.append(seed)
        if len(calls) == 2 * 3 + 2:       # generation 3's incumbent re-evaluation, after its population
            raise RuntimeError("evaluator went away")
        return healthy(heights_list, seed)

    run = OptimizationRun(run_dir, run_config(parameters()), GRID, flaky)
    with pytest.raises(RuntimeError, match="went away"):
        run.run()
    assert run.optimizer.generation == 3
    run.run()
    run.close()
    assert comparable(run_dir) == comparable(uninterrupted(tmp_path, True)[0])


def test_a_different_config_refuses_to_resume(tmp_path):
    run_dir = os.path.join(tmp_path, "run")
    run = OptimizationRun(run_dir, run_config(parameters(**{"optimizer.max_generations": 2})), GRID,
                          SyntheticEvaluator(OPTIMUM, trials=30))
    run.run()
    run.close()
    with pytest.raises(ConfigError, match=r"optimizer.trials: 30 -> 40"):
        OptimizationRun(run_dir, run_config(parameters(**{"optimizer.max_generations": 2, "optimizer.trials": 40})), GRID,
                        SyntheticEvaluator(OPTIMUM, trials=40), resume=True)
    with pytest.raises(ValueError, match="already exists"):
        OptimizationRun(run_dir, run_config(parameters(**{"optimizer.max_generations": 2})), GRID,
                        SyntheticEvaluator(OPTIMUM, trials=30))
    with pytest.raises(FileNotFoundError, match="not an optimization run"):
        OptimizationRun(os.path.join(tmp_path, "nothing"), run_config(parameters()), GRID, SyntheticEvaluator(OPTIMUM, 30),
                        resume=True)


def test_checkpoint_write_is_atomic_and_checked(tmp_path):
    path = os.path.join(tmp_path, checkpoints.CHECKPOINT_FILENAME)
    checkpoints.atomic_write_bytes(path, b"old")
    checkpoints.atomic_write_bytes(path, b"new")
    assert open(path, "rb").read() == b"new"
    assert os.listdir(tmp_path) == [checkpoints.CHECKPOINT_FILENAME]   # no temp file left behind
    with pytest.raises(ValueError, match="not JSON"):
        checkpoints.load_checkpoint(path)
    assert checkpoints.load_checkpoint(os.path.join(tmp_path, "missing.pkl")) is None
    state = {"a": 1}
    checkpoints.save_checkpoint(path, "r", {"x": 1}, {"generation": 3, **state}, 0.5)
    loaded = checkpoints.load_checkpoint(path)
    assert loaded["generation"] == 3 and loaded["best_so_far"] == 0.5
    checkpoints.check_same_config(loaded, {"x": 1}, path)
    with pytest.raises(ConfigError, match=r"x: 1 -> 2; y: \(unset\) -> 3"):
        checkpoints.check_same_config(loaded, {"x": 2, "y": 3}, path)


@pytest.mark.slow   # the CLI path of the kill and resume above (about 12 s): CI's --slow step runs it
def test_cli_run_with_real_physics_killed_and_resumed_equals_uninterrupted(tmp_path, capsys):
    """`rollability optimize` on a tiny real evaluation (6 variables, 4 trials): SIGKILL after the first stored
    generation, `--resume`, compare with an uninterrupted run; then `rollability select` on the result."""
    pytest.importorskip("pybullet")
    from rollability_ros.cli import main

    config = os.path.join(tmp_path, "tiny.yaml")
    with open(config, "w") as stream:
        stream.write(textwrap.dedent(f"""
            /**:
              ros__parameters:
                optimizer: {{method: cmaes, popsize: 4, trials: 4, max_generations: 4, seed: 2,
                             initial_mean_screen: 0, output_dir: "{tmp_path}"}}
                profile: {{rows: 3, cols: 2}}
                evaluator: {{workers: 1}}
                selection: {{count: 2, min_distance: 0.0, reevaluate_trials: 2, race_launches: [2], race_elites: 3,
                             launch_trials: 2}}
            """))
    killed_dir = os.path.join(tmp_path, "killed")
    child = subprocess.Popen([sys.executable, "-m", "rollability_ros.cli", "optimize", "--config", config,
                              "--run-id", "killed"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while True:
            assert child.poll() is None, "the run finished before it could be killed"
            assert time.monotonic() < deadline, "the run stored no generation in time"
            if os.path.exists(os.path.join(killed_dir, checkpoints.CHECKPOINT_FILENAME)):
                break
            time.sleep(0.02)
        child.send_signal(signal.SIGKILL)
    finally:
        child.kill()
        child.wait()
    with Store(killed_dir) as store:
        assert 1 <= len(store.generations()) < 4

    assert main(["optimize", "--resume", killed_dir]) == 0
    assert main(["optimize", "--config", config, "--run-id", "straight"]) == 0
    output = capsys.readouterr().out
    assert "resuming after generation" in output and "gen    4/4" in output
    killed, straight = comparable(killed_dir), comparable(os.path.join(tmp_path, "straight"))
    assert killed == straight and len(killed[1]) == 4
    assert sum(c.successes for c in killed[0]) > 0   # the physics decided something

    other = os.path.join(tmp_path, "other.yaml")
    with open(config) as source, open(other, "w") as target:
        target.write(source.read().replace("trials: 4,", "trials: 5,"))
    assert main(["optimize", "--resume", killed_dir, "--config", other]) == 2
    assert "optimizer.trials: 4 -> 5" in capsys.readouterr().err

    assert main(["select", killed_dir]) == 0
    assert "A " in capsys.readouterr().out
    assert sorted(os.listdir(os.path.join(killed_dir, "designs"))) == [
        "designs.yaml", "mesh_A.3mf", "mesh_A.stl", "mesh_B.3mf", "mesh_B.stl", "selection_world_check.csv",
        "table3.csv"]


class NoResults(RuntimeError):
    """Stands in for the node's EvaluationFailed."""


class Shutdown(RuntimeError):
    """Stands in for the node's PoolClosed."""


def test_the_one_loop_retries_gives_up_stops_and_is_interrupted_by_policy(tmp_path):
    from rollability_ros.core.optimization.optimization_run import run_generations

    healthy = SyntheticEvaluator(OPTIMUM, trials=30)
    calls = []

    def failing_at(*call_numbers, error=NoResults):
        def evaluate_batch(heights_list, seed):
            calls.append(seed)
            if len(calls) in call_numbers:
                raise error("no evaluator answered")
            return healthy(heights_list, seed)
        return evaluate_batch

    # retry (the node pauses, then resumes): the run ends as if nothing failed
    failures = []
    run = OptimizationRun(tmp_path / "retry", run_config(parameters()), GRID, failing_at(3, 4))
    end = run_generations(run, on_evaluation_failed=lambda exc: failures.append(exc) or True,
                          evaluation_errors=(NoResults,))
    run.close()
    assert end.status == "finished" and end.exit_code == 0 and len(failures) == 2
    assert comparable(tmp_path / "retry") == comparable(uninterrupted(tmp_path, True)[0])

    # give up (exit_on_finish): failed, with the generation's number (from 1) in the reason
    calls.clear()
    run = OptimizationRun(tmp_path / "give-up", run_config(parameters()), GRID, failing_at(3))
    end = run_generations(run, evaluation_errors=(NoResults,))
    assert end.status == "failed" and end.exit_code == 1
    assert end.reason == "generation 2 got no real results (no evaluator answered)"
    run.close()

    # interrupted (shutdown): no exit code, resumable; an error of no listed kind propagates
    calls.clear()
    run = OptimizationRun(tmp_path / "shutdown", run_config(parameters()), GRID, failing_at(3, error=Shutdown))
    end = run_generations(run, evaluation_errors=(NoResults,), interruptions=(Shutdown,))
    assert end.status == "interrupted" and end.exit_code is None and run.optimizer.generation == 1
    with pytest.raises(RuntimeError, match="went away"):
        OptimizationRun(tmp_path / "bug", run_config(parameters()), GRID,
                        lambda h, s: (_ for _ in ()).throw(RuntimeError("went away"))).run()
    run.close()

    # stop between generations: the current generation is finished and checkpointed
    stop_after = []
    run = OptimizationRun(tmp_path / "stop", run_config(parameters()), GRID, healthy,
                          on_generation=lambda record: stop_after.append(record.generation))
    end = run_generations(run, stop_requested=lambda: len(stop_after) >= 3)
    assert end.status == "stopped" and stop_after == [1, 2, 3] and run.optimizer.generation == 3
    assert f"ended after 3 generation(s), {end.result.evaluations} evaluations (stop service)" in run.end_text(end)
    run.close()


def test_generations_are_numbered_from_1_and_runs_numbered_from_0_keep_their_numbers(tmp_path, monkeypatch):
    from rollability_ros.core.optimization import optimization_run
    from rollability_ros.core.optimization import run_directory

    run = OptimizationRun(tmp_path / "new", run_config(parameters(**{"optimizer.max_generations": 3})), GRID,
                          SyntheticEvaluator(OPTIMUM, trials=30))
    run.run()
    assert [g.generation for g in run.store.generations()] == [1, 2, 3]
    assert {c.generation for c in run.store.candidates()} == {1, 2, 3}
    assert run.store.run_info("new")["info"]["first_generation"] == 1
    run.close()

    # a run stored by the code before this numbering: generations from 0 and no first_generation in its info
    monkeypatch.setattr(optimization_run, "FIRST_GENERATION", 0)
    old_dir = tmp_path / "old"
    killed = OptimizationRun(old_dir, run_config(parameters()), GRID, SyntheticEvaluator(OPTIMUM, trials=30))
    for _ in range(3):
        killed.step()
    info = dict(killed.store.run_info("old")["info"])
    del info["first_generation"]
    killed.store.set_run_info("old", run_directory.RUN_KIND, info)
    killed.close()
    monkeypatch.setattr(optimization_run, "FIRST_GENERATION", 1)
    resumed = OptimizationRun(old_dir, run_config(parameters()), GRID, SyntheticEvaluator(OPTIMUM, trials=30), resume=True)
    assert resumed.first_generation == 0 and "resuming after generation 2" in resumed.start_text(True)
    resumed.run()
    assert [g.generation for g in resumed.store.generations()] == list(range(GENERATIONS))
    resumed.close()


# --- issue 17: checkpoints are data, and a resume never runs on a missing, damaged or foreign one ---------------
def _partial_run(tmp_path, name="run", generations=3):
    """A run stopped after ``generations`` of GENERATIONS generations (as if killed between generations)."""
    run_dir = os.path.join(tmp_path, name)
    run = OptimizationRun(run_dir, run_config(parameters()), GRID, SyntheticEvaluator(OPTIMUM, trials=30))
    for _ in range(generations):
        run.step()
    run.close()
    return run_dir


def _rows(run_dir):
    with Store(run_dir) as store:
        return len(store.candidates()), len(store.generations())


def _resume(run_dir):
    return OptimizationRun(run_dir, run_config(read_run_config(run_dir)), GRID, SyntheticEvaluator(OPTIMUM, trials=30),
                           resume=True)


def test_checkpoint_is_json_with_its_sha256_recorded_in_the_store(tmp_path):
    import json

    run_dir = _partial_run(tmp_path)
    path = os.path.join(run_dir, checkpoints.CHECKPOINT_FILENAME)
    with open(path, "rb") as stream:
        document = json.loads(stream.read())          # plain data: JSON parses it, nothing is executed
    assert document["checkpoint"]["generation"] == 3
    with Store(run_dir) as store:
        recorded = store.run_info(os.path.basename(run_dir))["info"]["checkpoint"]
    assert recorded == {"file": checkpoints.CHECKPOINT_FILENAME, "generation": 3,
                        "sha256": checkpoints.file_sha256(path)}
    resumed = _resume(run_dir)
    result = resumed.run()
    resumed.close()
    straight_dir, straight = uninterrupted(tmp_path, True)
    assert comparable(run_dir) == comparable(straight_dir)
    np.testing.assert_array_equal(result.mean, straight.mean)


def test_resume_with_a_deleted_checkpoint_is_refused_and_adds_no_rows(tmp_path):
    run_dir = _partial_run(tmp_path)
    os.remove(os.path.join(run_dir, checkpoints.CHECKPOINT_FILENAME))
    before = _rows(run_dir)
    with pytest.raises(ConfigError, match="checkpoint .* is missing.*3 generation"):
        _resume(run_dir)
    assert _rows(run_dir) == before


def test_a_crafted_pickle_checkpoint_is_never_loaded(tmp_path):
    """A pickle that runs code on load, under the old name or the new one: refused, the code never runs."""
    run_dir = _partial_run(tmp_path)
    marker = os.path.join(tmp_path, "pwned")

    class Payload:
        def __reduce__(self):
            return (open, (marker, "w"))

    crafted = pickle.dumps({"format": 1, "payload": Payload()})
    checkpoint = os.path.join(run_dir, checkpoints.CHECKPOINT_FILENAME)
    os.replace(checkpoint, checkpoint + ".kept")
    with open(os.path.join(run_dir, checkpoints.LEGACY_CHECKPOINT_FILENAME), "wb") as stream:
        stream.write(crafted)
    with pytest.raises(ConfigError, match="pickled checkpoint"):
        _resume(run_dir)
    with open(checkpoint, "wb") as stream:
        stream.write(crafted)
    with pytest.raises(ConfigError, match="not JSON"):
        _resume(run_dir)
    assert not os.path.exists(marker)


def test_flipped_bytes_in_the_checkpoint_are_refused(tmp_path):
    run_dir = _partial_run(tmp_path)
    path = os.path.join(run_dir, checkpoints.CHECKPOINT_FILENAME)
    with open(path, "rb") as stream:
        data = stream.read()
    position = data.index(b'"sigma":') + len(b'"sigma":') + 3      # a digit inside the step size
    damaged = data[:position] + bytes([data[position] ^ 0x01]) + data[position + 1:]
    assert damaged != data
    with open(path, "wb") as stream:
        stream.write(damaged)
    before = _rows(run_dir)
    with pytest.raises(ConfigError, match="damaged"):
        _resume(run_dir)
    assert _rows(run_dir) == before


def test_a_foreign_checkpoint_is_refused(tmp_path):
    """Another run's (valid) checkpoint copied in, or this run's older one put back: both refused."""
    import shutil

    run_dir = _partial_run(tmp_path, "run", generations=3)
    other_dir = _partial_run(tmp_path, "other", generations=3)
    path = os.path.join(run_dir, checkpoints.CHECKPOINT_FILENAME)
    older = path + ".older"
    shutil.copyfile(path, older)
    shutil.copyfile(os.path.join(other_dir, checkpoints.CHECKPOINT_FILENAME), path)
    with pytest.raises(ConfigError, match="checkpoint of run 'other'"):
        _resume(run_dir)
    run = _resume_after_restoring(run_dir, older, path)
    run.step()
    run.close()
    shutil.copyfile(older, path)      # the generation-3 checkpoint, now that the store recorded generation 4
    before = _rows(run_dir)
    with pytest.raises(ConfigError, match="not the checkpoint this run's store recorded"):
        _resume(run_dir)
    assert _rows(run_dir) == before


def _resume_after_restoring(run_dir, saved, path):
    import shutil

    shutil.copyfile(saved, path)
    return _resume(run_dir)


def test_checkpoint_written_but_not_yet_recorded_is_accepted(tmp_path):
    """A kill between writing checkpoint g+1 and recording its SHA-256: the resume accepts the newer file."""
    run_dir = _partial_run(tmp_path, generations=3)
    run_id = os.path.basename(run_dir)
    with Store(run_dir) as store:
        described = store.run_info(run_id)
        info = dict(described["info"], checkpoint={"file": checkpoints.CHECKPOINT_FILENAME, "generation": 2,
                                                   "sha256": "0" * 64})
        store.set_run_info(run_id, described["kind"], info)
    resumed = _resume(run_dir)
    assert resumed.optimizer.generation == 3
    resumed.close()


def test_state_dict_survives_json():
    """The optimizer state is plain data: a JSON round trip rebuilds an optimizer that continues identically."""
    import json

    from rollability_ros.core.optimization.cmaes import ProfileOptimizer
    from rollability_ros.core.optimization.optimization_run import run_settings

    settings = run_settings(parameters()).optimizer
    original = ProfileOptimizer(GRID.n_variables, settings, 0.0, 0.45)
    evaluator = SyntheticEvaluator(OPTIMUM, trials=30)
    for generation in range(3):
        population = original.ask()
        results = evaluator(population, generation)
        original.tell(population, [s / t for s, t, *_ in results], [t for _, t, *_ in results])
        request = original.reevaluation_request()
        if request is not None:
            (again,) = evaluator([request], 100 + generation)
            original.tell_reevaluation(again[0] / again[1], again[1])
    state = json.loads(json.dumps(original.state_dict(), allow_nan=False))
    copy = ProfileOptimizer.from_state_dict(state, GRID.n_variables, settings, 0.0, 0.45)
    for x, y in zip(original.ask(), copy.ask()):
        np.testing.assert_array_equal(x, y)
    assert copy.best.fitness == original.best.fitness and copy.evaluations == original.evaluations
