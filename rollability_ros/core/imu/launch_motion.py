"""The continuous outcomes of one launch from the chassis IMU: final tilt, time to rest, peak deceleration.

Beside the upright verdict (:class:`~rollability_ros.core.imu.upright.ImuUprightClassifier`), the rig's IMU sees the
landing and the tumble. :class:`LaunchMotionMeter` is fed the same samples from the fire on and reports, with the
classifier's settled reading, what the launch twin reports for a simulated launch
(:class:`~rollability_ros.core.sim.launch_twin.LaunchResult`):

- the acceleration of the body (kinematic, gravity removed) of every sample: with the IMU's orientation,
  ``| R f - g z |`` (``f`` the specific force the accelerometer measures, ``R`` world<-body, ``z`` world up), the
  twin's measure; without an orientation, ``| |f| - g |``, a lower bound of it (the direction of gravity in the
  body is not known during an impact);
- the landing: the first sample whose acceleration exceeds ``impact_threshold_mps2`` (free flight reads about g,
  the landing on the foam several g);
- ``peak_deceleration_mps2``: the largest acceleration from the landing on;
- ``time_to_rest_s``: from the landing until the classifier's rest rule held (its settled reading's stamp: still for
  ``settle_time_s``; the twin's is its trials' hold time);
- ``final_tilt_deg``: the settled reading's tilt.

Each is NaN when the IMU did not see it (no landing above the threshold, no settled reading): never made up.
Pure Python: this runs per IMU sample on the robot computer.
"""
import dataclasses
import math
import typing

from rollability_ros.core.imu._quaternion import normalize_quaternion, rotate_vector, vector3
from rollability_ros.core.imu.upright import STANDARD_GRAVITY_MPS2, ImuMount, ImuSample, UprightReading

NOT_SEEN = math.nan


@dataclasses.dataclass(frozen=True)
class LaunchMotion:
    """The continuous outcomes the IMU saw (NaN = not seen): deg, s, m/s^2, and the landing's stamp (s)."""

    final_tilt_deg: float = NOT_SEEN
    time_to_rest_s: float = NOT_SEEN
    peak_deceleration_mps2: float = NOT_SEEN
    landed_s: float = NOT_SEEN

    def outcome_fields(self) -> typing.Dict[str, float]:
        """The fields of a :class:`~rollability_ros.core.records.LaunchOutcome` this sets."""
        return {"final_tilt_deg": self.final_tilt_deg, "time_to_rest_s": self.time_to_rest_s,
                "peak_deceleration_mps2": self.peak_deceleration_mps2}


def body_acceleration_mps2(sample: ImuSample, mount: ImuMount, gravity_mps2: float = STANDARD_GRAVITY_MPS2) -> float:
    """The magnitude of the body's acceleration (gravity removed), m/s^2, of one sample (module docstring): exact
    with the IMU's orientation, the lower bound ``| |f| - g |`` without one."""
    specific_force = mount.to_body(vector3(sample.linear_acceleration_mps2, "linear_acceleration"))
    if sample.orientation is None:
        return abs(math.hypot(*specific_force) - gravity_mps2)
    world_from_body = mount.body_orientation(normalize_quaternion(sample.orientation))
    fx, fy, fz = rotate_vector(world_from_body, specific_force)
    return math.hypot(fx, fy, fz - gravity_mps2)


class LaunchMotionMeter:
    """Landing, peak deceleration and time to rest of one launch from its IMU samples (module docstring).

    Parameters
    ----------
    impact_threshold_mps2 : float
        The landing is the first sample whose body acceleration exceeds this, m/s^2 (> g: free flight reads g).
    mount : ImuMount, optional
        The IMU's mounting rotation (identity by default).
    gravity_mps2 : float
        Local gravity, m/s^2.
    """

    def __init__(self, impact_threshold_mps2: float, mount: typing.Optional[ImuMount] = None,
                 gravity_mps2: float = STANDARD_GRAVITY_MPS2) -> None:
        if not gravity_mps2 < impact_threshold_mps2 < math.inf:
            raise ValueError(f"impact_threshold_mps2 must exceed g ({gravity_mps2:g} m/s^2: free flight reads that), "
                             f"got {impact_threshold_mps2!r}")
        self.impact_threshold_mps2 = impact_threshold_mps2
        self.mount = mount or ImuMount()
        self.gravity_mps2 = gravity_mps2
        self.reset()

    def reset(self) -> None:
        """Forget the previous launch (call at the fire)."""
        self._landed_s: typing.Optional[float] = None
        self._peak = 0.0

    def update(self, sample: ImuSample) -> None:
        """Feed one sample (after the fire)."""
        acceleration = body_acceleration_mps2(sample, self.mount, self.gravity_mps2)
        if self._landed_s is None and acceleration > self.impact_threshold_mps2:
            self._landed_s = float(sample.stamp_s)
        if self._landed_s is not None:
            self._peak = max(self._peak, acceleration)

    def motion(self, settled: typing.Optional[UprightReading]) -> LaunchMotion:
        """What the launch showed, given the classifier's settled reading (None: it never settled)."""
        landed_s = self._landed_s
        tilt = settled.tilt_deg if settled is not None and settled.settled else NOT_SEEN
        to_rest = NOT_SEEN
        if landed_s is not None and settled is not None and settled.settled and settled.stamp_s >= landed_s:
            to_rest = settled.stamp_s - landed_s
        if landed_s is None:
            return LaunchMotion(final_tilt_deg=tilt)
        return LaunchMotion(final_tilt_deg=tilt, time_to_rest_s=to_rest, peak_deceleration_mps2=self._peak,
                            landed_s=landed_s)
