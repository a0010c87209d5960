"""A launch's continuous outcomes from its IMU (issue 44.2): the landing, the peak deceleration, the time to rest and
the final tilt, on synthetic IMU traces with a known impact and tumble."""
import math

import pytest
from synthetic_imu import piecewise, stream

from rollability_ros.core.imu import ImuMount, ImuOutcomeConfig, ImuUprightClassifier, LaunchMotionMeter

#: The scripted launch: on the launcher until the landing's half-sine shock at 0.60 s (0.05 s long, 80 m/s^2 on the
#: body's x and z), a tumble onto its back from 0.65 s to 1.2 s, then still.
IMPACT_S, IMPACT_LENGTH_S, IMPACT_MPS2 = 0.60, 0.05, 80.0
TUMBLE = piecewise([(0.0, 0.0), (0.65, 0.0), (1.2, 180.0)])


def _measure(samples, settle_time_s=1.0, threshold=30.0, mount=ImuMount()):
    classifier = ImuUprightClassifier(30.0, settle_time_s, mount=mount, require_motion=True)
    meter = LaunchMotionMeter(threshold, mount)
    settled = None
    for sample in samples:
        reading = classifier.update(sample)
        meter.update(sample)
        if reading.classification is not None:
            settled = reading
            break
    return meter.motion(settled)


def _launch(**options):
    return stream(TUMBLE, 3.0, rate_hz=100.0, seed=5, bumps=[(IMPACT_S, IMPACT_LENGTH_S, IMPACT_MPS2, 4.0)],
                  **options)


def test_landing_peak_deceleration_time_to_rest_and_final_tilt_of_a_synthetic_launch():
    motion = _measure(_launch())
    # samples every 10 ms: the shock's first sample above 30 m/s^2 is at 0.61 s (sqrt(2) 80 sin(36 deg) = 66.5)
    assert motion.landed_s == pytest.approx(0.61, abs=1e-9)
    # its largest sample: sqrt(2) 80 sin(72 deg), the shock along x and z, gravity removed through the orientation
    assert motion.peak_deceleration_mps2 == pytest.approx(math.sqrt(2) * IMPACT_MPS2 * math.sin(0.4 * math.pi),
                                                          abs=1.0)
    # still from 1.2 s on (the tumble ends), settled 1.0 s later: the rest rule holds at 2.2 s
    assert motion.time_to_rest_s == pytest.approx(2.2 - 0.61, abs=0.011)
    assert motion.final_tilt_deg == pytest.approx(180.0, abs=1.0)


def test_without_orientation_the_peak_is_a_lower_bound_and_a_mounted_imu_reads_the_same():
    exact = _measure(_launch())
    bound = _measure(_launch(with_orientation=False))
    assert IMPACT_MPS2 < bound.peak_deceleration_mps2 <= exact.peak_deceleration_mps2 + 0.5
    assert bound.time_to_rest_s == pytest.approx(exact.time_to_rest_s, abs=0.02)
    turned = (0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4))   # IMU yawed 90 deg on the chassis
    mounted = _measure(_launch(imu_from_body=turned), mount=ImuMount.from_rpy_deg([0.0, 0.0, -90.0]))
    assert mounted.peak_deceleration_mps2 == pytest.approx(exact.peak_deceleration_mps2, abs=1.0)
    assert mounted.final_tilt_deg == pytest.approx(exact.final_tilt_deg, abs=1.0)


def test_what_the_imu_did_not_see_is_nan_never_made_up():
    gentle = _measure(stream(TUMBLE, 3.0, rate_hz=100.0, seed=5))      # no shock above the threshold: no landing
    assert math.isnan(gentle.peak_deceleration_mps2) and math.isnan(gentle.time_to_rest_s)
    assert gentle.final_tilt_deg == pytest.approx(180.0, abs=1.0)     # the settled tilt is still measured
    unsettled = _measure(_launch()[:150])                             # the trace ends before the rest rule held
    assert math.isnan(unsettled.final_tilt_deg) and math.isnan(unsettled.time_to_rest_s)
    assert unsettled.peak_deceleration_mps2 > IMPACT_MPS2              # the impact was seen


def test_an_impact_threshold_at_or_below_g_is_refused():
    with pytest.raises(ValueError, match="impact_threshold_mps2 must exceed g"):
        LaunchMotionMeter(9.0)
    from rollability_ros.core.config import ConfigError, check_settings

    with pytest.raises(ConfigError, match="imu_outcome.impact_threshold_mps2"):
        check_settings(ImuOutcomeConfig(impact_threshold_mps2=5.0), "imu_outcome")
    check_settings(ImuOutcomeConfig(), "imu_outcome")
