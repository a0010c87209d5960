"""Orientation math and the IMU upright classifier (the rig's IMU outcome and the tip monitor share it)."""
import math
import random

import pytest

from synthetic_imu import piecewise, stream
from rollability_ros.core.config import ConfigError, from_mapping, load_parameters, section
from rollability_ros.core.imu.upright import (
    STANDARD_GRAVITY_MPS2, ImuMount, ImuOutcomeConfig, ImuSample, ImuUprightClassifier, normalize_quaternion,
    orientation_from_acceleration, orientation_if_valid, quaternion_conjugate, quaternion_from_axis_angle,
    quaternion_from_rpy_deg, quaternion_multiply, rotate_vector, tilt_from_acceleration_deg,
    tilt_from_orientation_deg)

G = STANDARD_GRAVITY_MPS2


def random_quaternion(rng):
    return normalize_quaternion([rng.gauss(0, 1) for _ in range(4)])


def test_rotation_basics():
    quarter_x = quaternion_from_axis_angle((2, 0, 0), math.pi / 2)
    assert rotate_vector(quarter_x, (0, 1, 0)) == pytest.approx((0, 0, 1))
    rng = random.Random(1)
    for _ in range(50):
        a, b, v = random_quaternion(rng), random_quaternion(rng), (rng.gauss(0, 1), rng.gauss(0, 1), rng.gauss(0, 1))
        assert rotate_vector(quaternion_multiply(a, b), v) == pytest.approx(rotate_vector(a, rotate_vector(b, v)))
        assert rotate_vector(quaternion_conjugate(a), rotate_vector(a, v)) == pytest.approx(v)


@pytest.mark.parametrize("rpy, tilt", [((0, 0, 0), 0), ((0, 0, 135), 0), ((90, 0, 0), 90), ((0, -90, 40), 90),
                                       ((180, 0, 0), 180), ((0, 180, 0), 180), ((30, 0, 0), 30), ((20, 20, 0), None)])
def test_tilt_from_orientation_known_angles(rpy, tilt):
    q = quaternion_from_rpy_deg(*rpy)
    if tilt is None:  # roll then pitch: cos(tilt) = cos(roll) cos(pitch)
        tilt = math.degrees(math.acos(math.cos(math.radians(20)) ** 2))
    assert tilt_from_orientation_deg(q) == pytest.approx(tilt, abs=1e-9)


def test_gravity_tilt_matches_orientation_tilt():
    rng = random.Random(2)
    for _ in range(100):
        q = random_quaternion(rng)
        specific_force = rotate_vector(quaternion_conjugate(q), (0, 0, G))   # what an IMU at rest reads
        assert tilt_from_acceleration_deg(specific_force) == pytest.approx(tilt_from_orientation_deg(q), abs=1e-7)
        estimate = orientation_from_acceleration(specific_force)
        assert rotate_vector(estimate, specific_force) == pytest.approx((0, 0, G), abs=1e-9)
        assert tilt_from_orientation_deg(estimate) == pytest.approx(tilt_from_orientation_deg(q), abs=1e-7)
    assert tilt_from_acceleration_deg((0, 0, G)) == 0.0 and tilt_from_acceleration_deg((0, 0, -G)) == 180.0
    assert tilt_from_orientation_deg(orientation_from_acceleration((0, 0, -G))) == pytest.approx(180.0)
    assert math.isnan(tilt_from_acceleration_deg((0, 0, 0)))
    with pytest.raises(ValueError, match="free fall"):
        orientation_from_acceleration((0, 0, 0))


def test_bad_vectors_and_quaternions_are_refused():
    with pytest.raises(ValueError, match="non-zero"):
        normalize_quaternion((0, 0, 0, 0))
    with pytest.raises(ValueError, match="4 numbers"):
        normalize_quaternion((0, 0, 1))
    with pytest.raises(ValueError, match="acceleration must be finite"):
        tilt_from_acceleration_deg((0, math.nan, 9.8))
    with pytest.raises(ValueError, match="3 angles"):
        ImuMount.from_rpy_deg([0, 0])


def test_missing_orientation_is_recognised():
    assert orientation_if_valid((0, 0, 0, 1), [-1.0] + [0.0] * 8) is None
    assert orientation_if_valid((0, 0, 0, 0), [0.0] * 9) is None
    assert orientation_if_valid((0, 0, 0, 2), [0.01] * 9) == (0, 0, 0, 1)


def test_upside_down_mounted_imu():
    mount = ImuMount.from_rpy_deg([180, 0, 0])   # IMU z points down into the chassis
    imu_from_body = quaternion_conjugate(mount.body_from_imu)
    for with_orientation in (True, False):
        samples = stream(piecewise([(0, 0.0)]), 0.5, with_orientation=with_orientation, imu_from_body=imu_from_body)
        assert samples[0].linear_acceleration_mps2[2] == pytest.approx(-G, abs=0.6), "raw IMU reads -g upright"
        bare = ImuUprightClassifier(30, 0.2, 0.3)
        mounted = ImuUprightClassifier(30, 0.2, 0.3, mount=mount)
        for sample in samples:
            bare_reading, reading = bare.update(sample), mounted.update(sample)
        assert reading.tilt_deg < 5 and reading.classification is True
        assert bare_reading.tilt_deg > 175 and bare_reading.classification is False


def settle_stream(final_tilt_deg, with_orientation, seed=0):
    """On the launcher (still), launched, tumbling to ``final_tilt_deg``, then resting."""
    profile = piecewise([(0, 0.0), (0.5, 0.0), (1.1, final_tilt_deg + 40), (1.4, final_tilt_deg)])
    return stream(profile, 4.0, with_orientation=with_orientation, seed=seed)


@pytest.mark.parametrize("with_orientation", [True, False])
@pytest.mark.parametrize("final_tilt_deg, upright", [(4.0, True), (25.0, True), (95.0, False), (178.0, False)])
def test_launch_outcome_is_classified_after_settling(with_orientation, final_tilt_deg, upright):
    classifier = ImuUprightClassifier(30.0, 1.0, 0.3, require_motion=True)
    readings = [classifier.update(s) for s in settle_stream(final_tilt_deg, with_orientation)]
    first = next(r for r in readings if r.settled)
    assert first.stamp_s == pytest.approx(2.4, abs=0.15), "settled settle_time after the tumble stopped, not before"
    assert not any(r.settled for r in readings if r.stamp_s < 1.4), "still on the launcher is not settled"
    assert first.classification is upright
    assert first.tilt_deg == pytest.approx(final_tilt_deg, abs=3.0)
    assert readings[-1].source == ("orientation" if with_orientation else "gravity")


def test_settled_without_required_motion():
    classifier = ImuUprightClassifier(30.0, 0.5, 0.3)
    readings = [classifier.update(s) for s in stream(piecewise([(0, 0.0)]), 1.0)]
    assert next(r for r in readings if r.settled).stamp_s == pytest.approx(0.5, abs=0.011)
    assert readings[-1].upright_for_s == pytest.approx(1.0)


def test_free_fall_is_not_still_and_tilt_is_unknown():
    classifier = ImuUprightClassifier(30.0, 0.5, 0.3, accel_filter_s=0.0)
    reading = classifier.update(ImuSample(0.0, None, (0, 0, 0), (0, 0, 0)))
    assert math.isnan(reading.tilt_deg) and not reading.still and not reading.upright
    assert reading.classification is None


def test_stamp_going_backwards_restarts_history():
    classifier = ImuUprightClassifier(30.0, 0.5, 0.3)
    for sample in stream(piecewise([(0, 0.0)]), 1.0):
        classifier.update(sample)
    reading = classifier.update(ImuSample(0.2, None, (0, 0, 0), (0, 0, G)))
    assert reading.still_for_s == 0.0 and not reading.settled


def test_imu_outcome_config_from_rig_yaml():
    config = from_mapping(ImuOutcomeConfig, section(load_parameters("rig"), "imu_outcome"), "imu_outcome")
    classifier = ImuUprightClassifier.from_config(config)
    assert classifier.require_motion and classifier.tilt_threshold_deg == config.tilt_threshold_deg
    for bad, match in [({"tilt_threshold_deg": 0.0}, "tilt_threshold_deg"), ({"settle_time_s": -1.0}, "settle_time_s"),
                       ({"mount_rpy_deg": [0.0, 0.0]}, "3 angles"), ({"settle_timeout_s": 0.5}, "settle_timeout_s")]:
        with pytest.raises(ConfigError, match=match):
            from_mapping(ImuOutcomeConfig, bad, "imu_outcome")
