"""Builds ROS launch descriptions from :mod:`rollability_ros.core.graph.bringup`, for ``launch/*.launch.py``.

Imported only by ``ros2 launch`` on a machine with launch / launch_ros installed (they are not on PyPI).
"""
import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction, SetEnvironmentVariable
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from rollability_ros.core.graph.bringup import load_graph_settings, session_nodes
from rollability_ros.core.graph.node_commands import parameter_files
from rollability_ros.core.rig.rig_network import physical_rig_environment


def _nodes(context, rig_backend, optimizer, evaluators):
    extra = LaunchConfiguration("config").perform(context)
    run_dir = LaunchConfiguration("run_dir").perform(context)
    param_files = parameter_files(["bringup", *([extra] if extra else [])])
    settings = load_graph_settings(param_files)
    if evaluators is not None:
        settings.evaluators = evaluators
    os.makedirs(run_dir, exist_ok=True)
    launches = session_nodes(settings, run_dir, rig_backend=rig_backend, optimizer=optimizer)
    # the physical rig's own domain and localhost discovery, unless the operator set them (as `rollability bringup`)
    isolation = []
    if rig_backend == "physical":
        isolation = [SetEnvironmentVariable(name, value)
                     for name, value in physical_rig_environment(os.environ).items()]
    return isolation + [
        Node(package="rollability_ros", executable=launch.module, name=launch.name or launch.module,
             namespace=launch.namespace or "", parameters=[*param_files, dict(launch.params)], output="screen",
             respawn=launch.restart, respawn_delay=2.0)
        for launch in launches]


def describe_session(rig_backend, optimizer, evaluators=None):
    """A LaunchDescription with the ``config`` and ``run_dir`` arguments and the session's nodes."""
    return LaunchDescription([
        DeclareLaunchArgument("config", default_value="", description="extra ROS 2 parameter file (overrides)"),
        DeclareLaunchArgument("run_dir", default_value="runs/session",
                              description="where the outcome store and the bag of this session go"),
        OpaqueFunction(function=_nodes, args=[rig_backend, optimizer, evaluators]),
    ])
