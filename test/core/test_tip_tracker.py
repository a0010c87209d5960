"""TipTracker on synthetic IMU streams: a tip that rights itself, one that stays stuck, and a rough drive.

Each stream is run with an IMU that reports orientation and with one that does not (gravity only).
Detection latency is measured from the moment the true tilt crosses the tip threshold.
"""
import math

import pytest

from synthetic_imu import piecewise, stream
from rollability_ros.core.config import ConfigError, from_mapping, load_parameters, section
from rollability_ros.core.imu.tip_tracker import (DIAGNOSTIC_ERROR, DIAGNOSTIC_OK, DIAGNOSTIC_STALE, DIAGNOSTIC_WARN,
                                              TipMonitorConfig, TipState, TipTracker, diagnostic_status)
from rollability_ros.core.imu.upright import tilt_from_orientation_deg

CONFIG = TipMonitorConfig(robot="husky")
MODES = pytest.mark.parametrize("with_orientation", [True, False], ids=["orientation", "gravity_only"])


def run(samples, config=CONFIG):
    tracker = TipTracker(config)
    updates = [tracker.update(s) for s in samples]
    changes = [(u.reading.stamp_s, u.state) for u in updates if u.changed]
    events = [u.event for u in updates if u.event is not None]
    return changes, events


def crossing_time(points, threshold_deg):
    """When a piecewise-linear tilt profile first reaches ``threshold_deg``."""
    for (t0, a0), (t1, a1) in zip(points, points[1:]):
        if a0 < threshold_deg <= a1:
            return t0 + (threshold_deg - a0) / (a1 - a0) * (t1 - t0)
    raise ValueError("profile never crosses the threshold")


ROUGH = dict(vibration_mps2=2.0, vibration_radps=0.3, yaw_rate_radps=0.4)


@MODES
def test_tip_that_rights_itself(with_orientation):
    points = [(0, 0.0), (2.0, 0.0), (2.5, 110.0), (4.0, 110.0), (4.8, -8.0), (5.0, 0.0)]
    samples = stream(piecewise(points), 10.0, with_orientation=with_orientation, **ROUGH,
                     bumps=[(1.0, 0.04, 12.0, 1.5)])
    changes, events = run(samples)
    assert [state for _, state in changes] == [TipState.TIPPED, TipState.RIGHTING, TipState.RECOVERED,
                                               TipState.UPRIGHT]
    latency = changes[0][0] - crossing_time(points, CONFIG.tip_threshold_deg)
    print(f"\nself-righting ({'orientation' if with_orientation else 'gravity only'}): "
          f"detection latency {latency * 1000:.0f} ms, recovered at {changes[2][0]:.2f} s")
    assert CONFIG.tip_confirm_s <= latency < CONFIG.tip_confirm_s + 0.25
    (event,) = events
    assert event.recovered and event.robot == "husky" and event.frame_id == "imu_link"
    assert event.tipped_at_s == pytest.approx(crossing_time(points, 60.0), abs=0.15)
    # recovered when it came back within the 30 deg recover threshold (4.54 s), while still driving on
    assert event.tipped_at_s + event.duration_s == pytest.approx(4.0 + 80 / 118 * 0.8, abs=0.15)
    assert event.peak_tilt_deg == pytest.approx(110.0, abs=6.0)
    assert event.peak_angular_rate_radps > math.radians(110 / 0.8) * 0.8
    assert tilt_from_orientation_deg(event.final_orientation) < 10.0
    assert changes[3][0] - changes[2][0] == pytest.approx(CONFIG.recovered_hold_s, abs=0.02)


@MODES
def test_tip_that_stays_stuck_then_is_rescued(with_orientation):
    points = [(0, 0.0), (1.0, 0.0), (1.6, 178.0), (16.0, 178.0), (17.0, 0.0)]
    samples = stream(piecewise(points), 20.0, with_orientation=with_orientation, seed=4)
    changes, events = run(samples)
    assert [state for _, state in changes] == [TipState.TIPPED, TipState.STUCK, TipState.UPRIGHT]
    (event,) = events
    assert not event.recovered
    assert event.duration_s == pytest.approx(CONFIG.give_up_s, abs=0.02)
    assert changes[1][0] == pytest.approx(event.tipped_at_s + CONFIG.give_up_s, abs=0.02)
    assert event.peak_tilt_deg == pytest.approx(178.0, abs=4.0)
    assert tilt_from_orientation_deg(event.final_orientation) > 170.0
    assert changes[2][0] == pytest.approx(17.0 + CONFIG.settle_time_s, abs=0.2), "rescued: upright, no new event"


@MODES
def test_noisy_upright_drive_raises_no_alarm(with_orientation):
    """60 s on rough ground: vibration, a bump every 3 s, 25 deg ramps, brief 30 deg and 70 deg tilts."""
    points = [(0, 0.0)]
    for start in range(5, 55, 10):           # a 25 deg ramp for 2 s, then a brief 30 deg tilt
        points += [(start, 0.0), (start + 0.5, 25.0), (start + 2.5, 25.0), (start + 3.0, 0.0),
                   (start + 5.0, 0.0), (start + 5.2, 30.0), (start + 5.7, 30.0), (start + 5.9, 0.0)]
    points += [(57.0, 0.0), (57.05, 70.0), (57.2, 70.0), (57.25, 0.0)]  # 0.2 s over the tip threshold
    bumps = [(t + 1.3, 0.04, 15.0, 2.0) for t in range(0, 60, 3)]
    samples = stream(piecewise(points), 60.0, with_orientation=with_orientation, vibration_mps2=3.0,
                     vibration_radps=0.5, yaw_rate_radps=0.3, bumps=bumps, seed=7)
    changes, events = run(samples)
    assert changes == [] and events == [], f"false alarms: {changes}"


@MODES
def test_brief_tilt_just_longer_than_confirmation_is_a_tip(with_orientation):
    """The same 70 deg excursion as in the drive test, held 0.5 s: counted (the test above can fail)."""
    points = [(0, 0.0), (2.0, 0.0), (2.05, 70.0), (2.55, 70.0), (2.6, 0.0)]
    changes, events = run(stream(piecewise(points), 6.0, with_orientation=with_orientation))
    assert [state for _, state in changes] == [TipState.TIPPED, TipState.RIGHTING, TipState.RECOVERED,
                                               TipState.UPRIGHT]
    assert events[0].recovered


def test_tipping_again_while_recovered_is_a_new_event():
    points = [(0, 0.0), (1.0, 0.0), (1.3, 100.0), (2.0, 100.0), (2.3, 0.0), (3.8, 0.0), (4.1, 100.0),
              (5.0, 100.0), (5.3, 0.0)]
    changes, events = run(stream(piecewise(points), 9.0))
    assert [state for _, state in changes] == [TipState.TIPPED, TipState.RIGHTING, TipState.RECOVERED,
                                               TipState.TIPPED, TipState.RIGHTING, TipState.RECOVERED,
                                               TipState.UPRIGHT]
    assert [e.recovered for e in events] == [True, True]
    assert events[1].tipped_at_s == pytest.approx(crossing_time(points[5:], 60.0), abs=0.05)


def test_resting_inside_the_hysteresis_band_is_not_recovered():
    points = [(0, 0.0), (1.0, 0.0), (1.5, 90.0), (2.0, 45.0)]   # leans on something at 45 deg
    changes, events = run(stream(piecewise(points), 12.5))
    assert [state for _, state in changes] == [TipState.TIPPED, TipState.STUCK]
    assert not events[0].recovered


def test_tip_monitor_yaml_and_validation():
    config = from_mapping(TipMonitorConfig, section(load_parameters("tip_monitor"), "tip_monitor"), "tip_monitor")
    assert config.tip_threshold_deg > config.recover_threshold_deg
    for bad, match in [({"tip_threshold_deg": 30.0, "recover_threshold_deg": 40.0}, "hysteresis"),
                       ({"give_up_s": 0.5}, "give_up_s"), ({"settle_time_s": 0.0}, "settle_time_s"),
                       ({"mount_rpy_deg": [1.0]}, "3 angles"), ({"robot": ""}, "non-empty"),
                       ({"tilt_deg": 3.0}, "unknown parameter")]:
        with pytest.raises(ConfigError, match=match):
            from_mapping(TipMonitorConfig, bad, "tip_monitor")


def test_diagnostic_levels():
    assert diagnostic_status(TipState.UPRIGHT, 3.0, 0.01, 1.0) == (DIAGNOSTIC_OK, "upright, tilt 3 deg")
    assert diagnostic_status(TipState.RECOVERED, 3.0, 0.01, 1.0)[0] == DIAGNOSTIC_OK
    assert diagnostic_status(TipState.TIPPED, 95.0, 0.01, 1.0)[0] == DIAGNOSTIC_WARN
    assert diagnostic_status(TipState.RIGHTING, 20.0, 0.01, 1.0)[0] == DIAGNOSTIC_WARN
    assert diagnostic_status(TipState.STUCK, 180.0, 0.01, 1.0) == (DIAGNOSTIC_ERROR, "stuck, tilt 180 deg")
    assert diagnostic_status(TipState.UPRIGHT, 0.0, 2.5, 1.0) == (DIAGNOSTIC_STALE, "no IMU data for 2.5 s")
    assert diagnostic_status(TipState.UPRIGHT, 0.0, None, 1.0) == (DIAGNOSTIC_STALE, "no IMU data for ever")
    assert TipState.STUCK.label == "stuck" and int(TipState.RIGHTING) == 2
