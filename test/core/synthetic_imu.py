"""Synthetic IMU streams for the upright classifier and tip tracker tests.

A scripted body motion (tilt about a horizontal body axis, optional heading rate) is sampled into
``ImuSample``s: orientation world<-imu, angular velocity from consecutive orientations, and the specific force
``R^T (0, 0, g)`` plus vibration, bumps and white noise, all in the IMU frame (identity mount unless given).
"""
import math
import random

from rollability_ros.core.imu.upright import (STANDARD_GRAVITY_MPS2, ImuSample, quaternion_conjugate,
                                          quaternion_from_axis_angle, quaternion_multiply, rotate_vector)


def piecewise(points):
    """Tilt profile (deg) interpolated linearly between ``[(t_s, tilt_deg), ...]``, held after the last point."""
    def tilt_deg(t):
        if t <= points[0][0]:
            return points[0][1]
        for (t0, a0), (t1, a1) in zip(points, points[1:]):
            if t <= t1:
                return a0 + (a1 - a0) * (t - t0) / (t1 - t0)
        return points[-1][1]
    return tilt_deg


def stream(tilt_deg, duration_s, rate_hz=100.0, axis=(1.0, 0.0, 0.0), yaw_rate_radps=0.0, seed=0,
           gyro_noise_radps=0.02, accel_noise_mps2=0.15, vibration_mps2=0.0, vibration_hz=23.0,
           vibration_radps=0.0, bumps=(), with_orientation=True, imu_from_body=(0.0, 0.0, 0.0, 1.0)):
    """Sample a scripted motion into a list of ``ImuSample`` (stamps from 0 s).

    ``bumps`` is ``[(t_s, length_s, accel_mps2, rate_radps), ...]``: half-sine shocks on the body's x and z
    acceleration and x rate. ``imu_from_body`` mounts the IMU rotated against the body frame.
    """
    rng = random.Random(seed)
    dt = 1.0 / rate_hz

    def body_orientation(t):
        yaw = quaternion_from_axis_angle((0, 0, 1), yaw_rate_radps * t)
        return quaternion_multiply(yaw, quaternion_from_axis_angle(axis, math.radians(tilt_deg(t))))

    phases = [rng.uniform(0, 2 * math.pi) for _ in range(6)]
    samples = []
    for i in range(int(round(duration_s * rate_hz)) + 1):
        t = i * dt
        q_now, q_next = body_orientation(t), body_orientation(t + dt)
        delta = quaternion_multiply(quaternion_conjugate(q_now), q_next)
        sign = 2.0 if delta[3] >= 0 else -2.0
        rate = [sign * c / dt for c in delta[:3]]                       # body frame, small-angle
        accel = list(rotate_vector(quaternion_conjugate(q_now), (0.0, 0.0, STANDARD_GRAVITY_MPS2)))
        for k in range(3):
            accel[k] += vibration_mps2 * math.sin(2 * math.pi * vibration_hz * t + phases[k])
            accel[k] += rng.gauss(0.0, accel_noise_mps2)
            rate[k] += vibration_radps * math.sin(2 * math.pi * vibration_hz * 1.3 * t + phases[3 + k])
            rate[k] += rng.gauss(0.0, gyro_noise_radps)
        for start, length, accel_peak, rate_peak in bumps:
            if start <= t < start + length:
                shape = math.sin(math.pi * (t - start) / length)
                accel[0] += accel_peak * shape
                accel[2] += accel_peak * shape
                rate[0] += rate_peak * shape
        orientation = quaternion_multiply(q_now, quaternion_conjugate(imu_from_body)) if with_orientation else None
        samples.append(ImuSample(t, orientation, rotate_vector(imu_from_body, rate),
                                 rotate_vector(imu_from_body, accel), "imu_link"))
    return samples
