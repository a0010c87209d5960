"""How a node process stops when something inside it hangs (nodes/_support.run_node)."""
import signal
import subprocess
import sys
import textwrap
import time

import pytest

pytest.importorskip("rclpy")

# A node whose close() blocks in a C call that holds the GIL (ctypes.PyDLL never releases it), as a middleware call
# that never returns would: no Python thread can run, so only a C-level watchdog can end the process.
_STUCK_NODE = textwrap.dedent("""
    import ctypes, sys
    from rclpy.node import Node
    from rollability_ros.nodes import _support

    _support.SHUTDOWN_GRACE_S = float(sys.argv[1])
    _support.HARD_DEADLINE_EXTRA_S = float(sys.argv[2])

    class Stuck(Node):
        def __init__(self):
            super().__init__("stuck_on_close")
            print("ready", flush=True)

        def close(self):
            ctypes.PyDLL(None).sleep(600)

    sys.exit(_support.run_node(Stuck))
""")


def _start(tmp_path, *args):
    log = tmp_path / "node.log"
    stream = open(log, "wb")
    process = subprocess.Popen([sys.executable, "-c", _STUCK_NODE, *map(str, args)], stdout=stream,
                               stderr=subprocess.STDOUT, start_new_session=True)
    deadline = time.monotonic() + 60
    while "ready" not in log.read_text(errors="replace"):
        assert process.poll() is None and time.monotonic() < deadline, log.read_text(errors="replace")
        time.sleep(0.05)
    return process, log


def test_a_node_stuck_in_a_call_that_holds_the_gil_still_exits_after_its_grace_period(tmp_path):
    process, log = _start(tmp_path, 0.5, 1.0)
    try:
        process.send_signal(signal.SIGINT)
        code = process.wait(timeout=30)       # the watchdog ends it 1.5 s after the signal; SIGKILL is not needed
    finally:
        if process.poll() is None:
            process.kill()
    text = log.read_text(errors="replace")
    assert code == 1, text
    assert "Timeout" in text and "in close" in text, text   # every thread's stack says where it hung


def test_sigusr1_prints_every_threads_stack_and_the_node_runs_on(tmp_path):
    process, log = _start(tmp_path, 25, 5)
    try:
        process.send_signal(signal.SIGUSR1)
        deadline = time.monotonic() + 30
        while "in run_node" not in log.read_text(errors="replace") and time.monotonic() < deadline:
            time.sleep(0.05)
        text = log.read_text(errors="replace")
        assert "most recent call first" in text and "in run_node" in text, text   # the main thread's stack too
        time.sleep(0.5)
        assert process.poll() is None, text
    finally:
        process.kill()
        process.wait()


def _catches_sigint(pid):
    """True once process ``pid`` has its own SIGINT handler (``SigCgt`` in /proc/<pid>/status)."""
    with open(f"/proc/{pid}/status") as stream:
        masks = dict(line.split(":", 1) for line in stream if line.startswith(("SigCgt", "SigIgn")))
    bit = 1 << (signal.SIGINT - 1)
    return bool(int(masks["SigCgt"], 16) & bit) and not int(masks["SigIgn"], 16) & bit


@pytest.mark.parametrize("module", ["campaign_runner", "outcome_logger"])
def test_sigint_stops_a_node_started_with_sigint_ignored(tmp_path, module):
    """A script's background job (`cmd &` without job control, nohup) starts with SIGINT ignored, and Python keeps
    it ignored: every node sets its own stop handlers, so the supervisor's or launch's SIGINT still stops it."""
    args = {"campaign_runner": ["-p", "runner.server_timeout_s:=600.0", "-r", "stored_trials:=/nowhere/stored_trials"],
            "outcome_logger": ["-p", f"store_path:={tmp_path / 'store.sqlite'}"]}[module]
    log = tmp_path / "node.log"
    with open(log, "wb") as stream:
        process = subprocess.Popen([sys.executable, "-m", f"rollability_ros.nodes.{module}", "--ros-args", *args],
                                   stdout=stream, stderr=subprocess.STDOUT, start_new_session=True,
                                   preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        deadline = time.monotonic() + 30
        while process.poll() is None and not _catches_sigint(process.pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert process.poll() is None, log.read_text(errors="replace")
        assert _catches_sigint(process.pid), f"{module} left SIGINT ignored"
        process.send_signal(signal.SIGINT)
        process.wait(timeout=10)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    text = log.read_text(errors="replace")
    # a stop by SIGINT may also be reported as death by SIGINT (-2: CPython exits so once a KeyboardInterrupt went
    # unhandled anywhere, even in a nested call, whoever caught it later); the node's stop line shows that it stopped
    # itself cleanly, which is what this test is about (without it, it was killed by the signal's default action)
    if process.returncode == -signal.SIGINT:
        assert module == "campaign_runner" and "stopped by a stop signal" in text, (process.returncode, text)
    else:
        assert process.returncode in (0, 130), (process.returncode, text)


def test_an_executor_is_shut_down_only_after_its_spinning_thread_left_it():
    """rclpy (Jazzy) ``Executor.shutdown`` destroys the executor's guard condition at once, also under a thread that
    is building a wait set from it (CI: ``'NoneType' object has no attribute 'handle'`` at a node's SIGINT). The
    executor thread of every node and console is therefore stopped first and the executor shut down after."""
    import threading

    import rclpy
    from rclpy.context import Context
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.node import Node

    from rollability_ros.nodes._support import ExecutorThread

    context = Context()
    rclpy.init(context=context)
    try:
        node = Node("executor_thread_probe", context=context, start_parameter_services=False)
        ticks = []
        node.create_timer(0.001, lambda: ticks.append(1))
        for _ in range(20):
            executor = MultiThreadedExecutor(num_threads=2, context=context)
            executor.add_node(node)
            spinner = ExecutorThread(executor, name="probe").start()
            shut_down_while_spinning = []
            original = executor.shutdown

            def shutdown(*args, _original=original, _spinner=spinner, **kwargs):
                shut_down_while_spinning.append(any(t.name == "probe" and t.is_alive() for t in threading.enumerate()))
                return _original(*args, **kwargs)

            executor.shutdown = shutdown
            time.sleep(0.005)
            spinner.stop()
            assert spinner.stopped.is_set() and shut_down_while_spinning == [False]
            assert spinner.failures == []
        assert ticks, "the timer never ran: the executor thread did not spin"
        node.destroy_node()
    finally:
        context.try_shutdown()
