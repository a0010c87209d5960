"""Robot models the simulation spawns: the built-in chassis, and any wheeled robot from its URDF.

- robot: RobotModel interface, ChassisSpec, ProfileBody
- urdf_description: read and check a URDF into a rigid-body description
- urdf_robot: a URDF robot with the profile on a mount link
"""
