"""Issue 42, item 3: parameter files are read within bounds (core/safe_yaml.py), and every key of a file a user
gives a command is applied or refused naming it (config.check_given_files). The CLI cases (one line, exit 2,
nothing written, in every verb) are in test_bad_inputs.py."""
import glob
import os

import pytest
import yaml

from rollability_ros.core import safe_yaml
from rollability_ros.core.config import ConfigError, check_given_files, config_dir, load_parameters

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
PARAMS = "/**:\n  ros__parameters:\n"


def _laughs(levels, fan_out=10):
    """A billion-laughs document: ``fan_out ** levels`` keys once its aliases are expanded."""
    text = "a0: &a0 {" + ", ".join(f"k{j}: {j}" for j in range(fan_out)) + "}\n"
    for i in range(1, levels + 1):
        text += f"a{i}: &a{i} {{" + ", ".join(f"k{j}: *a{i - 1}" for j in range(fan_out)) + "}\n"
    return text


@pytest.mark.parametrize("text, reason", [
    ("x: " + "[" * 20000, "nesting deeper than 100 levels at line 1"),            # flow: stops in the scanner
    ("x: " + "[" * 200000, "nesting deeper than 100 levels"),
    ("x:\n  " + "- " * 20000 + "1\n", "nesting deeper than 100 levels at line 2"),  # block sequences
    ("".join(" " * i + f"k{i}:\n" for i in range(500)), "nesting deeper than 100 levels"),   # block mappings
    (_laughs(9), "anchors and aliases expand to more than 100000 extra nodes"),
    ("m0: &m0 {a: 1, b: 2, c: 3}\n" + "".join(f"m{i}: &m{i} {{<<: [{', '.join([f'*m{i - 1}'] * 10)}]}}\n"
                                              for i in range(1, 9)), "expand to more than"),   # merge keys
    ("x: &a [1, *a]\n", "refers to a node that contains it (a cycle)"),
    ("x: &a {y: *a}\n", "(a cycle)"),
    ("sim:\n  trials: 2\n  trials: 3\n", "duplicate key 'trials' at line 3 (first at line 2)"),
    ("sim: {trials: 2, 'trials': 3}\n", "duplicate key 'trials' at line 1"),
])
def test_what_no_file_of_ours_needs_is_refused_in_one_line(text, reason):
    with pytest.raises(safe_yaml.YamlLimitError, match=reason.replace("(", r"\(").replace(")", r"\)")) as caught:
        safe_yaml.load(text)
    assert "\n" not in str(caught.value)


def test_the_limits_leave_plain_data_as_safe_load_reads_it():
    text = ("base: &base {x: 1, y: [1, 2]}\ncopy: *base\nmerged: {<<: *base, x: 3}\n"   # an override is no duplicate
            + "deep: " + "[" * 99 + "]" * 99 + "\n" + _laughs(3))                          # 22,221 nodes expanded: fine
    assert safe_yaml.load(text) == yaml.safe_load(text)
    assert safe_yaml.load("") is None and safe_yaml.load("# a comment only\n") is None
    with pytest.raises(yaml.constructor.ConstructorError):   # still no tag that builds an object or runs code
        safe_yaml.load("x: !!python/object/apply:os.system ['true']\n")


def test_every_shipped_file_and_the_sample_bag_read_within_the_limits():
    files = glob.glob(os.path.join(config_dir(), "*.yaml")) + glob.glob(os.path.join(REPO, "bags", "*", "*.yaml")) \
        + glob.glob(os.path.join(REPO, "test", "resources", "*.yaml"))
    assert len(files) > 12
    for path in files:
        with open(path, encoding="utf-8") as stream:
            text = stream.read()
        assert safe_yaml.load(text) == yaml.safe_load(text), path


def test_a_yaml_syntax_error_is_one_line_with_its_place(tmp_path):
    broken = tmp_path / "broken.yaml"
    broken.write_text(PARAMS + "    evaluator: {trials: [oops\n")
    with pytest.raises(ConfigError) as caught:
        load_parameters([str(broken)])
    assert str(caught.value) == (f"parameter file {broken} is not valid YAML: while parsing a flow sequence "
                                 "expected ',' or ']', but got '<stream end>' (line 4, column 1)")


def _file(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(PARAMS + text)
    return str(path)


def test_a_key_a_command_does_not_apply_is_refused_naming_file_key_and_command(tmp_path):
    lab = _file(tmp_path, "lab.yaml", "    sim: {time_step_s: 0.005}\n    use_sim_time: true\n"
                                      "    qos_overrides: {/tf: {publisher: {depth: 10}}}\n    campaign: {repetitions: 2}\n")
    check_given_files([lab], {"sim", "campaign"}, "rollability x")   # ROS's own keys pass
    with pytest.raises(ConfigError) as caught:
        check_given_files([lab], {"sim"}, "rollability x")
    assert str(caught.value) == (f"parameter file {lab}: rollability x does not read campaign.repetitions (it reads "
                                 "sim); remove it or give the file to a command that reads it")


def test_a_twin_key_given_to_an_evaluation_that_launches_changes_its_twin(tmp_path):
    """Issue 42: `evaluate --fidelity launch --config F` ran on the shipped pad whatever F's launch_twin said (the
    twin reads objective.twin_config only); now F's twin keys reach the twin, and without launches are refused."""
    from rollability_ros.core.sim import evaluation
    from rollability_ros.core.sim.launch.settings import load_launch_twin_settings

    pad = _file(tmp_path, "pad.yaml", "    launch_twin: {foam: {length_m: 3.5}}\n")
    shipped = load_launch_twin_settings().twin.foam.length_m
    assert shipped != 3.5
    loaded = evaluation.load_settings(["sim", "robot", "evaluator", pad])
    launch = evaluation.with_given_files(evaluation.settings_at_fidelity(loaded, "launch"), [pad], "evaluate")
    assert launch.objective.twin_config[-1] == pad
    assert load_launch_twin_settings(launch.objective.twin_config).twin.foam.length_m == 3.5
    with pytest.raises(ConfigError, match="evaluate does not read launch_twin.foam.length_m"):
        evaluation.with_given_files(evaluation.settings_at_fidelity(loaded, "screen"), [pad], "evaluate")
    robot = _file(tmp_path, "robot.yaml", "    robot: {com_offset_z_m: 0.004}\n")   # no twin key: list unchanged
    assert evaluation.with_given_files(evaluation.settings_at_fidelity(loaded, "launch"), [robot],
                                       "evaluate").objective.twin_config == loaded.objective.twin_config


def test_a_run_and_the_in_process_rig_append_twin_files_to_their_twin(tmp_path):
    from rollability_ros.core.campaign import local_rig_settings_from_files
    from rollability_ros.core.optimization import optimization_run

    pad = _file(tmp_path, "pad.yaml", "    launch_twin: {foam: {length_m: 3.5}}\n    optimizer: {popsize: 6}\n")
    parameters = optimization_run.with_given_files(optimization_run.load_run_parameters([pad]), [pad], "optimize")
    assert parameters["objective.twin_config"][-1] == pad and parameters["optimizer.popsize"] == 6
    with pytest.raises(ConfigError, match="rollability campaign --rig-config does not read optimizer.popsize"):
        local_rig_settings_from_files("sim", ["rig", pad], "rollability campaign --rig-config")
    twin = _file(tmp_path, "twin.yaml", "    launch_twin: {foam: {length_m: 3.5}}\n    robot: {com_offset_z_m: 0.004}\n")
    rig = local_rig_settings_from_files("sim", ["rig", twin], "rollability campaign --rig-config")
    assert rig.rig.twin_config[-1] == twin and rig.valve.backend == load_parameters(["rig"])["valve.backend"]


def test_a_session_applies_or_refuses_every_key_before_it_starts(tmp_path):
    from rollability_ros.core.graph import (NodeLaunch, add_twin_files, graph_namespaces, parameter_files,
                                            refuse_bad_session)

    assert {"bringup", "campaign", "launch_twin", "optimizer", "rig", "sim"} <= graph_namespaces()
    assert "campaign" not in graph_namespaces(["rig", "sim_evaluator"])            # no campaign_runner in it
    assert "launch_twin" not in graph_namespaces(["sim_evaluator"])               # no rig: no twin
    twin = _file(tmp_path, "twin.yaml", "    launch_twin: {foam: {length_m: -5.0}}\n")
    files = parameter_files(["bringup", twin])
    nodes = [NodeLaunch("rig", params={"rig.backend": "sim"}), NodeLaunch("sim_evaluator", label="eval_0"),
             NodeLaunch("optimizer", params={"objective.twin_config": ["sim", "robot", "launch_twin", "cal.yaml"]}),
             NodeLaunch("recorder"), NodeLaunch("view_bridge")]
    add_twin_files(nodes, files, [twin])    # every twin of the session reads the user's twin keys
    assert nodes[0].params["rig.twin_config"] == ["sim", "robot", "launch_twin", twin]
    assert nodes[1].params["objective.twin_config"] == ["sim", "robot", "launch_twin", twin]
    assert nodes[2].params["objective.twin_config"] == ["sim", "robot", "launch_twin", "cal.yaml", twin]
    assert nodes[3].params == {} and nodes[4].params == {}
    with pytest.raises(ConfigError, match=r"nothing started: rig: launch twin .*launch_twin.foam.length_m out of "
                                          r"range: -5.0 is not in \(0.0, 100.0\]$"):
        refuse_bad_session(files, [twin], {node.module: node.params for node in nodes}, "rollability bringup")
    refuse_bad_session(files, [twin], {"rig": {"rig.backend": "physical"}}, "rollability bringup")   # no twin there
    robot = _file(tmp_path, "robot.yaml", "    robot: {com_offset_z_m: 0.004}\n")
    untouched = [NodeLaunch("rig")]
    add_twin_files(untouched, parameter_files(["bringup", robot]), [robot])     # no twin key: no list changed
    assert untouched[0].params == {}
