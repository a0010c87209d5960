"""The session graph for ``launch/*.launch.py``: which installed executables, with which arguments.

:func:`session_commands` needs no launch package: the install-space test (test/test_packaging.py) starts exactly
its executables with exactly its arguments. Only :func:`describe_session` imports ``launch`` / ``launch_ros``
(``ros2 launch`` on a ROS 2 install; they are not on PyPI); it adds nothing to the commands.
"""
import os
import typing

from rollability_ros.core.graph import load_graph_settings, parameter_files, session_nodes
from rollability_ros.core.rig import launch_backend_class, physical_rig_environment


class NodeCommand(typing.NamedTuple):
    """One node of a session: ``lib/rollability_ros/<executable> <arguments>``; ``restart``: respawn it."""

    executable: str
    arguments: typing.List[str]
    restart: bool


def session_commands(rig_backend: str, optimizer: bool, evaluators: typing.Optional[int] = None, config: str = "",
                     run_dir: str = "runs/session") -> typing.List[NodeCommand]:
    """The :class:`NodeCommand` of every node of a session, in start order.

    ``config``: an extra parameter file on top of the shipped ones; ``evaluators``: overrides
    ``bringup.evaluators`` (None: as configured). Writes each node's own overrides as a parameter file under
    ``run_dir/node-params/`` (:func:`~rollability_ros.core.graph.bringup.override_file`), named last in its arguments.
    """
    param_files = parameter_files(["bringup", *([config] if config else [])])
    settings = load_graph_settings(param_files)
    if evaluators is not None:
        settings.evaluators = evaluators
    launches = session_nodes(settings, run_dir, rig_backend=rig_backend, optimizer=optimizer)
    return [NodeCommand(launch.module, launch.ros_args(param_files, run_dir), launch.restart) for launch in launches]


def _nodes(context, rig_backend, optimizer, evaluators):
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    run_dir = LaunchConfiguration("run_dir").perform(context)
    os.makedirs(run_dir, exist_ok=True)
    commands = session_commands(rig_backend, optimizer, evaluators, LaunchConfiguration("config").perform(context),
                                run_dir)
    # the physical rig's own domain and localhost discovery, unless the operator set them (as `rollability bringup`)
    isolation = []
    if launch_backend_class(rig_backend).authenticated:   # a backend that moves hardware
        from launch.actions import SetEnvironmentVariable

        isolation = [SetEnvironmentVariable(name, value)
                     for name, value in physical_rig_environment(os.environ).items()]
    # name, namespace and parameters are in the arguments already: launch_ros adds nothing to the command line
    return isolation + [Node(package="rollability_ros", executable=command.executable, arguments=command.arguments,
                 output="screen", respawn=command.restart, respawn_delay=2.0)
            for command in commands]


def describe_session(rig_backend: str, optimizer: bool, evaluators: typing.Optional[int] = None) -> typing.Any:
    """A LaunchDescription (``launch`` is untyped here: a ROS 2 install's, not on PyPI) with the ``config`` and
    ``run_dir`` arguments and the session's nodes."""
    import importlib

    from launch.actions import DeclareLaunchArgument, OpaqueFunction

    # by name: mypy, run in the repository, takes its launch/ folder (the launch files) for the launch package
    return importlib.import_module("launch").LaunchDescription([
        DeclareLaunchArgument("config", default_value="", description="extra ROS 2 parameter file (overrides)"),
        DeclareLaunchArgument("run_dir", default_value="runs/session",
                              description="where the outcome store and the bag of this session go"),
        OpaqueFunction(function=_nodes, args=[rig_backend, optimizer, evaluators]),
    ])
