"""rig node: runs Launch goals on the simulated launch twin or on the physical pneumatic launcher.

Action server:
  ``launch`` (rollability_ros/Launch): one launch per goal, one at a time. A goal that cannot run (NaN or negative
  height, unknown configuration, no regulator pressure for its speed, rig busy) is aborted at once with the reason
  in ``result.message``. Feedback phases: waiting_for_operator, armed, fired, in_flight, settling, classifying
  (``detail`` says what the operator must do). Cancel is honoured at the next wait (before firing, or while
  waiting for the operator or the IMU).
Publications:
  ``launch_outcomes`` (rollability_ros/LaunchOutcome, reliable, deep queue): every outcome, for the outcome_logger.
  ``rig/heartbeat`` (std_msgs/Header, physical backend): every ``valve.heartbeat_period_ms`` on a steady-clock
  timer while the node runs; the valve controller's watchdog closes the valve when it stops.
  ``rig/pose`` (geometry_msgs/PoseStamped, sim backend): the chassis pose during a simulated launch, when the
  twin reports poses.
Services (physical backend):
  ``record_outcome`` (rollability_ros/RecordOutcome): the operator's outcome of the launch the rig waits on (or an
  override of the IMU's verdict during the override window); refused with a reason when no launch waits.
  ``rig/confirm`` (std_srvs/Trigger): the operator confirms the regulator pressure asked for in the feedback.
Clients (physical backend): ``valve/arm`` (std_srvs/SetBool), ``valve/fire`` (FireValve); subscribes to
  ``valve/state`` (latched) and to the IMU topic ``imu_outcome.topic`` (sensor_msgs/Imu, default ``imu/data``)
  when ``rig.outcome_source`` is ``imu``.
Parameters: ``rig.*`` (:class:`~rollability_ros.core.rig.rig_session.RigSettings`: ``rig.backend`` sim | physical,
  ...), ``valve.*`` (launch pulse, heartbeat period, regulator pressures), ``speed_gate.*``, ``imu_outcome.*``,
  all in ``config/rig.yaml``; the sim backend reads the launch twin's own parameter files (``rig.twin_config``,
  default sim, robot, launch_twin) at start-up. Fixed at start-up.
"""
import dataclasses
import math
import threading
import time

from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import ActionServer, CancelResponse
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import Imu
from std_msgs.msg import Header
from std_srvs.srv import SetBool, Trigger

from rollability_ros.action import Launch
from rollability_ros.core.rig import rig_session
from rollability_ros.core.rig.rig_session import (ImuOutcome, LaunchAborted, OperatorChannel, OperatorOutcome,
                                              PhysicalLaunch, RigSettings, SimulatedLaunch)
from rollability_ros.core.rig.speed_gate import SpeedGateConfig, make_speed_gate
from rollability_ros.core.imu.upright import ImuOutcomeConfig, ImuSample, orientation_if_valid
from rollability_ros.core.rig.valve import ValveConfig, ValveStatus
from rollability_ros.msg import LaunchOutcome, ValveState
from rollability_ros.nodes import _convert
from rollability_ros.nodes._support import (LATCHED_QOS, RECORD_QOS, STREAM_QOS, ParameterError, declare_settings,
                                            run_node)
from rollability_ros.srv import FireValve, RecordOutcome


class ValveServices:
    """The valve port of :class:`PhysicalLaunch` over the valve_controller's services and latched state."""

    def __init__(self, node, timeout_s, callback_group):
        self._timeout_s = timeout_s
        self._arm = node.create_client(SetBool, "valve/arm", callback_group=callback_group)
        self._fire = node.create_client(FireValve, "valve/fire", callback_group=callback_group)
        self._lock = threading.Lock()
        self._status = ValveStatus(False, False, False, "", "", 0, 0)
        node.create_subscription(ValveState, "valve/state", self._on_state, LATCHED_QOS,
                                 callback_group=callback_group)

    def _on_state(self, msg):
        self._remember(msg)

    def _remember(self, msg):
        with self._lock:
            self._status = ValveStatus(msg.armed, msg.open, msg.fault, msg.fault_reason, msg.backend,
                                       msg.last_pulse_ms, msg.pulses)

    def status(self):
        """The newest valve state known (from ``valve/state`` or the last fire response)."""
        with self._lock:
            return self._status

    def _call(self, client, request, timeout_s):
        if not client.wait_for_service(timeout_sec=self._timeout_s):
            return None, f"valve controller service {client.srv_name} is not available"
        response = client.call(request, timeout_sec=timeout_s)
        if response is None:
            return None, f"valve controller did not answer {client.srv_name} within {timeout_s:g} s"
        return response, ""

    def _set_armed(self, armed):
        response, failure = self._call(self._arm, SetBool.Request(data=armed), self._timeout_s)
        if response is None:
            return False, failure
        if response.success:
            with self._lock:
                self._status = dataclasses.replace(self._status, armed=armed, fault=self._status.fault and armed)
        return response.success, response.message

    def arm(self):
        """Arm the valve: ``(ok, reason)``."""
        return self._set_armed(True)

    def disarm(self):
        """Disarm the valve: ``(ok, reason)``."""
        return self._set_armed(False)

    def fire(self, pulse_ms):
        """Fire one pulse: ``(ok, reason)``; the response's state becomes the known status."""
        response, failure = self._call(self._fire, FireValve.Request(pulse_ms=int(pulse_ms)),
                                       self._timeout_s + pulse_ms / 1000.0)
        if response is None:
            return False, failure
        self._remember(response.state)
        return response.success, response.message


def imu_sample_from_msg(msg):
    """``sensor_msgs/Imu`` -> :class:`ImuSample` (orientation None when the IMU gives none)."""
    q = msg.orientation
    return ImuSample(
        stamp_s=_convert.stamp_to_s(msg.header.stamp),
        orientation=orientation_if_valid((q.x, q.y, q.z, q.w), list(msg.orientation_covariance)),
        angular_velocity_radps=(msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z),
        linear_acceleration_mps2=(msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z),
        frame_id=msg.header.frame_id)


class RigNode(Node):
    """Thin adapter: the Launch action -> :class:`PhysicalLaunch` or the launch twin; outcomes -> topic."""

    def __init__(self):
        super().__init__("rig")
        self.settings = declare_settings(self, "rig", RigSettings, read_only=True)
        valve = declare_settings(self, "valve", ValveConfig, read_only=True)
        self.speed_config = declare_settings(self, "speed_gate", SpeedGateConfig, read_only=True)
        imu_config = declare_settings(self, "imu_outcome", ImuOutcomeConfig, read_only=True)
        self.add_on_set_parameters_callback(self._refuse_change)
        self._closing = threading.Event()
        self._busy = threading.Lock()
        self.outcome_publisher = self.create_publisher(LaunchOutcome, "launch_outcomes", RECORD_QOS)
        group = ReentrantCallbackGroup()
        if self.settings.backend == "physical":
            self._setup_physical(valve, imu_config, group)
        else:
            self.simulated = SimulatedLaunch(self.settings, self.speed_config)
            try:
                self.simulated.load()
            except (ValueError, ImportError) as exc:  # ConfigError is a ValueError, MissingDependency ImportError
                raise ParameterError(f"rig.backend sim: cannot load the launch twin: {exc}") from exc
            self.pose_publisher = self.create_publisher(PoseStamped, "rig/pose", STREAM_QOS)
        ActionServer(self, Launch, "launch", execute_callback=self._execute, callback_group=group,
                     cancel_callback=lambda _goal: CancelResponse.ACCEPT)
        self.get_logger().info(f"rig ready: backend {self.settings.backend}" + (
            f", outcome from {self.settings.outcome_source}" if self.settings.backend == "physical" else ""))

    def _refuse_change(self, params):
        if any(p.name.split(".")[0] in ("rig", "valve", "speed_gate", "imu_outcome") for p in params):
            return SetParametersResult(successful=False, reason="rig parameters are fixed at start-up; restart "
                                                                "the node")
        return SetParametersResult(successful=True)

    def _setup_physical(self, valve, imu_config, group):
        self.operator = OperatorChannel()
        imu = None
        if self.settings.outcome_source == "imu":
            imu = ImuOutcome(imu_config)
            self.create_subscription(Imu, imu_config.topic, lambda msg: self._on_imu(imu, msg), STREAM_QOS,
                                     callback_group=MutuallyExclusiveCallbackGroup())
        self.physical = PhysicalLaunch(
            self.settings, ValveServices(self, self.settings.valve_timeout_s, group),
            make_speed_gate(self.speed_config), self.speed_config, valve.launch_pulse_ms, valve.regulator,
            self.operator, imu)
        self.create_service(RecordOutcome, "record_outcome", self._on_record_outcome, callback_group=group)
        self.create_service(Trigger, "rig/confirm", self._on_confirm, callback_group=group)
        self.heartbeat_publisher = self.create_publisher(Header, "rig/heartbeat", 10)
        # steady clock: sim time must not stall the heartbeat the valve's watchdog relies on
        self.create_timer(valve.heartbeat_period_ms / 1000.0, self._heartbeat,
                          callback_group=MutuallyExclusiveCallbackGroup(), clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _heartbeat(self):
        msg = Header(frame_id=self.get_name())
        msg.stamp = self.get_clock().now().to_msg()
        self.heartbeat_publisher.publish(msg)

    def _on_imu(self, imu, msg):
        try:
            imu.feed(imu_sample_from_msg(msg))
        except ValueError as exc:
            self.get_logger().warning(f"ignored IMU sample: {exc}", throttle_duration_sec=5.0)

    def _on_record_outcome(self, request, response):
        travel_time_s = request.travel_time_s if request.travel_time_s > 0 else math.nan
        response.accepted, response.message = self.operator.record_outcome(
            OperatorOutcome(bool(request.upright), travel_time_s, request.note), request.trial_id)
        self.get_logger().info(f"operator outcome for {request.trial_id or 'the current launch'}: "
                               f"{'upright' if request.upright else 'not upright'} -> {response.message}")
        return response

    def _on_confirm(self, request, response):
        response.success, response.message = self.operator.confirm()
        self.get_logger().info(f"operator confirmation: {response.message}")
        return response

    def _execute(self, goal_handle):
        goal = goal_handle.request
        result = Launch.Result()
        logger = self.get_logger()

        def on_phase(phase, detail):
            logger.info(f"{goal.trial_id}: {phase}: {detail}")
            goal_handle.publish_feedback(Launch.Feedback(phase=phase, detail=detail))

        def cancelled():
            return goal_handle.is_cancel_requested or self._closing.is_set()

        if not self._busy.acquire(blocking=False):
            result.message = f"rig busy with another launch; {goal.trial_id} refused"
            logger.warning(result.message)
            goal_handle.abort()
            return result
        try:
            condition = _convert.condition_from_msg(goal.condition)
            reason = (self.physical.check(goal.run_id, goal.trial_id, condition)
                      if self.settings.backend == "physical" else
                      rig_session.check_goal(goal.run_id, goal.trial_id, condition, self.settings.configurations))
            if reason:
                raise ValueError(reason)
            if self.settings.backend == "physical":
                outcome = self.physical.launch(goal.run_id, goal.trial_id, condition, on_phase, cancelled)
            else:
                started_s = time.time()
                outcome = self.simulated.launch(
                    goal.run_id, goal.trial_id, condition, on_phase,
                    lambda t_s, position, orientation: self._publish_pose(started_s + t_s, position, orientation))
        except (ValueError, LaunchAborted) as exc:
            result.message = f"{goal.trial_id}: {exc}"
            logger.error(f"launch aborted: {result.message}")
            if goal_handle.is_cancel_requested:
                goal_handle.canceled()
            else:
                goal_handle.abort()
            return result
        finally:
            self._busy.release()
        result.outcome = _convert.outcome_to_msg(outcome)
        self.outcome_publisher.publish(result.outcome)
        logger.info(f"{goal.trial_id}: {'upright' if outcome.upright else 'NOT upright'} "
                    f"(classified by {outcome.classified_by}){'; ' + outcome.note if outcome.note else ''}")
        goal_handle.succeed()
        return result

    def _publish_pose(self, stamp_s, position_m, orientation_xyzw):
        msg = PoseStamped()
        msg.header.stamp = _convert.s_to_stamp(stamp_s)
        msg.header.frame_id = "world"
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in position_m)
        msg.pose.orientation = _convert.tuple_to_quaternion(orientation_xyzw)
        self.pose_publisher.publish(msg)

    def close(self):
        """Abort a running launch at its next wait; the valve is disarmed by the launch's own cleanup."""
        self._closing.set()


def main(args=None):
    return run_node(RigNode, args, threads=6)


if __name__ == "__main__":
    raise SystemExit(main())
