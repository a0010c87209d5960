"""Fixtures for tests over real DDS: an in-test rclpy node spun in a thread, and node processes."""
import os
import signal
import subprocess
import sys
import threading
import time
import traceback

import pytest


def transitions_qos():
    """A reader's profile for a latched state topic whose every transition a test checks.

    It matches the latched writer (reliable, transient-local) but keeps a history of 100: a reader with the
    writer's own history of 1 keeps only the newest sample its executor has not taken yet, so a test process busy
    elsewhere (publishing an IMU stream, waiting in a service call) can miss a short-lived state (docs/testing.md,
    fresh-clone run 38).
    """
    from rclpy.qos import QoSProfile

    from rollability_ros.nodes._support import LATCHED_QOS

    return QoSProfile(depth=100, reliability=LATCHED_QOS.reliability, durability=LATCHED_QOS.durability,
                      history=LATCHED_QOS.history)


class SpunNode:
    """An rclpy node in its own context, spun by a background executor thread."""

    def __init__(self, name):
        import rclpy
        from rclpy.executors import MultiThreadedExecutor

        self.context = rclpy.Context()
        rclpy.init(context=self.context, args=[])
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = MultiThreadedExecutor(num_threads=2, context=self.context)
        self.error = None
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        import rclpy

        try:
            self.executor.spin()
        except Exception as exc:
            if rclpy.ok(context=self.context):   # not a shutdown race: a test callback failed; say so loudly
                traceback.print_exc()
                self.error = exc

    def wait_for(self, predicate, timeout_s=30.0, period_s=0.05):
        """Poll ``predicate()`` until true or ``timeout_s``; returns its last value."""
        deadline = time.monotonic() + timeout_s
        value = predicate()
        while not value and time.monotonic() < deadline:
            if self.error is not None:
                raise AssertionError(f"the test node's executor stopped: {self.error!r}") from self.error
            time.sleep(period_s)
            value = predicate()
        return value

    def close(self):
        import rclpy

        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self._thread.join(timeout=5)


class NodeProcess:
    """A node (``python -m rollability_ros.nodes.<module>``) or any Python module run as a separate process."""

    def __init__(self, argv, log_path, env=None, cwd=None):
        self.log_path = log_path
        self._log = open(log_path, "wb")
        self.process = subprocess.Popen(argv, stdout=self._log, stderr=subprocess.STDOUT,
                                        env=env or os.environ.copy(), start_new_session=True, cwd=cwd)
        self._interrupted = False

    def log(self):
        if not self._log.closed:   # stop() closes it; the file stays readable
            self._log.flush()
        with open(self.log_path, encoding="utf-8", errors="replace") as stream:
            return stream.read()

    def alive(self):
        return self.process.poll() is None

    def signal(self, signum):
        if self.alive():
            os.killpg(self.process.pid, signum)

    def interrupt(self):
        """SIGINT, once: a second one would interrupt the node's own shutdown."""
        if self.alive() and not self._interrupted:
            self.signal(signal.SIGINT)
            self._interrupted = True

    def stop(self, timeout_s=15.0):
        """SIGINT (unless :meth:`interrupt` sent it), then SIGKILL after ``timeout_s``; returns the exit code."""
        if self.alive():
            self.interrupt()
            try:
                self.process.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                self.signal(signal.SIGUSR1)    # a node prints every thread's stack first (what it hangs in)
                try:
                    self.process.wait(timeout=2)
                except subprocess.TimeoutExpired:
                    pass
                self.signal(signal.SIGKILL)
                self.process.wait()
        self._log.close()
        return self.process.returncode


@pytest.fixture
def ros_node(request):
    """An rclpy node spun in the background of the test process."""
    spun = SpunNode("test_" + request.node.name.replace("[", "_").replace("]", "").replace("-", "_")[:40])
    yield spun
    spun.close()


@pytest.fixture
def start_process(tmp_path):
    """``start_process(module, *args, name=..., cwd=...)`` starts ``python -m module args...``; all stopped at
    teardown."""
    started = []

    def start(module, *args, name=None, env=None, cwd=None):
        name = name or module.rsplit(".", 1)[-1]
        handle = NodeProcess([sys.executable, "-m", module, *args], tmp_path / f"{name}-{len(started)}.log", env,
                             cwd)
        started.append(handle)
        return handle

    yield start
    for handle in reversed(started):   # every process shuts down at once, then each is waited for
        handle.interrupt()
    for handle in reversed(started):
        handle.stop()


@pytest.fixture
def start_node(start_process):
    """``start_node(node_module, params={...}, ros_args=[...], cwd=...)`` runs ``rollability_ros.nodes.<node_module>``."""

    def start(node_module, params=None, ros_args=(), name=None, env=None, cwd=None):
        args = ["--ros-args"]
        for key, value in (params or {}).items():
            if isinstance(value, bool):
                value = "true" if value else "false"
            elif isinstance(value, (list, tuple)):
                value = "[" + ",".join(str(v) for v in value) + "]"
            args += ["-p", f"{key}:={value}"]
        args += list(ros_args)
        return start_process(f"rollability_ros.nodes.{node_module}", *args, name=name or node_module, env=env,
                             cwd=cwd)

    return start
