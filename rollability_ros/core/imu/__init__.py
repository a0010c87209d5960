"""Orientation from an IMU: the upright classifier and the tip-over state machine.

- upright: orientation maths and the IMU upright classifier
- tip_tracker: tip-over state machine behind the tip_monitor node
"""
