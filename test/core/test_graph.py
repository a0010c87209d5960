"""Node command lines: parameter files in order, the node's overrides a last file that reads back as given."""
import sys

import pytest
import yaml

from rollability_ros.core.config import load_parameters
from rollability_ros.core.graph.bringup import DEFAULT_CONFIGS, NodeLaunch, parameter_files


def test_argv_and_overrides_round_trip_through_yaml(tmp_path):
    launch = NodeLaunch("sim_evaluator", label="eval_0", namespace="/eval_0",
                        params={"evaluator.workers": 1, "flag": True, "path": "runs/it's here", "files": ["a", "b"],
                                "ratio": 0.5, "reply": "Y"})
    argv = launch.argv(["one.yaml", "two.yaml"], str(tmp_path))
    assert argv[:4] == [sys.executable, "-m", "rollability_ros.nodes.sim_evaluator", "--ros-args"]
    assert argv[argv.index("-r") + 1] == "__ns:=/eval_0"
    override = str(tmp_path / "node-params" / "eval_0.yaml")
    # the overrides are the last parameter file (a -p loses to a parameter two files set: core/graph/bringup.py)
    assert [argv[i + 1] for i, arg in enumerate(argv) if arg == "--params-file"] == ["one.yaml", "two.yaml", override]
    assert "-p" not in argv
    with open(override, encoding="utf-8") as stream:
        document = yaml.safe_load(stream)
    assert document == {"/**": {"ros__parameters": {"evaluator": {"workers": 1}, "flag": True,
                                                    "path": "runs/it's here", "files": ["a", "b"], "ratio": 0.5,
                                                    "reply": "Y"}}}
    assert load_parameters([override]) == {"evaluator.workers": 1, "flag": True, "path": "runs/it's here",
                                           "files": ["a", "b"], "ratio": 0.5, "reply": "Y"}
    assert launch.process_spec([], str(tmp_path)).name == "eval_0"
    assert NodeLaunch("rig", namespace="/rollability").process_spec([], str(tmp_path)).name == "rig"
    assert NodeLaunch("rig").argv([], str(tmp_path))[-1] == "--ros-args"   # no overrides: no file


def test_parameter_files_resolve_in_order():
    files = parameter_files(["paper"])
    assert [path.rsplit("/", 1)[-1] for path in files] == [f"{name}.yaml" for name in (*DEFAULT_CONFIGS, "paper")]


def test_one_valve_backend_key_and_a_rig_only_session_starts_no_evaluators(tmp_path):
    """Issue 45: bringup.valve_backend and valve.backend both picked the valve's backend; a bringup without the
    optimizer still started two sim evaluators."""
    from rollability_ros.core.graph.bringup import load_graph_settings, parameter_files, session_nodes

    settings = load_graph_settings(parameter_files(["bringup"]))   # the shipped bringup.yaml reads
    rig_only = [node.process_label for node in session_nodes(settings, str(tmp_path), "physical", optimizer=False)]
    assert rig_only == ["recorder", "outcome_logger", "valve_controller", "rig"]
    full = [node.process_label for node in session_nodes(settings, str(tmp_path), "sim")]
    assert full == ["recorder", "outcome_logger", "valve_controller", "eval_0", "eval_1", "rig", "optimizer"]
    valve = next(node for node in session_nodes(settings, str(tmp_path)) if node.module == "valve_controller")
    assert "valve.backend" not in valve.params      # the node reads valve.backend from the files: the one key
    old = tmp_path / "lab.yaml"
    old.write_text("/**:\n  ros__parameters:\n    bringup:\n      valve_backend: serial_relay\n")
    with pytest.raises(ValueError, match="bringup.valve_backend is no longer read: set valve.backend"):
        load_graph_settings(parameter_files([str(old)]))
