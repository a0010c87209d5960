"""The face of ``rollability_ros.core.imu``: the names code outside the subpackage imports, and where each
lives. Type checkers read this stub; at run time ``lazy_loader.attach_stub`` (``__init__.py``) reads the same
imports and loads a name's module when the name is first used."""
from .launch_motion import LaunchMotion, LaunchMotionMeter, body_acceleration_mps2
from .tip_tracker import TipMonitorConfig, TipState, TipTracker, TipUpdate, diagnostic_status
from .upright import (ImuMount, ImuOutcomeConfig, ImuSample, ImuUprightClassifier, UprightReading,
                      imu_sample_from_message, orientation_from_acceleration, tilt_from_acceleration_deg,
                      tilt_from_orientation_deg)
from ._quaternion import (IDENTITY, normalize_quaternion, quaternion_conjugate, quaternion_from_axis_angle,
                          quaternion_from_rpy_deg, quaternion_multiply, rotate_vector, rpy_deg_from_quaternion)

__all__ = [
    "IDENTITY", "ImuMount", "ImuOutcomeConfig", "ImuSample", "ImuUprightClassifier", "LaunchMotion",
    "LaunchMotionMeter", "body_acceleration_mps2", "TipMonitorConfig", "TipState",
    "TipTracker", "TipUpdate", "UprightReading", "diagnostic_status", "imu_sample_from_message", "normalize_quaternion",
    "orientation_from_acceleration", "quaternion_conjugate", "quaternion_from_axis_angle", "quaternion_from_rpy_deg",
    "quaternion_multiply", "rotate_vector", "rpy_deg_from_quaternion", "tilt_from_acceleration_deg",
    "tilt_from_orientation_deg"
]
