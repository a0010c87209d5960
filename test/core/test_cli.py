"""Every `rollability` verb answers --help, and user errors print one line naming the problem."""
import pytest

from rollability_ros.cli import build_parser, main

VERBS = sorted(build_parser()._subparsers._group_actions[0].choices)


def test_the_verbs_of_the_readme_exist():
    assert {"doctor", "evaluate", "optimize", "select", "campaign", "bringup", "study", "report", "record", "play",
            "bag", "view", "calibrate", "rig"} <= set(VERBS)


@pytest.mark.parametrize("verb", VERBS)
def test_every_verb_has_help(verb, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([verb, "--help"])
    assert exit_info.value.code == 0
    assert f"usage: rollability {verb}" in capsys.readouterr().out


def test_a_broken_config_is_one_clear_line(tmp_path, capsys):
    broken = tmp_path / "broken.yaml"
    broken.write_text("/**:\n  ros__parameters:\n    evaluator: {trials: [oops\n")
    assert main(["evaluate", "--baseline", "--config", str(broken)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("rollability evaluate: error:") and "broken.yaml" in error and "not valid YAML" in error
