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


def test_output_is_line_buffered_into_a_pipe_whatever_the_environment():
    """`rollability study > study.log` or a pipe to a supervisor shows each line as it is printed."""
    import os
    import subprocess
    import sys

    env = {key: value for key, value in os.environ.items() if key != "PYTHONUNBUFFERED"}
    check = ("import sys\nfrom rollability_ros.cli import main\ntry:\n    main(['doctor', '--help'])\n"
             "except SystemExit:\n    pass\nprint('line buffered:', sys.stdout.line_buffering, sys.stderr.line_buffering)")
    done = subprocess.run([sys.executable, "-c", check], env=env, stdout=subprocess.PIPE, text=True, timeout=120,
                          check=True)
    assert done.stdout.splitlines()[-1] == "line buffered: True True"


def test_rig_commands_default_to_the_bringup_namespace_and_name_where_a_service_is():
    from rollability_ros.cli.rig import default_namespace, namespaces_offering

    assert default_namespace() == "/rollability"   # where `rollability bringup` and the launch files put the rig
    names = ["/rollability/valve/arm", "/lab2/valve/arm", "/valve/arm", "/rollability/valve/arm_extra",
             "/rollability/eval_0/evaluate_profile"]
    assert namespaces_offering(names, "valve/arm") == ["/", "/lab2", "/rollability"]
    assert namespaces_offering(names, "rig/confirm") == []
