"""The suite's own reporting: every run ends with the count of automatic reruns and names each rerun test."""
import pathlib

pytest_plugins = ["pytester"]

TEST_DIR = pathlib.Path(__file__).resolve().parents[1]


def test_every_run_ends_with_the_rerun_count_and_names_each_rerun_test(pytester, monkeypatch):
    import os

    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(TEST_DIR), os.environ.get("PYTHONPATH")])))
    pytester.makepyfile(test_inner="""
        import pytest
        calls = []

        @pytest.mark.flaky(reruns=1)
        def test_passes_on_its_rerun():
            calls.append(1)
            assert len(calls) > 1, "lost the race the first time"

        def test_steady():
            pass
    """)
    result = pytester.runpytest_subprocess("-p", "rerun_summary", "-p", "rerunfailures")
    outcomes = result.parseoutcomes()
    assert (outcomes.get("passed"), outcomes.get("rerun")) == (2, 1), outcomes
    result.stdout.fnmatch_lines(["*= reruns: 1 =*",
                                 "RERUN test_inner.py::test_passes_on_its_rerun (call): AssertionError: lost the race*"])
    quiet = pytester.runpytest_subprocess("-p", "rerun_summary", "-p", "no:rerunfailures", "-k", "steady")
    quiet.stdout.fnmatch_lines(["*= reruns: 0 =*"])
