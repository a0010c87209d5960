"""Node command lines: parameter files in order, overrides quoted so the ROS argument parser reads them back."""
import sys

import yaml

from rollability_ros.core.graph.bringup import DEFAULT_CONFIGS, NodeLaunch, parameter_files


def test_argv_and_overrides_round_trip_through_yaml():
    launch = NodeLaunch("sim_evaluator", label="eval_0", namespace="/eval_0",
                        params={"evaluator.workers": 1, "flag": True, "path": "runs/it's here", "files": ["a", "b"],
                                "ratio": 0.5})
    argv = launch.argv(["one.yaml", "two.yaml"])
    assert argv[:4] == [sys.executable, "-m", "rollability_ros.nodes.sim_evaluator", "--ros-args"]
    assert argv[argv.index("-r") + 1] == "__ns:=/eval_0"
    assert [argv[i + 1] for i, arg in enumerate(argv) if arg == "--params-file"] == ["one.yaml", "two.yaml"]
    overrides = dict(argv[i + 1].split(":=", 1) for i, arg in enumerate(argv) if arg == "-p")
    assert {key: yaml.safe_load(value) for key, value in overrides.items()} == {
        "evaluator.workers": 1, "flag": True, "path": "runs/it's here", "files": ["a", "b"], "ratio": 0.5}
    assert launch.process_spec([]).name == "eval_0"
    assert NodeLaunch("rig", namespace="/rollability").process_spec([]).name == "rig"


def test_parameter_files_resolve_in_order():
    files = parameter_files(["paper"])
    assert [path.rsplit("/", 1)[-1] for path in files] == [f"{name}.yaml" for name in (*DEFAULT_CONFIGS, "paper")]
