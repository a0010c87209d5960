"""Robot models the simulation spawns: the built-in chassis, and any wheeled robot from its URDF.

- robot: RobotModel interface, ChassisSpec, ProfileBody
- urdf_description: read and check a URDF into a rigid-body description
- urdf_robot: a URDF robot with the profile on a mount link

The face below is what code outside ``core/robots`` imports (``from rollability_ros.core.robots import
ChassisSpec``). It is lazy (``core/faces.py``): importing it loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller never pays for numpy and PyBullet.
"""
import typing

from rollability_ros.core.faces import lazy_attribute

if typing.TYPE_CHECKING:   # imported when first used: lazy_attribute reads this block
    from rollability_ros.core.robots.robot import (ChassisModel, ChassisSpec, ProfileBody, ProfileMountSpec, RobotModel,
                                                   SpawnedRobot)
    from rollability_ros.core.robots.urdf_robot import (RobotChoice, UrdfRobotModel, UrdfRobotSpec, footprint_grid,
                                                        obj_text, profile_inertia, profile_mount)

__all__ = [
    "ChassisModel", "ChassisSpec", "ProfileBody", "ProfileMountSpec", "RobotChoice", "RobotModel", "SpawnedRobot",
    "UrdfRobotModel", "UrdfRobotSpec", "footprint_grid", "obj_text", "profile_inertia", "profile_mount",
]


def __getattr__(name: str) -> typing.Any:
    return lazy_attribute(__name__, name)
