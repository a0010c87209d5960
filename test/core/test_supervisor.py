"""The process supervisor: order, restart on death, give up and stop everything, stop in reverse order."""
import os
import signal
import subprocess
import sys
import time

from conftest import pid_running
from rollability_ros.core.graph.supervisor import ProcessSpec, Supervisor

# A child that logs its start and its SIGINT, then exits 0 on SIGINT (like a node) unless told to ignore it.
CHILD = """
import signal, sys, time
name, mode = sys.argv[1], sys.argv[2]
print("start", name, flush=True)
def on_int(*_):
    print("sigint", name, time.monotonic(), flush=True)
    if mode != "stubborn":
        sys.exit(0)
signal.signal(signal.SIGINT, on_int)
if mode == "crash":
    time.sleep(0.2); sys.exit(3)
if mode == "refuse":
    print("error: no outcome_logger serves stored_trials within 30 s", file=sys.stderr, flush=True); sys.exit(2)
while True:
    time.sleep(0.05)
"""


def _spec(tmp_path, name, mode="run", **kwargs):
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    kwargs.setdefault("stop_timeout_s", 2.0)
    return ProcessSpec(name=name, argv=[sys.executable, str(script), name, mode], **kwargs)


def _events(collected):
    return [(event.kind, event.name) for event in collected]


def _log(supervisor, name):
    return open(os.path.join(supervisor.log_dir, f"{name}.log")).read()


def test_stops_in_reverse_order(tmp_path):
    events = []
    sup = Supervisor([_spec(tmp_path, "recorder"), _spec(tmp_path, "rig")], str(tmp_path / "logs"), events.append)
    sup.start()
    time.sleep(0.5)
    assert sup.poll()
    sup.stop()
    assert _events(events)[-4:] == [("stopping", "rig"), ("stopped", "rig"), ("stopping", "recorder"),
                                    ("stopped", "recorder")]
    rig_stop = float(_log(sup, "rig").split("sigint rig")[1].split()[0])
    recorder_stop = float(_log(sup, "recorder").split("sigint recorder")[1].split()[0])
    assert rig_stop < recorder_stop


def test_restarts_then_gives_up_and_stops_the_graph(tmp_path):
    events = []
    sup = Supervisor([_spec(tmp_path, "steady"), _spec(tmp_path, "flaky", "crash", max_restarts=2)],
                     str(tmp_path / "logs"), events.append)
    sup.start()
    deadline = time.monotonic() + 20
    while sup.poll() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert ("restarted", "flaky") in _events(events)
    assert sum(1 for kind, name in _events(events) if kind == "restarted") == 2
    assert ("gave_up", "flaky") in _events(events) and "flaky exited with code 3" in sup.failed
    assert "exit code 3" in [e.detail for e in events if e.kind == "exited"][0]
    sup.stop()
    assert sup.child("steady").returncode == 0        # the healthy node was stopped cleanly, not left alive


def test_a_failed_exit_says_the_node_s_last_line(tmp_path):
    """``rollability study``'s "did not complete" line names why the node exited, not only its code."""
    sup = Supervisor([_spec(tmp_path, "campaign_runner", "refuse")], str(tmp_path / "logs"), lambda event: None)
    sup.start()
    code, reason = sup.wait_for_exit("campaign_runner", timeout_s=20)
    sup.stop()
    assert code == 2
    expected = "campaign_runner exited with code 2: error: no outcome_logger serves stored_trials within 30 s"
    assert reason.startswith(expected), reason
    assert reason.endswith("campaign_runner.log)"), reason


def test_a_stubborn_child_is_killed(tmp_path):
    sup = Supervisor([_spec(tmp_path, "stubborn", "stubborn", stop_timeout_s=0.5)], str(tmp_path / "logs"),
                     lambda event: None)
    sup.start()
    time.sleep(0.5)
    sup.stop()
    assert sup.child("stubborn").returncode in (-signal.SIGTERM, -signal.SIGKILL)


def test_a_finished_job_is_not_a_failure(tmp_path):
    script = tmp_path / "job.py"
    script.write_text("print('done')\n")
    sup = Supervisor([_spec(tmp_path, "node"), ProcessSpec("job", [sys.executable, str(script)])],
                     str(tmp_path / "logs"), lambda event: None)
    sup.start()
    ticks = []
    assert sup.wait_for_exit("job", timeout_s=20, on_tick=lambda: ticks.append(1)) == (0, "")
    assert sup.poll() and sup.failed == ""
    sup.stop()


SUPERVISOR = """
import sys, time
from rollability_ros.core.graph.supervisor import ProcessSpec, Supervisor
script, log_dir = sys.argv[1], sys.argv[2]
supervisor = Supervisor([ProcessSpec(name=n, argv=[sys.executable, script, n, "run"]) for n in ("a", "b")], log_dir,
                        on_event=lambda event: None)
supervisor.start()
print(" ".join(str(supervisor.child(n).pid) for n in ("a", "b")), flush=True)
while supervisor.poll():
    time.sleep(0.1)
"""


def test_children_get_sigterm_when_the_supervisor_is_killed(tmp_path):
    """kill -9 of `rollability bringup` / `study` leaves no node running: the kernel tells each child."""
    _spec(tmp_path, "unused")                                        # writes the child script
    parent = subprocess.Popen([sys.executable, "-c", SUPERVISOR, str(tmp_path / "child.py"), str(tmp_path / "logs")],
                              stdout=subprocess.PIPE, text=True)
    try:
        pids = [int(pid) for pid in parent.stdout.readline().split()]
    finally:
        parent.kill()
        parent.wait()
    deadline = time.monotonic() + 20
    while any(pid_running(pid) for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(pid_running(pid) for pid in pids), f"children outlived their supervisor: {pids}"

