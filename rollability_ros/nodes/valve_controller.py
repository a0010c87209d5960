"""valve_controller node: the launcher's solenoid valve as a fail-closed ROS device that only the operator fires.

At start the node writes a fresh per-session arming key (``valve.session_key_file``, mode 0600; see
:mod:`rollability_ros.core.rig.valve_auth`); only processes on this computer that can read it (the rig node,
``rollability rig``) can arm, disarm, fire or keep the valve alive. Unauthenticated, stale or replayed requests are
refused and counted.

Services:
  ``valve/arm`` (rollability_ros/ArmValve): ``arm: true`` arms, ``false`` disarms (drives the valve closed and
  acknowledges a latched fault); refused unless ``auth`` signs ``arm`` / ``disarm``.
  ``valve/fire`` (rollability_ros/FireValve): one pulse of ``pulse_ms``; refused (with the reason in ``message``)
  unless authenticated, armed, fault-free and ``pulse_ms <= valve.max_pulse_ms``; returns after the valve is
  closed.
Subscriptions:
  ``valve/estop`` (std_msgs/Bool): ``true`` latches an e-stop fault and drives the valve closed at once. Not
  authenticated on purpose: anyone may stop.
  ``rig/heartbeat`` (rollability_ros/ValveHeartbeat): the rig's signed heartbeat; while armed,
  ``valve.watchdog_ms`` without an authentic one of this session (steady clock, never ROS time) latches a
  watchdog fault and closes the valve.
Publications:
  ``valve/state`` (rollability_ros/ValveState, latched): on every state change; each change is also logged.
  ``/diagnostics`` (diagnostic_msgs/DiagnosticArray): every second and on every state change: armed, fault and
  its reason, watchdog margin, device link, refused requests.
Parameters:
  ``valve.*`` (:class:`~rollability_ros.core.rig.valve.ValveConfig`, shipped in ``config/rig.yaml``), fixed at
  start-up: a running safety device does not change its backend or limits underneath the rig.

Fail-closed: the valve is driven closed at start, on disarm, e-stop, watchdog trip, backend error, at the end of
every pulse, and on SIGINT / SIGTERM / node destruction (``close()``, called by ``run_node`` before destroy). What
happens when this process is killed depends on the backend (docs/valve-safety.md): the serial relay board drops the
relay on its own; a plain GPIO line cannot.
"""
import math
import threading
import typing

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import Bool

from rollability_ros.core.rig import (AuthError, RequestVerifier, ValveConfig, create_session_key, default_key_path,
                                      make_controller, remove_session_key)
from rollability_ros.msg import ValveHeartbeat, ValveState
from rollability_ros.nodes import _convert
from rollability_ros.nodes._support import LATCHED_QOS, ParameterError, declare_settings, run_node, wait_for_acks
from rollability_ros.srv import ArmValve, FireValve

DIAGNOSTICS_PERIOD_S = 1.0


def key_path(node: Node, config: ValveConfig) -> str:
    """The session key file of this valve_controller (``valve.session_key_file`` or the per-domain default)."""
    return config.session_key_file or default_key_path(node.get_namespace())


#: Longest wait at shutdown for the subscribers of valve/state to acknowledge the closed state, s.
CLOSED_STATE_ACK_S = 2.0


class ValveControllerNode(Node):
    """Thin adapter: authenticated services and topics -> :class:`~rollability_ros.core.rig.valve.ValveController`."""

    def __init__(self):
        super().__init__("valve_controller")
        config = declare_settings(self, "valve", ValveConfig, read_only=True)
        self.key_path = key_path(self, config)
        try:
            self.session_key = create_session_key(self.key_path)
        except (OSError, AuthError) as exc:
            raise ParameterError(f"valve.session_key_file: cannot write {self.key_path}: {exc}") from exc
        self.verifier = RequestVerifier(self.session_key)
        self.state_publisher = self.create_publisher(ValveState, "valve/state", LATCHED_QOS)
        self.diagnostics_publisher = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        try:
            self.controller = make_controller(config, on_state=self._publish_state)
        except ValueError as exc:
            raise ParameterError(f"valve: {exc}") from exc
        self.add_on_set_parameters_callback(self._refuse_valve_change)
        # fire blocks for the pulse: e-stop, heartbeat and disarm must get through meanwhile
        reentrant = ReentrantCallbackGroup()
        self.create_service(ArmValve, "valve/arm", self._on_arm, callback_group=reentrant)
        self.create_service(FireValve, "valve/fire", self._on_fire, callback_group=MutuallyExclusiveCallbackGroup())
        self.create_subscription(Bool, "valve/estop", self._on_estop, 10, callback_group=reentrant)
        self.create_subscription(ValveHeartbeat, "rig/heartbeat", self._on_heartbeat, 10, callback_group=reentrant)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._publish_diagnostics, callback_group=reentrant,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        warning = self.controller.startup_warning()
        if warning:
            self.get_logger().warning(warning)
        limits = self.controller.device_limits()
        if limits is not None and limits.max_pulse_ms < config.max_pulse_ms:
            self.get_logger().warning(f"the relay board caps pulses at {limits.max_pulse_ms} ms, below "
                                      f"valve.max_pulse_ms {config.max_pulse_ms}")
        self.get_logger().info(f"valve ready: backend {config.backend}, max pulse {config.max_pulse_ms} ms, "
                               f"watchdog {config.watchdog_ms} ms, session {self.session_key.session} "
                               f"(key file {self.key_path})")

    def _refuse_valve_change(self, params):
        if any(p.name.startswith("valve.") for p in params):
            return SetParametersResult(successful=False,
                                       reason="valve parameters are fixed at start-up; restart the node")
        return SetParametersResult(successful=True)

    def _state_msg(self, status):
        msg = ValveState(armed=status.armed, open=status.open, fault=status.fault, fault_reason=status.fault_reason,
                         backend=status.backend, last_pulse_ms=status.last_pulse_ms, pulses=status.pulses)
        msg.header.stamp = self.get_clock().now().to_msg()
        return msg

    def _publish_state(self, status):
        line = (f"valve state: armed={status.armed} open={status.open} fault={status.fault}"
                f"{f' ({status.fault_reason})' if status.fault else ''} pulses={status.pulses} "
                f"last_pulse_ms={status.last_pulse_ms}")
        if status.fault:  # rclpy refuses two severities from one call site
            self.get_logger().error(line)
        else:
            self.get_logger().info(line)
        self.state_publisher.publish(self._state_msg(status))
        if hasattr(self, "controller"):
            self._publish_diagnostics()

    def _publish_diagnostics(self):
        status, margin_ms, link = self.controller.health()
        if status.fault:
            level, summary = DiagnosticStatus.ERROR, f"fault: {status.fault_reason}"
        elif link.startswith(f"{status.backend}: no device") or "lost" in link or "NO hardware" in link:
            level, summary = DiagnosticStatus.WARN, ("armed" if status.armed else "disarmed") + "; " + link
        else:
            level, summary = DiagnosticStatus.OK, "armed" if status.armed else "disarmed, valve closed"
        values = {
            "armed": str(status.armed).lower(), "open": str(status.open).lower(), "fault": str(status.fault).lower(),
            "fault_reason": status.fault_reason, "backend": status.backend,
            "watchdog_margin_ms": "" if margin_ms is None or math.isnan(margin_ms) else f"{margin_ms:.0f}",
            "device_link": link, "pulses": str(status.pulses), "last_pulse_ms": str(status.last_pulse_ms),
            "rejected_requests": str(self.verifier.rejected), "session": self.session_key.session,
        }
        array = DiagnosticArray()
        array.header.stamp = self.get_clock().now().to_msg()
        array.status = [DiagnosticStatus(level=level, name=f"{self.get_fully_qualified_name()}: valve",
                                         message=summary, hardware_id=status.backend,
                                         values=[KeyValue(key=k, value=v) for k, v in values.items()])]
        self.diagnostics_publisher.publish(array)

    def _authentic(self, auth, command, pulse_ms=None):
        ok, reason = self.verifier.verify(_convert.signature_from_msg(auth), command, pulse_ms)
        if not ok:
            self.get_logger().warning(f"refused {command} request: {reason}", throttle_duration_sec=1.0)
        return ok, reason

    def _on_arm(self, request, response):
        command = "arm" if request.arm else "disarm"
        ok, reason = self._authentic(request.auth, command)
        if not ok:
            response.success, response.message = False, reason
            return response
        response.success, response.message = self.controller.arm() if request.arm else self.controller.disarm()
        if not response.success:
            self.get_logger().warning(f"{command} refused: {response.message}")
        return response

    def _on_fire(self, request, response):
        ok, reason = self._authentic(request.auth, "fire", request.pulse_ms)
        if ok:
            response.success, response.message = self.controller.fire(request.pulse_ms)
            if not response.success:
                self.get_logger().warning(f"fire {request.pulse_ms} ms: {response.message}")
        else:   # logged (throttled) by _authentic: a flood of stray requests must not starve the device link
            response.success, response.message = False, reason
        response.state = self._state_msg(self.controller.status())
        return response

    def _on_estop(self, msg):
        if msg.data:
            self.controller.estop("e-stop (valve/estop)")

    def _on_heartbeat(self, msg):
        if self._authentic(msg.auth, "heartbeat")[0]:
            self.controller.heartbeat()

    def close(self) -> None:
        """Drive the valve closed, release the backend and remove this session's key file (idempotent); then give
        the subscribers up to :data:`CLOSED_STATE_ACK_S` to acknowledge the closed state before the node goes (a
        writer destroyed right after publishing can take its last sample with it on a loaded machine)."""
        self.controller.shutdown()
        remove_session_key(self.key_path, self.session_key)
        wait_for_acks([self.state_publisher], CLOSED_STATE_ACK_S, threading.Event())


def main(args: typing.Optional[typing.List[str]] = None) -> int:
    return run_node(ValveControllerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
