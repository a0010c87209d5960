"""rig node: runs Launch goals on the configured launch backend (the simulated launch twin or the physical
pneumatic launcher), through the :class:`~rollability_ros.core.rig.launch_backend.LaunchBackend` contract that
:func:`~rollability_ros.core.rig.rig_session.make_launch_backend` builds from ``rig.backend``.

Action server:
  ``launch`` (rollability_ros/Launch): one launch per goal, one at a time. A goal that cannot run (not
  authenticated on the physical backend, NaN or negative height, unknown configuration, no regulator pressure for
  its speed, rig busy) is aborted at once with the reason in ``result.message``. Feedback phases: waiting_for_operator,
  armed, fired, in_flight, settling, classifying; a question to the operator is repeated every
  ``rig.question_repeat_s`` until answered (a feedback sent before a client's subscription matched is lost)
  (``detail`` says what the operator must do). Cancel is honoured at the next wait (before firing, or while
  waiting for the operator or the IMU). With ``session.id`` set, a goal of another session (``goal.session``) is
  aborted at once, logged once: a rig serves only its own session's campaign runner.
Publications:
  ``launch_outcomes`` (rollability_ros/LaunchOutcome, reliable, deep queue): every outcome, for the outcome_logger;
  a physical one carries the rig's record signature (``auth``), made only for a goal that was signed. Each carries
  the twin the rig launches in (``twin``: its files and their SHA-256 as read at start-up, or that the physical
  rig has none: :mod:`rollability_ros.core.rig.launched_twin`), which the logger records in the run's info.
  ``rig/pose`` (geometry_msgs/PoseStamped): the chassis pose during a launch, when the backend reports poses (the
  launch twin does).
  ``rig/heartbeat`` (rollability_ros/ValveHeartbeat, when the backend opens the valve): every
  ``valve.heartbeat_period_ms`` on a steady-clock timer from the first arming on, signed with the valve's session
  key; the valve controller's watchdog closes the valve when it stops.
Services:
  ``record_outcome`` (rollability_ros/RecordOutcome): the operator's outcome of the launch the rig waits on (or an
  override of the IMU's verdict during the override window); refused with a reason when no launch waits (always,
  on the simulated backend).
  ``rig/confirm`` (rollability_ros/ConfirmRegulator): the operator confirms the regulator pressure asked for in the
  feedback (for the named trial, or the launch waiting now).
Authentication (physical backend, :mod:`rollability_ros.core.rig.rig_auth`): launch goals, confirmations and
  outcomes must be signed with the valve's session key (``valve.session_key_file``) by the operator's tools,
  fresh and used once; anything else is refused with "not authenticated: ...". The sim backend needs no key.
Ports the physical backend opens (:class:`RosRigPorts`): clients ``valve/arm`` (ArmValve), ``valve/fire``
  (FireValve), signed with the session key ``valve.session_key_file`` that the valve_controller on this computer
  writes; subscriptions to ``valve/state`` (latched) and, when ``rig.outcome_source`` is ``imu``, to the IMU
  topic ``imu_outcome.topic`` (sensor_msgs/Imu, default ``imu/data``).
Parameters: ``rig.*`` (:class:`~rollability_ros.core.rig.launch_backend.RigSettings`: ``rig.backend`` sim | physical,
  ...), ``valve.*`` (launch pulse, heartbeat period, regulator pressures), ``speed_gate.*``, ``imu_outcome.*``,
  all in ``config/rig.yaml``; the sim backend reads the launch twin's own parameter files (``rig.twin_config``,
  default sim, robot, launch_twin) at start-up. Fixed at start-up.
"""
import dataclasses
import math
import threading
import time
import typing

from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import ActionServer, CancelResponse
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import Imu

from rollability_ros.action import Launch
from rollability_ros.core.imu import ImuOutcomeConfig, imu_sample_from_message
from rollability_ros.core.rig import (AuthError, ImuOutcome, LaunchAborted, OperatorOutcome, RequestSigner, RigPorts,
                                      RigSettings, SpeedGateConfig, ValveConfig, ValveStatus, default_key_path,
                                      load_session_key, make_launch_backend, make_speed_gate, request_guard,
                                      twin_to_text)
from rollability_ros.msg import LaunchOutcome, ValveHeartbeat, ValveState
from rollability_ros.nodes import _convert
from rollability_ros.nodes._support import (LATCHED_QOS, RECORD_QOS, STREAM_QOS, ParameterError, SessionMembership,
                                            declare_settings, run_node)
from rollability_ros.nodes._convert import auth_msg, signature_from_msg
from rollability_ros.srv import ArmValve, ConfirmRegulator, FireValve, RecordOutcome


class ValveServices:
    """The valve port of the physical backend over the valve_controller's services and latched state.

    Every request and heartbeat is signed with the valve_controller's session key, read from ``key_path`` when the
    launch sequence arms (after the operator's confirmation), so a valve_controller restart is picked up.
    """

    def __init__(self, node, timeout_s, callback_group, key_path):
        self._timeout_s = timeout_s
        self._key_path = key_path
        self._signer = None
        self._arm = node.create_client(ArmValve, "valve/arm", callback_group=callback_group)
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

    def status(self) -> ValveStatus:
        """The newest valve state known (from ``valve/state`` or the last fire response)."""
        with self._lock:
            return self._status

    def _call(self, client, make_request, timeout_s):
        """Wait for the service, then build (sign) the request: a signature is fresh for a few seconds only."""
        if not client.wait_for_service(timeout_sec=self._timeout_s):
            return None, f"valve controller service {client.srv_name} is not available"
        try:
            request = make_request()
        except AuthError as exc:
            return None, str(exc)
        response = client.call(request, timeout_sec=timeout_s)
        if response is None:
            return None, f"valve controller did not answer {client.srv_name} within {timeout_s:g} s"
        return response, ""

    def _sign(self, command, pulse_ms=None, reload=False):
        """A ``ValveAuth`` for ``command``; re-reads the key file when asked or when none was read yet."""
        if reload or self._signer is None:
            self._signer = RequestSigner(load_session_key(self._key_path))
        return auth_msg(self._signer.sign(command, pulse_ms))

    def heartbeat(self, node_name: str, stamp: typing.Any) -> typing.Any:
        """A signed ``ValveHeartbeat``, or None before the first arming (no key read yet)."""
        if self._signer is None:
            return None
        msg = ValveHeartbeat(auth=self._sign("heartbeat"))
        msg.header.frame_id, msg.header.stamp = node_name, stamp
        return msg

    def _set_armed(self, armed):
        response, failure = self._call(self._arm, lambda: ArmValve.Request(
            arm=armed, auth=self._sign("arm" if armed else "disarm", reload=armed)), self._timeout_s)
        if response is None:
            return False, failure
        if response.success:
            with self._lock:
                self._status = dataclasses.replace(self._status, armed=armed, fault=self._status.fault and armed)
        return response.success, response.message

    def arm(self) -> typing.Tuple[bool, str]:
        """Arm the valve: ``(ok, reason)``."""
        return self._set_armed(True)

    def disarm(self) -> typing.Tuple[bool, str]:
        """Disarm the valve: ``(ok, reason)``."""
        return self._set_armed(False)

    def fire(self, pulse_ms: int) -> typing.Tuple[bool, str]:
        """Fire one pulse: ``(ok, reason)``; the response's state becomes the known status."""
        response, failure = self._call(self._fire, lambda: FireValve.Request(
            pulse_ms=int(pulse_ms), auth=self._sign("fire", int(pulse_ms))), self._timeout_s + pulse_ms / 1000.0)
        if response is None:
            return False, failure
        self._remember(response.state)
        return response.success, response.message


def session_key_path(node: Node, valve_config: ValveConfig) -> str:
    """The valve_controller's key file: ``valve.session_key_file``, else the default for this namespace."""
    return valve_config.session_key_file or default_key_path(node.get_namespace())


class RosRigPorts(RigPorts):
    """The rig's ports over ROS: the valve_controller's services with a heartbeat timer, the speed gate, the IMU
    topic. Each is created only when the backend opens it, so a simulated rig has no valve client or heartbeat."""

    def __init__(self, node, valve_timeout_s, callback_group):
        self._node = node
        self._valve_timeout_s = valve_timeout_s
        self._group = callback_group
        self._heartbeat_publisher: typing.Any = None   # a Publisher of ValveHeartbeat, made by open_valve
        self._valve_services: typing.Optional[ValveServices] = None

    def open_valve(self, valve_config: ValveConfig) -> typing.Any:
        """:class:`ValveServices` signing with the valve's session key, and ``rig/heartbeat`` every
        ``valve.heartbeat_period_ms`` for the watchdog (signed; sent from the first arming on)."""
        node = self._node
        key_path = session_key_path(node, valve_config)
        self._valve_services = ValveServices(node, self._valve_timeout_s, self._group, key_path)
        self._heartbeat_publisher = node.create_publisher(ValveHeartbeat, "rig/heartbeat", 10)
        # steady clock: sim time must not stall the heartbeat the valve's watchdog relies on
        node.create_timer(valve_config.heartbeat_period_ms / 1000.0, self._heartbeat,
                          callback_group=MutuallyExclusiveCallbackGroup(), clock=Clock(clock_type=ClockType.STEADY_TIME))
        return self._valve_services

    def _heartbeat(self):
        assert self._valve_services is not None   # the timer starts in open_valve
        msg = self._valve_services.heartbeat(self._node.get_name(), self._node.get_clock().now().to_msg())
        if msg is not None:
            self._heartbeat_publisher.publish(msg)

    def open_speed_gate(self, speed_config: SpeedGateConfig) -> typing.Any:
        """The configured speed gate."""
        return make_speed_gate(speed_config)

    def open_imu(self, imu_outcome: ImuOutcome) -> None:
        """Feed ``imu_outcome`` from its configured IMU topic (sensor_msgs/Imu)."""
        self._node.create_subscription(Imu, imu_outcome.config.topic, lambda msg: self._on_imu(imu_outcome, msg),
                                       STREAM_QOS, callback_group=MutuallyExclusiveCallbackGroup())

    def open_twin(self, twin_config: typing.Sequence[str]) -> typing.Any:
        """The launch twin of the files ``rig.twin_config`` names, parsed here, at the node (the edge), once."""
        from rollability_ros.core.sim import load_launch_twin_settings

        return load_launch_twin_settings(twin_config)

    def _on_imu(self, imu_outcome, msg):
        try:
            imu_outcome.feed(imu_sample_from_message(msg, time.time()))
        except ValueError as exc:
            self._node.get_logger().warning(f"ignored IMU sample: {exc}", throttle_duration_sec=5.0)


class RigNode(Node):
    """Thin adapter: the Launch action -> the configured :class:`LaunchBackend`; outcomes -> topic."""

    def __init__(self):
        super().__init__("rig")
        self.settings = declare_settings(self, "rig", RigSettings, read_only=True)
        valve = declare_settings(self, "valve", ValveConfig, read_only=True)
        speed_config = declare_settings(self, "speed_gate", SpeedGateConfig, read_only=True)
        imu_config = declare_settings(self, "imu_outcome", ImuOutcomeConfig, read_only=True)
        self._session = SessionMembership(self)
        self.add_on_set_parameters_callback(self._refuse_change)
        self._closing = threading.Event()
        self._busy = threading.Lock()
        self.outcome_publisher = self.create_publisher(LaunchOutcome, "launch_outcomes", RECORD_QOS)
        self.pose_publisher = self.create_publisher(PoseStamped, "rig/pose", STREAM_QOS)
        group = ReentrantCallbackGroup()
        try:
            self.backend = make_launch_backend(self.settings, speed_config, valve, imu_config,
                                               RosRigPorts(self, self.settings.valve_timeout_s, group))
        except (ValueError, ImportError) as exc:  # ConfigError is a ValueError, MissingDependency ImportError
            raise ParameterError(f"rig.backend {self.settings.backend}: {exc}") from exc
        self.twin_text = twin_to_text(self.backend.launched_twin())   # the files as loaded now, for each outcome
        self.guard = request_guard(self.backend.authenticated, session_key_path(self, valve))
        self.create_service(RecordOutcome, "record_outcome", self._on_record_outcome, callback_group=group)
        self.create_service(ConfirmRegulator, "rig/confirm", self._on_confirm, callback_group=group)
        ActionServer(self, Launch, "launch", execute_callback=self._execute, callback_group=group,
                     cancel_callback=lambda _goal: CancelResponse.ACCEPT)
        self.get_logger().info(f"rig ready: {self.backend.describe()}")

    def _refuse_change(self, params):
        if any(p.name.split(".")[0] in ("rig", "valve", "speed_gate", "imu_outcome") for p in params):
            return SetParametersResult(successful=False, reason="rig parameters are fixed at start-up; restart "
                                                                "the node")
        return SetParametersResult(successful=True)

    def _on_record_outcome(self, request, response):
        response.accepted, response.message = self.guard.check_outcome(
            signature_from_msg(request.auth), request.trial_id, request.upright, request.travel_time_s, request.note,
            request.rest_distance_m)
        if response.accepted:
            travel_time_s = request.travel_time_s if request.travel_time_s > 0 else math.nan
            rolled_m = request.rest_distance_m if math.isfinite(request.rest_distance_m) and \
                request.rest_distance_m >= 0 else math.nan   # < 0 (the default), NaN: not measured
            response.accepted, response.message = self.backend.operator.record_outcome(
                OperatorOutcome(bool(request.upright), travel_time_s, request.note, rolled_m), request.trial_id)
        self._log_answer(response.accepted, f"operator outcome for {request.trial_id or 'the current launch'}: "
                         f"{'upright' if request.upright else 'not upright'} -> {response.message}")
        return response

    def _log_answer(self, accepted, text):
        if accepted:
            self.get_logger().info(text)
        else:   # a stray participant's flood of refused answers must not flood the log
            self.get_logger().warning(text, throttle_duration_sec=1.0)

    def _on_confirm(self, request, response):
        response.success, response.message = self.guard.check_confirm(signature_from_msg(request.auth),
                                                                      request.trial_id)
        if response.success:
            response.success, response.message = self.backend.operator.confirm(request.trial_id)
        self._log_answer(response.success, f"operator confirmation for {request.trial_id or 'the current launch'}: "
                                           f"{response.message}")
        return response

    def _execute(self, goal_handle):
        goal = goal_handle.request
        result = Launch.Result()
        logger = self.get_logger()

        last_logged: typing.Optional[typing.Tuple[str, str]] = None

        def on_phase(phase: str, detail: str) -> None:
            nonlocal last_logged
            if (phase, detail) != last_logged:    # a question repeated while it waits is logged once
                logger.info(f"{goal.trial_id}: {phase}: {detail}")
                last_logged = (phase, detail)
            goal_handle.publish_feedback(Launch.Feedback(phase=phase, detail=detail))

        def cancelled() -> bool:
            return goal_handle.is_cancel_requested or self._closing.is_set()

        refusal = self._session.refusal(goal.session, "launch goal")
        if refusal:   # another session's campaign runner: never served, never holds the rig busy
            result.message = f"{goal.trial_id}: {refusal}"
            goal_handle.abort()
            return result
        # authenticated before anything else: a stray participant's goals never hold the rig busy
        ticket, reason = self.guard.check_launch(signature_from_msg(goal.auth), goal.run_id, goal.trial_id,
                                                 goal.condition)
        if ticket is None:
            result.message = f"{goal.trial_id}: {reason}"
            logger.warning(f"launch refused: {result.message}", throttle_duration_sec=1.0)
            goal_handle.abort()
            return result
        if not self._busy.acquire(blocking=False):
            result.message = f"rig busy with another launch; {goal.trial_id} refused"
            logger.warning(result.message)
            goal_handle.abort()
            return result
        try:
            condition = _convert.condition_from_msg(goal.condition)
            reason = self.backend.check(goal.run_id, goal.trial_id, condition)
            if reason:
                raise ValueError(reason)
            started_s = time.time()
            outcome = self.backend.launch(
                goal.run_id, goal.trial_id, condition, on_phase,
                on_pose=lambda t_s, position, orientation: self._publish_pose(started_s + t_s, position, orientation),
                cancelled=cancelled)
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
        result.outcome.twin = self.twin_text
        # the record is signed as the logger will read it back from the message (stamps round to ns)
        result.outcome.auth = auth_msg(ticket.sign_record(_convert.outcome_from_msg(result.outcome)))
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

    def close(self) -> None:
        """Abort a running launch at its next wait and wait for it to end (the node still spins meanwhile, so the
        launch's own cleanup can disarm the valve over its service); then close the backend."""
        self._closing.set()
        with self._busy:
            pass
        self.backend.close()


def main(args: typing.Optional[typing.List[str]] = None) -> int:
    return run_node(RigNode, args, threads=6)


if __name__ == "__main__":
    raise SystemExit(main())
