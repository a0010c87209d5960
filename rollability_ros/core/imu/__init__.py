"""Orientation from an IMU: the upright classifier and the tip-over state machine.

- _quaternion: quaternion maths on (x, y, z, w) tuples, roll/pitch/yaw
- upright: tilt, IMU message -> sample, and the IMU upright classifier
- tip_tracker: tip-over state machine behind the tip_monitor node
- launch_motion: a launch's continuous outcomes (final tilt, time to rest, peak deceleration) from its IMU samples

The face below is what code outside ``core/imu`` imports (nodes/ and cli/ only through it; test/core/test_faces.py).
It loads nothing heavier than ``math``.
"""
from rollability_ros.core.imu._quaternion import (IDENTITY, normalize_quaternion, quaternion_conjugate,
                                                  quaternion_from_axis_angle, quaternion_from_rpy_deg,
                                                  quaternion_multiply, rotate_vector, rpy_deg_from_quaternion)
from rollability_ros.core.imu.launch_motion import LaunchMotion, LaunchMotionMeter, body_acceleration_mps2
from rollability_ros.core.imu.tip_tracker import (TipMonitorConfig, TipState, TipTracker, TipUpdate,
                                                  diagnostic_status)
from rollability_ros.core.imu.upright import (ImuMount, ImuOutcomeConfig, ImuSample, ImuUprightClassifier,
                                              UprightReading, imu_sample_from_message, orientation_from_acceleration,
                                              tilt_from_acceleration_deg, tilt_from_orientation_deg)

__all__ = [
    "IDENTITY", "normalize_quaternion", "quaternion_conjugate", "quaternion_from_axis_angle",
    "quaternion_from_rpy_deg", "quaternion_multiply", "rotate_vector", "rpy_deg_from_quaternion",
    "LaunchMotion", "LaunchMotionMeter", "body_acceleration_mps2",
    "TipMonitorConfig", "TipState", "TipTracker", "TipUpdate", "diagnostic_status",
    "ImuMount", "ImuOutcomeConfig", "ImuSample", "ImuUprightClassifier", "UprightReading", "imu_sample_from_message",
    "orientation_from_acceleration", "tilt_from_acceleration_deg", "tilt_from_orientation_deg",
]
