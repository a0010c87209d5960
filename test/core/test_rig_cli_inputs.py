"""`rollability rig` refuses bad input at the door: one line naming the problem, exit 2, before ROS starts (no
traceback, no hang), for every flag: the namespace, each number (NaN, sign, range), flags given to the wrong action.

Run with ``-s`` to print the table of cases and results (issue 26's closing note quotes it).
"""
import os
import subprocess
import sys

import pytest

from rollability_ros.cli import main
from rollability_ros.core.rig.rig_network import check_domain_id, check_namespace

#: (arguments after `rollability rig`, environment overrides, words the one-line error must contain)
BAD_INPUT = [
    (["arm", "--namespace", "bad ns!!"], {}, "not a ROS namespace"),
    (["arm", "--namespace", "/lab//2"], {}, "not a ROS namespace"),
    (["confirm", "--namespace", "/2lab"], {}, "not a ROS namespace"),
    (["estop", "--namespace", "/" + "a" * 250], {}, "at most 200 characters"),
    (["estop", "--timeout-s", "nan"], {}, "--timeout-s must be"),
    (["estop", "--timeout-s", "-1"], {}, "--timeout-s must be"),
    (["arm", "--timeout-s", "0"], {}, "--timeout-s must be"),
    (["disarm", "--timeout-s", "inf"], {}, "--timeout-s must be"),
    (["confirm", "--timeout-s", "1e12"], {}, "--timeout-s must be"),
    (["outcome", "upright", "--timeout-s=-inf"], {}, "--timeout-s must be"),
    (["outcome", "upright", "--travel-time-s", "nan"], {}, "--travel-time-s must be"),
    (["outcome", "tipped", "--travel-time-s", "-0.4"], {}, "--travel-time-s must be"),
    (["outcome", "upright", "--travel-time-s", "0"], {}, "--travel-time-s must be"),
    (["outcome", "upright", "--travel-time-s", "inf"], {}, "--travel-time-s must be"),
    (["arm", "--travel-time-s", "0.4"], {}, "for outcome only"),
    (["outcome"], {}, "needs a verdict"),
    (["confirm", "upright"], {}, "for outcome only"),
    (["arm", "--trial-id", "t0"], {}, "for confirm and outcome only"),
    (["estop", "--note", "hello"], {}, "for outcome only"),
    (["estop"], {"ROS_DOMAIN_ID": "abc"}, "ROS_DOMAIN_ID must be an integer in 0..232"),
    (["estop"], {"ROS_DOMAIN_ID": "233"}, "ROS_DOMAIN_ID must be an integer in 0..232"),
    (["arm", "--config", "/no/such/file.yaml"], {}, "file.yaml"),
    (["outcome", "tipped", "--rolled-m", "-0.2"], {}, "the distance rolled must be a number of metres >= 0"),
    (["outcome", "tipped", "--rolled-m", "nan"], {}, "the distance rolled must be a number of metres >= 0"),
    (["estop", "--rolled-m", "0.3"], {}, "--rolled-m is for outcome only"),
]
#: argparse refuses these itself (usage line + one error line, exit 2)
ARGPARSE_REFUSES = [
    (["estop", "--timeout-s", "soon"], "invalid float value"),
    (["outcome", "sideways"], "invalid choice"),
    (["launch"], "invalid choice"),
]
TABLE = []


@pytest.fixture(scope="module", autouse=True)
def print_table():
    yield
    if TABLE:
        print("\n| `rollability rig ...` | result |")
        print("|---|---|")
        for case, result in TABLE:
            print(f"| `{case}` | {result} |")


@pytest.mark.parametrize("argv, env, expected", BAD_INPUT, ids=[" ".join(c[0]) + str(c[1]) for c in BAD_INPUT])
def test_bad_rig_input_is_one_line_and_exit_2(argv, env, expected, capsys, monkeypatch, tmp_path):
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    monkeypatch.chdir(tmp_path)
    code = main(["rig", *argv])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    TABLE.append((" ".join(["rig", *argv]) + "".join(f" ({k}={v})" for k, v in env.items()),
                  f"clean error, exit {code}: {lines[-1] if lines else '(none)'}"))
    assert code == 2 and len(lines) == 1 and expected in lines[0] and lines[0].startswith("rollability rig: error:"), err


@pytest.mark.parametrize("argv, expected", ARGPARSE_REFUSES)
def test_malformed_values_are_refused_by_the_parser(argv, expected, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["rig", *argv])
    err = capsys.readouterr().err
    TABLE.append((" ".join(["rig", *argv]), f"clean error (argparse), exit {exit_info.value.code}"))
    assert exit_info.value.code == 2 and expected in err and "Traceback" not in err


def test_the_reported_cases_exit_at_once_without_a_traceback():
    """The issue's two cases through the real command: a traceback and a hang before."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "LC_ALL": "C.UTF-8", "TERM": "dumb"}
    for argv, expected in ((["arm", "--namespace", "bad ns!!"], "not a ROS namespace"),
                           (["estop", "--timeout-s", "nan"], "--timeout-s must be")):
        result = subprocess.run([sys.executable, "-m", "rollability_ros.cli", "rig", *argv], capture_output=True,
                                text=True, timeout=30, env=env)
        assert result.returncode == 2 and expected in result.stderr, result.stderr
        assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr


def test_namespace_and_domain_checks_accept_what_rcl_accepts():
    assert check_namespace("/rollability") == "/rollability" == check_namespace("rollability/")
    assert check_namespace("") == "/" == check_namespace("/")
    assert check_namespace("/lab_2/rig") == "/lab_2/rig"
    assert check_domain_id("0") == 0 and check_domain_id("232") == 232
    for bad in ("-1", "1.5", "", "0x10"):
        with pytest.raises(ValueError, match="ROS_DOMAIN_ID"):
            check_domain_id(bad)
