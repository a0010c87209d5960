"""Orientation from an IMU: the upright classifier and the tip-over state machine.

- quaternion: quaternion maths on (x, y, z, w) tuples, roll/pitch/yaw
- upright: tilt, IMU message -> sample, and the IMU upright classifier
- tip_tracker: tip-over state machine behind the tip_monitor node
"""
