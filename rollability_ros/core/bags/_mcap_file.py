"""The MCAP files of a bag: chunked, unbuffered writes (:class:`McapFile`), their constants, names and the recovery
sidecar; shared by the writer (:mod:`~rollability_ros.core.bags.writer`) and the recovery
(:mod:`~rollability_ros.core.bags.recover`), which therefore do not import each other for them.
"""
import json
import os
import typing

from rollability_ros.core.bags.metadata import FileInfo, TopicInfo, dump_metadata
from rollability_ros.core.bags.qos import qos_profiles_yaml

#: Default uncompressed chunk size, bytes: the most a SIGKILL can lose (see module docstring).
DEFAULT_CHUNK_SIZE_BYTES = 256 * 1024

#: Default longest time a message waits in an open chunk before the chunk is written, s.
DEFAULT_FLUSH_INTERVAL_S = 1.0

#: ``custom_data`` key listing (comma separated) the indexes of storage files that a restarted writer began.
RESTARTS_KEY = "recorder_restarts"

#: ``custom_data`` key: messages a restarted writer did not record again because the bag already held them (a
#: transient-local publisher re-delivers its history to the new subscription).
DUPLICATES_KEY = "recorder_duplicates_skipped"

#: Name of the sidecar holding type definitions while a bag is being written.
RECOVERY_SIDECAR = ".recovery.json"

#: MCAP header profile and library string.
MCAP_PROFILE = "ros2"
MCAP_LIBRARY = "rollability_ros bag_writer"

#: Schema encoding of ``.msg``-style definitions.
SCHEMA_ENCODING = "ros2msg"


def storage_file_name(bag_name: str, index: int) -> str:
    """Return the name of storage file ``index`` of bag ``bag_name`` (``<name>_<index>.mcap``)."""
    return f"{bag_name}_{index}.mcap"


def mcap_compression(compression: str) -> typing.Any:
    """Return the ``mcap.writer.CompressionType`` for ``"zstd"``, ``"lz4"`` or ``"none"``/``""``."""
    from mcap.writer import CompressionType

    choices = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE,
               "": CompressionType.NONE}
    if compression not in choices:
        raise ValueError(f"compression must be one of zstd, lz4, none; got {compression!r}")
    return choices[compression]


def channel_metadata(topic: TopicInfo) -> typing.Dict[str, str]:
    """Return the MCAP channel metadata rosbag2 stores for a :class:`TopicInfo`."""
    return {"offered_qos_profiles": qos_profiles_yaml(topic.offered_qos_profiles),
            "topic_type_hash": topic.type_description_hash}


def write_sidecar(directory: str, schemas: typing.Mapping[str, str]) -> None:
    """Atomically write the recovery sidecar: ``{type name: full definition}``."""
    path = os.path.join(directory, RECOVERY_SIDECAR)
    with open(path + ".tmp", "w", encoding="utf-8") as stream:
        json.dump({"definitions": schemas}, stream)
    os.replace(path + ".tmp", path)


def read_sidecar(directory: str) -> typing.Dict[str, str]:
    """Return the recovery sidecar's ``{type name: full definition}``, or ``{}`` when there is none."""
    path = os.path.join(directory, RECOVERY_SIDECAR)
    try:
        with open(path, encoding="utf-8") as stream:
            return dict(json.load(stream).get("definitions", {}))
    except (FileNotFoundError, ValueError, RecursionError):
        return {}  # written atomically, so only outside damage breaks it; the storage files hold most schemas


class UnbufferedSink:
    """A write-only file that hands every write straight to the OS (no user-space buffer to lose on a kill)."""

    def __init__(self, path, fsync=False):
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        self._position = 0
        self._fsync = fsync

    def write(self, data: bytes) -> int:
        view = memoryview(data)
        while view:
            written = os.write(self._fd, view)
            view = view[written:]
        self._position += len(data)
        return len(data)

    def tell(self) -> int:
        return self._position

    def flush(self) -> None:
        if self._fsync:
            os.fsync(self._fd)

    def close(self) -> None:
        if self._fd >= 0:
            self.flush()
            os.close(self._fd)
            self._fd = -1   # closed


class McapFile:
    """One open MCAP storage file of a bag: its writer, sink, channel ids and :class:`FileInfo`."""

    def __init__(self, path, compression, chunk_size_bytes, fsync):
        from mcap.writer import Writer

        self.info = FileInfo(os.path.basename(path))
        self.sink = UnbufferedSink(path, fsync=fsync)
        self.writer = Writer(typing.cast(typing.IO[bytes], self.sink), chunk_size=chunk_size_bytes, compression=compression)
        self.writer.start(profile=MCAP_PROFILE, library=MCAP_LIBRARY)
        self.schema_ids = {}
        self.channel_ids = {}
        self.end_time_ns = 0

    def add_schema(self, type_name: str, encoding: str, data: bytes) -> int:
        """Register a schema once per type name and return its id."""
        if type_name not in self.schema_ids:
            self.schema_ids[type_name] = self.writer.register_schema(type_name, encoding, data)
        return self.schema_ids[type_name]

    def add_channel(self, topic_name: str, message_encoding: str, schema_id: int,
                    metadata: typing.Mapping[str, str]) -> None:
        """Register the channel of ``topic_name``."""
        self.channel_ids[topic_name] = self.writer.register_channel(topic_name, message_encoding, schema_id,
                                                                    dict(metadata))

    def add_topic(self, topic: TopicInfo, definition: str) -> None:
        """Register ``topic``'s schema (once per type) and channel."""
        schema_id = self.add_schema(topic.type_name, SCHEMA_ENCODING, definition.encode("utf-8"))
        self.add_channel(topic.name, topic.serialization_format, schema_id, channel_metadata(topic))

    def write(self, topic_name: str, data: bytes, log_time_ns: int, publish_time_ns: int) -> None:
        """Append one message and update the file's count and time span."""
        self.writer.add_message(self.channel_ids[topic_name], log_time_ns, data, publish_time_ns)
        info = self.info
        if info.message_count == 0:
            info.starting_time_ns = self.end_time_ns = log_time_ns
        info.starting_time_ns = min(info.starting_time_ns, log_time_ns)
        self.end_time_ns = max(self.end_time_ns, log_time_ns)
        info.duration_ns = self.end_time_ns - info.starting_time_ns
        info.message_count += 1

    def close(self, information: typing.Mapping[str, typing.Any]) -> None:
        """Write the ``rosbag2`` metadata record and the summary section, and close the file."""
        self.writer.add_metadata("rosbag2", {"serialized_metadata": dump_metadata(information),
                                             "ROS_DISTRO": information["ros_distro"]})
        self.writer.finish()
        self.sink.close()
