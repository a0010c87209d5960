"""Live view: the project's ROS topics served to the Foxglove app over the Foxglove WebSocket protocol.

No ROS install is needed on the viewing side: each topic becomes a Foxglove channel with message encoding
``cdr`` and a ``ros2msg`` schema holding the type's full definition (nested types included, as rosbag2 writes
them into MCAP, :func:`~rollability_ros.core.bags.msg_definitions.definition_for`), so the app decodes our custom
types. Messages are logged as the serialized CDR bytes a raw ROS subscription delivers; this module never
imports rclpy (the ``view_bridge`` node feeds it ``(topic, type_name, cdr_bytes, time)``).

Latched topics (the summary, the best profile marker): their last message is kept and logged again when a
client subscribes, so a freshly opened app shows them at once. Clients that were already subscribed get that
message a second time; the app simply shows it again.

The server binds to ``127.0.0.1`` unless another address is given. ``foxglove-sdk`` is the ``view`` extra.
"""
import dataclasses
import ipaddress
import logging
import threading
import time

from rollability_ros.core.bags.msg_definitions import definition_for, full_type_name
from rollability_ros.core.optional import require

_LOG = logging.getLogger(__name__)

#: Port the Foxglove app connects to by default (ws://localhost:8765).
DEFAULT_PORT = 8765


@dataclasses.dataclass
class ViewSettings:
    """Where the view listens and how often it looks for new topics (``view_bridge`` parameters)."""

    host: str = dataclasses.field(default="127.0.0.1", metadata={
        "description": "address to listen on; 127.0.0.1 = this machine only, 0.0.0.0 = every interface"})
    port: int = dataclasses.field(default=DEFAULT_PORT, metadata={
        "description": "TCP port of the Foxglove WebSocket server (0 = any free port, logged at start)"})
    discovery_period_s: float = dataclasses.field(default=2.0, metadata={
        "description": "how often the ROS graph is searched for new topics to serve, s"})

    def validate(self):
        """Raise ``ValueError`` naming the first unusable field."""
        if self.host != "localhost":
            try:
                ipaddress.ip_address(self.host)
            except ValueError:
                raise ValueError(f"host must be an IP address or 'localhost', got {self.host!r}") from None
        if isinstance(self.port, bool) or not isinstance(self.port, int) or not 0 <= self.port <= 65535:
            raise ValueError(f"port must be in [0, 65535], got {self.port!r}")
        if not 0 < self.discovery_period_s < float("inf"):
            raise ValueError(f"discovery_period_s must be > 0, got {self.discovery_period_s}")


def ros2msg_schema(type_name):
    """``(schema name, schema text)`` of ``pkg/msg/Type`` as the Foxglove app expects for ``cdr`` channels.

    Raises ``ValueError`` when the type's interface files are not found.
    """
    name = full_type_name(type_name)
    return name, definition_for(name)


def _replay_listener(foxglove, view):
    """A foxglove ``ServerListener`` that replays latched topics to a new subscriber (other events: no-ops)."""

    class ReplayLatched(foxglove.websocket.ServerListener):
        def on_subscribe(self, client, channel):
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
        settings.validate()
        self.settings = settings
        self.name = name
        self._foxglove = None
        self._context = None
        self._server = None
        self._channels = {}          # topic -> (type name, foxglove.Channel)
        self._latched = {}           # topic -> last (cdr bytes, log time ns) of a latched topic
        self._lock = threading.Lock()

    def start(self):
        """Start serving; return the bound port. Raises ``MissingDependency`` without the ``view`` extra."""
        foxglove = self._foxglove = require("foxglove", feature="the live Foxglove view")
        self._context = foxglove.Context()
        self._server = foxglove.start_server(name=self.name, host=self.settings.host, port=self.settings.port,
                                             context=self._context, server_listener=_replay_listener(foxglove, self))
        _LOG.info("Foxglove view on ws://%s:%d", self.settings.host, self.port)
        return self.port

    @property
    def port(self):
        """The port the server listens on (None before :meth:`start`)."""
        return None if self._server is None else self._server.port

    @property
    def topics(self):
        """``{topic: type name}`` of the channels served so far."""
        with self._lock:
            return {topic: type_name for topic, (type_name, _) in self._channels.items()}

    def add_topic(self, topic, type_name, latched=False):
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
            schema = self._foxglove.Schema(name=schema_name, encoding="ros2msg", data=schema_text.encode())
            channel = self._foxglove.Channel(topic, message_encoding="cdr", schema=schema, context=self._context)
            self._channels[topic] = (schema_name, channel)
            if latched:
                self._latched.setdefault(topic, None)
        return True

    def log(self, topic, cdr_bytes, time_ns=None):
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

    def replay(self, topic):
        """Log the kept last message of latched ``topic`` again (nothing for other topics or before one came)."""
        with self._lock:
            last = self._latched.get(topic)
            entry = self._channels.get(topic)
        if last is not None and entry is not None:
            entry[1].log(last[0], log_time=last[1])

    def stop(self):
        """Stop the server (idempotent)."""
        if self._server is not None:
            self._server.stop()
            self._server = None
