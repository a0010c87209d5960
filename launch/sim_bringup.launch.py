"""Simulation bringup on a full ROS 2 Jazzy install: the same graph as `rollability bringup --backend sim`.

    ros2 launch rollability_ros sim_bringup.launch.py [config:=/path/extra.yaml] [run_dir:=runs/session]

The node list comes from rollability_ros.core.graph.bringup (one definition for the CLI and for ros2 launch); every
node reads the shipped parameter files plus the optional extra one.
"""
from rollability_ros.launch_support import describe_session


def generate_launch_description():
    return describe_session(rig_backend="sim", optimizer=True)
