"""The bench scripts run against the package as it is: bench/smoke.py runs each bench with a ``--smoke`` size once
(tiny inputs, every step; the numbers mean nothing), in one process, and fails naming a bench that raised or
returned non-zero. mypy checks every bench script too (test/core/test_mypy.py)."""
import os
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench import smoke  # noqa: E402


def _smoke(*names, pythonpath=str(ROOT)):
    """Runs bench/smoke.py in a fresh directory: a bench's default output folder lands there, not in the repo."""
    env = dict(os.environ, PYTHONPATH=pythonpath, LC_ALL="C.UTF-8", PYTHONUNBUFFERED="1", MPLBACKEND="Agg")
    with tempfile.TemporaryDirectory(prefix="bench-smoke-") as cwd:
        return subprocess.run([sys.executable, str(ROOT / "bench" / "smoke.py"), *names], capture_output=True,
                              text=True, timeout=300, env=env, cwd=cwd)


def test_every_smoke_bench_runs_at_its_tiny_size():
    result = _smoke()
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    for name in smoke.SMOKE:
        assert f"smoke {name}: ok" in result.stdout, result.stdout
    assert f"smoke: {len(smoke.SMOKE)} benches ran" in result.stdout


def test_every_smoke_bench_takes_the_option():
    """A bench in SMOKE declares --smoke (its tiny size), so the run exercises it rather than its full size."""
    for name in smoke.SMOKE:
        assert '"--smoke"' in (ROOT / "bench" / f"{name}.py").read_text(), name


def test_a_bench_that_breaks_fails_the_run(tmp_path):
    """A bench that raises (here a made-up one in the ``bench`` namespace) fails the run, named, with its error."""
    (tmp_path / "bench").mkdir()
    (tmp_path / "bench" / "bench_broken.py").write_text(
        "def main(argv=None):\n    raise RuntimeError('the package moved under me')\n")
    (tmp_path / "bench" / "bench_unhappy.py").write_text("def main(argv=None):\n    return 3\n")
    result = _smoke("bench_broken", "bench_unhappy", pythonpath=f"{tmp_path}{os.pathsep}{ROOT}")
    assert result.returncode == 1
    assert "smoke bench_broken: FAILED (RuntimeError: the package moved under me)" in result.stdout
    assert "smoke bench_unhappy: FAILED (3)" in result.stdout
    assert "2 of 2 benches failed: bench_broken, bench_unhappy" in result.stdout
