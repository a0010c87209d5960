"""rosbag2 ``metadata.yaml`` (version 9), as ``ros2 bag`` on ROS 2 Jazzy reads it.

A rosbag2 bag is a directory: ``metadata.yaml`` plus storage files. This module writes and reads that file
(atomically: temp file + rename). Times are integer nanoseconds (since the Unix epoch for time stamps).
"""
import dataclasses
import os
import typing

import yaml

from rollability_ros.core import safe_yaml
from rollability_ros.core.bags.qos import normalize_qos_profiles

#: metadata.yaml format version written (rosbag2 on Jazzy writes 9).
METADATA_VERSION = 9

#: File name of the bag metadata inside a bag directory.
METADATA_FILE = "metadata.yaml"

#: ROS distribution recorded in the metadata.
ROS_DISTRO = "jazzy"

class BagError(ValueError):
    """A bag directory or storage file is missing, truncated or corrupt; the message names the file."""


@dataclasses.dataclass
class TopicInfo:
    """One recorded topic: name, type, serialization format, offered QoS (v9 dicts), RIHS01 hash, count."""

    name: str
    type_name: str
    serialization_format: str = "cdr"
    offered_qos_profiles: list = dataclasses.field(default_factory=list)
    type_description_hash: str = ""
    message_count: int = 0


@dataclasses.dataclass
class FileInfo:
    """One storage file of a bag: relative path, first message log time (ns), duration (ns), message count."""

    path: str
    starting_time_ns: int = 0
    duration_ns: int = 0
    message_count: int = 0


def build_metadata(topics: typing.Iterable[TopicInfo], files: typing.Sequence[FileInfo], *,
                   storage_identifier: str = "mcap", compression_format: str = "", compression_mode: str = "",
                   custom_data: typing.Optional[typing.Mapping[str, str]] = None,
                   ros_distro: str = ROS_DISTRO) -> typing.Dict[str, typing.Any]:
    """Return the ``rosbag2_bagfile_information`` mapping (version 9) for ``topics`` and ``files``.

    Bag start and duration span the files that hold messages; an empty bag starts at 0 with duration 0.
    ``custom_data`` is a ``{str: str}`` dict or None.
    """
    if custom_data is not None and not all(isinstance(k, str) and isinstance(v, str)
                                           for k, v in custom_data.items()):
        raise ValueError(f"custom_data must map strings to strings, got {custom_data!r}")
    used = [f for f in files if f.message_count]
    start_ns = min((f.starting_time_ns for f in used), default=0)
    end_ns = max((f.starting_time_ns + f.duration_ns for f in used), default=0)
    return {
        "version": METADATA_VERSION,
        "storage_identifier": storage_identifier,
        "duration": {"nanoseconds": end_ns - start_ns},
        "starting_time": {"nanoseconds_since_epoch": start_ns},
        "message_count": sum(f.message_count for f in files),
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": t.name,
                    "type": t.type_name,
                    "serialization_format": t.serialization_format,
                    "offered_qos_profiles": t.offered_qos_profiles,
                    "type_description_hash": t.type_description_hash,
                },
                "message_count": t.message_count,
            }
            for t in topics
        ],
        "compression_format": compression_format,
        "compression_mode": compression_mode,
        "relative_file_paths": [f.path for f in files],
        "files": [
            {
                "path": f.path,
                "starting_time": {"nanoseconds_since_epoch": f.starting_time_ns},
                "duration": {"nanoseconds": f.duration_ns},
                "message_count": f.message_count,
            }
            for f in files
        ],
        "custom_data": dict(custom_data) if custom_data else None,
        "ros_distro": ros_distro,
    }


def dump_metadata(information: typing.Mapping[str, object]) -> str:
    """Return ``information`` (a ``rosbag2_bagfile_information`` mapping) as YAML text, without the top key."""
    return yaml.safe_dump(information, sort_keys=False, default_flow_style=False)


def write_metadata(directory: str, information: typing.Mapping[str, object]) -> None:
    """Write ``<directory>/metadata.yaml`` atomically (temp file, fsync, rename)."""
    path = os.path.join(directory, METADATA_FILE)
    text = yaml.safe_dump({"rosbag2_bagfile_information": information}, sort_keys=False,
                          default_flow_style=False)
    temporary = path + ".tmp"
    with open(temporary, "w", encoding="utf-8") as stream:
        stream.write(text)
        stream.flush()
        os.fsync(stream.fileno())
    os.replace(temporary, path)


def read_metadata(directory: str) -> typing.Dict[str, typing.Any]:
    """Return the ``rosbag2_bagfile_information`` mapping of a bag directory.

    Raises
    ------
    BagError
        ``metadata.yaml`` is missing, unreadable, not YAML, or lacks the fields every version has.
    """
    path = os.path.join(directory, METADATA_FILE)
    if not os.path.isdir(directory):
        raise BagError(f"{directory}: not a bag directory (does not exist or is not a directory)")
    try:
        with open(path, encoding="utf-8") as stream:
            document = safe_yaml.load(stream)
    except FileNotFoundError as exc:
        raise BagError(f"{path}: missing; if the recorder was killed, run `rollability bag recover "
                       f"{directory}`") from exc
    except OSError as exc:
        raise BagError(f"{path}: cannot read: {exc.strerror}") from exc
    except UnicodeDecodeError as exc:
        raise BagError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start}); if the recorder was killed, "
                       f"run `rollability bag recover {directory}`") from exc
    except yaml.YAMLError as exc:
        raise BagError(f"{path}: not valid YAML: {safe_yaml.one_line(exc)}") from exc
    information = document.get("rosbag2_bagfile_information") if isinstance(document, dict) else None
    required = ("version", "storage_identifier", "relative_file_paths", "topics_with_message_count")
    if not isinstance(information, dict) or any(key not in information for key in required):
        raise BagError(f"{path}: not rosbag2 metadata (needs rosbag2_bagfile_information with {', '.join(required)})")
    listed = information["relative_file_paths"]
    if not isinstance(listed, list) or not all(isinstance(name, str) and name for name in listed):
        raise BagError(f"{path}: relative_file_paths must be a list of file names, got {listed!r:.120}; "
                       f"`rollability bag recover {directory}` rewrites it from the storage files")
    try:
        topics_from_metadata(information)   # every reader of the bag takes its topics from here
    except ValueError as exc:
        raise BagError(f"{path}: {exc}; `rollability bag recover {directory}` rewrites it from the storage "
                       "files") from exc
    return information


def topics_from_metadata(information: typing.Mapping[str, object]) -> typing.List[TopicInfo]:
    """Return the :class:`TopicInfo` list of a ``rosbag2_bagfile_information`` mapping (QoS normalised)."""
    topics = []
    entries = information.get("topics_with_message_count") or []
    if not isinstance(entries, list):
        raise BagError(f"metadata topics_with_message_count must be a list, got {entries!r}")
    for index, entry in enumerate(entries):
        where = f"topics_with_message_count[{index}]"
        meta = entry.get("topic_metadata") if isinstance(entry, dict) else None
        if not isinstance(meta, dict) or not all(isinstance(meta.get(key), str) and meta[key]
                                                 for key in ("name", "type")):
            raise BagError(f"metadata {where} must be a mapping whose topic_metadata has a name and a type, "
                           f"got {entry!r:.120}")
        count = entry.get("message_count", 0)
        if isinstance(count, bool) or not isinstance(count, int) or count < 0:
            raise BagError(f"metadata {where} ({meta['name']}): message_count must be a whole number >= 0, "
                           f"got {count!r:.40}")
        try:
            qos = normalize_qos_profiles(meta.get("offered_qos_profiles"))
        except ValueError as exc:
            raise BagError(f"metadata {where} ({meta['name']}): {exc}") from exc
        topics.append(TopicInfo(
            name=meta["name"],
            type_name=meta["type"],
            serialization_format=str(meta.get("serialization_format", "cdr")),
            offered_qos_profiles=qos,
            type_description_hash=str(meta.get("type_description_hash", "")),
            message_count=count,
        ))
    return topics
