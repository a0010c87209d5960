"""pytest plugin (loaded by test/conftest.py): the bench smoke starts when collection ends, beside the other tests.

``test_bench_smoke.py::test_every_smoke_bench_runs_at_its_tiny_size`` runs bench/smoke.py (every bench of ``SMOKE``
at its tiny size) in a process of its own and checks what it printed. That process shares nothing with the tests
but the machine, and it is about two minutes of one core, while the core tests that pytest runs first (test/core,
single-threaded) leave the second core of a two-core machine mostly idle. So when the run selected that test
(and others beside it), the smoke process starts here, right after collection, and the test, moved to the end of
the run, only waits for its result: the same benches, the same checks, the wall time hidden behind the other
tests'. Run alone (or when the run collected nothing else), the test starts it itself. A run that stops early
(``-x``, Ctrl-C) stops it too.
"""
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import tempfile
import typing

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: The test whose smoke run starts early.
EARLY_TEST = "test_every_smoke_bench_runs_at_its_tiny_size"


def repo_files() -> typing.Dict[str, typing.Tuple[int, int]]:
    """``{path: (size, mtime ns)}`` of the checkout's files (hidden folders, caches and build trees left out)."""
    files = {}
    for folder, folders, names in os.walk(ROOT):
        folders[:] = [f for f in folders if not f.startswith(".") and f not in ("__pycache__", "build", "install",
                                                                                 "log")]
        for name in names:
            path = pathlib.Path(folder, name)
            stat = path.stat()
            files[str(path.relative_to(ROOT))] = (stat.st_size, stat.st_mtime_ns)
    return files


class SmokeRun:
    """bench/smoke.py with ``args``, started now in a fresh directory (a bench's default output folder lands there,
    not in the repo), its output in a file (a pipe nobody reads would fill and stop it)."""

    def __init__(self, *args: str, pythonpath: str = str(ROOT)) -> None:
        self.args = args
        self.before = repo_files()
        self.cwd = tempfile.mkdtemp(prefix="bench-smoke-")
        env = dict(os.environ, PYTHONPATH=pythonpath, LC_ALL="C.UTF-8", PYTHONUNBUFFERED="1", MPLBACKEND="Agg")
        self._out = open(os.path.join(self.cwd, "stdout"), "w+", encoding="utf-8")
        self._err = open(os.path.join(self.cwd, "stderr"), "w+", encoding="utf-8")
        self.process = subprocess.Popen([sys.executable, str(ROOT / "bench" / "smoke.py"), *args], stdout=self._out,
                                        stderr=self._err, env=env, cwd=self.cwd, start_new_session=True)

    def wait(self, timeout_s: float) -> subprocess.CompletedProcess:
        """Its exit code and output once it ended (killed, and the expiry raised, after ``timeout_s``)."""
        try:
            self.process.wait(timeout=timeout_s)
        finally:
            self.stop()
        outputs = []
        for stream in (self._out, self._err):
            stream.seek(0)
            outputs.append(stream.read())
            stream.close()
        shutil.rmtree(self.cwd, ignore_errors=True)
        return subprocess.CompletedProcess(self.process.args, self.process.returncode, *outputs)

    def stop(self) -> None:
        """Ends the run and every process it started (its session), if it is still going."""
        if self.process.poll() is None:
            try:
                os.killpg(self.process.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self.process.wait()


_early: typing.Dict[typing.Tuple[str, ...], SmokeRun] = {}


def smoke_run(*args: str) -> SmokeRun:
    """The run of bench/smoke.py with ``args`` started early for this pytest run, or a new one."""
    return _early.pop(args, None) or SmokeRun(*args)


def _distributed(config) -> bool:
    """True in a pytest-xdist worker: every worker collects every test, and the scheduler hands them out."""
    return hasattr(config, "workerinput")


def pytest_collection_modifyitems(config, items):
    """The test that waits for the early run goes last: the benches then run beside every other test (the ROS
    graph tests after test/core leave a core idle too), not only beside test/core, whose end they used to outlast
    by about two minutes of waiting. The order of the other tests is unchanged. Under pytest-xdist (``-n``) it goes
    first instead and starts the run itself: the first worker takes it while the others take the rest (every worker
    collects every test, so an early start here would run the benches once per worker)."""
    early = [item for item in items if item.name == EARLY_TEST]
    if early and len(items) > 1:
        rest = [item for item in items if item.name != EARLY_TEST]
        items[:] = early + rest if _distributed(config) else rest + early


def pytest_collection_finish(session):
    if session.config.option.collectonly or _distributed(session.config):
        return
    if len(session.items) > 1 and any(item.name == EARLY_TEST for item in session.items):
        _early[()] = SmokeRun()


def pytest_unconfigure(config):
    for run in _early.values():
        run.stop()
        shutil.rmtree(run.cwd, ignore_errors=True)
    _early.clear()
