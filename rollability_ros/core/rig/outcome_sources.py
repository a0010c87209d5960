"""Where a launch outcome's data besides the verdict come from: the chassis IMU (:class:`ImuOutcome`: the upright
verdict and the continuous outcomes a :class:`~rollability_ros.core.imu.launch_motion.LaunchMotionMeter` measures),
the operator's measured distance rolled (:func:`check_rest_distance`), and the launch twin's result
(:func:`simulated_continuous_outcomes`). Light (no numpy, no physics): the rig computer runs it.
"""
import math
import threading
import time
import typing

from rollability_ros.core.imu import (ImuMount, ImuOutcomeConfig, ImuSample, ImuUprightClassifier, LaunchMotion,
                                      LaunchMotionMeter, UprightReading)
from rollability_ros.core.records import NOT_MEASURED
from rollability_ros.core.rig.launch_backend import not_cancelled

#: The word of a typed outcome that gives the distance rolled, m: ``rolled=0.35``.
ROLLED_WORD = "rolled="


class ImuOutcome:
    """The upright classifier fed from the IMU topic; a launch resets it at firing and waits for its verdict. The
    same samples feed a :class:`~rollability_ros.core.imu.launch_motion.LaunchMotionMeter` (the launch's final tilt,
    time to rest and peak deceleration: :meth:`motion`)."""

    def __init__(self, config):
        self.config = config
        self._classifier = ImuUprightClassifier.from_config(config)
        self._meter = LaunchMotionMeter(config.impact_threshold_mps2, ImuMount.from_rpy_deg(config.mount_rpy_deg))
        self._cond = threading.Condition()
        self._reading = None
        self._settled = None   # the first settled reading since the reset

    def reset(self) -> None:
        """Forget everything before the launch (a chassis waiting on the launcher looks settled too)."""
        with self._cond:
            self._classifier.reset()
            self._meter.reset()
            self._reading = None
            self._settled = None

    def feed(self, sample: ImuSample) -> None:
        """Classify one :class:`~rollability_ros.core.imu.upright.ImuSample`; bad samples raise ``ValueError``."""
        with self._cond:
            reading = self._classifier.update(sample)
            if self._settled is None:
                self._meter.update(sample)
            self._reading = reading
            if reading.classification is not None:
                if self._settled is None:
                    self._settled = reading
                self._cond.notify_all()

    def motion(self) -> LaunchMotion:
        """The continuous outcomes of the launch since the reset (NaN what the IMU did not see)."""
        with self._cond:
            return self._meter.motion(self._settled)

    def wait_settled(self, timeout_s: float, cancelled: typing.Callable[[], bool] = not_cancelled,
                     poll_s: float = 0.05) -> typing.Optional[UprightReading]:
        """The first settled :class:`~rollability_ros.core.imu.upright.UprightReading`, or None on timeout/cancel."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while self._reading is None or self._reading.classification is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0 or cancelled():
                    return None
                self._cond.wait(min(poll_s, remaining))
            return self._reading


def check_rest_distance(value: typing.Union[str, float]) -> float:
    """The distance rolled an operator gives (text or number), m: a finite number >= 0, else ``ValueError``."""
    try:
        distance = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"the distance rolled must be a number of metres >= 0 ({ROLLED_WORD}0.35), got {value!r}") \
            from None
    if not (math.isfinite(distance) and distance >= 0):
        raise ValueError(f"the distance rolled must be a number of metres >= 0 ({ROLLED_WORD}0.35), got {value!r}")
    return distance


def simulated_continuous_outcomes(result: object) -> typing.Dict[str, float]:
    """The continuous outcomes (:data:`~rollability_ros.core.records.CONTINUOUS_OUTCOMES`) of a launch twin result:
    its ``tilt_deg``, ``rest_distance_m``, ``time_to_rest_s`` and ``peak_deceleration_mps2``, each NaN where the twin
    did not see it (a non-finite value; no time to rest after the time cap or an early decision; no peak
    deceleration for a launch that never landed, whose ``landing_position_m`` is NaN)."""
    def finite(name: str, default: float = NOT_MEASURED) -> float:
        value = float(getattr(result, name, default))
        return value if math.isfinite(value) else NOT_MEASURED

    landed = all(math.isfinite(float(v)) for v in getattr(result, "landing_position_m", (NOT_MEASURED,)))
    return {"final_tilt_deg": finite("tilt_deg"), "rest_distance_m": finite("rest_distance_m"),
            "time_to_rest_s": finite("time_to_rest_s"),
            "peak_deceleration_mps2": finite("peak_deceleration_mps2") if landed else NOT_MEASURED}
