"""Orientation from an IMU: the upright classifier and the tip-over state machine.

- _quaternion: quaternion maths on (x, y, z, w) tuples, roll/pitch/yaw
- upright: tilt, IMU message -> sample, and the IMU upright classifier
- tip_tracker: tip-over state machine behind the tip_monitor node
- launch_motion: a launch's continuous outcomes (final tilt, time to rest, peak deceleration) from its IMU samples

The face is ``__init__.pyi`` beside this file: the names code outside ``core/imu`` imports (``from
rollability_ros.core.imu import <name>``), each with the module it lives in. ``lazy_loader.attach_stub``
(scientific-python SPEC 1) reads it: importing the face loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller (the rig computer) never pays for numpy,
physics or plotting. Type checkers read the same stub. test/core/test_faces.py checks both.
"""
import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
