"""A peer process for the interface round-trip test: echoes a topic, serves a service and an action.

Run as a separate OS process so the round trip crosses DDS between processes, not just within one.
"""
import sys

import rclpy
from rclpy.action import ActionServer
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node

from rollability_ros.action import EvaluateProfile
from rollability_ros.msg import LaunchOutcome
from rollability_ros.srv import FireValve


class InterfacePeer(Node):
    def __init__(self):
        super().__init__("interface_peer")
        self.echo = self.create_publisher(LaunchOutcome, "/peer/outcome_out", 10)
        self.create_subscription(LaunchOutcome, "/peer/outcome_in", self.on_outcome, 10)
        self.create_service(FireValve, "/peer/fire", self.on_fire)
        ActionServer(self, EvaluateProfile, "/peer/evaluate", self.on_evaluate)

    def on_outcome(self, msg):
        msg.note = msg.note + " echoed"
        self.echo.publish(msg)

    def on_fire(self, request, response):
        response.success = request.pulse_ms <= 100
        response.message = "fired" if response.success else f"pulse {request.pulse_ms} ms above 100 ms"
        response.state.last_pulse_ms = request.pulse_ms if response.success else 0
        return response

    def on_evaluate(self, goal_handle):
        trials = goal_handle.request.trials
        for done in range(1, trials + 1):
            goal_handle.publish_feedback(EvaluateProfile.Feedback(trials_done=done, successes_so_far=done // 2))
        goal_handle.succeed()
        return EvaluateProfile.Result(fitness=(trials // 2) / trials, successes=trials // 2, trials=trials,
                                      evaluator=self.get_fully_qualified_name())


def main():
    rclpy.init()
    node = InterfacePeer()
    print("READY", flush=True)
    executor = MultiThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
