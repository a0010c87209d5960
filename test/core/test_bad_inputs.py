"""Issue 26, point 4: bad input at every verb's door gives one line naming the problem and exit 2; nothing is
written and no existing file changes (SHA-256 of every file in the workspace before and after). The cases are the
issue's and those a probe of every verb's numeric and path flags found; the full probe table is in the issue's
closing note."""
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from doubles import SyntheticEvaluator, damaged_store, tree_checksums
from rollability_ros.cli import main

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SAMPLE_BAG = os.path.join(REPO, "bags", "sample")
HEADER = "run_id,trial_id,configuration,height_m,speed_mps,angle_deg,repetition,upright"
CSVS = {
    "good.csv": f"{HEADER}\nr,t1,A,0.1,1.0,0,0,true\nr,t2,baseline,0.1,1.0,0,0,false\n",
    "quaternion0.csv": f"{HEADER},final_qx,final_qy,final_qz,final_qw\nr,t1,A,0.1,1.0,0,0,true,0,0,0,0\n",
    "quaternion_half.csv": f"{HEADER},final_qx,final_qy,final_qz,final_qw\nr,t1,A,0.1,1.0,0,0,true,0,0,0,0.5\n",
    "travel_nan.csv": f"{HEADER},travel_time_s\nr,t1,A,0.1,1.0,0,0,true,nan\n",
    "height_nan.csv": f"{HEADER}\nr,t1,A,nan,1.0,0,0,true\n",
    "negative_travel.csv": f"{HEADER},travel_time_s\nr,t1,A,0.1,1.0,0,0,true,-0.5\n",
    "negative_speed.csv": f"{HEADER},measured_speed_mps\nr,t1,A,0.1,1.0,0,0,true,-1\n",
    "stamp_nan.csv": f"{HEADER},stamp_s\nr,t1,A,0.1,1.0,0,0,true,nan\n",
    "nul_configuration.csv": f"{HEADER}\nr,t1,A,0.1,1.0,0,0,true\nr,t2,A\x00,0.1,1.0,0,0,false\n",
}


PARAMS = "/**:\n  ros__parameters:\n"
LAUGHS = PARAMS + "    a0: &a0 {" + ", ".join(f"k{j}: {j}" for j in range(10)) + "}\n" + "".join(
    f"    a{i}: &a{i} {{" + ", ".join(f"k{j}: *a{i - 1}" for j in range(10)) + "}\n" for i in range(1, 9)) + \
    "    sim: *a8\n"   # 10^9 keys once expanded (issue 42: MemoryError in config._flatten after 52 s)
PARAMETER_FILES = {
    "deep.yaml": PARAMS + "    sim: " + "[" * 20000 + "\n",   # issue 42: a RecursionError traceback in every verb
    "laughs.yaml": LAUGHS,
    "duplicate.yaml": PARAMS + "    evaluator:\n      trials: 2\n      trials: 3\n",
    "twin_negative.yaml": PARAMS + "    launch_twin: {foam: {length_m: -5.0}}\n",
    "optimizer_keys.yaml": PARAMS + "    optimizer: {popsize: 8}\n",
    "calibration_keys.yaml": PARAMS + "    calibration: {popsize: 4}\n",
    "campaign_keys.yaml": PARAMS + "    campaign: {repetitions: 2}\n",
    "far_heights.yaml": PARAMS + "    campaign: {heights_m: [1.0e+308]}\n",
    "climbing.yaml": PARAMS + "    bringup: {output_dir: '" + "../" * 64 + "runs'}\n",
}


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    """A folder with a bag, a finished optimization run (runs/ex), outcome CSVs, a file, a folder of notes and a
    folder holding an earlier calibration."""
    from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config
    from rollability_ros.core.profile import geometry

    root = tmp_path_factory.mktemp("bad_inputs")
    shutil.copytree(SAMPLE_BAG, root / "bag")
    grid = geometry.ProfileGrid(rows=3, cols=3)
    run = OptimizationRun(str(root / "runs" / "ex"), run_config({"optimizer.max_generations": 4, "optimizer.trials": 20,
                                                      "profile.rows": 3, "profile.cols": 3}), grid,
                          SyntheticEvaluator(np.linspace(0.1, 0.4, grid.n_variables), 20))
    run.run()
    run.close()
    for name, text in {**CSVS, **PARAMETER_FILES}.items():
        (root / name).write_text(text)
    shutil.copytree(root / "runs" / "ex", root / "runs" / "deep_checkpoint")
    (root / "runs" / "deep_checkpoint" / "checkpoint.json").write_text("[" * 20000)   # was a RecursionError
    damaged_store(root / "damaged.sqlite")   # opens (page 1 intact), its outcomes unreadable
    (root / "afile.txt").write_text("the operator's notes\n")
    (root / "full").mkdir()
    (root / "full" / "x.txt").write_text("something else\n")
    (root / "cal_done").mkdir()
    (root / "cal_done" / "calibrated.yaml").write_text("# an earlier calibration\n")
    (root / "study.yaml").write_text("/**:\n  ros__parameters:\n    bringup: {output_dir: '.'}\n")
    return root


ID_RULE = "one folder name of letters, digits"
CASES = [
    # the issue's cases
    (["report", "bag", "--out", "afile.txt"], "is an existing file, not a folder"),
    (["study", "--study-id", "full", "--config", "study.yaml"], "already exists"),
    (["optimize", "--config", "optimizer", "--run-id", "../escaped_run"], ID_RULE),
    (["optimize", "--config", "optimizer", "--run-id", ""], ID_RULE),
    (["report", "quaternion0.csv", "--out", "r1"], "must be a unit quaternion"),
    (["report", "travel_nan.csv", "--out", "r2"], "travel_time_s must be finite"),
    # found by the probe, or checked at the door
    (["report", "quaternion_half.csv", "--out", "r3"], "must be a unit quaternion"),
    (["report", "height_nan.csv", "--out", "r4"], "height_m must be finite"),
    (["report", "negative_travel.csv", "--out", "r5"], "travel_time_s must be >= 0"),
    (["report", "negative_speed.csv", "--out", "r6"], "measured_speed_mps must be >= 0"),
    (["report", "stamp_nan.csv", "--out", "r7"], "stamp_s must be finite"),
    # "A\x00" was imported as a configuration of its own, beside A
    (["report", "nul_configuration.csv", "--out", "r_nul"],
     "nul_configuration.csv: refused, nothing imported: line 3: configuration must not hold control characters, "
     "got 'A\\x00'"),
    (["calibrate", "--physical", "nul_configuration.csv", "--out", "c_nul"],
     "line 3: configuration must not hold control characters"),
    (["report", "bag", "--out", "full"], "holds other files"),
    (["report", "good.csv", "--out", "bag"], "holds other files"),
    (["report", "good.csv", "--sim-fitness", "A=nan", "--out", "r8"], "fitness in [0, 1]"),
    (["calibrate", "--physical", "quaternion0.csv", "--out", "c1"], "must be a unit quaternion"),
    (["calibrate", "--physical", "good.csv", "--out", "afile.txt"], "is an existing file, not a folder"),
    (["calibrate", "--physical", "good.csv", "--out", "cal_done"], "already holds the results of an earlier run"),
    (["calibrate", "--physical", "good.csv", "--workers", "-1", "--out", "c2"], "--workers must be >= 1"),
    (["sensitivity", "--trials", "1", "--out", "afile.txt"], "is an existing file, not a folder"),
    (["sensitivity", "--trials", "1", "--vary", "twin.foam.thickness_m=0.02,0.1", "--out", "s1"], "--vary needs --launches"),
    (["sensitivity", "--launches", "--trials", "1", "--vary", "twin.foam.thickness_m=0.02", "--out", "s2"],
     "--vary takes NAME=LOW,HIGH"),
    (["sensitivity", "--launches", "--trials", "1", "--vary", "twin.foam.thickness_m=0.02,nan", "--out", "s3"],
     "--vary takes NAME=LOW,HIGH"),
    (["sensitivity", "--worlds", "2", "--out", "s4"], "the world check needs designs"),
    (["sensitivity", "--engine", "mujoco", "--out", "s5"], "give --worlds N"),
    (["sensitivity", "--worlds", "2", "--launches", "--out", "s6"], "--worlds runs the world check"),
    (["calibrate", "--characterisation", "good.csv", "--out", "c3"], "good.csv: must be a mapping"),
    (["calibrate", "--physical", "good.csv", "--fit", "sim.gravity_mps2", "--out", "c4"],
     "sim.gravity_mps2 is not declared in calibration.parameters"),
    (["study", "--study-id", "../x", "--config", "study.yaml"], ID_RULE),
    (["study", "--study-id", "", "--config", "study.yaml"], ID_RULE),
    (["bringup", "--session-id", "../x", "--config", "study.yaml"], ID_RULE),
    (["bringup", "--session-id", "", "--config", "study.yaml"], ID_RULE),
    (["bringup", "--session-id", "full", "--config", "study.yaml"], "already exists"),
    (["optimize", "--config", "optimizer", "--run-id", "ex"], "already exists; resume it"),
    (["optimize", "--config", "optimizer", "--run-id", "a/b"], ID_RULE),
    (["campaign", "--backend", "sim", "--store", "camp.sqlite", "--run-id", ""], ID_RULE),
    (["campaign", "--backend", "sim", "--store", "camp.sqlite", "--run-id", "../x"], ID_RULE),
    (["campaign", "--backend", "sim", "--graph", "--store-timeout-s", "nan"],
     "runner.store_timeout_s out of range: nan is not in (0.0, 3600.0]"),
    # the shipped campaign launches A, B, C: without designs the twin has no profile for them (was: 100 baseline
    # launches stored, then "campaign stopped" at the first A)
    (["campaign", "--backend", "sim", "--store", "camp.sqlite"], "campaign not started: unknown configuration 'A'"),
    (["campaign", "--backend", "sim", "--resimulate", "baseline", "nan", "1", "0", "--seed", "1"], "finite"),
    (["select", "ex", "--output-dir", "runs", "--min-distance", "nan"],
     "selection.min_distance out of range: nan is not in [0.0, 1000.0]"),
    (["select", "ex", "--output-dir", "runs", "--top-fraction", "1.5"],
     "selection.top_fraction out of range: 1.5 is not in (0.0, 1.0]"),
    (["select", "ex", "--output-dir", "runs", "--count", "0"], "selection.count out of range: 0 is not in [1, 26]"),
    (["bag", "info", "afile.txt"], "not a bag"),
    (["bag", "recover", "afile.txt"], "not a bag directory"),
    (["bag", "convert", "bag", "bag", "--storage", "mcap"], "does not overwrite"),
    # issue 42, item 3
    (["campaign", "--backend", "sim", "--resimulate", "baseline", "1e308", "1", "0", "--seed", "1"],
     "height_m must be <= 10 m, got 1e+308"),
    (["campaign", "--backend", "sim", "--resimulate", "baseline", "1", "1e9", "0", "--seed", "1"],
     "speed_mps must be <= 10 m/s, got 1000000000.0"),
    (["campaign", "--backend", "sim", "--resimulate", "baseline", "1", "1", "0", "--seed", str(2**63)],
     "seed must be a twin seed in [0, 2**63)"),
    (["campaign", "--backend", "sim", "--store", "camp.sqlite", "--config", "far_heights.yaml"],
     "height_m must be <= 10 m, got 1e+308"),                       # the same bounds as --resimulate
    (["evaluate", "--baseline", "--engines", ""], "--engines needs two different engines"),
    # was numpy's MemoryError traceback ("Unable to allocate 11.0 TiB"); 10^8 would have taken gigabytes and days
    (["calibrate", "--prepare", "p.npz", "--prepare-launches", "100000000000"],
     "--prepare-launches must be in [200, 1000000], got 100000000000"),
    # a binary file given as the heights: "'utf-8' codec can't decode byte 0x..." named neither the flag nor the file
    (["evaluate", "--heights-file", "bag/bag_0.mcap"], "--heights-file bag/bag_0.mcap: not a text file of heights"),
    (["optimize", "--resume", "deep_checkpoint"], "is damaged or not a checkpoint"),
    # was a sqlite3.DatabaseError traceback: the store opened, its first read met a damaged page
    (["report", "damaged.sqlite", "--out", "r9"], "damaged.sqlite is damaged (database disk image is malformed)"),
    (["bringup", "--config", "climbing.yaml"], "bringup.output_dir"),
    (["study", "--config", "climbing.yaml"], "has more '..' than"),
    # a key of a given file the command never applies is refused, naming the file, key and command
    (["evaluate", "--baseline", "--config", "twin_negative.yaml"],
     "twin_negative.yaml: rollability evaluate --fidelity screen does not read launch_twin.foam.length_m"),
    (["evaluate", "--baseline", "--fidelity", "launch", "--config", "twin_negative.yaml"],
     "launch_twin.foam.length_m out of range: -5.0 is not in (0.0, 100.0]"),
    (["evaluate", "--baseline", "--config", "optimizer_keys.yaml"], "does not read optimizer.popsize"),
    (["sensitivity", "--trials", "1", "--out", "s1", "--config", "optimizer_keys.yaml"],
     "rollability sensitivity does not read optimizer.popsize"),
    (["optimize", "--config", "campaign_keys.yaml"], "rollability optimize does not read campaign.repetitions"),
    (["select", "ex", "--output-dir", "runs", "--config", "campaign_keys.yaml"],
     "rollability select does not read campaign.repetitions"),
    (["campaign", "--backend", "sim", "--store", "camp.sqlite", "--config", "optimizer_keys.yaml"],
     "rollability campaign --config does not read optimizer.popsize"),
    (["campaign", "--backend", "sim", "--store", "camp.sqlite", "--rig-config", "optimizer_keys.yaml"],
     "rollability campaign --rig-config does not read optimizer.popsize"),
    (["campaign", "--backend", "sim", "--graph", "--rig-config", "rig"], "--rig-config is for the in-process rig"),
    (["calibrate", "--physical", "good.csv", "--out", "c3", "--config", "optimizer_keys.yaml"],
     "rollability calibrate does not read optimizer.popsize"),
    (["study", "--config", "calibration_keys.yaml"], "rollability study does not read calibration.popsize"),
    (["bringup", "--config", "calibration_keys.yaml"], "rollability bringup does not read calibration.popsize"),
    (["bringup", "--config", "twin_negative.yaml"],   # before any node starts
     "launch_twin.foam.length_m out of range: -5.0 is not in (0.0, 100.0]"),
]
#: Every verb that reads parameter files, with FILE for the file under test.
VERBS_WITH_FILES = [
    ["evaluate", "--baseline", "--config", "FILE"],
    ["optimize", "--config", "FILE"],
    ["select", "ex", "--output-dir", "runs", "--config", "FILE"],
    ["sensitivity", "--trials", "1", "--out", "s2", "--config", "FILE"],
    ["calibrate", "--physical", "good.csv", "--out", "c4", "--config", "FILE"],
    ["campaign", "--backend", "sim", "--store", "camp.sqlite", "--config", "FILE"],
    ["campaign", "--backend", "sim", "--store", "camp.sqlite", "--rig-config", "FILE"],
    ["campaign", "--backend", "sim", "--resimulate", "baseline", "1", "1", "0", "--seed", "1", "--rig-config", "FILE"],
    ["study", "--config", "FILE"],
    ["bringup", "--config", "FILE"],
]
for _file, _reason in [("deep.yaml", "nesting deeper than 100 levels at line 3"),
                       ("laughs.yaml", "anchors and aliases expand to more than"),
                       ("duplicate.yaml", "duplicate key 'trials' at line 5 (first at line 4)")]:
    CASES += [([_file if arg == "FILE" else arg for arg in argv], f"{_file}: {_reason}") for argv in VERBS_WITH_FILES]


@pytest.mark.parametrize("argv, reason", CASES, ids=[" ".join(argv)[:60] for argv, _ in CASES])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(workspace, monkeypatch, capsys, argv, reason):
    monkeypatch.chdir(workspace)
    before = tree_checksums(workspace)
    assert main(list(argv)) == 2
    error = capsys.readouterr().err
    assert error.startswith(f"rollability {argv[0]}: error:") and reason in error, error
    assert len(error.strip().splitlines()) == 1, error   # a CSV with one refused row too (more: one line each)
    assert tree_checksums(workspace) == before


def _cli(workspace, *argv):
    environment = dict(os.environ, PYTHONPATH=REPO, LC_ALL="C.UTF-8", TERM="dumb", PYTHONUNBUFFERED="1")
    return subprocess.run([sys.executable, "-m", "rollability_ros.cli", *argv], capture_output=True, text=True,
                          timeout=120, cwd=workspace, env=environment)


@pytest.mark.parametrize("argv, reason", [
    (["play", "bag", "--start-offset", "1e12", "--wait-for-subscribers", "0"], "player.start_offset_s"),
    (["play", "bag", "--start-offset", "1000", "--wait-for-subscribers", "0"], "beyond the end of the bag"),
    (["play", "bag", "--wait-for-subscribers", "-1"], "player.wait_for_subscribers_s"),   # out of its range
])
def test_the_player_refuses_what_it_cannot_play(workspace, argv, reason):
    """Was: `play --start-offset 1e12` exited 0 after "played 0 messages"."""
    before = tree_checksums(workspace)
    result = _cli(workspace, *argv)
    assert result.returncode == 2, result.stdout + result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and reason in errors[0] and "Traceback" not in result.stderr, result.stderr
    assert tree_checksums(workspace) == before


def test_an_engine_comparison_never_overwrites_an_earlier_one(tmp_path, monkeypatch, capsys):
    """`evaluate --designs ... --engines` writes engine_agreement.csv beside the designs; a second comparison is
    refused before its trials instead of replacing the first table."""
    import yaml

    designs = tmp_path / "designs.yaml"
    designs.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"designs": {
        "labels": ["A"], "grid": {"rows": 3, "cols": 3, "length_m": 0.18, "width_m": 0.14, "height_min": 0.0,
                                  "height_max": 0.45, "unit_m": 0.2}, "A": {"heights": [0.2] * 9}}}}}))
    (tmp_path / "engine_agreement.csv").write_text("design,engine\nA,pybullet\n")
    before = tree_checksums(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", "--designs", "designs.yaml", "--engines", "pybullet,mujoco", "--trials", "2"]) == 2
    error = capsys.readouterr().err
    assert "already holds an earlier engine comparison" in error and len(error.strip().splitlines()) == 1
    assert tree_checksums(tmp_path) == before


def test_the_operators_rig_command_refuses_a_bringup_file_bringup_would(workspace):
    """`rollability rig --config FILE` reads the file given to bringup (for its namespace) the same way (a process:
    the command sets the physical rig's ROS environment)."""
    before = tree_checksums(workspace)
    result = _cli(workspace, "rig", "estop", "--config", "deep.yaml", "--timeout-s", "1")
    reason = "deep.yaml: nesting deeper than 100 levels"
    assert result.returncode == 2, result.stdout + result.stderr
    assert result.stderr.startswith("rollability rig: error:") and reason in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert tree_checksums(workspace) == before


@pytest.mark.parametrize("argv", [["evaluate", "--baseline", "--trials", "1", "--workers", "5000"],
                                  ["calibrate", "--physical", "good.csv", "--workers", "5000", "--out", "c9"]])
def test_a_worker_count_beyond_the_declared_range_starts_no_process(workspace, monkeypatch, capsys, argv):
    """`--workers 5000` started 5000 interpreters (evaluator.workers is declared up to 1024; the flag was not
    held to it): refused before any process starts."""
    import concurrent.futures

    def no_pool(*args, **kwargs):
        raise AssertionError(f"a pool was started: {kwargs.get('max_workers')} workers")

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", no_pool)
    monkeypatch.chdir(workspace)
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert "worker processes must be in [1, 1024], got 5000" in error and len(error.strip().splitlines()) == 1


def _holds_1024_workers():
    from rollability_ros.core.sim import WORKER_RSS_MB, available_memory_mb

    available_mb = available_memory_mb()
    return available_mb is None or available_mb >= 1024 * WORKER_RSS_MB


@pytest.mark.skipif(_holds_1024_workers(), reason="this machine holds 1024 workers, or says nothing of its memory")
@pytest.mark.parametrize("argv", [["evaluate", "--baseline", "--trials", "1", "--workers", "1024"],
                                  ["calibrate", "--physical", "good.csv", "--workers", "1024", "--out", "c10"]])
def test_a_worker_count_beyond_the_available_memory_starts_no_process(workspace, monkeypatch, capsys, argv):
    """`--workers 1024` (in evaluator.workers' range) started 1024 interpreters of about 290 MB each, more than the
    machine's memory: refused before any process starts, in one line naming the count, the per-worker figure and
    where it comes from, and the memory available."""
    import concurrent.futures

    def no_pool(*args, **kwargs):
        raise AssertionError(f"a pool was started: {kwargs.get('max_workers')} workers")

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", no_pool)
    monkeypatch.chdir(workspace)
    before = tree_checksums(workspace)
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert "1024 worker processes need about 296960 MB (290 MB each: a trial worker's RSS plateau, " \
           "bench/bench_worker_memory.py), more than the " in error, error
    assert " MB available (MemAvailable, /proc/meminfo): use at most " in error and len(error.strip().splitlines()) == 1
    assert tree_checksums(workspace) == before


def test_the_memory_check_reads_memavailable_and_refuses_only_what_does_not_fit(tmp_path):
    """MemAvailable in MB from a meminfo file; none there (another system, an old kernel): nothing is refused."""
    from rollability_ros.core.sim import available_memory_mb, spawn_pool, worker_memory_refusal

    meminfo = tmp_path / "meminfo"
    meminfo.write_text("MemTotal:        4096000 kB\nMemFree:          100000 kB\nMemAvailable:     1024000 kB\n")
    assert available_memory_mb(str(meminfo)) == 1000.0
    with pytest.raises(ValueError, match="^4 worker processes need about 1160 MB"):
        spawn_pool(4, meminfo_path=str(meminfo))
    assert available_memory_mb(str(tmp_path / "absent")) is None
    meminfo.write_text("MemTotal:        4096000 kB\nMemFree:          100000 kB\n")
    assert available_memory_mb(str(meminfo)) is None
    assert worker_memory_refusal(3, 1000.0) == ""                       # 870 MB fit in 1000 MB
    assert worker_memory_refusal(4, 1000.0).endswith("more than the 1000 MB available (MemAvailable, /proc/meminfo): "
                                                     "use at most 3")
    assert worker_memory_refusal(1, 200.0).endswith("free memory first")
    assert worker_memory_refusal(1024, None) == ""                      # not known: not refused
