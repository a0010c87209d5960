"""A generated robot unlike the Husky and the chassis: small, two drive wheels and a caster wheel, a high
underside (the body's bottom 0.10 m up; the drive wheels behind the middle, a caster wheel in front), a tall sensor mast with a spinning lidar on top (0.6 m), and its
robot config (a ROS 2 parameter file, the only thing a user writes for a new robot: docs/other-robots.md)."""

#: The mast robot's base box: length, width, height (m), its bottom 0.10 m above the ground.
BODY_SIZE_M = (0.30, 0.24, 0.08)
#: Height of the mount surface (top of the body box) in the base_link frame (m).
MOUNT_TOP_M = BODY_SIZE_M[2] / 2


def _inertial(mass_kg, ixx, iyy, izz):
    return (f'<inertial><mass value="{mass_kg}"/><origin xyz="0 0 0"/>'
            f'<inertia ixx="{ixx}" ixy="0" ixz="0" iyy="{iyy}" iyz="0" izz="{izz}"/></inertial>')


def _wheel(name, x, y, z, radius, width, mass_kg):
    izz = mass_kg * radius ** 2 / 2
    side = mass_kg * (3 * radius ** 2 + width ** 2) / 12
    return (f'<link name="{name}"><collision><origin rpy="1.5708 0 0"/><geometry><cylinder radius="{radius}" '
            f'length="{width}"/></geometry></collision>{_inertial(mass_kg, side, izz, side)}</link>'
            f'<joint name="{name}_joint" type="continuous"><parent link="base_link"/><child link="{name}"/>'
            f'<origin xyz="{x} {y} {z}"/><axis xyz="0 1 0"/></joint>')


def mast_robot_urdf():
    """The URDF text: base_link (box) with a top_plate frame, left/right drive wheels (r 0.10 m), a front caster
    wheel (r 0.03 m), a mast (fixed, rear) and a lidar on a continuous joint on the mast's top."""
    length, width, height = BODY_SIZE_M
    axle_z = -height / 2 - 0.10 + 0.10          # body bottom 0.10 m up; drive wheel radius 0.10 m
    return f"""<?xml version="1.0"?>
<robot name="mast_bot">
  <link name="base_link"><collision><geometry><box size="{length} {width} {height}"/></geometry></collision>
    {_inertial(6.0, 0.032, 0.048, 0.074)}</link>
  <link name="top_plate"/>
  <joint name="top_plate_joint" type="fixed"><parent link="base_link"/><child link="top_plate"/>
    <origin xyz="0 0 {MOUNT_TOP_M}"/></joint>
  {_wheel("left_wheel", -0.06, 0.155, axle_z, 0.10, 0.04, 0.6)}
  {_wheel("right_wheel", -0.06, -0.155, axle_z, 0.10, 0.04, 0.6)}
  {_wheel("front_caster", 0.12, 0.0, axle_z - 0.07, 0.03, 0.02, 0.05)}
  <link name="mast_link"><collision><origin xyz="0 0 0.175"/><geometry><cylinder radius="0.015" length="0.35"/>
    </geometry></collision>{_inertial(0.3, 0.003, 0.003, 0.0001)}</link>
  <joint name="mast_joint" type="fixed"><parent link="base_link"/><child link="mast_link"/>
    <origin xyz="-0.10 0 {MOUNT_TOP_M}"/></joint>
  <link name="lidar_link"><collision><geometry><cylinder radius="0.05" length="0.06"/></geometry></collision>
    {_inertial(0.4, 0.0004, 0.0004, 0.0005)}</link>
  <joint name="lidar_joint" type="continuous"><parent link="mast_link"/><child link="lidar_link"/>
    <origin xyz="0 0 0.38"/><axis xyz="0 0 1"/></joint>
</robot>
"""


def mast_robot_config(urdf_path, footprint_offset_x_m=0.06, footprint_length_m=0.16, extra=""):
    """The robot config for the mast robot at ``urdf_path``: the profile in front of the mast, on the body top."""
    return f"""/**:
  ros__parameters:
    urdf_robot:
      urdf_path: {urdf_path}
      mount_link: top_plate
      footprint_length_m: {footprint_length_m}
      footprint_width_m: 0.2
      footprint_offset_m: [{footprint_offset_x_m}, 0.0, 0.0]
      wheel_link_regex: "(left|right)_wheel"
      min_wheels_in_contact: 2
      up_axis_xyz: [0.0, 0.0, 1.0]
      upright_tilt_deg: 30.0
      contact_tolerance_m: 0.005
      joint_drag_torque_nm: 0.05
      profile_print:
        model: solid
        solid_density_kgpm3: 60.0
{extra}"""
