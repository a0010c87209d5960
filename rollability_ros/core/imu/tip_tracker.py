"""Rollability in the field: the tip-over state machine behind the ``tip_monitor`` node.

States (``msg/TipState.msg``)::

    UPRIGHT --tilt >= tip threshold for tip_confirm_s--> TIPPED --tilt < recover threshold--> RIGHTING
    RIGHTING --tilt >= tip threshold--> TIPPED
    RIGHTING --tilt < recover threshold for settle_time_s--> RECOVERED           (event, recovered)
    TIPPED / RIGHTING --give_up_s after tipping--> STUCK                          (event, not recovered)
    RECOVERED --recovered_hold_s--> UPRIGHT;  RECOVERED --tips again--> TIPPED (a new event)
    STUCK --tilt < recover threshold for settle_time_s (rescued)--> UPRIGHT

The tip threshold is above the recover threshold (hysteresis), so a body wobbling around one angle does not
flap between states; tilts below the tip threshold (ramps, bumps) never leave UPRIGHT. Recovery needs the tilt
back within the recover threshold for ``settle_time_s``, not stillness: a robot that rights itself and drives
on has recovered. Tilt (orientation, or low-pass gravity for IMUs without one) and the IMU mounting come from
:class:`~rollability_ros.core.imu.upright.ImuUprightClassifier`, the rig's classifier.
"""
import dataclasses
import enum
import logging
import math
import typing

from rollability_ros.core.config import check_settings
from rollability_ros.core.records import TipEventRecord
from rollability_ros.core.imu.upright import ImuMount, ImuSample, ImuUprightClassifier, UprightReading

_LOG = logging.getLogger(__name__)


class TipState(enum.IntEnum):
    """Tip states; values are the constants of ``msg/TipState.msg``."""

    UPRIGHT = 0
    TIPPED = 1
    RIGHTING = 2
    RECOVERED = 3
    STUCK = 4

    @property
    def label(self) -> str:
        """The state as lower-case text (``TipState.label``)."""
        return self.name.lower()


#: ``diagnostic_msgs/DiagnosticStatus`` levels.
DIAGNOSTIC_OK, DIAGNOSTIC_WARN, DIAGNOSTIC_ERROR, DIAGNOSTIC_STALE = 0, 1, 2, 3


@dataclasses.dataclass
class TipMonitorConfig:
    """``tip_monitor.*`` of ``config/tip_monitor.yaml``: the robot, its IMU and the tip thresholds."""

    robot: str = dataclasses.field(default="robot", metadata={
        "description": "name of the watched robot, written into events and diagnostics"})
    imu_topic: str = dataclasses.field(default="imu/data", metadata={
        "description": "sensor_msgs/Imu topic of the robot's IMU"})
    mount_rpy_deg: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0], metadata={
        "description": "rotation IMU frame -> robot body frame as roll, pitch, yaw about fixed axes, deg"})
    tip_threshold_deg: float = dataclasses.field(default=60.0, metadata={
        "description": "tilt of the body +z axis from world up above which the robot is tipping, deg",
        "range": (0.0, 180.0), "exclusive": "high"})
    recover_threshold_deg: float = dataclasses.field(default=30.0, metadata={
        "description": "tilt below which the robot counts as back upright (must be below the tip threshold), deg",
        "range": (0.0, 180.0), "exclusive": "low"})
    tip_confirm_s: float = dataclasses.field(default=0.3, metadata={
        "description": "the tilt must stay above the tip threshold this long to count as tipped, s",
        "range": (0.0, 3600.0)})
    settle_time_s: float = dataclasses.field(default=1.0, metadata={
        "description": "the tilt must stay below the recover threshold this long to count as recovered, s",
        "range": (0.0, 3600.0), "exclusive": "low"})
    give_up_s: float = dataclasses.field(default=10.0, metadata={
        "description": "a tip-over not recovered this long after it began is STUCK, s",
        "range": (0.0, 86400.0), "exclusive": "low"})
    recovered_hold_s: float = dataclasses.field(default=2.0, metadata={
        "description": "time RECOVERED is shown before the state returns to UPRIGHT, s", "range": (0.0, 3600.0)})
    accel_filter_s: float = dataclasses.field(default=0.1, metadata={
        "description": "low-pass time constant of the gravity estimate used without orientation, s",
        "range": (0.0, 10.0)})
    imu_timeout_s: float = dataclasses.field(default=1.0, metadata={
        "description": "no IMU sample this long: diagnostics go STALE, s", "range": (0.0, 3600.0), "exclusive": "low"})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if not self.robot or not self.imu_topic:
            raise ValueError("robot and imu_topic must be non-empty")
        if not self.recover_threshold_deg < self.tip_threshold_deg:
            raise ValueError(f"need recover_threshold_deg ({self.recover_threshold_deg}) < tip_threshold_deg "
                             f"({self.tip_threshold_deg}): the hysteresis band must not be empty")
        if not self.give_up_s > self.settle_time_s:
            raise ValueError(f"give_up_s ({self.give_up_s}) must exceed settle_time_s ({self.settle_time_s}): "
                             "a robot must have time to right itself before it is declared stuck")
        self.classifier()

    def classifier(self) -> ImuUprightClassifier:
        """The upright classifier these thresholds configure (upright = within the recover threshold)."""
        return ImuUprightClassifier(self.recover_threshold_deg, self.settle_time_s,
                                    accel_filter_s=self.accel_filter_s, mount=ImuMount.from_rpy_deg(self.mount_rpy_deg))


@dataclasses.dataclass(frozen=True)
class TipUpdate:
    """The tracker after one sample: state, whether it just changed, the reading, and a finished event if any."""

    state: TipState
    changed: bool
    reading: UprightReading
    event: TipEventRecord | None = None


class TipTracker:
    """Tracks one robot's tip-overs from its IMU samples; see the module docstring for the state machine."""

    def __init__(self, config):
        check_settings(config, "tip_monitor")
        self.config = config
        self._classifier = config.classifier()
        self.state = TipState.UPRIGHT
        self.last_reading = None
        self._above_since = None      # first sample of the current stretch above the tip threshold
        self._tipped_at: typing.Optional[float] = None
        self._recovered_at = None
        self._peak_tilt = 0.0
        self._peak_rate = 0.0

    def update(self, sample: ImuSample) -> "TipUpdate":
        """Feed one :class:`~rollability_ros.core.imu.upright.ImuSample`; return a :class:`TipUpdate`."""
        cfg = self.config
        reading = self.last_reading = self._classifier.update(sample)
        now, tilt = reading.stamp_s, reading.tilt_deg
        above_tip = tilt >= cfg.tip_threshold_deg               # False while the tilt is unknown (NaN)
        back_upright = reading.upright_for_s >= cfg.settle_time_s
        previous, event = self.state, None

        if self.state in (TipState.UPRIGHT, TipState.RECOVERED):
            if above_tip:
                if self._above_since is None:
                    self._above_since, self._peak_tilt, self._peak_rate = now, 0.0, 0.0
                self._track_peaks(reading)
                if now - self._above_since >= cfg.tip_confirm_s:
                    self._tipped_at, self._above_since = self._above_since, None
                    self.state = TipState.TIPPED
            elif not math.isnan(tilt):
                self._above_since = None
                if self.state == TipState.RECOVERED and now - self._recovered_at >= cfg.recovered_hold_s:
                    self.state = TipState.UPRIGHT
        elif self.state in (TipState.TIPPED, TipState.RIGHTING):
            self._track_peaks(reading)
            if back_upright:
                self._recovered_at = now
                self.state = TipState.RECOVERED
                event = self._event(sample, reading, now - reading.upright_for_s - self._tipped_at, recovered=True)
            elif now - self._tipped_at >= cfg.give_up_s:
                self.state = TipState.STUCK
                event = self._event(sample, reading, now - self._tipped_at, recovered=False)
            elif self.state == TipState.TIPPED and reading.upright:
                self.state = TipState.RIGHTING
            elif self.state == TipState.RIGHTING and above_tip:
                self.state = TipState.TIPPED
        elif self.state == TipState.STUCK and back_upright:
            _LOG.info("%s: upright again after being stuck (rescued or a late recovery)", cfg.robot)
            self.state = TipState.UPRIGHT

        changed = self.state != previous
        if changed:
            _LOG.info("%s: %s -> %s at %.3f s (tilt %.1f deg)", cfg.robot, previous.label, self.state.label, now, tilt)
        return TipUpdate(self.state, changed, reading, event)

    def _track_peaks(self, reading):
        if not math.isnan(reading.tilt_deg):
            self._peak_tilt = max(self._peak_tilt, reading.tilt_deg)
        self._peak_rate = max(self._peak_rate, reading.angular_rate_radps)

    def _event(self, sample, reading, duration_s, recovered):
        assert self._tipped_at is not None   # an event ends a tip that started
        record = TipEventRecord(
            robot=self.config.robot, tipped_at_s=self._tipped_at, duration_s=duration_s, recovered=recovered,
            peak_tilt_deg=self._peak_tilt, peak_angular_rate_radps=self._peak_rate,
            final_orientation=tuple(reading.orientation), frame_id=sample.frame_id, stamp_s=reading.stamp_s,
        )
        _LOG.info("%s: tip-over %s after %.2f s (peak tilt %.0f deg, peak rate %.1f rad/s)", record.robot,
                  "recovered" if recovered else "gave up", duration_s, record.peak_tilt_deg,
                  record.peak_angular_rate_radps)
        return record


def diagnostic_status(state: TipState, tilt_deg: float, seconds_since_sample: typing.Optional[float],
                      imu_timeout_s: float) -> typing.Tuple[int, str]:
    """Return ``(level, message)`` for ``diagnostic_msgs/DiagnosticStatus``.

    OK upright / recovered, WARN tipped / righting, ERROR stuck, STALE when no IMU sample for ``imu_timeout_s``.
    """
    if seconds_since_sample is None or seconds_since_sample > imu_timeout_s:
        waited = "ever" if seconds_since_sample is None else f"{seconds_since_sample:.1f} s"
        return DIAGNOSTIC_STALE, f"no IMU data for {waited}"
    level = {TipState.UPRIGHT: DIAGNOSTIC_OK, TipState.RECOVERED: DIAGNOSTIC_OK, TipState.TIPPED: DIAGNOSTIC_WARN,
             TipState.RIGHTING: DIAGNOSTIC_WARN, TipState.STUCK: DIAGNOSTIC_ERROR}[state]
    return level, f"{state.label}, tilt {tilt_deg:.0f} deg"
