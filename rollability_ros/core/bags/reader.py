"""Read rosbag2 bags (MCAP or SQLite3 storage): messages in log-time order across split files, and bag info.

Every problem with a bag (missing metadata.yaml or storage file, truncated or corrupt MCAP) raises
:class:`~rollability_ros.core.bags.metadata.BagError` naming the file and the problem.
"""
import contextlib
import heapq
import os
import typing

from rollability_ros.core.bags.metadata import BagError, read_metadata, topics_from_metadata

if typing.TYPE_CHECKING:  # annotations only: mcap is imported where used
    from mcap.reader import SeekingReader
    from mcap.records import Schema, Statistics
    from mcap.summary import Summary

#: The 8 bytes that open and close every complete MCAP file.
MCAP_MAGIC = b"\x89MCAP0\r\n"


class BagMessage(typing.NamedTuple):
    """One recorded message: topic, ``pkg/msg/Type``, serialized CDR bytes, log (receive) time in ns."""

    topic: str
    type_name: str
    data: bytes
    log_time_ns: int


@contextlib.contextmanager
def bag_file_errors(path: str) -> typing.Iterator[None]:
    """Re-raise any failure inside the block as :class:`BagError` naming ``path`` (not a deep mcap traceback)."""
    try:
        yield
    except BagError:
        raise
    except FileNotFoundError as exc:
        raise BagError(f"{path}: storage file missing") from exc
    except Exception as exc:  # mcap, zstd and struct raise many types for corrupt input; name the file instead
        raise BagError(f"{path}: corrupt or unreadable bag file ({type(exc).__name__}: {exc}); "
                       f"if it is an MCAP bag of a killed recorder, run `rollability bag recover`") from exc


def statistics_of(summary: "Summary") -> "Statistics":
    """The statistics record of a summary :func:`open_mcap` returned (it refuses a file without one)."""
    if summary.statistics is None:
        raise BagError("an MCAP summary without statistics (open it with open_mcap)")
    return summary.statistics


def open_mcap(path: str, stream: typing.BinaryIO) -> typing.Tuple["SeekingReader", "Summary"]:
    """Return ``(reader, summary)`` for a complete MCAP file open as ``stream``; BagError if it is not one."""
    from mcap.reader import SeekingReader

    with bag_file_errors(path):
        stream.seek(0, os.SEEK_END)
        size = stream.tell()
        stream.seek(0)
        if stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise BagError(f"{path}: not an MCAP file (bad magic bytes)")
        stream.seek(size - len(MCAP_MAGIC))
        if size < 2 * len(MCAP_MAGIC) or stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise BagError(f"{path}: truncated (no footer; was the recorder killed?); run "
                           f"`rollability bag recover` on the bag")
        stream.seek(0)
        reader = SeekingReader(stream)
        summary = reader.get_summary()
        if summary is None or summary.statistics is None:
            raise BagError(f"{path}: has no summary section with statistics; run `rollability bag recover`")
    return reader, summary


def storage_paths(directory: str, information: typing.Mapping[str, typing.Any]) -> typing.List[str]:
    """Return the absolute storage file paths listed in metadata; BagError naming the first missing one."""
    paths = []
    for relative in information.get("relative_file_paths") or []:
        path = os.path.join(directory, relative)
        if not os.path.isfile(path):
            raise BagError(f"{path}: storage file listed in metadata.yaml is missing")
        paths.append(path)
    return paths


class BagReader:
    """Iterate a bag's messages as :class:`BagMessage` in log-time order, across all its storage files.

    Parameters
    ----------
    directory : str or path
        The bag directory (holding ``metadata.yaml``).
    topics : iterable of str, optional
        Only these topics (default all); an unknown topic raises ValueError naming the bag's topics.
    start_time_ns, end_time_ns : int, optional
        Only messages with ``start_time_ns <= log_time_ns < end_time_ns`` (ns since the epoch).

    The reader can be iterated several times (each pass re-reads the files), e.g. for looped playback.
    """

    def __init__(self, directory, topics=None, start_time_ns=None, end_time_ns=None):
        self.directory = os.fspath(directory)
        self.metadata = read_metadata(self.directory)
        self.storage_identifier = self.metadata["storage_identifier"]
        if self.storage_identifier not in ("mcap", "sqlite3"):
            raise BagError(f"{self.directory}: storage '{self.storage_identifier}' is not supported (mcap, sqlite3)")
        self.topic_infos = topics_from_metadata(self.metadata)
        known = {t.name for t in self.topic_infos}
        self.topics = None if topics is None else set(topics)
        if self.topics is not None and not self.topics <= known:
            raise ValueError(f"topics {sorted(self.topics - known)} are not in bag {self.directory} "
                             f"(it has {sorted(known)})")
        self.start_time_ns = start_time_ns
        self.end_time_ns = end_time_ns
        self.paths = storage_paths(self.directory, self.metadata)

    def __iter__(self):
        return (message for message, _ in self.with_definitions())

    def with_definitions(self) -> typing.Iterator[typing.Tuple[BagMessage, str]]:
        """Yield ``(BagMessage, definition)``: each message with the full ``ros2msg`` definition the bag stores for
        its type ("" when it has none), the one to decode it with; for a bag recorded before an interface changed
        it is not the installed one."""
        if self.storage_identifier == "sqlite3":
            return self._iter_rosbags()
        return self._iter_mcap()

    def _iter_mcap(self):
        with contextlib.ExitStack() as stack:
            streams = []
            for path in self.paths:
                stream = stack.enter_context(open(path, "rb"))
                reader, summary = open_mcap(path, stream)
                if statistics_of(summary).message_count:
                    streams.append(self._mcap_messages(path, reader))
            yield from heapq.merge(*streams, key=lambda pair: pair[0].log_time_ns)

    def _mcap_messages(self, path, reader):
        with bag_file_errors(path):
            for schema, channel, message in reader.iter_messages(
                    topics=self.topics, starting_at=self.start_time_ns, ending_before=self.end_time_ns):
                yield (BagMessage(channel.topic, schema.name if schema else "", message.data, message.log_time),
                       schema_text(schema))

    def _iter_rosbags(self):
        from rosbags.rosbag2 import Reader

        with bag_file_errors(self.directory), Reader(self.directory) as reader:
            connections = [c for c in reader.connections if self.topics is None or c.topic in self.topics]
            for connection, log_time_ns, data in reader.messages(
                    connections=connections, start=self.start_time_ns, stop=self.end_time_ns):
                msgdef = getattr(connection, "msgdef", None)
                yield (BagMessage(connection.topic, connection.msgtype, bytes(data), log_time_ns),
                       getattr(msgdef, "data", "") or "")


def schema_text(schema: typing.Optional["Schema"]) -> str:
    """The ``ros2msg`` definition an MCAP schema holds ("" for none or another encoding)."""
    if schema is None or schema.encoding != "ros2msg":
        return ""
    return schema.data.decode("utf-8", errors="replace")


def verify_mcap_file(path: str) -> None:
    """Raise BagError unless ``path`` is a complete MCAP file whose every chunk passes its CRC checks."""
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader, breakup_chunk

    with open(path, "rb") as stream:
        open_mcap(path, stream)
        stream.seek(0)
        with bag_file_errors(path):
            for record in StreamReader(stream, skip_magic=False, emit_chunks=True, validate_crcs=True).records:
                if isinstance(record, Chunk):
                    for _ in breakup_chunk(record, validate_crc=True):
                        pass


def check_readable(reader: BagReader) -> None:
    """Raise BagError unless every storage file of ``reader``'s bag opens and every MCAP chunk passes its CRC.

    Reads the whole bag once (no message is decoded), so a player refuses a damaged bag before publishing any
    of it rather than stopping part-way.
    """
    if reader.storage_identifier != "mcap":
        with bag_file_errors(reader.directory):
            for _ in reader:
                pass
        return
    for path in reader.paths:
        verify_mcap_file(path)


def _chunk_problems(path, stream, summary):
    """``(chunks, [problem, ...])``: every chunk the summary of the MCAP file ``path`` (open as ``stream``) indexes,
    read at its offset, decompressed and checked against its CRC; each problem names the chunk's byte offset."""
    import io

    from mcap.data_stream import ReadDataStream
    from mcap.records import Chunk
    from mcap.stream_reader import breakup_chunk

    problems = []
    for index in summary.chunk_indexes:
        offset = index.chunk_start_offset
        stream.seek(offset)
        head = stream.read(9)
        if len(head) < 9 or head[0] != 0x06:
            problems.append(f"{os.path.basename(path)}: no chunk record at byte {offset}, where the index puts one")
            continue
        body = stream.read(int.from_bytes(head[1:9], "little"))
        try:
            chunk = Chunk.read(ReadDataStream(io.BytesIO(body)))
            if not chunk.uncompressed_crc:
                problems.append(f"{os.path.basename(path)}: the chunk at byte {offset} carries no CRC (unverifiable)")
                continue
            breakup_chunk(chunk, validate_crc=True)
        except Exception as exc:  # CRC mismatch, undecompressible or garbled chunk
            problems.append(f"{os.path.basename(path)}: the chunk at byte {offset} is corrupt "
                            f"({type(exc).__name__}: {exc})")
    return len(summary.chunk_indexes), problems


def _mcap_file_info(path, verify_chunks=False):
    """Return the info of one complete MCAP file from its summary section (no message is read); with
    ``verify_chunks`` also ``chunks`` and ``chunk_problems`` (:func:`_chunk_problems`)."""
    with open(path, "rb") as stream:
        _, summary = open_mcap(path, stream)
        chunks, problems = _chunk_problems(path, stream, summary) if verify_chunks else (None, None)
    statistics = statistics_of(summary)
    counts: typing.Dict[typing.Tuple[str, str], int] = {}
    for channel_id, count in statistics.channel_message_counts.items():
        channel = summary.channels[channel_id]
        schema = summary.schemas.get(channel.schema_id)
        key = (channel.topic, schema.name if schema else "")
        counts[key] = counts.get(key, 0) + count
    compressions = sorted({index.compression or "none" for index in summary.chunk_indexes})
    return {
        "path": os.path.basename(path),
        "size_bytes": os.path.getsize(path),
        "message_count": statistics.message_count,
        "start_time_ns": statistics.message_start_time if statistics.message_count else None,
        "end_time_ns": statistics.message_end_time if statistics.message_count else None,
        "chunk_compression": compressions,
        "topic_counts": counts,
        "chunks": chunks,
        "chunk_problems": problems,
    }


def _rosbags_file_infos(directory, information):
    """Return one info entry for a SQLite3 bag as a whole, from rosbags' reader."""
    from rosbags.rosbag2 import Reader

    paths = storage_paths(directory, information)
    with bag_file_errors(directory), Reader(directory) as reader:
        counts = {(c.topic, c.msgtype): c.msgcount for c in reader.connections}
        count = reader.message_count
        return [{
            "path": ", ".join(os.path.basename(p) for p in paths),
            "size_bytes": sum(os.path.getsize(p) for p in paths),
            "message_count": count,
            "start_time_ns": reader.start_time if count else None,
            "end_time_ns": reader.end_time - 1 if count else None,
            "chunk_compression": [],
            "topic_counts": counts,
        }]


def _mcap_file_metadata(path):
    """A ``rosbag2_bagfile_information``-like mapping of one MCAP file from its own records: topics with type,
    serialization, offered QoS and type hash from the channels, counts from the statistics, distro and version
    from rosbag2's ``rosbag2`` metadata record where present (other MCAP writers have none)."""
    import yaml
    from rollability_ros.core import safe_yaml
    from rollability_ros.core.bags.metadata import METADATA_VERSION

    with open(path, "rb") as stream:
        reader, summary = open_mcap(path, stream)
        with bag_file_errors(path):
            records = {m.name: m.metadata for m in reader.iter_metadata()}
    embedded = records.get("rosbag2", {})
    try:
        version = int((safe_yaml.load(embedded.get("serialized_metadata") or "") or {}).get("version",
                                                                                          METADATA_VERSION))
    except (yaml.YAMLError, AttributeError, TypeError, ValueError):
        version = METADATA_VERSION
    topics: typing.Dict[typing.Tuple[str, str], typing.Dict[str, typing.Any]] = {}
    for channel_id, channel in sorted(summary.channels.items()):
        schema = summary.schemas.get(channel.schema_id)
        key = (channel.topic, schema.name if schema else "")
        entry = topics.setdefault(key, {"topic_metadata": {
            "name": channel.topic, "type": key[1], "serialization_format": channel.message_encoding,
            "offered_qos_profiles": channel.metadata.get("offered_qos_profiles", ""),
            "type_description_hash": channel.metadata.get("topic_type_hash", "")}, "message_count": 0})
        entry["message_count"] += statistics_of(summary).channel_message_counts.get(channel_id, 0)
    return {"version": version, "storage_identifier": "mcap", "relative_file_paths": [os.path.basename(path)],
            "topics_with_message_count": list(topics.values()), "ros_distro": embedded.get("ROS_DISTRO", ""),
            "compression_format": "", "compression_mode": ""}


def human_time(time_ns: typing.Optional[int]) -> str:
    """``time_ns`` (ns since the Unix epoch) as ``2026-11-23 21:18:18.483396998 UTC``; None -> '-'."""
    import datetime

    if time_ns is None:
        return "-"
    seconds, nanoseconds = divmod(int(time_ns), 1_000_000_000)
    moment = datetime.datetime.fromtimestamp(seconds, tz=datetime.timezone.utc)
    return f"{moment:%Y-%m-%d %H:%M:%S}.{nanoseconds:09d} UTC"


def _chunk_check(information, files, verify_chunks, corrupt_chunks):
    """The sentence of :func:`bag_info`'s ``chunk_check`` (the files' chunk counts are taken from them)."""
    chunk_count = sum(f.pop("chunks", None) or 0 for f in files)
    if information["storage_identifier"] == "sqlite3":
        return "not applicable (sqlite3 storage has no chunk CRCs)"
    if not verify_chunks:
        return "not verified"
    if corrupt_chunks:
        return f"{len(corrupt_chunks)} of {chunk_count} chunks fail their check: run `rollability bag recover`"
    return f"verified: all {chunk_count} chunks match their CRCs"


def _topics_against_metadata(information, files):
    """``(topics, warnings)`` of :func:`bag_info`: each topic with the count its files hold (the files' topic
    counts are taken from them), and a warning for each count or topic metadata.yaml does not match."""
    counts: typing.Dict[typing.Tuple[str, str], int] = {}
    for entry in files:
        for key, count in entry.pop("topic_counts").items():
            counts[key] = counts.get(key, 0) + count
    warnings = []
    topics = []
    for topic in topics_from_metadata(information):
        found = counts.pop((topic.name, topic.type_name), 0)
        if found != topic.message_count:
            warnings.append(f"metadata.yaml counts {topic.message_count} messages on {topic.name}, files hold {found}")
        topics.append({"name": topic.name, "type": topic.type_name, "message_count": found,
                       "serialization_format": topic.serialization_format,
                       "type_description_hash": topic.type_description_hash,
                       "offered_qos_profiles": topic.offered_qos_profiles})
    for (name, type_name), count in counts.items():
        warnings.append(f"topic {name} ({type_name}) is in the storage files but not in metadata.yaml")
        topics.append({"name": name, "type": type_name, "message_count": count, "serialization_format": "cdr",
                       "type_description_hash": "", "offered_qos_profiles": []})
    return topics, warnings


def bag_info(path: typing.Union[str, os.PathLike], verify_chunks: bool = False) -> typing.Dict[str, typing.Any]:
    """Summarise a bag directory, or one ``.mcap`` file: topics, types, counts, QoS, time span, files, sizes.

    Counts and times come from the storage files themselves (MCAP summary sections), so a metadata.yaml
    that disagrees with them (e.g. a recorder killed before closing) is reported in ``warnings``. With
    ``verify_chunks`` every MCAP chunk is also read and checked against its CRC (``chunk_check``: a sentence
    saying what was checked; ``corrupt_chunks``: one line per damaged chunk); without, ``chunk_check`` says the
    CRCs were not verified.

    Returns
    -------
    dict
        ``path``, ``storage_identifier``, ``ros_distro``, ``version``, ``message_count``, ``start_time_ns``,
        ``end_time_ns``, ``start_time``, ``end_time`` (UTC text, :func:`human_time`), ``duration_s``,
        ``size_bytes``, ``compression`` (e.g. ``"zstd (mcap chunks)"`` or
        ``"none"``), ``custom_data``, ``topics`` (list of dicts: ``name``, ``type``, ``message_count``,
        ``serialization_format``, ``type_description_hash``, ``offered_qos_profiles``), ``files`` (list of
        dicts: ``path``, ``size_bytes``, ``message_count``, ``start_time_ns``, ``end_time_ns``), ``warnings``.
    """
    path = os.fspath(path)
    if os.path.isfile(path) and path.lower().endswith(".mcap"):
        directory, information = os.path.dirname(path) or ".", _mcap_file_metadata(path)
    elif os.path.isfile(path):
        raise BagError(f"{path}: not a bag: give a bag directory (with metadata.yaml) or an .mcap file")
    else:
        directory, information = path, read_metadata(path)
    if information["storage_identifier"] == "sqlite3":
        files = _rosbags_file_infos(directory, information)
    else:
        files = [_mcap_file_info(path, verify_chunks) for path in storage_paths(directory, information)]
    corrupt_chunks = [problem for f in files for problem in (f.pop("chunk_problems", None) or [])]
    chunk_check = _chunk_check(information, files, verify_chunks, corrupt_chunks)
    topics, warnings = _topics_against_metadata(information, files)
    starts = [f["start_time_ns"] for f in files if f["start_time_ns"] is not None]
    ends = [f["end_time_ns"] for f in files if f["end_time_ns"] is not None]
    chunk_compressions = sorted({c for f in files for c in f.pop("chunk_compression")} - {"none"})
    if information.get("compression_mode"):
        compression = f"{information.get('compression_format')} ({information['compression_mode']} mode)"
    elif chunk_compressions:
        compression = f"{'+'.join(chunk_compressions)} (mcap chunks)"
    else:
        compression = "none"
    start_ns = min(starts) if starts else None
    end_ns = max(ends) if ends else None
    return {
        "path": path,
        "storage_identifier": information["storage_identifier"],
        "ros_distro": information.get("ros_distro", ""),
        "version": information["version"],
        "message_count": sum(f["message_count"] for f in files),
        "start_time_ns": start_ns,
        "end_time_ns": end_ns,
        "start_time": human_time(start_ns),
        "end_time": human_time(end_ns),
        "duration_s": (end_ns - start_ns) / 1e9 if end_ns is not None and start_ns is not None else 0.0,
        "size_bytes": sum(f["size_bytes"] for f in files),
        "compression": compression,
        "custom_data": information.get("custom_data") or {},
        "topics": topics,
        "files": files,
        "warnings": warnings,
        "chunk_check": chunk_check,
        "corrupt_chunks": corrupt_chunks,
    }


def _qos_text(profiles):
    """Offered QoS profiles as ``reliable, transient_local[, keep_last 10]`` (several joined by ' | ')."""
    texts = []
    for profile in profiles:
        history = profile.get("history", "unknown")  # rosbag2 records offered profiles with history unknown
        depth = f", keep_last {profile['depth']}" if history == "keep_last" else \
            (", keep_all" if history == "keep_all" else "")
        texts.append(f"{profile.get('reliability')}, {profile.get('durability')}{depth}")
    return " | ".join(texts) or "-"


def format_bag_info(info: typing.Mapping[str, typing.Any]) -> str:
    """Return :func:`bag_info`'s dict as the text ``rollability bag info`` prints (the fields of ``ros2 bag
    info`` and per-topic QoS)."""
    lines = [
        f"Bag:               {info['path']}",
        f"Storage id:        {info['storage_identifier']} (metadata version {info['version']}, "
        f"ROS distro {info['ros_distro'] or '?'})",
        f"Bag size:          {_size_text(info['size_bytes'])}",
        f"Compression:       {info['compression']}",
        f"Duration:          {info['duration_s']:.9f} s",
        f"Start:             {info['start_time']} ({_seconds_text(info['start_time_ns'])})",
        f"End:               {info['end_time']} ({_seconds_text(info['end_time_ns'])})",
        f"Messages:          {info['message_count']}",
        f"Files:             {len(info['files'])}",
        f"Chunk CRCs:        {info['chunk_check']}",
    ]
    for entry in info["files"]:
        lines.append(f"  {entry['path']}  {_size_text(entry['size_bytes'])}, {entry['message_count']} msgs, "
                     f"{human_time(entry['start_time_ns'])} .. {human_time(entry['end_time_ns'])}")
    if info["custom_data"]:
        lines.append("Custom data:       " + ", ".join(f"{k}={v}" for k, v in sorted(info["custom_data"].items())))
    lines.append(f"Topics:            {len(info['topics'])}")
    width = max((len(t["name"]) for t in info["topics"]), default=0)
    for topic in info["topics"]:
        lines.append(f"  Topic: {topic['name']:<{width}} | Type: {topic['type']} | Count: {topic['message_count']} | "
                     f"Serialization Format: {topic['serialization_format']} | "
                     f"QoS: {_qos_text(topic['offered_qos_profiles'])}")
    for warning in info["warnings"]:
        lines.append(f"warning: {warning}")
    for problem in info["corrupt_chunks"]:
        lines.append(f"corrupt: {problem}")
    return "\n".join(lines)


def _size_text(size_bytes):
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if size_bytes >= scale:
            return f"{size_bytes / scale:.1f} {unit} ({size_bytes} bytes)"
    return f"{size_bytes} bytes"


def _seconds_text(time_ns):
    return "-" if time_ns is None else f"{time_ns // 1_000_000_000}.{time_ns % 1_000_000_000:09d} s"
