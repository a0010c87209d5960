"""Recover a bag whose recorder was killed or whose files were damaged: rebuild MCAP files and metadata.yaml.

After a SIGKILL the last storage file has no summary section or footer, possibly a half-written chunk, and
metadata.yaml still holds what was known when it was last written (topics with QoS and type hashes, custom
data, ROS distro, files so far; counts of 0). Outside damage (flipped bytes) can hit any record. :func:`recover`

- leaves complete MCAP files whose every chunk passes its CRC alone;
- rebuilds every other file from each intact record it holds, found by scanning the bytes for self-delimiting
  schema, channel and chunk records (a chunk counts only when its CRC matches), so damage to the magic, the
  header, one chunk or the summary costs only what was damaged; schemas and channels also come from the
  summary section's copies; channels of known topics without a surviving chunk are re-created from the
  recovery sidecar's definitions;
- never makes a bag worse: each rebuilt file is written beside the original, verified (complete, CRC-valid,
  holding every salvaged message) and only then renamed over it, the damaged original kept as
  ``<file>.before-recover``; when a damaged file yields nothing, BagError says so and nothing is changed;
- refuses (BagError, nothing changed) a bag in which no message at all can be saved (an empty, 10-byte or
  header-only file): "recovering" it would only replace a metadata.yaml that still names what was recorded;
- rewrites metadata.yaml (the old one kept as ``metadata.yaml.before-recover``) with counts and times from the
  files, keeping every field of the old one (storage id, ROS distro, custom data, compression fields, per-topic
  QoS and type hashes). With no metadata.yaml left it takes them from the files' channel metadata and
  ``rosbag2`` metadata records.

What a kill loses is bounded by :mod:`rollability_ros.core.bags.writer`: the messages of the one chunk that was
open at the kill (``ros2 bag reindex`` by contrast needs readable files and rebuilds metadata.yaml from them,
dropping custom data and the ROS distro). :func:`is_left_open`, :func:`mark_restart` and :func:`recording_gaps`
support a writer that continues a bag after a restart.
"""
import os
import re
import typing

from rollability_ros.core import safe_yaml
from rollability_ros.core.bags.metadata import (
    METADATA_FILE,
    ROS_DISTRO,
    BagError,
    FileInfo,
    TopicInfo,
    build_metadata,
    read_metadata,
    topics_from_metadata,
    write_metadata,
)
from rollability_ros.core.bags.qos import normalize_qos_profiles
from rollability_ros.core.bags.reader import (MCAP_MAGIC, bag_file_errors, open_mcap, statistics_of,
                                              verify_mcap_file)
from rollability_ros.core.bags._mcap_file import (
    DEFAULT_CHUNK_SIZE_BYTES,
    RECOVERY_SIDECAR,
    McapFile,
    mcap_compression,
    read_sidecar,
)

_SPLIT_INDEX = re.compile(r"_(\d+)\.mcap$")

#: Opcodes the salvage scan looks for: schema, channel, chunk.
_SALVAGED_OPCODES = re.compile(b"[\x03\x04\x06]")

#: Suffix of the copy of a damaged storage file that ``recover`` keeps next to the repaired one.
BACKUP_SUFFIX = ".before-recover"


class FileRecovery(typing.TypedDict, total=False):
    """What :func:`recover` did to one storage file: ``intact``, or ``recovered`` with the counts of what it saved and
    dropped and the name its damaged original is kept under."""

    path: typing.Required[str]
    status: typing.Required[str]
    messages: int
    chunks_recovered: int
    chunks_discarded: int
    bytes_discarded: int
    messages_without_channel: int
    header_intact: bool
    backup: str


class TopicWindow(typing.TypedDict):
    """What one topic missed at one restart of a bag's writer (:func:`missed_windows`)."""

    after_ns: typing.Optional[int]      # its last message before the restart (None: none)
    until_ns: typing.Optional[int]      # its first message after it (None: none yet)
    rate_hz: typing.Optional[float]     # its mean rate over the whole bag (None below 2 messages)
    periodic: bool                      # its messages come at a steady rate


class RecoveryReport(typing.TypedDict):
    """The report of :func:`recover` (its docstring says what each key holds)."""

    files: typing.List[FileRecovery]
    message_count: int
    topics: typing.Dict[str, int]
    metadata_rewritten: bool
    metadata_backup: str
    sidecar_backup: str


def backup_path(path: str) -> str:
    """The name ``recover`` keeps the original of ``path`` under: ``<path>.before-recover``, or the first free
    ``<path>.before-recover-<n>`` when an earlier recovery already kept one (no backup is ever overwritten)."""
    candidate, number = path + BACKUP_SUFFIX, 2
    while os.path.lexists(candidate):
        candidate, number = f"{path}{BACKUP_SUFFIX}-{number}", number + 1
    return candidate


def _is_complete(path):
    """Whether ``path`` is a complete MCAP file whose every chunk passes its CRC (not just a readable footer)."""
    try:
        verify_mcap_file(path)
        return True
    except (BagError, OSError):
        return False


def _split_stem(name: str) -> str:
    """``bag`` of ``bag_3.mcap`` (a split's name without its index), ``notes`` of ``notes.mcap``."""
    return _SPLIT_INDEX.sub("", name) if _SPLIT_INDEX.search(name) else name[:-len(".mcap")]


def _storage_files(directory, information):
    """Return the bag's MCAP file names: those in metadata.yaml that exist, then the unlisted splits of the same
    series or named after the folder (a killed writer's last split), by split index. When metadata.yaml lists files, an unlisted file of
    another name (a copy, a stray ``notes.mcap``) is not the bag's and is left alone: adopting it would double
    every message of a copied split, or refuse the recovery over a file that is no MCAP."""
    listed = [p for p in (information.get("relative_file_paths") or [])
              if os.path.isfile(os.path.join(directory, p))]
    stems = {_split_stem(name) for name in listed}
    stems |= {os.path.basename(os.path.normpath(directory))} if stems else set()   # what a writer here names them
    others = [n for n in os.listdir(directory)
              if n.endswith(".mcap") and n not in listed and (not stems or _split_stem(n) in stems)]

    def split_index(name: str) -> typing.Tuple[int, str]:
        match = _SPLIT_INDEX.search(name)
        return (int(match.group(1)) if match else -1, name)

    return listed + sorted(others, key=split_index)


def _parse_record(record_type, body):
    """Parse ``body`` as one ``record_type`` record; return it, or None unless the parse uses exactly all bytes."""
    import io

    from mcap.data_stream import ReadDataStream

    stream = io.BytesIO(body)
    try:
        record = record_type.read(ReadDataStream(stream))
    except Exception:  # garbled lengths, bad UTF-8, short reads: not a record of this type
        return None
    return record if stream.tell() == len(body) else None


def _plausible(record):
    """Whether a parsed Schema / Channel (which carry no CRC) looks like one a ROS 2 recorder wrote."""
    from mcap.records import Channel, Schema

    if isinstance(record, Schema):
        return record.id > 0 and "/" in record.name and record.name.isprintable() and record.encoding.isprintable()
    if isinstance(record, Channel):
        return record.topic.startswith("/") and record.topic.isprintable() and record.message_encoding.isprintable()
    return True


def _scan_records(data, report):
    """Return the schemas, channels and messages of every intact record in the bytes ``data`` of an MCAP file.

    The bytes are scanned rather than read in sequence, so damage anywhere (header, a chunk, an index, the
    summary) costs only the damaged records: at every offset where a schema (0x03), channel (0x04) or chunk
    (0x06) opcode and its 8-byte length describe a record that parses exactly, and, for a chunk, whose
    uncompressed CRC matches, the record is taken and the scan continues after it. Chunks are self-delimiting
    and CRC-checked, so a damaged one is counted in ``report["chunks_discarded"]`` and skipped. Schemas and
    channels also reappear in the summary section, so a damaged copy of one usually has an intact twin.
    """
    from mcap.records import Channel, Chunk, Schema
    from mcap.stream_reader import breakup_chunk

    record_types = {0x03: Schema, 0x04: Channel, 0x06: Chunk}
    records = []
    size, last_end = len(data), 0
    match = _SALVAGED_OPCODES.search(data)
    position = match.start() if match else size
    while position + 9 <= size:
        opcode = data[position]
        record_type = record_types.get(opcode)
        length = int.from_bytes(data[position + 1:position + 9], "little")
        end = position + 9 + length
        record = None
        if record_type is not None and end <= size:
            record = _parse_record(record_type, data[position + 9:end])
        if record is None or not _plausible(record) or (isinstance(record, Chunk) and not record.uncompressed_crc):
            match = _SALVAGED_OPCODES.search(data, position + 1)
            position = match.start() if match else size
            continue
        if isinstance(record, Chunk):
            try:
                inner = list(breakup_chunk(record, validate_crc=True))
            except Exception:  # CRC mismatch or undecompressible chunk: its frame is intact, so skip all of it
                report["chunks_discarded"] += 1
                position = end
                continue
            report["chunks_recovered"] += 1
            records.extend(inner)
        else:
            records.append(record)
        last_end = position = end
    # a file without its closing magic was cut: what follows the last intact record is the lost tail
    report["bytes_discarded"] = 0 if data.endswith(MCAP_MAGIC) else size - last_end
    return records


def _rewrite_mcap(path, temporary, information, definitions, topics):
    """Write to ``temporary`` a valid MCAP with every intact record of the damaged MCAP ``path``; return the
    file's recovery report. ``path`` itself is only read."""
    from mcap.records import Channel, Message, Schema

    report = {"path": os.path.basename(path), "status": "recovered", "messages": 0, "chunks_recovered": 0,
              "chunks_discarded": 0, "bytes_discarded": 0, "messages_without_channel": 0}
    with open(path, "rb") as stream:
        data = stream.read()
    records = _scan_records(data, report) if data else []
    report["header_intact"] = data.startswith(MCAP_MAGIC)
    schemas: typing.Dict[int, Schema] = {}
    channels: typing.Dict[int, Channel] = {}
    channel_topics: typing.Dict[int, str] = {}
    types_by_topic: typing.Dict[str, str] = {}
    for record in records:
        if isinstance(record, Schema):
            schemas.setdefault(record.id, record)
        elif isinstance(record, Channel):
            channels.setdefault(record.id, record)
    if os.path.exists(temporary):
        os.remove(temporary)
    output = McapFile(temporary, mcap_compression("zstd"), DEFAULT_CHUNK_SIZE_BYTES, fsync=True)
    for channel_id, channel in sorted(channels.items()):
        schema = schemas.get(channel.schema_id)
        if schema is None or channel.topic in types_by_topic:
            continue
        schema_id = output.add_schema(schema.name, schema.encoding, schema.data)
        output.add_channel(channel.topic, channel.message_encoding, schema_id, dict(channel.metadata))
        channel_topics[channel_id] = channel.topic
        types_by_topic[channel.topic] = schema.name
    for record in records:
        if isinstance(record, Message):
            if record.channel_id not in channel_topics:
                report["messages_without_channel"] += 1
                continue
            output.write(channel_topics[record.channel_id], record.data, record.log_time, record.publish_time)
            report["messages"] += 1
    for topic in topics:
        if topic.name not in types_by_topic and topic.type_name in definitions:
            output.add_topic(topic, definitions[topic.type_name])
    output.close(information)
    return report


def _verify(path, expected_messages):
    """Raise BagError unless ``path`` is a complete, CRC-valid MCAP holding ``expected_messages`` messages."""
    if not _is_complete(path):
        raise BagError(f"{path}: the recovered file does not verify; the original is left as it was")
    with open(path, "rb") as stream:
        _, summary = open_mcap(path, stream)
    if statistics_of(summary).message_count != expected_messages:
        raise BagError(f"{path}: the recovered file holds {statistics_of(summary).message_count} messages, "
                       f"{expected_messages} were salvaged; the original is left as it was")


def _nothing_saved(report, size):
    """Whether a damaged file of ``size`` bytes gave nothing worth writing (so it must be left untouched)."""
    if report["messages"] or not size:
        return False
    return report["chunks_discarded"] > 0 or not report["header_intact"]


def _file_summary(path):
    """Return ``(FileInfo, {topic: TopicInfo from channel metadata}, rosbag2 metadata record dict or {})``."""

    with open(path, "rb") as stream, bag_file_errors(path):
        reader, summary = open_mcap(path, stream)
        statistics = statistics_of(summary)
        info = FileInfo(os.path.basename(path), statistics.message_start_time if statistics.message_count else 0,
                        statistics.message_end_time - statistics.message_start_time
                        if statistics.message_count else 0, statistics.message_count)
        topics: typing.Dict[str, TopicInfo] = {}
        for channel_id, channel in summary.channels.items():
            schema = summary.schemas.get(channel.schema_id)
            topic = topics.setdefault(channel.topic, TopicInfo(
                name=channel.topic, type_name=schema.name if schema else "",
                serialization_format=channel.message_encoding,
                offered_qos_profiles=normalize_qos_profiles(channel.metadata.get("offered_qos_profiles")),
                type_description_hash=channel.metadata.get("topic_type_hash", "")))
            topic.message_count += statistics.channel_message_counts.get(channel_id, 0)
        stored: typing.Dict[str, typing.Any] = {}
        for record in reader.iter_metadata():
            if record.name == "rosbag2" and record.metadata.get("serialized_metadata"):
                stored = safe_yaml.load(record.metadata["serialized_metadata"]) or {}
    return info, topics, stored


def _previous_metadata(directory):
    """Return the old metadata.yaml contents, or ``{}`` if it is missing or unreadable."""
    if not os.path.exists(os.path.join(directory, METADATA_FILE)):
        return {}
    try:
        return read_metadata(directory)
    except BagError:
        return {}


def _recoverable(directory):
    """``(old metadata.yaml contents or {}, storage file names)`` of the bag ``directory`` to recover; BagError
    for a path that is no bag directory, another storage than mcap, or no storage file."""
    if not os.path.isdir(directory):
        raise BagError(f"{directory}: not a bag directory")
    previous = _previous_metadata(directory)
    if previous.get("storage_identifier", "mcap") != "mcap":
        raise BagError(f"{directory}: recover handles mcap storage, this bag is {previous['storage_identifier']}")
    names = _storage_files(directory, previous)
    if not names:
        raise BagError(f"{directory}: no .mcap storage file to recover")
    return previous, names


def _add_counts(found_topics, topics):
    """Add ``topics`` (one storage file's) to ``found_topics`` ``{name: TopicInfo}``, summing message counts."""
    for topic in topics:
        if topic.name in found_topics:
            found_topics[topic.name].message_count += topic.message_count
        else:
            found_topics[topic.name] = topic


def _repair(path, temporary, stored, known_topics, files, definitions):
    """Rewrite the damaged storage file ``path`` as ``temporary`` (every intact chunk and readable record) and
    verify it; return its report. BagError when nothing can be saved from it."""
    partial = build_metadata(known_topics, files, custom_data=stored.get("custom_data"),
                             ros_distro=stored.get("ros_distro") or ROS_DISTRO)
    report = _rewrite_mcap(path, temporary, partial, definitions, known_topics)
    if _nothing_saved(report, os.path.getsize(path)):
        raise BagError(
            f"{path}: nothing can be saved ({report['chunks_discarded']} damaged chunks, no intact one"
            f"{'' if report['header_intact'] else ', no MCAP header'}); the bag is left as it was")
    _verify(temporary, report["messages"])
    return report


def _close_recovered(directory, previous, stored, topics, files):
    """Write the recovered bag's metadata.yaml (the old one kept as a backup when it changes) and keep an open
    writer's recovery sidecar under a backup name; return ``(metadata, metadata backup, sidecar backup)`` (the
    backups' paths, "" for none)."""
    information = build_metadata(
        topics, files, storage_identifier="mcap",
        compression_format=stored.get("compression_format", ""), compression_mode=stored.get("compression_mode", ""),
        custom_data=stored.get("custom_data"), ros_distro=stored.get("ros_distro") or ROS_DISTRO)
    metadata_path = os.path.join(directory, METADATA_FILE)
    metadata_backup = ""
    if information != previous:
        if os.path.lexists(metadata_path):
            metadata_backup = backup_path(metadata_path)
            os.link(metadata_path, metadata_backup)
        write_metadata(directory, information)
    sidecar = os.path.join(directory, RECOVERY_SIDECAR)
    sidecar_backup = ""
    if os.path.exists(sidecar):   # the bag is closed now; the open writer's definitions stay, renamed
        sidecar_backup = backup_path(sidecar)
        os.replace(sidecar, sidecar_backup)
    return information, metadata_backup, sidecar_backup


def recover(directory: typing.Union[str, os.PathLike], allow_empty: bool = False) -> RecoveryReport:
    """Recover the bag in ``directory`` in place (see the module docstring); return a report.

    A bag in which no message can be saved is refused (BagError, nothing changed) unless ``allow_empty``: a writer
    continuing the bag of a recorder killed before its first chunk reached the disk recovers it to an empty bag
    (the originals kept as backups) and records on.

    Nothing is replaced until every repaired file has been written beside its original and verified
    (complete, CRC-valid, holding every salvaged message); each damaged original is then kept as
    ``<file>.mcap.before-recover`` (``-<n>`` added when an earlier recovery kept one), and so is metadata.yaml
    when it changes, and the recovery sidecar of an open writer. When a damaged file yields nothing (no intact
    chunk, or no readable record at all), BagError says so and the bag is left exactly as it was.

    Returns
    -------
    dict
        ``files``: one dict per storage file (``path``, ``status`` "intact" or "recovered", and for recovered
        files ``messages``, ``chunks_recovered``, ``chunks_discarded``, ``bytes_discarded``,
        ``messages_without_channel``, ``header_intact``, ``backup``); ``message_count``: messages in the
        recovered bag; ``topics``: ``{topic: message count}``; ``metadata_rewritten`` (bool),
        ``metadata_backup`` and ``sidecar_backup`` (file names of the kept originals, "" for none).

    Raises
    ------
    BagError
        ``directory`` is not a directory, holds no MCAP storage file, holds a damaged file from which
        nothing can be saved, or (without ``allow_empty``) no message can be saved at all.
    """
    directory = os.fspath(directory)
    previous, names = _recoverable(directory)
    known_topics = topics_from_metadata(previous) if previous else []
    definitions = read_sidecar(directory)
    stored = dict(previous)
    reports: typing.List[FileRecovery] = []
    files: typing.List[FileInfo] = []
    found_topics: typing.Dict[str, TopicInfo] = {}
    repaired: typing.List[typing.Tuple[str, str]] = []
    try:
        for name in names:
            path = os.path.join(directory, name)
            summary_path = path
            if _is_complete(path):
                reports.append({"path": name, "status": "intact"})
            else:
                temporary = path + ".recovering"
                repaired.append((path, temporary))
                reports.append(_repair(path, temporary, stored, known_topics, files, definitions))
                summary_path = temporary
            info, topics, file_stored = _file_summary(summary_path)
            info.path = name
            stored = stored or file_stored
            files.append(info)
            _add_counts(found_topics, topics.values())
        if not allow_empty and not sum(info.message_count for info in files):
            declared = previous.get("message_count")
            raise BagError(f"{directory}: nothing can be saved: no intact message in {', '.join(names)}"
                           f"{f' (metadata.yaml declares {declared})' if declared else ''}; the bag is left as it was")
    except BaseException:
        for _, temporary in repaired:
            if os.path.exists(temporary):
                os.remove(temporary)
        raise
    for (path, temporary), report in zip(repaired, [r for r in reports if r["status"] == "recovered"]):
        backup = backup_path(path)
        os.link(path, backup)          # the damaged original stays, under another name
        report["backup"] = os.path.basename(backup)
        os.replace(temporary, path)
    if not known_topics:
        known_topics = topics_from_metadata(stored) if stored.get("topics_with_message_count") else []
    topics = []
    for topic in known_topics:
        topic.message_count = found_topics.pop(topic.name).message_count if topic.name in found_topics else 0
        topics.append(topic)
    topics.extend(found_topics.values())
    information, metadata_backup, sidecar_backup = _close_recovered(directory, previous, stored, topics, files)
    return RecoveryReport(files=reports, message_count=int(information["message_count"]),
                          topics={t.name: t.message_count for t in topics}, metadata_rewritten=information != previous,
                          metadata_backup=os.path.basename(metadata_backup),
                          sidecar_backup=os.path.basename(sidecar_backup))


def is_left_open(directory: typing.Union[str, os.PathLike]) -> bool:
    """Whether ``directory`` holds a bag its writer did not close: a recovery sidecar, or an incomplete file."""
    directory = os.fspath(directory)
    if os.path.exists(os.path.join(directory, RECOVERY_SIDECAR)):
        return True
    names = _storage_files(directory, _previous_metadata(directory))
    return any(not _is_complete(os.path.join(directory, name)) for name in names)


def recording_gaps(directory: typing.Union[str, os.PathLike]) -> typing.List[typing.Tuple[int, typing.Optional[int]]]:
    """Return the windows a bag may be missing because its writer was killed and restarted.

    Returns
    -------
    list of (int, int or None)
        ``(after_ns, until_ns)`` per restart: messages logged after ``after_ns`` (the last one kept before the
        kill; 0 if none) and before ``until_ns`` (the first one written after the restart; None if none yet)
        may be missing. Empty for a bag recorded without a restart.
    """
    information = read_metadata(os.fspath(directory))
    files = information.get("files") or []
    restarts = _restart_indexes(information)
    gaps = []
    for index in restarts:
        before = [f["starting_time"]["nanoseconds_since_epoch"] + f["duration"]["nanoseconds"]
                  for f in files[:index] if f["message_count"]]
        after = [f["starting_time"]["nanoseconds_since_epoch"] for f in files[index:] if f["message_count"]]
        gaps.append((max(before, default=0), min(after, default=None)))
    return gaps


def _restart_indexes(information):
    from rollability_ros.core.bags._mcap_file import RESTARTS_KEY

    return [int(r) for r in ((information.get("custom_data") or {}).get(RESTARTS_KEY) or "").split(",") if r]


def missed_windows(directory: typing.Union[str, os.PathLike]
                   ) -> typing.List[typing.Dict[str, TopicWindow]]:
    """Per restart of the bag's writer, what each topic missed: the window from its last message before the kill
    to its first one after the restart (a topic's own window, not only the bag's: a 100 Hz pose stream and a
    launch outcome every few seconds lose different spans).

    Returns
    -------
    list of dict
        One ``{topic: {"after_ns", "until_ns", "rate_hz"}}`` per restart (as :func:`recording_gaps`):
        ``after_ns`` the topic's last message in the files before the restart (None: none), ``until_ns`` its first
        one after (None: none yet), ``rate_hz`` its mean message rate over the whole bag (None below 2 messages),
        ``periodic``: its messages come at a steady rate (the spacing inside each file varies by less than
        :data:`STEADY_SPACING_CV` of its mean, over at least 3 spacings), so the rate estimates what the window lost;
        an event topic's (False) does not.
    """
    directory = os.fspath(directory)
    information = read_metadata(directory)
    restarts = _restart_indexes(information)
    if not restarts:
        return []
    spans = []          # per storage file: {topic: [first ns, last ns, count]}
    spacing: typing.Dict[str, typing.List[float]] = {}   # topic: [spacings, sum, sum of squares], inside files only
    for relative in information.get("relative_file_paths") or []:
        path = os.path.join(directory, relative)
        span: typing.Dict[str, typing.List[int]] = {}
        with open(path, "rb") as stream, bag_file_errors(path):
            reader, summary = open_mcap(path, stream)
            if statistics_of(summary).message_count:
                for _, channel, message in reader.iter_messages():
                    entry = span.setdefault(channel.topic, [message.log_time, message.log_time, 0])
                    if entry[2]:
                        step_s = (message.log_time - entry[1]) / 1e9
                        stats = spacing.setdefault(channel.topic, [0, 0.0, 0.0])
                        stats[0], stats[1], stats[2] = stats[0] + 1, stats[1] + step_s, stats[2] + step_s * step_s
                    entry[0], entry[1] = min(entry[0], message.log_time), max(entry[1], message.log_time)
                    entry[2] += 1
        spans.append(span)
    totals: typing.Dict[str, typing.List[int]] = {}
    for span in spans:
        for topic, (first, last, count) in span.items():
            total = totals.setdefault(topic, [first, last, 0])
            total[0], total[1], total[2] = min(total[0], first), max(total[1], last), total[2] + count
    windows = []
    for index in restarts:
        window: typing.Dict[str, TopicWindow] = {}
        for topic, (first, last, count) in sorted(totals.items()):
            before = [span[topic][1] for span in spans[:index] if topic in span]
            after = [span[topic][0] for span in spans[index:] if topic in span]
            window[topic] = {"after_ns": max(before, default=None), "until_ns": min(after, default=None),
                             "rate_hz": (count - 1) / ((last - first) / 1e9) if count > 1 and last > first else None,
                             "periodic": _steady(spacing.get(topic))}
        windows.append(window)
    return windows


#: Largest coefficient of variation of a topic's message spacing for a steady-rate (periodic) topic.
STEADY_SPACING_CV = 0.5


def _steady(stats: typing.Optional[typing.List[float]]) -> bool:
    """True when the spacings ``[n, sum, sum of squares]`` (s) are at least 3 and steady (:data:`STEADY_SPACING_CV`)."""
    if not stats or stats[0] < 3 or stats[1] <= 0:
        return False
    mean = stats[1] / stats[0]
    variance = max(0.0, stats[2] / stats[0] - mean * mean)
    return variance ** 0.5 <= STEADY_SPACING_CV * mean


def mark_restart(directory: typing.Union[str, os.PathLike],
                 information: typing.Optional[typing.Mapping[str, object]] = None) -> typing.Dict[str, typing.Any]:
    """Note in ``directory``'s metadata.yaml that the recording stopped uncleanly after its current files
    (``custom_data["recorder_restarts"]`` gets the index of the next file); return the updated metadata."""
    from rollability_ros.core.bags._mcap_file import RESTARTS_KEY

    information = dict(information or read_metadata(os.fspath(directory)))
    custom = information.get("custom_data") or {}
    files = information.get("files") or []
    if not isinstance(custom, dict) or not isinstance(files, list):
        raise BagError(f"{directory}: metadata.yaml's custom_data must be a mapping and files a list")
    custom_data = dict(custom)
    restarts = [r for r in (custom_data.get(RESTARTS_KEY) or "").split(",") if r]
    custom_data[RESTARTS_KEY] = ",".join(restarts + [str(len(files))])
    information["custom_data"] = custom_data
    write_metadata(os.fspath(directory), information)
    return information
