"""mypy runs over rollability_ros/ and bench/ at the strictness mypy.ini states, with no error (its cache, .mypy_cache/, keeps a
re-run to about a second; a fresh clone's first run takes 10-35 s on the shared 2-core machine)."""
import os
import subprocess
import sys

from conftest import REPO_ROOT


def _mypy(*args):
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "TERM": "dumb", "LC_ALL": "C.UTF-8", "MYPY_FORCE_COLOR": "0"}
    return subprocess.run([sys.executable, "-m", "mypy", "--config-file", str(REPO_ROOT / "mypy.ini"), *args],
                          cwd=REPO_ROOT, env=env, capture_output=True, text=True, timeout=600)


def test_mypy_is_clean_over_the_package_and_the_benches():
    result = _mypy("rollability_ros", "bench")
    assert result.returncode == 0 and "Success: no issues found" in result.stdout, result.stdout + result.stderr


def test_the_same_configuration_reports_a_wrong_type():
    """The check can fail: an annotated function returning the wrong type is an error under mypy.ini."""
    result = _mypy("-c", "def tilt_deg(x: float) -> float:\n    return str(x)\n")
    assert result.returncode == 1 and 'Incompatible return value type (got "str", expected "float")' in result.stdout


def test_the_configuration_checks_unannotated_bodies():
    """check_untyped_defs: a function without annotations is still checked (its Optional value used unchecked)."""
    result = _mypy("-c", "import re\ndef group(text):\n    return re.match('a', text).group(0)\n")
    assert result.returncode == 1 and 'Item "None" of "Match[str] | None" has no attribute "group"' in result.stdout
