"""Live view: the project's ROS topics served to the Foxglove app over the Foxglove WebSocket protocol.

No ROS install is needed on the viewing side: each topic becomes a Foxglove channel with message encoding
``cdr`` and a ``ros2msg`` schema holding the type's full definition (nested types included, as rosbag2 writes
them into MCAP, :func:`~rollability_ros.core.bags.msg_definitions.definition_for`), so the app decodes our custom
types. Messages are logged as the serialized CDR bytes a raw ROS subscription delivers; this module never
imports rclpy (the ``view_bridge`` node feeds it ``(topic, type_name, cdr_bytes, time)``).

Latched topics (the summary, the best profile marker): their last message is kept and logged again when a
client subscribes, so a freshly opened app shows them at once. Clients that were already subscribed get that
message a second time; the app simply shows it again.

TF for the 3D panel: the profile marker is drawn in the chassis frame (``base_link``) and the chassis pose comes
as ``geometry_msgs/PoseStamped`` in ``world``; nothing in the PyPI install publishes /tf (``tf2_msgs`` is not
among the wheels). The view therefore turns each pose of a configured topic into a standard
``tf2_msgs/msg/TFMessage`` (parent = the pose's frame, child = the configured frame) on ``/tf``, served like any
other channel (``cdr`` + ``ros2msg``; the definition comes from rosbags' Jazzy type store when the interface is
not installed), so the app places the marker on the moving chassis; on a ROS install with a real /tf the same
message type is what the app already knows.

The server binds to ``127.0.0.1`` unless another address is given. ``foxglove-sdk`` is the ``view`` extra.
"""
import dataclasses
import ipaddress
import logging
import threading
import time
import typing

from rollability_ros.core import config
from rollability_ros.core.bags import definition_for, full_type_name
from rollability_ros.core.optional import require

_LOG = logging.getLogger(__name__)

#: Port the Foxglove app connects to by default (ws://localhost:8765).
DEFAULT_PORT = 8765
#: Topic and type of the transforms the view derives from pose topics.
TF_TOPIC, TF_TYPE = "/tf", "tf2_msgs/msg/TFMessage"


@dataclasses.dataclass
class ViewSettings:
    """Where the view listens and how often it looks for new topics (``view_bridge`` parameters)."""

    host: str = dataclasses.field(default="127.0.0.1", metadata={
        "description": "address to listen on; 127.0.0.1 = this machine only, 0.0.0.0 = every interface"})
    port: int = dataclasses.field(default=DEFAULT_PORT, metadata={
        "description": "TCP port of the Foxglove WebSocket server (0 = any free port, logged at start)",
        "range": (0, 65535)})
    discovery_period_s: float = dataclasses.field(default=2.0, metadata={
        "description": "how often the ROS graph is searched for new topics to serve, s",
        "range": (0.0, 3600.0), "exclusive": "low"})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if self.host != "localhost":
            try:
                ipaddress.ip_address(self.host)
            except ValueError:
                raise ValueError(f"host must be an IP address or 'localhost', got {self.host!r}") from None


def ros2msg_schema(type_name: str) -> typing.Tuple[str, str]:
    """``(schema name, schema text)`` of ``pkg/msg/Type`` as the Foxglove app expects for ``cdr`` channels.

    Raises ``ValueError`` when the type's interface files are not found.
    """
    name = full_type_name(type_name)
    try:
        return name, definition_for(name)
    except ValueError:
        store = _jazzy_typestore()
        if name not in store.types:
            raise
        return name, store.generate_msgdef(name, ros_version=2)[0]   # e.g. tf2_msgs: not among the PyPI wheels


def _jazzy_typestore():
    """rosbags' built-in ROS 2 Jazzy type store (standard message definitions and CDR codecs)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def tf_from_pose_cdr(pose_stamped_cdr: bytes, child_frame_id: str) -> bytes:
    """CDR bytes of a ``tf2_msgs/msg/TFMessage`` with one transform: the ``geometry_msgs/PoseStamped`` (CDR
    bytes) as the pose of ``child_frame_id`` in the pose's ``header.frame_id`` (same stamp; metres, unit
    quaternion). Raises ``ValueError`` for bytes that are not a PoseStamped or an empty frame."""
    store = _jazzy_typestore()
    try:
        pose = store.deserialize_cdr(bytes(pose_stamped_cdr), "geometry_msgs/msg/PoseStamped")
    except Exception as exc:  # rosbags raises struct / index errors for foreign bytes
        raise ValueError(f"not a geometry_msgs/PoseStamped: {exc}") from exc
    if not pose.header.frame_id or not child_frame_id:
        raise ValueError("a transform needs the pose's header.frame_id and a child frame")
    types = store.types
    position, orientation = pose.pose.position, pose.pose.orientation
    transform = types["geometry_msgs/msg/TransformStamped"](
        header=pose.header, child_frame_id=child_frame_id,
        transform=types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=position.x, y=position.y, z=position.z),
            rotation=orientation))
    return bytes(store.serialize_cdr(types[TF_TYPE](transforms=[transform]), TF_TYPE))


def parse_pose_frames(entries: typing.Iterable[str]) -> typing.Dict[str, str]:
    """``["/topic=child_frame", ...]`` -> ``{topic: child_frame}``; ``ValueError`` naming a malformed entry."""
    frames = {}
    for entry in entries:
        topic, separator, frame = entry.partition("=")
        if not separator or not topic.startswith("/") or not frame.strip():
            raise ValueError(f"pose_frames entry {entry!r} must be '/absolute/topic=child_frame'")
        frames[topic] = frame.strip()
    return frames


def _replay_listener(foxglove, view):
    """A foxglove ``ServerListener`` that replays latched topics to a new subscriber (other events: no-ops)."""

    listener: typing.Any = foxglove.websocket.ServerListener   # the SDK's base class, imported at run time

    class ReplayLatched(listener):
        def on_subscribe(self, client: typing.Any, channel: typing.Any) -> None:
            view.replay(channel.topic)

    return ReplayLatched()


class ViewServer:
    """A Foxglove WebSocket server with one ``cdr`` channel per served ROS topic.

    Parameters
    ----------
    settings : ViewSettings
        Address and port (``port=0`` picks a free one; :attr:`port` tells which).
    name : str
        Server name shown in the app.
    """

    def __init__(self, settings, name="rollability"):
        config.check_settings(settings, "")
        self.settings = settings
        self.name = name
        self._foxglove = None
        self._context = None
        self._server = None
        self._channels = {}          # topic -> (type name, foxglove.Channel)
        self._latched = {}           # topic -> last (cdr bytes, log time ns) of a latched topic
        self._lock = threading.Lock()

    def start(self) -> int:
        """Start serving; return the bound port. Raises ``MissingDependency`` without the ``view`` extra."""
        foxglove = self._foxglove = require("foxglove", feature="the live Foxglove view")
        self._context = foxglove.Context()
        self._server = foxglove.start_server(name=self.name, host=self.settings.host, port=self.settings.port,
                                             context=self._context, server_listener=_replay_listener(foxglove, self))
        port = int(self._server.port)
        _LOG.info("Foxglove view on ws://%s:%d", self.settings.host, port)
        return port

    @property
    def port(self) -> typing.Optional[int]:
        """The port the server listens on (None before :meth:`start`)."""
        return None if self._server is None else self._server.port

    @property
    def topics(self) -> typing.Dict[str, str]:
        """``{topic: type name}`` of the channels served so far."""
        with self._lock:
            return {topic: type_name for topic, (type_name, _) in self._channels.items()}

    def add_topic(self, topic: str, type_name: str, latched: bool = False) -> bool:
        """Advertise ``topic`` of ROS type ``type_name``; True if new, False if already served with that type.

        ``latched``: keep its last message for clients that subscribe later. Raises ``ValueError`` when the
        type's definition is not found or the topic is already served with another type.
        """
        if self._server is None:
            raise ValueError("start the view server before adding topics")
        schema_name, schema_text = ros2msg_schema(type_name)
        with self._lock:
            if topic in self._channels:
                served = self._channels[topic][0]
                if served != schema_name:
                    raise ValueError(f"{topic} is served as {served}, not {schema_name}")
                return False
            foxglove = self._foxglove
            assert foxglove is not None   # imported by start(), checked above
            schema = foxglove.Schema(name=schema_name, encoding="ros2msg", data=schema_text.encode())
            channel = foxglove.Channel(topic, message_encoding="cdr", schema=schema, context=self._context)
            self._channels[topic] = (schema_name, channel)
            if latched:
                self._latched.setdefault(topic, None)
        return True

    def log(self, topic: str, cdr_bytes: bytes, time_ns: typing.Optional[int] = None) -> None:
        """Send one serialized message of ``topic`` to its subscribers; ``time_ns`` defaults to now (ns).

        Raises ``ValueError`` for a topic that was never added.
        """
        time_ns = time.time_ns() if time_ns is None else int(time_ns)
        with self._lock:
            entry = self._channels.get(topic)
            if entry is None:
                raise ValueError(f"{topic} is not served: add_topic it first")
            if topic in self._latched:
                self._latched[topic] = (bytes(cdr_bytes), time_ns)
        entry[1].log(bytes(cdr_bytes), log_time=time_ns)

    def log_pose_as_tf(self, pose_stamped_cdr: bytes, child_frame_id: str,
                       time_ns: typing.Optional[int] = None) -> None:
        """Log a PoseStamped (CDR bytes) on :data:`TF_TOPIC` as the transform of ``child_frame_id``
        (:func:`tf_from_pose_cdr`), advertising the /tf channel on first use."""
        tf_bytes = tf_from_pose_cdr(pose_stamped_cdr, child_frame_id)
        self.add_topic(TF_TOPIC, TF_TYPE)
        self.log(TF_TOPIC, tf_bytes, time_ns)

    def replay(self, topic: str) -> None:
        """Log the kept last message of latched ``topic`` again (nothing for other topics or before one came)."""
        with self._lock:
            last = self._latched.get(topic)
            entry = self._channels.get(topic)
        if last is not None and entry is not None:
            entry[1].log(last[0], log_time=last[1])

    def stop(self) -> None:
        """Stop the server (idempotent)."""
        if self._server is not None:
            self._server.stop()
            self._server = None
