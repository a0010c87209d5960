"""tip_monitor node: rollability in the field -- tracks any robot's tip-overs from its ``sensor_msgs/Imu``.

The logic is :class:`rollability_ros.core.imu.tip_tracker.TipTracker` (states upright, tipped, righting, recovered,
stuck; IMU stamps are its clock); this node moves IMU messages in and states, events and diagnostics out.

Subscriptions:
  ``<tip_monitor.imu_topic>`` (sensor_msgs/Imu, default ``imu/data``): best effort, so it matches reliable and
  best-effort IMU drivers alike; keep last :data:`IMU_QUEUE_DEPTH`, so a node that stalls for up to a second
  (a busy robot computer) still gets every sample and its tip times stay those of the IMU stamps. Orientation
  is used when given; an orientation covariance of -1 or an all-zero quaternion means "none" and the tilt comes
  from gravity; so does a NaN / infinite quaternion (the sample's accelerometer and gyro are kept; counted as
  ``orientation_unusable`` in the diagnostics). A message with NaN /
  infinite rates or accelerations is refused (logged, counted in the diagnostics), never fed to the tracker. A
  zero header stamp is replaced by the time of arrival.
Publications:
  ``~/state`` (rollability_ros/TipState, latched): on the first sample and on every state change; stamp = the
  IMU stamp of the change.
  ``~/events`` and ``tip_events`` (rollability_ros/TipEvent, reliable): one per tip-over, when it ends
  (recovered or stuck). ``tip_events`` is the topic the outcome_logger stores; ``~/events`` is this monitor's own.
  ``/diagnostics`` (diagnostic_msgs/DiagnosticArray): every ``diagnostics_period_s`` and on each change; OK
  upright / recovered, WARN tipped / righting, ERROR stuck, STALE without IMU data for ``imu_timeout_s``
  (checked every quarter timeout, so STALE is published at most 1.25 x ``imu_timeout_s`` after the last sample).
Parameters:
  ``tip_monitor.*`` -- the fields of :class:`~rollability_ros.core.imu.tip_tracker.TipMonitorConfig` (see
  ``config/tip_monitor.yaml``), validated at start-up; a ``ros2 param set`` that would make them invalid is
  refused, an accepted one restarts tracking (state upright) with the new thresholds.
  ``mount_quaternion_xyzw`` (double[4], default all zeros = not given): IMU mounting rotation imu -> body as a
  quaternion; overrides ``tip_monitor.mount_rpy_deg`` when given. ``diagnostics_period_s`` (default 1.0). These two
  are fixed at start-up.

Who stores the events: the outcome_logger, the one writer of the outcome store, stores every ``tip_events``
message. This node opens no store (no process opens another node's store): a robot that runs the monitor without
the lab's graph runs an outcome_logger beside it (``rollability_ros.nodes.outcome_logger``, ``store_path`` the
store file the report reads; it needs no simulation extras), on the robot or on any computer of its ROS graph.
"""
import dataclasses
import math
import threading
import time
import typing

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.subscription import Subscription
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu
from std_msgs.msg import Header

from rollability_ros.core.imu import (TipMonitorConfig, TipTracker, diagnostic_status, imu_sample_from_message,
                                      normalize_quaternion, rpy_deg_from_quaternion)
from rollability_ros.msg import TipEvent, TipState
from rollability_ros.nodes import _convert
from rollability_ros.nodes._support import (LATCHED_QOS, RECORD_QOS, declare_settings,
                                            guard_settings, run_node)

PREFIX = "tip_monitor"
#: IMU samples queued for the node: a second at 1 kHz. With a keep-last queue of 10, a test run on a busy 2-core
#: machine declared "stuck" 0.67 s late: the 80 samples between had been overwritten before the executor took them.
IMU_QUEUE_DEPTH = 1000
IMU_QOS = QoSProfile(depth=IMU_QUEUE_DEPTH, reliability=ReliabilityPolicy.BEST_EFFORT,
                     durability=DurabilityPolicy.VOLATILE, history=HistoryPolicy.KEEP_LAST)


@dataclasses.dataclass
class TipMonitorNodeSettings:
    """Start-up settings of the node itself (the thresholds are :class:`TipMonitorConfig`)."""

    mount_quaternion_xyzw: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0, 0.0], metadata={
        "description": "IMU mounting rotation imu -> body as (x, y, z, w); all zeros (the default) = use "
                       "tip_monitor.mount_rpy_deg"})
    diagnostics_period_s: float = dataclasses.field(default=1.0, metadata={
        "description": "period of the /diagnostics message, s", "range": (0.0, 3600.0), "exclusive": "low"})

    @property
    def mount_given(self) -> bool:
        """True when ``mount_quaternion_xyzw`` is set (not all zeros, the Imu message's "none given")."""
        return any(self.mount_quaternion_xyzw)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if len(self.mount_quaternion_xyzw) != 4:
            raise ValueError(f"mount_quaternion_xyzw must be 4 numbers (x, y, z, w), got {self.mount_quaternion_xyzw}")
        if self.mount_given:
            normalize_quaternion(self.mount_quaternion_xyzw)


class TipMonitorNode(Node):
    """Thin adapter: Imu -> :class:`TipTracker` -> TipState, TipEvent, DiagnosticArray."""

    def __init__(self):
        super().__init__("tip_monitor")
        self._lock = threading.Lock()
        self.settings = declare_settings(self, "", TipMonitorNodeSettings, read_only=True)
        self.add_on_set_parameters_callback(self._refuse_start_up_change)
        config = declare_settings(self, PREFIX, TipMonitorConfig)
        self._group = MutuallyExclusiveCallbackGroup()
        self.state_publisher = self.create_publisher(TipState, "~/state", LATCHED_QOS)
        self.event_publishers = [self.create_publisher(TipEvent, topic, RECORD_QOS)
                                 for topic in ("~/events", "tip_events")]
        self.diagnostics_publisher = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.subscription: typing.Optional[Subscription] = None   # set by _configure below
        self._imu_topic: typing.Optional[str] = None
        self.counts = {"samples": 0, "refused_samples": 0, "orientation_unusable": 0, "events": 0, "recovered": 0,
                       "stuck": 0}
        self._stale_timer, self._reported_stale = None, False
        self._configure(config)
        guard_settings(self, PREFIX, TipMonitorConfig, on_change=self._reconfigure)
        self.create_timer(self.settings.diagnostics_period_s, self._publish_diagnostics, callback_group=self._group)
        self._publish_diagnostics()
        self.get_logger().info(
            f"watching {self._subscribed_topic()} for robot '{config.robot}': tipped above "
            f"{config.tip_threshold_deg:g} deg for {config.tip_confirm_s:g} s, recovered within "
            f"{config.recover_threshold_deg:g} deg for {config.settle_time_s:g} s, stuck after {config.give_up_s:g} s; "
            f"events on {self.resolve_topic_name('tip_events')} (an outcome_logger stores them)")

    def _refuse_start_up_change(self, params):
        fixed = {f.name for f in dataclasses.fields(TipMonitorNodeSettings)}
        names = sorted(p.name for p in params if p.name in fixed)
        if names:
            return SetParametersResult(successful=False, reason=f"{', '.join(names)} fixed at start-up; restart")
        return SetParametersResult(successful=True)

    def _configure(self, config):
        """(Re)start tracking with ``config``; (re)subscribe when the IMU topic changed."""
        if self.settings.mount_given:
            config = dataclasses.replace(config, mount_rpy_deg=rpy_deg_from_quaternion(
                self.settings.mount_quaternion_xyzw))
        with self._lock:
            self.config = config
            self.tracker = TipTracker(config)
            self._last_arrival = None         # monotonic time of the last accepted sample
            self._published_state = None
        if config.imu_topic != self._imu_topic:
            if self.subscription is not None:
                self.destroy_subscription(self.subscription)
            self.subscription = self.create_subscription(Imu, config.imu_topic, self._on_imu, IMU_QOS,
                                                         callback_group=self._group)
            self._imu_topic = config.imu_topic
        if self._stale_timer is not None:
            self.destroy_timer(self._stale_timer)
        # the diagnostics period alone could report a gap up to one period late
        self._stale_timer = self.create_timer(config.imu_timeout_s / 4, self._check_stale, callback_group=self._group)

    def _reconfigure(self, config):
        self.get_logger().info("thresholds changed: tracking restarts from upright")
        self._configure(config)

    def _subscribed_topic(self) -> str:
        """The resolved name of the IMU topic subscribed to."""
        return self.subscription.topic_name if self.subscription is not None else ""

    def _on_imu(self, msg):
        try:
            sample = imu_sample_from_message(msg, time.time())
        except ValueError as exc:
            with self._lock:
                self.counts["refused_samples"] += 1
            self.get_logger().warning(f"refused IMU message: {exc}", throttle_duration_sec=5.0)
            return
        orientation_unusable = sample.orientation_unusable
        if orientation_unusable:
            self.get_logger().warning("IMU orientation is not finite: tilt from gravity for such samples",
                                      throttle_duration_sec=5.0)
        with self._lock:
            update = self.tracker.update(sample)
            self._last_arrival = time.monotonic()
            self._reported_stale = False
            self.counts["samples"] += 1
            self.counts["orientation_unusable"] += orientation_unusable
            publish_state = update.changed or self._published_state is None
            if publish_state:
                self._published_state = update.state
        if publish_state:
            self.state_publisher.publish(TipState(
                header=Header(stamp=_convert.s_to_stamp(update.reading.stamp_s), frame_id=sample.frame_id),
                state=int(update.state), label=update.state.label, tilt_deg=float(update.reading.tilt_deg)))
        if update.event is not None:
            self._report_event(update.event)
        if update.changed:
            self._publish_diagnostics()

    def _report_event(self, event):
        with self._lock:
            self.counts["events"] += 1
            self.counts["recovered" if event.recovered else "stuck"] += 1
        msg = _convert.tip_event_to_msg(event)
        for publisher in self.event_publishers:
            publisher.publish(msg)

    def _check_stale(self):
        """Publish the diagnostics as soon as the IMU stream has been silent for ``imu_timeout_s``."""
        with self._lock:
            since = None if self._last_arrival is None else time.monotonic() - self._last_arrival
            newly_stale = since is not None and since > self.config.imu_timeout_s and not self._reported_stale
            self._reported_stale = self._reported_stale or newly_stale
        if newly_stale:
            self._publish_diagnostics()

    def _publish_diagnostics(self):
        with self._lock:
            state, reading, counts = self.tracker.state, self.tracker.last_reading, dict(self.counts)
            since = None if self._last_arrival is None else time.monotonic() - self._last_arrival
            robot, timeout_s = self.config.robot, self.config.imu_timeout_s
        tilt = reading.tilt_deg if reading is not None else math.nan
        level, message = diagnostic_status(state, tilt, since, timeout_s)
        values = {"state": state.label, "tilt_deg": f"{tilt:.1f}", "imu_topic": self._subscribed_topic(),
                  "seconds_since_sample": "never" if since is None else f"{since:.2f}",
                  **{name: str(count) for name, count in counts.items()}}
        status = DiagnosticStatus(level=bytes([level]), name=f"{self.get_name()}: {robot} tip state",
                                  message=message, hardware_id=robot,
                                  values=[KeyValue(key=k, value=v) for k, v in values.items()])
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self.diagnostics_publisher.publish(array)

def main(args: typing.Optional[typing.List[str]] = None) -> int:
    """Run the node on a single-threaded executor: on a busy 2-core machine the multi-threaded one delivered
    only 29 % of a 300 Hz IMU stream (60 % with one thread), the single-threaded one all of it."""
    return run_node(TipMonitorNode, args, threads=1)


if __name__ == "__main__":
    raise SystemExit(main())
