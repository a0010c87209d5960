"""The main job end to end through the real node graph (a miniature configuration), and Ctrl-C in the middle."""
import os
import re
import signal
import subprocess
import sys
import time

import pytest
from conftest import REPO_ROOT

MINI = str(REPO_ROOT / "test" / "resources" / "mini_study.yaml")


#: Every study process a test started; none outlives its test (see :func:`_no_study_outlives_its_test`).
_STARTED = []


@pytest.fixture(autouse=True)
def _no_study_outlives_its_test():
    """A test that fails mid-way must not leave its study running: the study would go on into its campaign beside
    the next tests, on the same ROS domain and key folder (a failed killed-twice test once left one whose valve
    wrote the key the operator CLI test then read). SIGKILL of the study's process group; its nodes stop by
    themselves once their supervisor is gone, as the tests here check."""
    yield
    while _STARTED:
        process = _STARTED.pop()
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout=30)


def _study(tmp_path, study_id=None):
    id_args = ["--study-id", study_id] if study_id else []
    process = subprocess.Popen([sys.executable, "-m", "rollability_ros.cli", "study", "--config", MINI, *id_args],
                               cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                               start_new_session=True)
    _STARTED.append(process)
    return process


def _still_running(output):
    """The pids the supervisor reported starting (``[name] started: pid N``) that are still running."""
    pids = [int(pid) for pid in re.findall(r"\] started: pid (\d+)", output)]
    assert pids, output
    running = []
    for pid in pids:
        try:
            with open(f"/proc/{pid}/stat") as stream:
                zombie = stream.read().split(") ")[1][0] == "Z"     # exited, not yet reaped
            with open(f"/proc/{pid}/cmdline", "rb") as stream:
                ours = b"rollability_ros.nodes" in stream.read()    # not a reused pid
        except OSError:
            continue
        if ours and not zombie:
            running.append(pid)
    return running


@pytest.mark.slow   # about 40 s; the README's command starts the same graph in the Ctrl-C test below
def test_miniature_main_job_end_to_end(tmp_path):
    from rollability_ros.core.results import report
    from rollability_ros.core.bags.reader import BagReader
    from rollability_ros.core.store import Store

    process = _study(tmp_path, "e2e")
    output, _ = process.communicate(timeout=900)
    assert process.returncode == 0, output
    study_dir = tmp_path / "runs" / "e2e"
    for expected in ("report:", "bag (MCAP):", "outcome store:", "designs (STL, Table 3):"):
        assert expected in output
    assert "configuration  conditions ok" in output       # the summary table
    assert "gain of each chosen design over the bare robot (simulated; fresh robust launches" in output
    # progress learnt over ROS (optimizer_progress, the logger's get_summary), never from the stores
    assert "optimizing | generation 2/2 | best " in output and " simulated trials evaluated | " in output
    assert "launch campaign (simulated rig) | " in output and "progress unavailable" not in output
    assert "trials upright minus the baseline's (Newcombe 95%)" in output

    designs = study_dir / "optimization" / "designs"
    assert (designs / "table3.csv").is_file() and list(designs.glob("*.stl"))
    # the selection's world check ran over the evaluators (fidelity world:<seed>) and the summary leads with it
    assert (designs / "selection_world_check.csv").is_file() and "RECOMMENDATION: " in output
    assert "<h2 id='recommendation'>" in (study_dir / "report" / "report.html").read_text()
    with Store(study_dir / "outcomes.sqlite") as store:
        outcomes = store.launch_outcomes("e2e")
        candidates = store.candidates()
    configurations = {o.condition.configuration for o in outcomes}
    assert "baseline" in configurations and len(configurations) >= 2
    assert len(outcomes) == 2 * len(configurations)           # 1 height x 1 speed x 2 angles x 1 repetition
    assert {o.backend for o in outcomes} == {"sim"} and len(candidates) == 10   # 2 generations x (4 + 1)

    html = (study_dir / "report" / "report.html").read_text()
    assert html.count("data:image/png;base64,") >= 3
    # the bag is a closed rosbag2 directory holding the same outcomes, and it replays into the same report
    topics = {message.topic for message in BagReader(study_dir / "bag")}
    assert {"/rollability/launch_outcomes", "/rollability/candidates", "/rollability/generations"} <= topics
    from_bag = report.load_report_data(study_dir / "bag", run_id="e2e")
    from_store = report.load_report_data(study_dir / "outcomes.sqlite", run_id="e2e")
    assert sorted(from_bag.outcomes, key=lambda o: o.trial_id) == sorted(from_store.outcomes, key=lambda o: o.trial_id)
    assert not _still_running(output)


def test_ctrl_c_stops_every_node_and_closes_the_bag(tmp_path):
    from rollability_ros.core.bags.reader import bag_info

    process = _study(tmp_path)                      # a generated study id: study-<UTC date>-<time>
    first_line = process.stdout.readline()
    assert first_line.startswith("study study-") and "results in runs/" in first_line, first_line
    study_dir = tmp_path / first_line.split("results in ")[1].strip()
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and not (study_dir / "optimization" / "store.sqlite").exists():
        time.sleep(0.2)
    assert process.poll() is None, process.communicate()[0]
    os.killpg(process.pid, signal.SIGINT)           # what a terminal's Ctrl-C does
    output = first_line + process.communicate(timeout=180)[0]
    assert process.returncode == 1 and "stopped by the operator" in output, output
    assert "[recorder] stopped: exit code 0" in output
    info = bag_info(study_dir / "bag")
    assert not info["warnings"], info["warnings"]
    assert not _still_running(output)


RESUMABLE = """
/**:
  ros__parameters:
    optimizer:
      max_generations: 8
    campaign:
      repetitions: 5
"""


def _study_to_file(tmp_path, log_name, *args):
    """Start ``rollability study ARGS`` with its output in ``tmp_path/log_name``; return (process, log path)."""
    log = tmp_path / log_name
    with open(log, "w") as stream:
        process = subprocess.Popen([sys.executable, "-m", "rollability_ros.cli", "study", *args], cwd=tmp_path,
                                   stdout=stream, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    _STARTED.append(process)
    return process, log


def _kill_when(process, log, ready, what):
    """SIGKILL the study process (only it: its nodes must stop by themselves) once ``ready()``; wait for them."""
    deadline = time.monotonic() + 300
    while not ready():
        assert process.poll() is None and time.monotonic() < deadline, f"no {what}:\n{log.read_text()}"
        time.sleep(0.05)
    process.kill()
    process.wait(timeout=30)
    deadline = time.monotonic() + 60
    while _still_running(log.read_text()) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not _still_running(log.read_text()), log.read_text()


@pytest.mark.slow
def test_a_study_killed_twice_resumes_to_the_same_complete_result(tmp_path):
    """kill -9 mid-optimization, resume, kill -9 mid-campaign, resume: every trial once, every bag readable."""
    from rollability_ros.core.results import report
    from rollability_ros.core.bags.reader import bag_info
    from rollability_ros.core.bags.messages import read_records_from_bag
    from rollability_ros.core.store import Store

    config = tmp_path / "resumable.yaml"
    config.write_text(RESUMABLE)
    study_dir = tmp_path / "runs" / "killed"
    designs = study_dir / "optimization" / "designs" / "designs.yaml"

    def generations():
        path = study_dir / "optimization" / "store.sqlite"
        if not path.exists():
            return 0
        with Store(path) as store:
            return len(store.generations())

    def trials():
        path = study_dir / "outcomes.sqlite"
        if not path.exists():
            return 0
        with Store(path) as store:
            return len(store.trial_ids("killed"))

    process, log = _study_to_file(tmp_path, "first.log", "--config", MINI, "--config", str(config),
                                  "--study-id", "killed")
    _kill_when(process, log, lambda: generations() >= 1, "generation")
    assert not designs.exists() and generations() < 8, log.read_text()

    process, log = _study_to_file(tmp_path, "second.log", "--resume", "killed")
    _kill_when(process, log, lambda: trials() >= 1, "stored trial")
    output = log.read_text()
    assert "resuming the optimization from its last checkpoint" in output and designs.exists(), output
    assert 1 <= trials() < 30, output

    process, log = _study_to_file(tmp_path, "third.log", "--resume", str(study_dir))
    assert process.wait(timeout=600) == 0, log.read_text()
    output = log.read_text()
    assert "finished before: continuing with the campaign" in output, output
    assert not _still_running(output)

    with Store(study_dir / "outcomes.sqlite") as store:
        outcomes = store.launch_outcomes("killed")
    with Store(study_dir / "optimization" / "store.sqlite") as store:
        candidates = store.candidates()
        assert [g.generation for g in store.generations()] == list(range(1, 9))
    # the bare robot and every selected design (the selection may keep fewer than it is asked for: diversity and
    # printability), x 2 angles x 5 repetitions, each launched exactly once over the three runs
    from rollability_ros.core import safe_yaml
    labels = safe_yaml.load(designs.read_text())["/**"]["ros__parameters"]["designs"]["labels"]
    assert 1 <= len(labels) <= 2
    assert len(outcomes) == len({o.trial_id for o in outcomes}) == (1 + len(labels)) * 2 * 5
    assert len(candidates) == len({(c.generation, c.index) for c in candidates}) == 8 * 5
    bags = sorted(p.name for p in study_dir.glob("bag*"))
    assert bags == ["bag", "bag-2", "bag-3"], bags
    bagged = {o.trial_id for name in bags for o in read_records_from_bag(study_dir / name)[0] if o.run_id == "killed"}
    assert bagged == {o.trial_id for o in outcomes}
    assert all(not bag_info(study_dir / name)["warnings"] for name in bags)
    assert report.load_report_data(study_dir / "outcomes.sqlite", run_id="killed").outcomes
    assert (study_dir / "report" / "report.html").is_file()

    process, log = _study_to_file(tmp_path, "bad.log", "--resume", "nothing-here")
    assert process.wait(timeout=60) != 0 and "no study to resume" in log.read_text(), log.read_text()
