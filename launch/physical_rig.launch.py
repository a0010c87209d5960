"""Physical rig bringup on the lab's robot computer (ROS 2 Jazzy): recorder, outcome_logger, valve_controller,
rig with the physical backend, no simulation nodes, so it runs without pybullet.

    ros2 launch rollability_ros physical_rig.launch.py [config:=/path/rig_site.yaml] [run_dir:=runs/rig]

Set the valve backend (gpio or serial_relay) and its wiring in the extra config file (see config/rig.yaml and
docs/firmware.md). Unless ROS_DOMAIN_ID / ROS_AUTOMATIC_DISCOVERY_RANGE are set, the nodes run on ROS domain 73 with
localhost-only discovery (docs/valve-safety.md); export the same in the operator's shells.
"""
from rollability_ros.launch_support import describe_session


def generate_launch_description():
    return describe_session(rig_backend="physical", optimizer=False, evaluators=0)
