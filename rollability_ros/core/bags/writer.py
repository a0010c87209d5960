"""Write rosbag2 bags (MCAP storage) that ``ros2 bag`` on ROS 2 Jazzy, rosbags and mcap readers open.

Layout of a bag directory ``<dir>/`` named ``<name>``::

    metadata.yaml             rosbag2 metadata version 9 (rewritten at open, on every new topic or file, at close)
    <name>_0.mcap, _1, ...    MCAP, profile "ros2": one schema per type (encoding "ros2msg", full definition
                              with nested types), one channel per topic (message encoding "cdr", metadata
                              offered_qos_profiles + topic_type_hash), "rosbag2" metadata record at close
    .recovery.json            sidecar while recording: every type's definition, so `recover` can rebuild
                              channels that had no complete chunk yet; removed by a clean close

MCAP chunk compression (zstd by default) lives inside the MCAP files, so ``compression_format`` and
``compression_mode`` in metadata.yaml stay empty, as rosbag2 writes them for MCAP chunk compression.

Durability: the MCAP writer's output goes to the OS with unbuffered writes, so every finished chunk survives a
SIGKILL of the writing process (``fsync=True`` also makes it survive power loss). A chunk is finished when it
holds ``chunk_size_bytes`` of (uncompressed) records, or when ``flush_interval_s`` has passed since the last
finished chunk at a :meth:`BagWriter.write` or :meth:`BagWriter.flush_if_due` call. **At most the messages of
the one open chunk are lost** on a kill: fewer than ``chunk_size_bytes`` of message records plus one message,
and (if the caller writes or calls ``flush_if_due`` at least every ``flush_interval_s``) at most the last
``2 * flush_interval_s`` of messages. :func:`rollability_ros.core.bags.recover.recover` restores the rest.
"""
import dataclasses
import hashlib
import os
import time
import typing

from rollability_ros.core.bags.metadata import (
    ROS_DISTRO,
    FileInfo,
    TopicInfo,
    build_metadata,
    write_metadata,
)
from rollability_ros.core.bags.qos import normalize_qos_profiles
from rollability_ros.core.bags.msg_definitions import definition_for, full_type_name, rihs01_hash
# the MCAP file layer (constants, McapFile, the sidecar) lives in _mcap_file.py; its names stay importable from here
from rollability_ros.core.bags._mcap_file import (  # noqa: F401
    DEFAULT_CHUNK_SIZE_BYTES,
    DEFAULT_FLUSH_INTERVAL_S,
    DUPLICATES_KEY,
    MCAP_LIBRARY,
    MCAP_PROFILE,
    RECOVERY_SIDECAR,
    RESTARTS_KEY,
    SCHEMA_ENCODING,
    McapFile,
    UnbufferedSink,
    channel_metadata,
    mcap_compression,
    read_sidecar,
    storage_file_name,
    write_sidecar,
)


class BagWriter:
    """Write a rosbag2 bag directory with MCAP storage; see the module docstring for layout and durability.

    Parameters
    ----------
    directory : str or path
        Bag directory to create; it must not exist or be empty. Its base name names the storage files.
    storage : str
        Storage id; only ``"mcap"`` (use :func:`rollability_ros.core.bags.convert.convert` for sqlite3).
    compression : str
        MCAP chunk compression: ``"zstd"``, ``"lz4"`` or ``"none"``.
    split_max_bytes : int
        Start a new storage file once the current one holds this many bytes on disk (0: never). A file can
        exceed it by up to one chunk.
    split_max_duration_s : float
        Start a new storage file when a message's log time is this many seconds after the file's first (0: never).
    custom_data : dict of str to str, optional
        Stored as ``custom_data`` in metadata.yaml.
    chunk_size_bytes : int
        Uncompressed MCAP chunk size, bytes; bounds what a kill can lose.
    flush_interval_s : float
        Longest time a message waits in an open chunk, s (0: write a chunk per message).
    fsync : bool
        fsync every finished chunk (survives power loss, slower).
    clock : callable
        Monotonic clock in seconds for the flush interval (for tests).
    continue_open : bool
        If ``directory`` holds a bag left open by a killed writer, recover it and continue it with a new storage
        file (metadata.yaml then lists every file; the restart is noted in ``custom_data["recorder_restarts"]``,
        see :func:`~rollability_ros.core.bags.recover.recording_gaps`). A closed bag is still refused.

    Not thread-safe: call it from one thread (a single-threaded executor, or behind one lock).
    """

    def __init__(self, directory, storage="mcap", compression="zstd", split_max_bytes=0, split_max_duration_s=0,
                 custom_data=None, chunk_size_bytes=DEFAULT_CHUNK_SIZE_BYTES,
                 flush_interval_s=DEFAULT_FLUSH_INTERVAL_S, fsync=False, clock=time.monotonic,
                 continue_open=False):
        if storage != "mcap":
            raise ValueError(f"BagWriter writes storage 'mcap' only, got {storage!r}; convert afterwards for sqlite3")
        for name, value in (("split_max_bytes", split_max_bytes), ("split_max_duration_s", split_max_duration_s),
                            ("flush_interval_s", flush_interval_s)):
            if not isinstance(value, (int, float)) or isinstance(value, bool) or value < 0:
                raise ValueError(f"{name} must be a number >= 0, got {value!r}")
        if not isinstance(chunk_size_bytes, int) or chunk_size_bytes <= 0:
            raise ValueError(f"chunk_size_bytes must be a positive integer, got {chunk_size_bytes!r}")
        self._compression = mcap_compression(compression)
        self.directory = os.fspath(directory)
        self._previous_files: typing.List[FileInfo] = []
        self._previous_topics: typing.Dict[str, TopicInfo] = {}
        self.continued: typing.Optional[typing.Dict[str, typing.Any]] = None   # recover()'s report when continued
        self._held = set()          # (topic, publish time, SHA-256) of re-deliverable messages the bag holds
        self.duplicates_skipped = {}
        if os.path.exists(self.directory) and (not os.path.isdir(self.directory) or os.listdir(self.directory)):
            if not (continue_open and os.path.isdir(self.directory)):
                raise ValueError(f"{self.directory}: exists and is not an empty directory; not overwriting a bag")
            custom_data = self._continue(custom_data)
        os.makedirs(self.directory, exist_ok=True)
        self.name = os.path.basename(os.path.normpath(self.directory))
        self.split_max_bytes = int(split_max_bytes)
        self.split_max_duration_ns = int(split_max_duration_s * 1e9)
        self.chunk_size_bytes = chunk_size_bytes
        self.flush_interval_s = float(flush_interval_s)
        self._fsync = fsync
        self._clock = clock
        self._custom_data = dict(custom_data) if custom_data else None
        self._topics = {}
        self._definitions = {}
        self._files = list(self._previous_files)
        self._current: typing.Optional[McapFile] = None   # the open storage file (None once closed)
        self._last_flush_s = clock()
        self._unflushed = 0
        build_metadata([], [], custom_data=self._custom_data)  # validates custom_data before any file exists
        self._open_file()

    def _continue(self, custom_data):
        """Take over the bag left open in ``directory`` by a killed writer: recover it, keep its files and topic
        counts, note the restart in ``custom_data["recorder_restarts"]`` (indexes of files that begin after a
        restart) and return the custom data to keep. A closed bag is refused (ValueError): it is not reopened."""
        from rollability_ros.core.bags.metadata import BagError, topics_from_metadata
        from rollability_ros.core.bags.recover import is_left_open, mark_restart, recover

        if not is_left_open(self.directory):
            raise ValueError(f"{self.directory}: holds a closed bag (or no bag); not writing into it")
        try:
            self.continued = recover(self.directory, allow_empty=True)   # killed before its first chunk: go on
            information = mark_restart(self.directory)
        except BagError as exc:
            raise ValueError(f"{self.directory}: cannot continue the bag left open there: {exc}") from exc
        self._previous_files = [FileInfo(f["path"], f["starting_time"]["nanoseconds_since_epoch"],
                                         f["duration"]["nanoseconds"], f["message_count"])
                                for f in information.get("files") or []]
        self._previous_topics = {t.name: t for t in topics_from_metadata(information)}
        self._held = self._redeliverable_messages(information)
        kept = dict(custom_data or {})
        kept.update(information["custom_data"])
        return kept

    def _redeliverable_messages(self, information):
        """Keys (:meth:`_key`) of the messages the continued bag holds on topics with a transient-local publisher:
        those a new subscription gets again from the publisher's history, and must not be recorded twice."""
        from rollability_ros.core.bags.reader import bag_file_errors, open_mcap, statistics_of

        topics = [t.name for t in self._previous_topics.values()
                  if any(p.get("durability") == "transient_local" for p in t.offered_qos_profiles)]
        held = set()
        for relative in (information.get("relative_file_paths") or []) if topics else []:
            path = os.path.join(self.directory, relative)
            with open(path, "rb") as stream, bag_file_errors(path):
                reader, summary = open_mcap(path, stream)
                if statistics_of(summary).message_count:
                    for _, channel, message in reader.iter_messages(topics=topics):
                        held.add(self._key(channel.topic, message.data, message.publish_time))
        return held

    @staticmethod
    def _key(topic, data, publish_time_ns):
        return topic, int(publish_time_ns), hashlib.sha256(bytes(data)).digest()

    # --- topics and messages -------------------------------------------------------------------------
    def add_topic(self, name: str, type_name: str, serialization_format: str = "cdr",
                  offered_qos_profiles: typing.Union[typing.Sequence[typing.Mapping[str, typing.Any]], str,
                                                     None] = None,
                  definition: typing.Optional[str] = None, type_description_hash: typing.Optional[str] = None) -> None:
        """Register a topic before writing to it.

        Parameters
        ----------
        name : str
            Topic name, e.g. ``/rollability/launch_outcomes``.
        type_name : str
            ``pkg/msg/Type`` (``pkg/Type`` is accepted and stored as ``pkg/msg/Type``).
        serialization_format : str
            ``"cdr"`` for ROS 2 messages.
        offered_qos_profiles : list of dict or str, optional
            The publishers' QoS (see :func:`~rollability_ros.core.bags.qos.normalize_qos_profiles`).
        definition : str, optional
            Full ``ros2msg`` definition; default :func:`~rollability_ros.core.bags.msg_definitions.definition_for`.
            ``""`` records a type whose definition is not installed (readers then cannot decode it without
            it); it needs ``type_description_hash``.
        type_description_hash : str, optional
            ``RIHS01_...`` hash; default computed from the definition. A recorder passes what the publishers
            advertise, so a type changed since the definition files were installed is still recorded truthfully.

        Raises
        ------
        ValueError
            The topic exists with another type, or a definition is not found.
        """
        type_name = full_type_name(type_name)
        if not isinstance(name, str) or not name.startswith("/"):
            raise ValueError(f"topic name must be an absolute ROS name starting with '/', got {name!r}")
        previous = self._previous_topics.get(name)
        if previous is not None and previous.type_name != type_name:
            raise ValueError(f"topic {name} is recorded in this bag with type {previous.type_name}, not {type_name}")
        if name in self._topics:
            if self._topics[name].type_name != type_name:
                raise ValueError(f"topic {name} is already recorded with type {self._topics[name].type_name}, "
                                 f"not {type_name}")
            return
        if definition == "" and not type_description_hash:
            raise ValueError(f"topic {name}: an empty definition of {type_name} needs the publishers' "
                             f"type_description_hash")
        if type_name not in self._definitions:
            self._definitions[type_name] = definition if definition is not None else definition_for(type_name)
        topic = TopicInfo(
            name=name,
            type_name=type_name,
            serialization_format=serialization_format,
            offered_qos_profiles=normalize_qos_profiles(offered_qos_profiles),
            type_description_hash=type_description_hash or rihs01_hash(type_name, self._definitions[type_name]),
        )
        self._topics[name] = topic
        self._file.add_topic(topic, self._definitions[type_name])
        write_sidecar(self.directory, self._definitions)
        self._write_metadata()

    @property
    def topics(self) -> typing.Dict[str, TopicInfo]:
        """The registered topics as ``{name: TopicInfo}`` (message counts so far)."""
        return dict(self._topics)

    def write(self, topic: str, cdr_bytes: bytes, log_time_ns: int,
              publish_time_ns: typing.Optional[int] = None) -> bool:
        """Append one serialized message.

        Parameters
        ----------
        topic : str
            A topic registered with :meth:`add_topic`.
        cdr_bytes : bytes
            The serialized message (CDR, as received from the middleware).
        log_time_ns : int
            Receive time, ns since the Unix epoch (rosbag2's ``recv_timestamp``; orders playback).
        publish_time_ns : int, optional
            Send time, ns; defaults to ``log_time_ns``.

        Returns
        -------
        bool
            False when the message was not written because it is a copy of one the bag held when this writer
            continued it (same topic, send time and bytes: a transient-local publisher's history re-delivered
            to the restarted recorder); counted in ``duplicates_skipped`` and in metadata.yaml's custom data.
        """
        if self._current is None:
            raise ValueError(f"{self.directory}: bag is closed")
        if topic not in self._topics:
            raise ValueError(f"topic {topic} was not added to the bag (call add_topic first)")
        log_time_ns = int(log_time_ns)
        if log_time_ns < 0:
            raise ValueError(f"log_time_ns must be >= 0, got {log_time_ns}")
        if self._held and publish_time_ns is not None and \
                self._key(topic, cdr_bytes, publish_time_ns) in self._held:
            self.duplicates_skipped[topic] = self.duplicates_skipped.get(topic, 0) + 1
            return False
        if self._split_due(log_time_ns):
            self._roll_over()
        self._current.write(topic, cdr_bytes, log_time_ns, log_time_ns if publish_time_ns is None
                            else int(publish_time_ns))
        self._topics[topic].message_count += 1
        self._unflushed += 1
        self.flush_if_due()
        return True

    def flush(self) -> None:
        """Finish the open chunk and hand it to the OS (a chunk with no messages is not written)."""
        if self._current is not None:
            self._current.writer.flush()
        self._last_flush_s = self._clock()
        self._unflushed = 0

    def flush_if_due(self) -> bool:
        """Flush when messages have waited ``flush_interval_s`` or longer; return True when it flushed.

        A recorder calls this from a timer so a quiet topic's last messages are not held in memory.
        """
        if self._unflushed and self._clock() - self._last_flush_s >= self.flush_interval_s:
            self.flush()
            return True
        return False

    def close(self) -> None:
        """Finish the last storage file, write the final metadata.yaml and drop the recovery sidecar."""
        if self._current is None:
            return
        self._current.close(self.metadata())
        self._current = None
        self._write_metadata()
        sidecar = os.path.join(self.directory, RECOVERY_SIDECAR)
        if os.path.exists(sidecar):
            os.remove(sidecar)

    def metadata(self) -> typing.Dict[str, typing.Any]:
        """Return the current ``rosbag2_bagfile_information`` mapping."""
        topics = []
        for name, previous in self._previous_topics.items():    # topics of files before a restart, first
            current = self._topics.get(name)
            topics.append(dataclasses.replace(current or previous, message_count=previous.message_count + (
                current.message_count if current else 0)))
        topics.extend(t for name, t in self._topics.items() if name not in self._previous_topics)
        custom_data = self._custom_data
        if self.duplicates_skipped:   # added to what earlier restarts of this bag skipped
            custom_data = dict(custom_data or {})
            custom_data[DUPLICATES_KEY] = str(int(custom_data.get(DUPLICATES_KEY, 0)) +
                                              sum(self.duplicates_skipped.values()))
        return build_metadata(topics, list(self._files), custom_data=custom_data, ros_distro=ROS_DISTRO)

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()

    # --- storage files -------------------------------------------------------------------------------
    @property
    def _file(self) -> McapFile:
        """The open storage file (a bag has one from its start until :meth:`close`)."""
        if self._current is None:
            raise ValueError(f"bag {self.directory} is closed")
        return self._current

    def _split_due(self, log_time_ns):
        info = self._file.info
        if info.message_count == 0:
            return False
        if self.split_max_bytes and self._file.sink.tell() >= self.split_max_bytes:
            return True
        return bool(self.split_max_duration_ns and log_time_ns - info.starting_time_ns >= self.split_max_duration_ns)

    def _open_file(self):
        path = os.path.join(self.directory, storage_file_name(self.name, len(self._files)))
        self._current = McapFile(path, self._compression, self.chunk_size_bytes, self._fsync)
        self._files.append(self._current.info)
        for topic in self._topics.values():
            self._current.add_topic(topic, self._definitions[topic.type_name])
        self._write_metadata()

    def _roll_over(self):
        self._file.close(self.metadata())
        self._open_file()
        self._last_flush_s = self._clock()
        self._unflushed = 0

    def _write_metadata(self):
        write_metadata(self.directory, self.metadata())
