"""Issue 17: strict inputs: empty or malformed --heights and invalid node parameters stop before any work."""
import os
import subprocess
import sys

import pytest
import yaml

from rollability_ros.core.config import ConfigError

REPO = os.path.join(os.path.dirname(__file__), "..", "..")


@pytest.mark.parametrize("text, reason", [
    ("", "is empty"), ("   \n", "is empty"), ("0.1,,0.2", "value 2 is empty"), ("0.1,", "value 2 is empty"),
    ("0.1 abc", "value 2 ('abc') is not a number"), ("nan", "not finite"), ("0.1,inf", "not finite")])
def test_bad_heights_are_refused_with_the_reason(text, reason):
    from rollability_ros.cli.evaluate import parse_heights

    with pytest.raises(ValueError, match=reason.replace("(", r"\(").replace(")", r"\)")):
        parse_heights(text)


def test_heights_accept_commas_and_whitespace():
    from rollability_ros.cli.evaluate import parse_heights

    assert parse_heights("0.1, 0.2\n0.3 0.4") == [0.1, 0.2, 0.3, 0.4]


def test_evaluate_with_empty_heights_exits_2_without_evaluating():
    """Was: `evaluate --heights ""` evaluated the bare chassis and exited 0."""
    result = subprocess.run([sys.executable, "-m", "rollability_ros.cli", "evaluate", "--heights", "",
                             "--trials", "1"], capture_output=True, text=True, timeout=300, cwd=REPO)
    assert result.returncode == 2 and "--heights is empty" in result.stderr, result.stderr
    assert "fitness" not in result.stdout


def _bad_config(tmp_path, values):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({"/**": {"ros__parameters": values}}))
    return str(path)


@pytest.mark.parametrize("optimizer, reason", [({"trials": -5}, "optimizer.trials out of range: -5 is not in [1, 10000000]"),
                                               ({"trials": float("nan")}, "optimizer.trials: expected an integer in [1, 10000000], got nan"),
                                               ({"sigma0": float("nan")}, "optimizer.sigma0 out of range: nan is not in (0.0, 100.0]")])
def test_study_checks_every_node_parameter_before_starting(tmp_path, optimizer, reason):
    from rollability_ros.core.graph.study import Study, study_config

    config = _bad_config(tmp_path, {"bringup": {"output_dir": str(tmp_path / "runs")}, "optimizer": optimizer})
    study = Study(study_config([config], "bad"), say=lambda text: None)
    with pytest.raises(ConfigError, match="optimizer") as caught:
        study.check_parameters()
    assert reason in str(caught.value)
    with pytest.raises(ConfigError):
        study.run()
    assert not os.path.exists(tmp_path / "runs" / "bad")      # nothing made, no process started


def test_study_cli_prints_the_reason_and_exits_2(tmp_path):
    config = _bad_config(tmp_path, {"bringup": {"output_dir": str(tmp_path / "runs")}, "optimizer": {"trials": -5},
                                    "campaign": {"repetitions": 0}})
    result = subprocess.run([sys.executable, "-m", "rollability_ros.cli", "study", "--config", config],
                            capture_output=True, text=True, timeout=300, cwd=REPO)
    assert result.returncode == 2, result.stdout + result.stderr
    assert "optimizer.trials out of range: -5 is not in [1, 10000000]" in result.stderr
    assert "campaign.repetitions out of range: 0 is not in [1, 1000]" in result.stderr
    assert not os.path.exists(tmp_path / "runs")


def test_shipped_configurations_pass_the_check():
    from rollability_ros.core.graph.bringup import parameter_files
    from rollability_ros.core.graph.preflight import check_graph_parameters

    for extra in ([], ["paper"]):
        assert check_graph_parameters(parameter_files(["bringup", *extra])) == []


def test_an_objective_file_the_evaluator_cannot_read_stops_the_study(tmp_path):
    """The sim_evaluator reads the files its objective names when it starts: the preflight reads them first."""
    from rollability_ros.core.graph.bringup import parameter_files
    from rollability_ros.core.graph.preflight import check_graph_parameters

    missing = str(tmp_path / "no_campaign.yaml")
    config = _bad_config(tmp_path, {"objective": {"campaign_config": [missing]}})
    problems = check_graph_parameters([*parameter_files(["bringup"]), config])
    assert len(problems) == 1 and problems[0].startswith("sim_evaluator: the objective's launch twin or campaign ")
    assert f"config file not found: {missing}" in problems[0]


@pytest.mark.parametrize("values, name", [
    ({"objective": {"screen_engnie": "mujoco"}}, "objective.screen_engnie"),          # misspelt
    ({"optimizer": {"race_first_trials": 10}}, "optimizer.race_first_trials"),        # a setting of an older version
    ({"objective": {"robust": {"foam_stifness_factor_min": 0.5}}}, "objective.robust.foam_stifness_factor_min")])
def test_a_parameter_no_node_reads_stops_the_study(tmp_path, values, name):
    """Was: rclpy drops a parameter file's undeclared names, so a study ran on the default without a word."""
    from rollability_ros.core.graph.study import Study, study_config

    config = _bad_config(tmp_path, {"bringup": {"output_dir": str(tmp_path / "runs")}, **values})
    study = Study(study_config([config], "bad"), say=lambda text: None)
    with pytest.raises(ConfigError, match=f"unknown parameter {name} "):
        study.check_parameters()
    assert not os.path.exists(tmp_path / "runs" / "bad")


def test_known_parameters_in_every_namespace_pass_the_unknown_check():
    """Every dotted name the shipped files set is a field some node reads (mapping-valued fields included)."""
    import glob

    from rollability_ros.core.config import load_parameters
    from rollability_ros.core.graph.preflight import unknown_parameters

    for path in sorted(glob.glob(os.path.join(REPO, "config", "*.yaml"))):
        assert unknown_parameters(load_parameters([path], node_name="/**")) == [], path
