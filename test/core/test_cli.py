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
    out = capsys.readouterr().out
    assert f"usage: rollability {verb}" in out
    assert "%%" not in out   # argparse does not %-format a description: "95%%" would print as written


def test_a_broken_config_is_one_clear_line(tmp_path, capsys):
    broken = tmp_path / "broken.yaml"
    broken.write_text("/**:\n  ros__parameters:\n    evaluator: {trials: [oops\n")
    assert main(["evaluate", "--baseline", "--config", str(broken)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("rollability evaluate: error:") and "broken.yaml" in error and "not valid YAML" in error


def test_a_misspelt_namespace_is_refused_not_ignored(tmp_path, capsys):
    misspelt = tmp_path / "physics.yaml"
    misspelt.write_text("/**:\n  ros__parameters:\n    physics: {time_step_s: 0.01}\n")
    assert main(["evaluate", "--baseline", "--config", str(misspelt)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("rollability evaluate: error:") and "physics.yaml" in error
    assert "unknown parameter namespace 'physics' (parameter physics.time_step_s)" in error and "sim" in error
    assert len(error.strip().splitlines()) == 1


def test_every_namespace_the_project_reads_is_known():
    import glob
    import os
    import re

    from rollability_ros.core.config import KNOWN_NAMESPACES, config_dir, load_parameters
    from rollability_ros.core.graph.preflight import _node_sections
    from rollability_ros.core.sim.evaluation import SETTINGS_SECTIONS

    shipped = glob.glob(os.path.join(config_dir(), "*.yaml"))
    assert len(shipped) >= 10
    read = {name.split(".")[0] for name in load_parameters(shipped)}  # loads: every shipped namespace is known
    assert {"sim", "robot", "launch_twin", "campaign", "valve"} <= read
    prefixes = {prefix for sections in _node_sections().values() for prefix in sections if prefix}
    assert prefixes | set(SETTINGS_SECTIONS.values()) <= KNOWN_NAMESPACES
    import rollability_ros

    nodes = os.path.join(os.path.dirname(rollability_ros.__file__), "nodes")
    declared = set()
    for path in glob.glob(os.path.join(nodes, "*.py")):
        with open(path, encoding="utf-8") as stream:
            text = stream.read()
        declared |= set(re.findall(r'declare_settings\((?:self|node), "([a-z_]+)"', text))
        declared |= set(re.findall(r'^PREFIX = "([a-z_]+)"', text, re.MULTILINE))
    assert {"player", "recorder", "tip_monitor", "campaign"} <= declared
    assert declared <= KNOWN_NAMESPACES


def test_ros_parameters_without_a_namespace_and_qos_overrides_pass(tmp_path):
    from rollability_ros.core.config import load_parameters

    path = tmp_path / "lab.yaml"
    path.write_text("/**:\n  ros__parameters:\n    use_sim_time: true\n    qos_overrides:\n      /tf:\n"
                    "        publisher: {depth: 10}\n    sim: {time_step_s: 0.005}\n")
    flat = load_parameters([str(path)])
    assert flat["use_sim_time"] is True and flat["sim.time_step_s"] == 0.005


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
