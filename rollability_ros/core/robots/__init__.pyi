"""The face of ``rollability_ros.core.robots``: the names code outside the subpackage imports, and where each
lives. Type checkers read this stub; at run time ``lazy_loader.attach_stub`` (``__init__.py``) reads the same
imports and loads a name's module when the name is first used."""
from .robot import ChassisModel, ChassisSpec, ProfileBody, ProfileMountSpec, RobotModel, SpawnedRobot
from .urdf_robot import (RobotChoice, UrdfRobotModel, UrdfRobotSpec, footprint_grid, mujoco_mesh_assets, obj_text,
                         profile_inertia, profile_mount)

__all__ = [
    "ChassisModel", "ChassisSpec", "ProfileBody", "ProfileMountSpec", "RobotChoice", "RobotModel", "SpawnedRobot",
    "UrdfRobotModel", "UrdfRobotSpec", "footprint_grid", "mujoco_mesh_assets", "obj_text", "profile_inertia", "profile_mount"
]
