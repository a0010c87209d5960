"""valve_controller node: the launcher's solenoid valve as a fail-closed ROS device.

Services:
  ``valve/arm`` (std_srvs/SetBool): ``data: true`` arms, ``false`` disarms (drives the valve closed and
  acknowledges a latched fault).
  ``valve/fire`` (rollability_ros/FireValve): one pulse of ``pulse_ms``; refused (with the reason in
  ``message``) unless armed, fault-free and ``pulse_ms <= valve.max_pulse_ms``; returns after the valve is closed.
Subscriptions:
  ``valve/estop`` (std_msgs/Bool): ``true`` latches an e-stop fault and drives the valve closed at once.
  ``rig/heartbeat`` (std_msgs/Header): the rig's heartbeat; while armed, ``valve.watchdog_ms`` of silence (steady
  clock, never ROS time) latches a watchdog fault and closes the valve.
Publications:
  ``valve/state`` (rollability_ros/ValveState, latched): on every state change; each change is also logged.
Parameters:
  ``valve.*`` (:class:`~rollability_ros.core.rig.valve.ValveConfig`, shipped in ``config/rig.yaml``), fixed at
  start-up: a running safety device does not change its backend or limits underneath the rig.

Fail-closed: the valve is driven closed at start, on disarm, e-stop, watchdog trip, backend error, at the end of
every pulse, and on SIGINT / SIGTERM / node destruction (``close()``, called by ``run_node`` before destroy).
"""
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from std_msgs.msg import Bool, Header
from std_srvs.srv import SetBool

from rollability_ros.core.rig.valve import ValveConfig
from rollability_ros.core.rig.valve_backends import make_controller
from rollability_ros.msg import ValveState
from rollability_ros.nodes._support import LATCHED_QOS, ParameterError, declare_settings, run_node
from rollability_ros.srv import FireValve


class ValveControllerNode(Node):
    """Thin adapter: services and topics -> :class:`~rollability_ros.core.rig.valve.ValveController`."""

    def __init__(self):
        super().__init__("valve_controller")
        config = declare_settings(self, "valve", ValveConfig, read_only=True)
        self.state_publisher = self.create_publisher(ValveState, "valve/state", LATCHED_QOS)
        try:
            self.controller = make_controller(config, on_state=self._publish_state)
        except ValueError as exc:
            raise ParameterError(f"valve: {exc}") from exc
        self.add_on_set_parameters_callback(self._refuse_valve_change)
        # fire blocks for the pulse: e-stop, heartbeat and disarm must get through meanwhile
        reentrant = ReentrantCallbackGroup()
        self.create_service(SetBool, "valve/arm", self._on_arm, callback_group=reentrant)
        self.create_service(FireValve, "valve/fire", self._on_fire, callback_group=MutuallyExclusiveCallbackGroup())
        self.create_subscription(Bool, "valve/estop", self._on_estop, 10, callback_group=reentrant)
        self.create_subscription(Header, "rig/heartbeat", self._on_heartbeat, 10, callback_group=reentrant)
        self.get_logger().info(f"valve ready: backend {config.backend}, max pulse {config.max_pulse_ms} ms, "
                               f"watchdog {config.watchdog_ms} ms")

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

    def _on_arm(self, request, response):
        response.success, response.message = self.controller.arm() if request.data else self.controller.disarm()
        if not response.success:
            self.get_logger().warning(f"{'arm' if request.data else 'disarm'} refused: {response.message}")
        return response

    def _on_fire(self, request, response):
        response.success, response.message = self.controller.fire(request.pulse_ms)
        if not response.success:
            self.get_logger().warning(f"fire {request.pulse_ms} ms: {response.message}")
        response.state = self._state_msg(self.controller.status())
        return response

    def _on_estop(self, msg):
        if msg.data:
            self.controller.estop("e-stop (valve/estop)")

    def _on_heartbeat(self, msg):
        self.controller.heartbeat()

    def close(self):
        """Drive the valve closed and release the backend (idempotent)."""
        self.controller.shutdown()


def main(args=None):
    return run_node(ValveControllerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
