"""The ROS launch files (for machines with a full ROS 2 Jazzy install).

`launch` and `launch_ros` are not on PyPI, so on a venv built from the wheels the expansion test says so plainly
and is skipped; on a ROS install it loads each launch file and expands its node list. Everywhere, with stand-ins
for the launch classes, the launch files are checked to start exactly the commands of
``launch_support.session_commands`` (which the install-space test in test_packaging.py runs) and nothing else.
"""
import importlib.util
import os
import sys
import types

import pytest

from conftest import REPO_ROOT

LAUNCH_FILES = sorted((REPO_ROOT / "launch").glob("*.launch.py"))


def test_launch_files_exist():
    assert {path.name for path in LAUNCH_FILES} == {"sim_bringup.launch.py", "physical_rig.launch.py"}


@pytest.mark.parametrize("path", LAUNCH_FILES, ids=lambda p: p.name)
def test_launch_file_expands(path, tmp_path):
    if importlib.util.find_spec("launch_ros") is None or importlib.util.find_spec("launch") is None:
        pytest.skip("launch / launch_ros are not importable here (they are not on PyPI; a full ROS 2 Jazzy "
                    "install has them): the launch files are not exercised in this environment")
    from launch import LaunchContext
    from launch.actions import OpaqueFunction

    spec = importlib.util.spec_from_file_location(path.stem.replace(".", "_"), path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    context = LaunchContext()
    context.launch_configurations.update({"config": "", "run_dir": str(tmp_path / "run")})
    nodes = []
    for entity in description.entities:
        if isinstance(entity, OpaqueFunction):
            nodes += entity.execute(context)
    executables = {node.node_executable for node in nodes}
    assert {"recorder", "outcome_logger", "valve_controller", "rig"} <= executables
    assert ("sim_evaluator" in executables) == ("sim" in path.name)


class _Recorded:
    """Stand-in for a launch class: keeps its constructor arguments."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


def _fake_launch_modules(monkeypatch):
    class LaunchConfiguration(_Recorded):
        def perform(self, context):
            return context[self.args[0]]

    class SetEnvironmentVariable(_Recorded):
        pass

    modules = {"launch": {"LaunchDescription": _Recorded}, "launch.actions": {"DeclareLaunchArgument": _Recorded,
               "OpaqueFunction": _Recorded, "SetEnvironmentVariable": SetEnvironmentVariable},
               "launch.substitutions": {"LaunchConfiguration": LaunchConfiguration},
               "launch_ros": {}, "launch_ros.actions": {"Node": _Recorded}}
    for name, attributes in modules.items():
        module = types.ModuleType(name)
        module.__dict__.update(attributes)
        monkeypatch.setitem(sys.modules, name, module)


@pytest.mark.parametrize("path", LAUNCH_FILES, ids=lambda p: p.name)
def test_launch_file_starts_exactly_the_session_commands(path, tmp_path, monkeypatch):
    from rollability_ros.launch_support import session_commands

    _fake_launch_modules(monkeypatch)
    spec = importlib.util.spec_from_file_location(path.stem.replace(".", "_"), path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    opaque = description.args[0][-1]
    context = {"config": "", "run_dir": str(tmp_path / "run")}
    entities = opaque.kwargs["function"](context, *opaque.kwargs["args"])
    rig_backend, optimizer, evaluators = opaque.kwargs["args"]
    # the physical rig's own ROS domain and localhost discovery, unless the environment sets them
    from rollability_ros.core.rig.rig_network import physical_rig_environment

    environment = [entity for entity in entities if type(entity).__name__ == "SetEnvironmentVariable"]
    expected_environment = physical_rig_environment(os.environ) if rig_backend == "physical" else {}
    assert {entity.args for entity in environment} == set(expected_environment.items())
    nodes = [entity for entity in entities if entity not in environment]
    expected = session_commands(rig_backend, optimizer, evaluators, "", str(tmp_path / "run"))
    assert [(node.kwargs["executable"], node.kwargs["arguments"]) for node in nodes] == \
        [(command.executable, command.arguments) for command in expected]
    for node in nodes:   # nothing that would make launch_ros add to the command line
        assert set(node.kwargs) == {"package", "executable", "arguments", "output", "respawn", "respawn_delay"}
    assert ("sim_evaluator" in {node.kwargs["executable"] for node in nodes}) == ("sim" in path.name)
