"""Recover a bag whose recorder was killed: rebuild MCAP summaries and indexes, and metadata.yaml.

After a SIGKILL the last storage file has no summary section or footer, possibly a half-written chunk, and
metadata.yaml still holds what was known when it was last written (topics with QoS and type hashes, custom
data, ROS distro, files so far; counts of 0). :func:`recover`

- leaves complete MCAP files alone;
- rewrites each incomplete one from every complete, CRC-valid chunk it holds (schemas, channels and messages
  in file order) into a new valid MCAP with message indexes, chunk indexes, statistics and summary, then
  atomically replaces the original (the original stays until the new file is complete and fsynced);
  channels of known topics without a surviving chunk are re-created from the recovery sidecar's definitions;
- rewrites metadata.yaml with counts and times from the files, keeping every field of the old one
  (storage id, ROS distro, custom data, compression fields, per-topic QoS and type hashes). With no
  metadata.yaml left it takes them from the files' channel metadata and ``rosbag2`` metadata records.

What is lost is bounded by :mod:`rollability_ros.core.bags.writer`: the messages of the one chunk that was
open at the kill (``ros2 bag reindex`` by contrast needs readable files and rebuilds metadata.yaml from them,
dropping custom data and the ROS distro).
"""
import os
import re

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
from rollability_ros.core.bags.reader import bag_file_errors, open_mcap
from rollability_ros.core.bags.writer import (
    DEFAULT_CHUNK_SIZE_BYTES,
    RECOVERY_SIDECAR,
    McapFile,
    mcap_compression,
    read_sidecar,
)

_SPLIT_INDEX = re.compile(r"_(\d+)\.mcap$")


def _is_complete(path):
    try:
        with open(path, "rb") as stream:
            open_mcap(path, stream)
        return True
    except BagError:
        return False


def _storage_files(directory, information):
    """Return the bag's MCAP file names: those in metadata.yaml that exist, then any others, by split index."""
    listed = [p for p in (information.get("relative_file_paths") or [])
              if os.path.isfile(os.path.join(directory, p))]
    others = [n for n in os.listdir(directory) if n.endswith(".mcap") and n not in listed]

    def split_index(name):
        match = _SPLIT_INDEX.search(name)
        return (int(match.group(1)) if match else -1, name)

    return listed + sorted(others, key=split_index)


def _complete_records(path, report):
    """Yield the records of every complete, CRC-valid chunk and top-level record of a possibly cut MCAP file.

    Counts recovered / discarded chunks and the discarded tail in ``report``.
    """
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader, breakup_chunk

    with open(path, "rb") as stream:
        reader = StreamReader(stream, skip_magic=False, emit_chunks=True, validate_crcs=True)
        size = os.fstat(stream.fileno()).st_size
        records = reader.records
        while True:
            position = stream.tell()
            try:
                record = next(records)
            except StopIteration:
                return
            except Exception:  # cut or garbled record: everything from here on is unreadable
                report["bytes_discarded"] = size - position
                return
            if not isinstance(record, Chunk):
                yield record
                continue
            try:
                inner = breakup_chunk(record, validate_crc=True)
            except Exception:  # a complete chunk that fails its CRC or decompression
                report["chunks_discarded"] += 1
                continue
            report["chunks_recovered"] += 1
            yield from inner


def _rewrite_mcap(path, information, definitions, topics):
    """Rewrite the incomplete MCAP ``path`` from its readable records; return the file's recovery report."""
    from mcap.records import Channel, Message, Schema

    report = {"path": os.path.basename(path), "status": "recovered", "messages": 0, "chunks_recovered": 0,
              "chunks_discarded": 0, "bytes_discarded": 0, "messages_without_channel": 0}
    schemas, channel_topics, types_by_topic = {}, {}, {}
    temporary = path + ".recovering"
    if os.path.exists(temporary):
        os.remove(temporary)
    output = McapFile(temporary, mcap_compression("zstd"), DEFAULT_CHUNK_SIZE_BYTES, fsync=True)
    records = _complete_records(path, report) if os.path.getsize(path) else ()
    for record in records:
        if isinstance(record, Schema) and record.id not in schemas:
            schemas[record.id] = record
        elif isinstance(record, Channel) and record.id not in channel_topics and record.schema_id in schemas:
            schema = schemas[record.schema_id]
            schema_id = output.add_schema(schema.name, schema.encoding, schema.data)
            output.add_channel(record.topic, record.message_encoding, schema_id, dict(record.metadata))
            channel_topics[record.id] = record.topic
            types_by_topic[record.topic] = schema.name
        elif isinstance(record, Message):
            if record.channel_id not in channel_topics:
                report["messages_without_channel"] += 1
                continue
            output.write(channel_topics[record.channel_id], record.data, record.log_time, record.publish_time)
            report["messages"] += 1
    for topic in topics:
        if topic.name not in types_by_topic and topic.type_name in definitions:
            output.add_topic(topic, definitions[topic.type_name])
    output.close(information)
    os.replace(temporary, path)
    return report


def _file_summary(path):
    """Return ``(FileInfo, {topic: TopicInfo from channel metadata}, rosbag2 metadata record dict or {})``."""
    import yaml

    with open(path, "rb") as stream, bag_file_errors(path):
        reader, summary = open_mcap(path, stream)
        statistics = summary.statistics
        info = FileInfo(os.path.basename(path), statistics.message_start_time if statistics.message_count else 0,
                        statistics.message_end_time - statistics.message_start_time
                        if statistics.message_count else 0, statistics.message_count)
        topics = {}
        for channel_id, channel in summary.channels.items():
            schema = summary.schemas.get(channel.schema_id)
            topic = topics.setdefault(channel.topic, TopicInfo(
                name=channel.topic, type_name=schema.name if schema else "",
                serialization_format=channel.message_encoding,
                offered_qos_profiles=normalize_qos_profiles(channel.metadata.get("offered_qos_profiles")),
                type_description_hash=channel.metadata.get("topic_type_hash", "")))
            topic.message_count += statistics.channel_message_counts.get(channel_id, 0)
        stored = {}
        for record in reader.iter_metadata():
            if record.name == "rosbag2" and record.metadata.get("serialized_metadata"):
                stored = yaml.safe_load(record.metadata["serialized_metadata"]) or {}
    return info, topics, stored


def _previous_metadata(directory):
    """Return the old metadata.yaml contents, or ``{}`` if it is missing or unreadable."""
    if not os.path.exists(os.path.join(directory, METADATA_FILE)):
        return {}
    try:
        return read_metadata(directory)
    except BagError:
        return {}


def recover(directory):
    """Recover the bag in ``directory`` in place (see the module docstring); return a report.

    Returns
    -------
    dict
        ``files``: one dict per storage file (``path``, ``status`` "intact" or "recovered", and for recovered
        files ``messages``, ``chunks_recovered``, ``chunks_discarded``, ``bytes_discarded``,
        ``messages_without_channel``); ``message_count``: messages in the recovered bag;
        ``topics``: ``{topic: message count}``.

    Raises
    ------
    BagError
        ``directory`` is not a directory or holds no MCAP storage file.
    """
    directory = os.fspath(directory)
    if not os.path.isdir(directory):
        raise BagError(f"{directory}: not a bag directory")
    previous = _previous_metadata(directory)
    if previous.get("storage_identifier", "mcap") != "mcap":
        raise BagError(f"{directory}: recover handles mcap storage, this bag is {previous['storage_identifier']}")
    names = _storage_files(directory, previous)
    if not names:
        raise BagError(f"{directory}: no .mcap storage file to recover")
    known_topics = topics_from_metadata(previous) if previous else []
    definitions = read_sidecar(directory)
    stored = dict(previous)
    reports, files, found_topics = [], [], {}
    for name in names:
        path = os.path.join(directory, name)
        if _is_complete(path):
            reports.append({"path": name, "status": "intact"})
        else:
            partial = build_metadata(known_topics, files, custom_data=stored.get("custom_data"),
                                     ros_distro=stored.get("ros_distro") or ROS_DISTRO)
            reports.append(_rewrite_mcap(path, partial, definitions, known_topics))
        info, topics, file_stored = _file_summary(path)
        stored = stored or file_stored
        files.append(info)
        for topic in topics.values():
            if topic.name in found_topics:
                found_topics[topic.name].message_count += topic.message_count
            else:
                found_topics[topic.name] = topic
    if not known_topics:
        known_topics = topics_from_metadata(stored) if stored.get("topics_with_message_count") else []
    topics = []
    for topic in known_topics:
        topic.message_count = found_topics.pop(topic.name).message_count if topic.name in found_topics else 0
        topics.append(topic)
    topics.extend(found_topics.values())
    information = build_metadata(
        topics, files, storage_identifier="mcap",
        compression_format=stored.get("compression_format", ""), compression_mode=stored.get("compression_mode", ""),
        custom_data=stored.get("custom_data"), ros_distro=stored.get("ros_distro") or ROS_DISTRO)
    write_metadata(directory, information)
    sidecar = os.path.join(directory, RECOVERY_SIDECAR)
    if os.path.exists(sidecar):
        os.remove(sidecar)
    return {"files": reports, "message_count": information["message_count"],
            "topics": {t.name: t.message_count for t in topics}}

