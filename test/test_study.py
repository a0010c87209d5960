"""The main job end to end through the real node graph (a miniature configuration), and Ctrl-C in the middle."""
import os
import re
import signal
import subprocess
import sys
import time


from conftest import REPO_ROOT

MINI = str(REPO_ROOT / "test" / "resources" / "mini_study.yaml")


def _study(tmp_path, study_id=None):
    id_args = ["--study-id", study_id] if study_id else []
    return subprocess.Popen([sys.executable, "-m", "rollability_ros.cli", "study", "--config", MINI, *id_args],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)


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


def test_miniature_main_job_end_to_end(tmp_path):
    from rollability_ros.core import report
    from rollability_ros.core.bag_reader import BagReader
    from rollability_ros.core.store import Store

    process = _study(tmp_path, "e2e")
    output, _ = process.communicate(timeout=900)
    assert process.returncode == 0, output
    study_dir = tmp_path / "runs" / "e2e"
    for expected in ("report:", "bag (MCAP):", "outcome store:", "designs (STL, Table 3):"):
        assert expected in output
    assert "configuration  conditions ok" in output       # the summary table

    designs = study_dir / "optimisation" / "designs"
    assert (designs / "table3.csv").is_file() and list(designs.glob("*.stl"))
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
    from rollability_ros.core.bag_reader import bag_info

    process = _study(tmp_path)                      # a generated study id: study-<UTC date>-<time>
    first_line = process.stdout.readline()
    assert first_line.startswith("study study-") and "results in runs/" in first_line, first_line
    study_dir = tmp_path / first_line.split("results in ")[1].strip()
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and not (study_dir / "optimisation" / "store.sqlite").exists():
        time.sleep(0.2)
    assert process.poll() is None, process.communicate()[0]
    os.killpg(process.pid, signal.SIGINT)           # what a terminal's Ctrl-C does
    output = first_line + process.communicate(timeout=180)[0]
    assert process.returncode == 1 and "stopped by the operator" in output, output
    assert "[recorder] stopped: exit code 0" in output
    info = bag_info(study_dir / "bag")
    assert not info["warnings"], info["warnings"]
    assert not _still_running(output)
