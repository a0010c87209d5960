"""view_bridge node: serves the project's live topics to the Foxglove app (WebSocket, ros2msg schemas, CDR).

Discovers topics every ``discovery_period_s`` (publishers that appear later are picked up) and subscribes to
each selected one raw (serialized CDR), with a QoS matched to its publishers (reliable / transient local only
when all of them are), handing the bytes to :class:`rollability_ros.core.graph.foxglove_view.ViewServer`. Topics
whose every publisher is transient local are served as latched: a client that connects later gets the last
message at once.

Selection: ``topics`` (absolute names) when given, else the project's graph as the recorder sees it
(:func:`rollability_ros.core.bags.record_play.select_topics`: our package's types, ``rig/pose``, markers,
``/diagnostics``, ``/tf``; not ``/rosout`` or hidden topics).
Parameters: ``host`` (default 127.0.0.1: this machine only), ``port`` (default 8765; 0 = any free port),
``discovery_period_s`` (default 2.0 s), ``topics`` (string[], default empty), ``pose_frames`` (string[],
default ``/rollability/rig/pose=base_link``: each pose of that topic is also served on ``/tf`` as a
``tf2_msgs/TFMessage`` world -> base_link, so the profile marker rides on the chassis). All fixed at start-up.
Run: ``python -m rollability_ros.nodes.view_bridge --ros-args -p port:=8765`` (``rollability view`` and
``rollability bringup --view`` do this); the log says ``Foxglove view on ws://<host>:<port>``.
"""
import functools
import time
import typing

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter

from rollability_ros.core.bags import check_topic_names, qos_dict_from_profile, select_topics, subscription_qos_for
from rollability_ros.core.graph import ViewServer, ViewSettings, parse_pose_frames
from rollability_ros.core.optional import MissingDependency
from rollability_ros.nodes._bag_nodes import message_class, qos_profile_from_dict
from rollability_ros.nodes._support import ParameterError, declare_settings, run_node

#: Pose topics also served as /tf by default: the rig's chassis pose (world) -> base_link, the frame of the profile
#: marker (docs/live-view.md).
DEFAULT_POSE_FRAMES = ("/rollability/rig/pose=base_link",)
#: Subscription queue depth, messages: the view shows the newest; a short queue bounds memory.
QUEUE_DEPTH = 10


class ViewBridgeNode(Node):
    """Thin adapter: graph discovery and raw subscriptions -> :class:`ViewServer`."""

    def __init__(self):
        super().__init__("view_bridge")
        self.settings = declare_settings(self, "", ViewSettings, read_only=True)
        self.declare_parameter("topics", Parameter.Type.STRING_ARRAY, ParameterDescriptor(
            description="absolute topic names to serve; empty: every topic of the project's graph",
            read_only=True))
        self.declare_parameter("pose_frames", list(DEFAULT_POSE_FRAMES), ParameterDescriptor(
            description="PoseStamped topics served also as /tf (tf2_msgs/TFMessage) transforms, each "
                        "'/topic=child_frame': the pose's header frame -> that frame, so markers drawn in the "
                        "child frame ride on the moving robot in the 3D panel; empty = no /tf",
            read_only=True))
        try:   # an empty string array on the command line is "not set": get_parameter_or gives value None
            self.chosen_topics = check_topic_names(self.get_parameter_or("topics").value or [])
        except ValueError as exc:
            raise ParameterError(f"topics: {exc}") from exc
        try:
            self.pose_frames = parse_pose_frames(self.get_parameter_or("pose_frames").value or [])
        except ValueError as exc:
            raise ParameterError(str(exc)) from exc
        self.view = ViewServer(self.settings)
        try:
            self.view.start()
        except (MissingDependency, RuntimeError, OSError) as exc:   # foxglove: port taken / bad address
            raise ParameterError(f"cannot start the Foxglove view on {self.settings.host}:{self.settings.port}: "
                                 f"{exc}") from exc
        self._group = MutuallyExclusiveCallbackGroup()
        self._served = {}
        self._skipped = set()
        self.create_timer(self.settings.discovery_period_s, self.discover, callback_group=self._group)
        self.get_logger().info(f"Foxglove view on ws://{self.settings.host}:{self.view.port} serving "
                               + (", ".join(self.chosen_topics) if self.chosen_topics else "the project's graph"))
        self.discover()

    def discover(self) -> None:
        """Serve every selected topic that has publishers and is not served yet."""
        selected, ambiguous = select_topics(self.get_topic_names_and_types(), self.chosen_topics)
        for topic, types in ambiguous:
            self._skip(topic, f"it has several types on the graph ({', '.join(types)})")
        for topic, type_name in selected:
            if topic in self._served or topic in self._skipped:
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if publishers:
                self._serve(topic, type_name, [qos_dict_from_profile(p.qos_profile) for p in publishers])

    def _skip(self, topic, reason):
        if topic not in self._skipped:
            self._skipped.add(topic)
            self.get_logger().warning(f"not serving {topic}: {reason}")

    def _serve(self, topic, type_name, offered):
        qos = subscription_qos_for(offered, depth=QUEUE_DEPTH)
        latched = qos["durability"] == "transient_local"
        try:
            msg_type = message_class(type_name)
            self.view.add_topic(topic, type_name, latched=latched)
        except ValueError as exc:
            self._skip(topic, str(exc))
            return
        child_frame = self.pose_frames.get(topic) if type_name.endswith("PoseStamped") else None
        self._served[topic] = self.create_subscription(
            msg_type, topic, functools.partial(self._forward, topic, child_frame=child_frame),
            qos_profile_from_dict(qos), callback_group=self._group, raw=True)
        self.get_logger().info(f"serving {topic} ({type_name}{', latched' if latched else ''})")

    def _forward(self, topic, data, child_frame):
        now_ns = time.time_ns()
        self.view.log(topic, data, now_ns)
        if child_frame:
            try:
                self.view.log_pose_as_tf(data, child_frame, now_ns)
            except ValueError as exc:
                self.get_logger().warning(f"{topic}: no transform: {exc}", throttle_duration_sec=5.0)

    def close(self) -> None:
        """Stop the WebSocket server (run_node calls this before destroying the node)."""
        self.view.stop()


def main(args: typing.Optional[typing.List[str]] = None) -> int:
    return run_node(ViewBridgeNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
