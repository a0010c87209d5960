"""`rollability bringup`: a node that dies is reported and restarted; Ctrl-C stops every node, the bag closes."""
import os
import re
import signal
import subprocess
import sys
import time

from test_study import _still_running

SMALL = """
/**:
  ros__parameters:
    bringup:
      evaluators: 1
      poll_period_s: 0.2
"""


def _read_until(process, pattern, lines, timeout_s=120):
    """Read bringup's output until a line matches ``pattern``; return the match."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if not line:
            break
        lines.append(line)
        match = re.search(pattern, line)
        if match:
            return match
    raise AssertionError(f"no line matching {pattern!r} in:\n{''.join(lines)}")


def _bringup(tmp_path):
    """Start `rollability bringup` (small config, session "lab") in its own session, output piped."""
    config = tmp_path / "small.yaml"
    config.write_text(SMALL)
    return subprocess.Popen([sys.executable, "-m", "rollability_ros.cli", "bringup", "--config", str(config),
                             "--session-id", "lab"], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True)


def test_a_killed_node_is_restarted_and_ctrl_c_stops_everything(tmp_path):
    from rollability_ros.core.bags.reader import bag_info

    process = _bringup(tmp_path)
    lines = []
    try:
        logger_pid = int(_read_until(process, r"\[outcome_logger\] started: pid (\d+)", lines).group(1))
        _read_until(process, r"\[optimizer\] started", lines)
        time.sleep(3)                                   # let the graph come up
        os.kill(logger_pid, signal.SIGKILL)
        _read_until(process, r"\[outcome_logger\] exited: exit code -9", lines)
        _read_until(process, r"\[outcome_logger\] restarted: attempt 1 of 3", lines)
        time.sleep(2)
        os.killpg(process.pid, signal.SIGINT)           # Ctrl-C
        output = "".join(lines) + process.communicate(timeout=180)[0]
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    assert process.returncode == 0, output
    session = tmp_path / "runs" / "lab"
    stopped = re.findall(r"\[(\S+)\] stopped: exit code (-?\d+)", output)
    assert [name for name, _ in stopped][-1] == "recorder" and len(stopped) == 6, output   # recorder last
    assert all(code == "0" for _, code in stopped), output
    assert not bag_info(session / "bag")["warnings"]
    assert not _still_running(output)


def test_killing_bringup_with_sigkill_stops_every_node_and_closes_the_bag(tmp_path):
    """kill -9 of the supervisor itself: the kernel sends each node SIGTERM (PR_SET_PDEATHSIG), so none is left
    running and the recorder closes its bag as on a clean stop."""
    from mcap.reader import make_reader

    from rollability_ros.core.bags.reader import bag_info
    from rollability_ros.core.bags.writer import RECOVERY_SIDECAR

    process = _bringup(tmp_path)
    lines = []
    try:
        _read_until(process, r"\[optimizer\] started", lines)
        time.sleep(3)                                   # let the graph come up
        process.kill()                                  # only the supervisor: the nodes run in their own sessions
        process.wait(timeout=30)
        output = "".join(lines)
        deadline = time.monotonic() + 60
        while _still_running(output) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not _still_running(output), output
    finally:
        if process.poll() is None:
            process.kill()
        for pid in _still_running("".join(lines)) if "started: pid" in "".join(lines) else ():
            os.kill(pid, signal.SIGKILL)
    bag = tmp_path / "runs" / "lab" / "bag"
    # closed, not abandoned: the recovery sidecar is gone and every file has its summary
    assert not (bag / RECOVERY_SIDECAR).exists(), os.listdir(bag)
    assert not bag_info(bag)["warnings"]
    for path in bag.glob("*.mcap"):
        with open(path, "rb") as stream:
            assert make_reader(stream).get_summary() is not None, path


LAB_RIG = """
/**:
  ros__parameters:
    valve:
      backend: serial_relay
"""


def test_the_graphs_own_overrides_win_over_a_file_that_repeats_them(tmp_path, start_process, ros_node):
    """A lab's file that repeats a parameter the graph overrides (here ``valve.backend``, also in the shipped
    rig.yaml) must not beat the override: in rcl a ``-p`` override lost to a parameter set in two files, so the
    overrides are a parameter file after all the others (core/graph/bringup.py)."""
    from rcl_interfaces.srv import GetParameters

    from rollability_ros.core.graph.bringup import NodeLaunch, parameter_files

    lab_rig = tmp_path / "lab_rig.yaml"
    lab_rig.write_text(LAB_RIG)
    node = NodeLaunch("valve_controller", namespace="/override_check", params={"valve.backend": "dry_run"})
    files = parameter_files([str(lab_rig)])
    args = node.ros_args(files, str(tmp_path))
    assert args[-2:] == ["--params-file", str(tmp_path / "node-params" / "valve_controller.yaml")]
    process = start_process("rollability_ros.nodes.valve_controller", *args)
    client = ros_node.node.create_client(GetParameters, "/override_check/valve_controller/get_parameters")
    assert ros_node.wait_for(lambda: client.service_is_ready(), timeout_s=60), process.log()
    future = client.call_async(GetParameters.Request(names=["valve.backend"]))
    assert ros_node.wait_for(future.done, timeout_s=30), process.log()
    assert future.result().values[0].string_value == "dry_run", process.log()
