"""Settings and pure helpers of the recorder and player nodes: which topics to record, bag names, remaps.

The recorder's default selection is "the project's graph": every topic whose type belongs to this package
(``rollability_ros/...``), the standard-typed topics our nodes publish (``rig/pose``,
``/diagnostics``, visualization markers), and ``/tf``, ``/tf_static`` and ``/clock`` when present. Hidden topics
(a name part starting with ``_``: action feedback/status, service events) and the ROS infrastructure topics
``/rosout`` and ``/parameter_events`` are left out, as ``ros2 bag record`` does.
"""
import dataclasses
import datetime
import os
import typing

from rollability_ros.core.bags._mcap_file import DEFAULT_CHUNK_SIZE_BYTES, DEFAULT_FLUSH_INTERVAL_S, mcap_compression
from rollability_ros.core.bags.msg_definitions import OWN_PACKAGE

#: Folder that holds recorded runs (relative to the working directory).
BAGS_DIR = "bags"

#: Topics recorded by default when they exist, whatever publishes them.
ALWAYS_TOPICS = ("/tf", "/tf_static", "/clock", "/diagnostics")

#: Topics of standard types that our nodes publish, by name relative to the node's namespace -> type.
PROJECT_STANDARD_TOPICS = {
    "rig/pose": "geometry_msgs/msg/PoseStamped",
}

#: Standard types recorded on any topic (the optimizer's and the rig's visualisation).
PROJECT_STANDARD_TYPES = ("visualization_msgs/msg/Marker", "visualization_msgs/msg/MarkerArray")

#: Infrastructure topics never recorded by default.
INFRASTRUCTURE_TOPICS = ("/rosout", "/parameter_events")


@dataclasses.dataclass(frozen=True)
class RecorderSettings:
    """Settings of the recorder node (parameters ``recorder.*``); the topic list is the ``recorder.topics`` array."""

    output_dir: str = dataclasses.field(default="", metadata={
        "description": "bag directory to create (must not exist or be empty); empty: "
                       "bags/rollability_<UTC date-time> under the working directory"})
    discovery_period_s: float = dataclasses.field(default=1.0, metadata={
        "description": "how often the graph is searched for new topics to record, s",
        "range": (0.0, 3600.0), "exclusive": "low"})
    compression: str = dataclasses.field(default="zstd", metadata={
        "description": "MCAP chunk compression: zstd, lz4 or none"})
    split_max_bytes: int = dataclasses.field(default=0, metadata={
        "description": "start a new storage file after this many bytes, B (0: never)", "range": (0, 2 ** 50)})
    split_max_duration_s: float = dataclasses.field(default=0.0, metadata={
        "description": "start a new storage file after this much recorded time, s (0: never)",
        "range": (0.0, 31536000.0)})
    chunk_size_bytes: int = dataclasses.field(default=DEFAULT_CHUNK_SIZE_BYTES, metadata={
        "description": "uncompressed MCAP chunk size, B: the most a kill -9 can lose", "range": (1, 2 ** 30)})
    flush_interval_s: float = dataclasses.field(default=DEFAULT_FLUSH_INTERVAL_S, metadata={
        "description": "longest time a message waits in memory before its chunk is written, s",
        "range": (0.0, 3600.0)})
    queue_depth: int = dataclasses.field(default=1000, metadata={
        "description": "subscription queue depth, messages (keep-last topics)", "range": (1, 1000000)})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable setting."""
        mcap_compression(self.compression)
        if self.output_dir and os.path.exists(self.output_dir) and (
                not os.path.isdir(self.output_dir) or os.listdir(self.output_dir)):
            from rollability_ros.core.bags.recover import is_left_open

            # a bag left open by a killed recorder is continued (BagWriter continue_open); any other is kept safe
            if not os.path.isdir(self.output_dir) or not is_left_open(self.output_dir):
                raise ValueError(f"output_dir {self.output_dir} exists and is not an empty directory or a bag "
                                 f"left open by a killed recorder")


@dataclasses.dataclass(frozen=True)
class PlayerSettings:
    """Settings of the player node (parameters ``player.*``); ``player.topics`` and ``player.remap`` are arrays."""

    bag: str = dataclasses.field(default="", metadata={"description": "bag directory to play (required)"})
    rate: float = dataclasses.field(default=1.0, metadata={
        "description": "playback speed factor: 2.0 plays twice as fast", "range": (0.0, 1000.0), "exclusive": "low"})
    start_offset_s: float = dataclasses.field(default=0.0, metadata={
        "description": "skip this much recorded time from the bag's start, s", "range": (0.0, 31536000.0)})
    loop: bool = dataclasses.field(default=False, metadata={"description": "play again from the start, forever"})
    clock: bool = dataclasses.field(default=False, metadata={
        "description": "publish /clock with each message's recorded time"})
    wait_for_subscribers_s: float = dataclasses.field(default=3.0, metadata={
        "description": "before the first message, wait up to this long for every played topic to have a "
                       "subscriber (discovery takes about a second), s; 0: start at once", "range": (0.0, 3600.0)})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable setting."""
        if not self.bag:
            raise ValueError("bag must name a bag directory")
        if not os.path.isdir(self.bag):
            raise ValueError(f"bag {self.bag} is not a directory")


def default_bag_directory(now: typing.Optional[datetime.datetime] = None, root: str = BAGS_DIR) -> str:
    """Return ``<root>/rollability_<YYYY_MM_DD-HH_MM_SS>`` for ``now`` (a UTC ``datetime``; default: now)."""
    now = now or datetime.datetime.now(datetime.timezone.utc)
    return os.path.join(root, now.strftime("rollability_%Y_%m_%d-%H_%M_%S"))


def is_hidden(topic: str) -> bool:
    """True for a hidden ROS topic: one of its name parts starts with ``_``."""
    return any(part.startswith("_") for part in topic.split("/"))


def in_project_graph(topic: str, type_name: str) -> bool:
    """True when the default selection records ``topic`` of ``type_name`` (see the module docstring)."""
    if topic in INFRASTRUCTURE_TOPICS or is_hidden(topic):
        return False
    if topic in ALWAYS_TOPICS or type_name.split("/", 1)[0] == OWN_PACKAGE or type_name in PROJECT_STANDARD_TYPES:
        return True
    return any(PROJECT_STANDARD_TOPICS[name] == type_name and (topic == "/" + name or topic.endswith("/" + name))
               for name in PROJECT_STANDARD_TOPICS)


def select_topics(names_and_types: typing.Iterable[typing.Tuple[str, typing.Sequence[str]]],
                  chosen: typing.Iterable[str] = ()) -> typing.Tuple[typing.List[typing.Tuple[str, str]],
                                                                   typing.List[typing.Tuple[str, typing.List[str]]]]:
    """Return ``[(topic, type_name), ...]`` to record from the graph's ``[(topic, [type names]), ...]``.

    Parameters
    ----------
    names_and_types : iterable of (str, list of str)
        As ``Node.get_topic_names_and_types()`` returns them.
    chosen : iterable of str
        Topics to record (absolute names); empty: the project's graph (:func:`in_project_graph`).

    A topic with more than one type on the graph is left out (a bag channel has one type); it is returned
    in the second list, ``[(topic, [types]), ...]``, so the caller can say so.
    """
    wanted_topics = set(chosen)
    selected: typing.List[typing.Tuple[str, str]] = []
    ambiguous: typing.List[typing.Tuple[str, typing.List[str]]] = []
    for topic, types in names_and_types:
        wanted = topic in wanted_topics if wanted_topics else any(in_project_graph(topic, t) for t in types)
        if not wanted:
            continue
        if len(types) != 1:
            ambiguous.append((topic, list(types)))
        else:
            selected.append((topic, types[0]))
    return selected, ambiguous


def check_topic_names(topics: typing.Iterable[str]) -> typing.Tuple[str, ...]:
    """Return ``topics`` as a tuple of absolute names; ``ValueError`` for a relative or malformed name."""
    for topic in topics:
        if (not isinstance(topic, str) or not topic.startswith("/") or topic.endswith("/") or "//" in topic
                or any(c.isspace() for c in topic)):
            raise ValueError(f"topic names must be absolute ROS names like /rollability/launch_outcomes, "
                             f"got {topic!r}")
    return tuple(topics)


def parse_remaps(items: typing.Iterable[str]) -> typing.Dict[str, str]:
    """Return ``{recorded topic: new topic}`` from ``["/a:=/b", ...]``; ``ValueError`` naming a bad item."""
    remap: typing.Dict[str, str] = {}
    for item in items:
        source, separator, target = str(item).partition(":=")
        if not separator:
            raise ValueError(f"remap {item!r} must look like /recorded/topic:=/new/topic")
        check_topic_names([source, target])
        if source in remap:
            raise ValueError(f"topic {source} is remapped twice")
        remap[source] = target
    return remap


def type_hash_string(version: int, value: typing.Optional[typing.Sequence[int]]) -> typing.Optional[str]:
    """Return ``RIHS01_<hex>`` for a version-1 type hash (32 bytes), else None (unknown / not advertised)."""
    if version != 1 or not value or not any(value):
        return None
    return "RIHS01_" + bytes(value).hex()
