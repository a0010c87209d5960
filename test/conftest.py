"""Test isolation shared by every test: each pytest run gets its own ROS domain and localhost-only discovery.

The domain id is taken with an exclusive lock on a file in the temp directory, so two test runs on one machine
(two checkouts, CI beside a developer) never share a domain, and nodes started by the tests inherit it.
"""
import atexit
import os
import pathlib
import shutil
import tempfile

import pytest

from rollability_ros.core.graph import claim_domain

REPO_ROOT = pathlib.Path(__file__).resolve().parents[1]


# 20..100: clear of the default 0 and of the benches (101..200); the lock is held for the life of this pytest process
_DOMAIN, _DOMAIN_LOCK = claim_domain(20, 100, start=20 + os.getpid() % 80)
os.environ["ROS_DOMAIN_ID"] = str(_DOMAIN)
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.pop("ROS_STATIC_PEERS", None)
os.environ.pop("ROS_LOCALHOST_ONLY", None)
# valve session keys (rollability_ros.core.rig.valve_auth) go to a private folder of this test run, not the user's
os.environ["XDG_RUNTIME_DIR"] = tempfile.mkdtemp(prefix="rollability-test-run-")
atexit.register(shutil.rmtree, os.environ["XDG_RUNTIME_DIR"], True)
# ROS logs of the nodes and of this process go there too: not into the caller's ~/.ros, which may not be writable
os.environ["ROS_LOG_DIR"] = os.path.join(os.environ["XDG_RUNTIME_DIR"], "ros-log")
# subprocesses (nodes, peers) import this checkout's sources, whatever their working directory
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO_ROOT), os.environ.get("PYTHONPATH", "")]))



def _ram_temp_root(path="/dev/shm", room_bytes=4 * 2**30):
    """``path`` when it is a writable folder with ``room_bytes`` free (Linux's RAM file system), else None.

    pytest's tmp_path folders go there: the store commits (fsyncs) every record and a checkpoint every generation,
    and on this project's 2-core VM's disk an fsync took about 6 ms: a 30-generation optimisation run on a store
    took 3.5 s of wall time on disk and 0.3 s in RAM, with the same records written. Nothing else changes: the
    files, their contents and the processes that write them are the same, and a kill -9 of a writer still loses
    what it had not committed. Where there is no such folder or too little room (a container's 64 MB /dev/shm),
    the system's temporary folder is used as before. Only pytest's folders move: ROS domain locks, ROS logs and
    what child processes put in their own temporary files stay in the system's (``TMPDIR`` is left alone)."""
    try:
        stat = os.statvfs(path)
    except OSError:
        return None
    if stat.f_bavail * stat.f_frsize < room_bytes or not os.access(path, os.W_OK | os.X_OK):
        return None
    return path


if "PYTEST_DEBUG_TEMPROOT" not in os.environ and _ram_temp_root():   # pytest's own seam for its temporary root
    os.environ["PYTEST_DEBUG_TEMPROOT"] = _ram_temp_root()

pytest_plugins = ["ros_fixtures", "rerun_summary", "smoke_early"]


def pid_running(pid):
    """True while process ``pid`` exists and has not exited (a zombie has exited, it only awaits reaping)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as stream:
            return stream.read().rsplit(")", 1)[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def pytest_collection_modifyitems(config, items):
    """No automatic rerun: a rerun that passes hides a race (the valve's byte-by-byte serial read was hidden that way
    until it failed 3 of 3 times), so a test that needs one gets its race fixed instead. A ``flaky`` mark is refused
    here; ``--reruns N`` on the command line still works for a local investigation, and every run ends with the
    count of reruns (test/rerun_summary.py)."""
    marked = [item.nodeid for item in items if item.get_closest_marker("flaky") is not None]
    if marked:
        raise pytest.UsageError("tests marked flaky (automatic reruns are not used here, docs/testing.md): "
                                + ", ".join(marked))
