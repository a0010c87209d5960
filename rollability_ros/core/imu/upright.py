"""Is the body upright? Tilt from orientation or gravity, and the IMU upright classifier shared by the rig and the
tip monitor (quaternion maths: :mod:`rollability_ros.core.imu._quaternion`).

Conventions (ROS, REP-103 / REP-145): quaternions are ``(x, y, z, w)``; the world frame has +z up; an IMU's
``orientation`` rotates its own frame into the world frame; an accelerometer at rest measures the reaction to
gravity, so an upright body at rest reads ``+g`` along its +z axis (gravity itself points along body -z). The
*tilt* is the angle between the body's +z axis and world up: 0 deg upright, 90 deg on its side, 180 deg inverted.
The IMU's mounting is a rotation ``imu frame -> body frame`` (``v_body = mount * v_imu``).

Pure Python on 3-vectors and 4-tuples: this runs per IMU sample on a robot computer.
"""
import dataclasses
import logging
import math
import typing

from rollability_ros.core.imu._quaternion import (  # noqa: F401  (re-exported: the classifier's frame maths)
    IDENTITY,
    Quaternion,
    Vector3,
    normalize_quaternion,
    quaternion_conjugate,
    quaternion_from_axis_angle,
    quaternion_from_rpy_deg,
    quaternion_multiply,
    rotate_vector,
    vector3 as _vector3,
)
from rollability_ros.core.record_messages import stamp_to_s

_LOG = logging.getLogger(__name__)

#: Standard gravity, m/s^2.
STANDARD_GRAVITY_MPS2 = 9.80665


def tilt_from_orientation_deg(orientation: typing.Iterable[float]) -> float:
    """Angle (deg, 0..180) between the body's +z axis and world up, from the orientation (x, y, z, w) world<-body."""
    x, y, z, w = normalize_quaternion(orientation)
    # body +z expressed in the world frame: third column of the rotation matrix
    up_x, up_y, up_z = 2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)
    return math.degrees(math.atan2(math.hypot(up_x, up_y), up_z))


def tilt_from_acceleration_deg(acceleration_body: typing.Iterable[float]) -> float:
    """Angle (deg, 0..180) between body +z and the measured specific force (world up at rest); NaN in free fall."""
    ax, ay, az = _vector3(acceleration_body, "acceleration")
    if math.hypot(ax, ay, az) < 1e-9:
        return math.nan
    return math.degrees(math.atan2(math.hypot(ax, ay), az))


def orientation_from_acceleration(acceleration_body: typing.Iterable[float]) -> Quaternion:
    """Yaw-free orientation world<-body (x, y, z, w) that turns the measured specific force onto world up.

    The heading is unobservable from gravity; this is the shortest rotation, so yaw is zero-ish by construction.
    """
    ax, ay, az = _vector3(acceleration_body, "acceleration")
    norm = math.hypot(ax, ay, az)
    if norm < 1e-9:
        raise ValueError("acceleration is zero (free fall): no gravity direction to orient by")
    ux, uy, uz = ax / norm, ay / norm, az / norm
    if uz < -1 + 1e-12:  # exactly inverted: any horizontal axis; pick body x
        return (1.0, 0.0, 0.0, 0.0)
    # shortest arc u -> z: axis u x z = (uy, -ux, 0), w = 1 + u.z, then normalise
    return normalize_quaternion((uy, -ux, 0.0, 1.0 + uz))


def orientation_if_valid(orientation: typing.Sequence[float],
                         orientation_covariance: typing.Optional[typing.Sequence[float]] = None
                         ) -> typing.Optional[Quaternion]:
    """Return the IMU's orientation (x, y, z, w), or None when the IMU does not provide one.

    ``sensor_msgs/Imu`` marks a missing orientation with ``orientation_covariance[0] == -1``; some drivers send
    an all-zero quaternion instead.
    """
    if orientation_covariance is not None and len(orientation_covariance) and orientation_covariance[0] == -1:
        return None
    if math.hypot(*orientation) < 1e-6:
        return None
    return normalize_quaternion(orientation)


class ImuMount:
    """The IMU's mounting rotation ``imu frame -> body frame``, applied to every sample."""

    def __init__(self, rotation=IDENTITY):
        self.body_from_imu = normalize_quaternion(rotation)

    @classmethod
    def from_rpy_deg(cls, rpy_deg: typing.Sequence[float]) -> "ImuMount":
        """Mount from (roll, pitch, yaw) in degrees, fixed axes."""
        if len(rpy_deg) != 3:
            raise ValueError(f"mount rotation must be 3 angles (roll, pitch, yaw) in deg, got {rpy_deg!r}")
        return cls(quaternion_from_rpy_deg(*rpy_deg))

    def body_orientation(self, world_from_imu: typing.Sequence[float]) -> Quaternion:
        """Orientation world<-body from the IMU's orientation world<-imu."""
        return quaternion_multiply(world_from_imu, quaternion_conjugate(self.body_from_imu))

    def to_body(self, vector_imu: typing.Sequence[float]) -> Vector3:
        """A vector (angular velocity, acceleration) from the IMU frame into the body frame (lever arm ignored)."""
        return rotate_vector(self.body_from_imu, vector_imu)


@dataclasses.dataclass(frozen=True)
class ImuSample:
    """One IMU reading (``sensor_msgs/Imu``), in the IMU's frame.

    ``orientation`` is world<-imu (x, y, z, w) or None when the IMU gives none (see :func:`orientation_if_valid`);
    ``angular_velocity_radps`` in rad/s, ``linear_acceleration_mps2`` in m/s^2 (gravity reaction included);
    ``orientation_unusable``: the message had a non-finite orientation, dropped for the tilt from gravity.
    """

    stamp_s: float
    orientation: tuple | None
    angular_velocity_radps: tuple
    linear_acceleration_mps2: tuple
    frame_id: str = ""
    orientation_unusable: bool = False


def imu_sample_from_message(msg: typing.Any, arrival_s: float) -> ImuSample:
    """A ``sensor_msgs/Imu`` message (rclpy or rosbags) -> :class:`ImuSample`; ``ValueError`` naming the bad field.

    ``arrival_s`` (s since the epoch) stands in for a zero header stamp. Orientation is None when the IMU gives
    none, or an unusable one (non-finite): the tilt then comes from gravity, as for an all-zero quaternion, and
    the sample's accelerometer and gyro still count. Non-finite rates or accelerations are refused.
    """
    stamp_s = stamp_to_s(msg.header.stamp) or arrival_s
    q = msg.orientation
    orientation = None
    unusable = not all(math.isfinite(component) for component in (q.x, q.y, q.z, q.w))
    if not unusable:
        try:
            orientation = orientation_if_valid((q.x, q.y, q.z, q.w), list(msg.orientation_covariance))
        except ValueError as exc:
            raise ValueError(f"orientation: {exc}") from None
    w, a = msg.angular_velocity, msg.linear_acceleration
    return ImuSample(stamp_s=stamp_s, orientation=orientation,
                     angular_velocity_radps=_vector3((w.x, w.y, w.z), "angular_velocity"),
                     linear_acceleration_mps2=_vector3((a.x, a.y, a.z), "linear_acceleration"),
                     frame_id=msg.header.frame_id, orientation_unusable=unusable)


@dataclasses.dataclass(frozen=True)
class UprightReading:
    """What the classifier makes of the latest sample.

    ``tilt_deg`` is NaN when unknown (no orientation and free fall). ``still_for_s`` and ``upright_for_s`` are
    how long the body has been continuously still / within the tilt threshold; ``settled`` is still for at least
    the settle time (after motion, when the classifier requires it). ``orientation`` is world<-body (x, y, z, w),
    yaw-free when it comes from gravity (``source == "gravity"``).
    """

    stamp_s: float
    tilt_deg: float
    angular_rate_radps: float
    still: bool
    still_for_s: float
    upright: bool
    upright_for_s: float
    settled: bool
    orientation: tuple
    source: str

    @property
    def classification(self) -> typing.Optional[bool]:
        """True (upright) or False once settled; None while the body has not settled."""
        return self.upright if self.settled else None


class ImuUprightClassifier:
    """Decides from a stream of IMU samples whether the body is still, settled and upright.

    Parameters
    ----------
    tilt_threshold_deg : float
        Upright when the tilt (body +z from world up) is at most this, deg.
    settle_time_s : float
        Settled once continuously still this long, s.
    max_rate_radps : float
        Still: angular rate magnitude at most this, rad/s.
    max_accel_deviation_mps2 : float
        Still: ``| |a| - g |`` at most this, m/s^2 (rules out free fall and impacts).
    accel_filter_s : float
        Time constant of the low-pass gravity estimate used when the IMU gives no orientation, s (0: raw).
    mount : ImuMount, optional
        IMU mounting rotation (identity by default).
    require_motion : bool
        Settled only after the body was seen moving since :meth:`reset` (the rig: a chassis waiting on the
        launcher, or rolling at constant speed, looks still to an IMU).
    gravity_mps2 : float
        Local gravity, m/s^2.
    """

    def __init__(self, tilt_threshold_deg, settle_time_s, max_rate_radps=0.3, max_accel_deviation_mps2=1.0,
                 accel_filter_s=0.05, mount=None, require_motion=False, gravity_mps2=STANDARD_GRAVITY_MPS2):
        if not 0 < tilt_threshold_deg < 180:
            raise ValueError(f"tilt_threshold_deg must be in (0, 180), got {tilt_threshold_deg!r}")
        for name, value in (("settle_time_s", settle_time_s), ("max_rate_radps", max_rate_radps),
                            ("max_accel_deviation_mps2", max_accel_deviation_mps2), ("gravity_mps2", gravity_mps2)):
            if not 0 < value < math.inf:
                raise ValueError(f"{name} must be > 0, got {value!r}")
        if not 0 <= accel_filter_s < math.inf:
            raise ValueError(f"accel_filter_s must be >= 0, got {accel_filter_s!r}")
        self.tilt_threshold_deg = tilt_threshold_deg
        self.settle_time_s = settle_time_s
        self.max_rate_radps = max_rate_radps
        self.max_accel_deviation_mps2 = max_accel_deviation_mps2
        self.accel_filter_s = accel_filter_s
        self.mount = mount or ImuMount()
        self.require_motion = require_motion
        self.gravity_mps2 = gravity_mps2
        self.reset()

    @classmethod
    def from_config(cls, config: "ImuOutcomeConfig") -> "ImuUprightClassifier":
        """Classifier for the rig's launch outcome from an :class:`ImuOutcomeConfig` (motion required)."""
        return cls(config.tilt_threshold_deg, config.settle_time_s, config.max_rate_radps,
                   config.max_accel_deviation_mps2, config.accel_filter_s, ImuMount.from_rpy_deg(config.mount_rpy_deg),
                   require_motion=True)

    def reset(self) -> None:
        """Forget the history (call when a launch is fired)."""
        self._last_stamp: typing.Optional[float] = None
        self._gravity: typing.Optional[tuple] = None          # low-pass specific force, body frame
        self._still_since: typing.Optional[float] = None
        self._upright_since: typing.Optional[float] = None
        self._moved = False

    def update(self, sample: ImuSample) -> UprightReading:
        """Feed one :class:`ImuSample`; return the :class:`UprightReading` after it.

        A stamp earlier than the previous one (a bag replayed in a loop) restarts the history.
        """
        stamp = float(sample.stamp_s)
        if self._last_stamp is not None and stamp < self._last_stamp:
            _LOG.warning("IMU stamp went backwards (%.3f s -> %.3f s): restarting the upright history",
                         self._last_stamp, stamp)
            self.reset()
        dt = 0.0 if self._last_stamp is None else stamp - self._last_stamp
        self._last_stamp = stamp

        acceleration = self.mount.to_body(_vector3(sample.linear_acceleration_mps2, "linear_acceleration"))
        rate = math.hypot(*_vector3(sample.angular_velocity_radps, "angular_velocity"))
        if self._gravity is None or self.accel_filter_s == 0:
            self._gravity = acceleration
        else:
            alpha = dt / (self.accel_filter_s + dt)
            self._gravity = tuple(g + alpha * (a - g) for g, a in zip(self._gravity, acceleration))

        if sample.orientation is not None:
            orientation = self.mount.body_orientation(normalize_quaternion(sample.orientation))
            tilt = tilt_from_orientation_deg(orientation)
            source = "orientation"
        else:
            tilt = tilt_from_acceleration_deg(self._gravity)
            orientation = IDENTITY if math.isnan(tilt) else orientation_from_acceleration(self._gravity)
            source = "gravity"

        still = (rate <= self.max_rate_radps
                 and abs(math.hypot(*acceleration) - self.gravity_mps2) <= self.max_accel_deviation_mps2)
        if not still:
            self._moved = True
        still_since = (self._still_since if self._still_since is not None else stamp) if still else None
        upright = tilt <= self.tilt_threshold_deg  # False for NaN
        upright_since = (self._upright_since if self._upright_since is not None else stamp) if upright else None
        self._still_since, self._upright_since = still_since, upright_since
        still_for = stamp - still_since if still_since is not None else 0.0
        return UprightReading(
            stamp_s=stamp, tilt_deg=tilt, angular_rate_radps=rate, still=still, still_for_s=still_for,
            upright=upright, upright_for_s=stamp - upright_since if upright_since is not None else 0.0,
            settled=still_for >= self.settle_time_s and (self._moved or not self.require_motion),
            orientation=orientation, source=source,
        )


@dataclasses.dataclass
class ImuOutcomeConfig:
    """``imu_outcome.*`` of ``config/rig.yaml``: classifying a launch from the chassis IMU."""

    topic: str = dataclasses.field(default="imu/data", metadata={
        "description": "sensor_msgs/Imu topic of the chassis IMU that classifies launch outcomes"})
    mount_rpy_deg: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0], metadata={
        "description": "rotation IMU frame -> chassis body frame as roll, pitch, yaw about fixed axes, deg"})
    tilt_threshold_deg: float = dataclasses.field(default=30.0, metadata={
        "description": "upright when the body +z axis is within this angle of world up after settling, deg",
        "range": (0.0, 180.0), "exclusive": "both"})
    settle_time_s: float = dataclasses.field(default=1.0, metadata={
        "description": "the chassis must be still this long before the IMU classifies it, s",
        "range": (0.0, 60.0), "exclusive": "low"})
    max_rate_radps: float = dataclasses.field(default=0.3, metadata={
        "description": "still when the angular rate magnitude stays at most this, rad/s",
        "range": (0.0, 100.0), "exclusive": "low"})
    max_accel_deviation_mps2: float = dataclasses.field(default=1.0, metadata={
        "description": "still when | |acceleration| - g | stays at most this, m/s^2",
        "range": (0.0, 100.0), "exclusive": "low"})
    accel_filter_s: float = dataclasses.field(default=0.05, metadata={
        "description": "low-pass time constant of the gravity estimate for IMUs without orientation, s",
        "range": (0.0, 10.0)})
    settle_timeout_s: float = dataclasses.field(default=15.0, metadata={
        "description": "no settled IMU reading this long after firing: ask the operator instead, s",
        "range": (0.0, 3600.0)})
    impact_threshold_mps2: float = dataclasses.field(default=30.0, metadata={
        "description": "the landing is the first sample after the fire whose acceleration (gravity removed) exceeds "
                       "this, m/s^2 (more than g, 9.81: free flight reads g); time to rest and peak deceleration count "
                       "from it", "range": (10.0, 10000.0)})

    def validate(self) -> None:
        """Raise ``ValueError`` for an empty topic, an unusable mount or a rule that spans fields (each number's
        range is declared in its metadata and checked by :func:`~rollability_ros.core.config.check_settings`)."""
        if not self.topic:
            raise ValueError("topic must name the IMU topic")
        ImuMount.from_rpy_deg(self.mount_rpy_deg)
        if not self.settle_timeout_s > self.settle_time_s:
            raise ValueError(f"settle_timeout_s ({self.settle_timeout_s}) must exceed settle_time_s "
                             f"({self.settle_time_s})")
