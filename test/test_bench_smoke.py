"""The bench scripts run against the package as it is: bench/smoke.py runs each bench once at its ``--smoke`` size
(tiny inputs, every step and every line of its report; the numbers mean nothing), in one process, and fails
naming a bench that raised, returned non-zero or did not print one of its headline lines. The README's command
runs ``SMOKE`` in one process, the slow tier each of ``SMOKE_SLOW`` in one of its own; together they are every
script in bench/. mypy checks every bench
script too (test/core/test_mypy.py)."""
import os
import pathlib
import sys
import types

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench import smoke  # noqa: E402
from smoke_early import SmokeRun, repo_files, smoke_run  # noqa: E402


def _smoke(*names, pythonpath=str(ROOT)):
    """Runs bench/smoke.py in a fresh directory: a bench's default output folder lands there, not in the repo."""
    return SmokeRun(*names, pythonpath=pythonpath).wait(1500)


def _runs_every_bench_of(names, run):
    result = run.wait(1500)
    assert result.returncode == 0, result.stdout[-6000:] + result.stderr[-3000:]
    for name in names:
        assert f"smoke {name}: ok (" in result.stdout, result.stdout
        for line in smoke.HEADLINES[name]:   # bench/smoke.py checks them too; this test asks it did
            assert line in result.stdout, (name, line)
    assert f"smoke: {len(names)} benches ran" in result.stdout
    after = repo_files()
    assert after == run.before, ("the checkout changed while the benches ran (a bench wrote into it, or a test that "
                                 "ran beside them: test/smoke_early.py)",
                                 sorted(set(after.items()) ^ set(run.before.items())))


@pytest.mark.timeout(1500)   # when run alone it runs the benches itself: 23 of them, minutes at a high load
def test_every_smoke_bench_runs_at_its_tiny_size():
    """SMOKE, in the process test/smoke_early.py started when collection ended (it runs beside the core tests)."""
    _runs_every_bench_of(smoke.SMOKE, smoke_run())


@pytest.mark.slow   # a learnt likelihood prepared and used, a miniature study on two engines: minutes each
@pytest.mark.timeout(1500)   # the learnt likelihood's preparation alone took 258 s at load average 19
@pytest.mark.parametrize("name", smoke.SMOKE_SLOW)
def test_every_slow_smoke_bench_runs_at_its_tiny_size(name):
    _runs_every_bench_of([name], SmokeRun(name))


def test_every_bench_script_is_run_at_its_tiny_size_by_a_tier():
    """Every script in bench/ is in exactly one of SMOKE and SMOKE_SLOW, declares --smoke (its tiny size, so the run
    exercises it rather than its full size) and names the lines its report must print."""
    scripts = sorted(path.stem for path in (ROOT / "bench").glob("*.py") if path.stem != "smoke")
    assert sorted(smoke.SMOKE + smoke.SMOKE_SLOW) == scripts
    for name in scripts:
        assert '"--smoke"' in (ROOT / "bench" / f"{name}.py").read_text(), name
        assert smoke.HEADLINES[name] and all(smoke.HEADLINES[name]), name
    assert set(smoke.HEADLINES) == set(scripts)


def test_a_bench_that_breaks_fails_the_run(tmp_path):
    """A bench that raises or returns non-zero (here made-up ones in the ``bench`` namespace) fails the run, named,
    with its error."""
    (tmp_path / "bench").mkdir()
    (tmp_path / "bench" / "bench_broken.py").write_text(
        "def main(argv=None):\n    raise RuntimeError('the package moved under me')\n")
    (tmp_path / "bench" / "bench_unhappy.py").write_text("def main(argv=None):\n    return 3\n")
    result = _smoke("bench_broken", "bench_unhappy", pythonpath=f"{tmp_path}{os.pathsep}{ROOT}")
    assert result.returncode == 1
    assert "smoke bench_broken: FAILED (RuntimeError: the package moved under me)" in result.stdout
    assert "smoke bench_unhappy: FAILED (3)" in result.stdout
    assert "2 of 2 benches failed: bench_broken, bench_unhappy" in result.stdout


def test_a_bench_that_leaves_out_a_line_of_its_report_fails(monkeypatch, capsys):
    """Exit 0 is not enough: a bench that stops before its report, or drops a line of it, fails naming the line; one
    without HEADLINES fails too. The made-up benches run in this process, from ``sys.modules``."""
    def bench(*lines):
        module = types.ModuleType("made-up bench")
        module.main = lambda argv: print(*lines, sep="\n")   # returns None: success, as a bench may
        return module

    monkeypatch.setitem(sys.modules, "bench.bench_complete", bench("rate 3.0 x", "verdict: meets the target"))
    monkeypatch.setitem(sys.modules, "bench.bench_cut_short", bench("rate 3.0 x"))
    monkeypatch.setitem(sys.modules, "bench.bench_unlisted", bench("rate 3.0 x"))
    monkeypatch.setattr(smoke, "HEADLINES", {"bench_complete": ("rate ", "verdict: "),
                                             "bench_cut_short": ("rate ", "verdict: ")})
    assert smoke.run(["bench_complete", "bench_cut_short", "bench_unlisted"]) == ["bench_cut_short", "bench_unlisted"]
    printed = capsys.readouterr().out
    assert "smoke bench_complete: ok (" in printed
    assert "smoke bench_cut_short: FAILED (no line with 'verdict: ')" in printed
    assert "smoke bench_unlisted: FAILED (no HEADLINES entry in bench/smoke.py)" in printed
