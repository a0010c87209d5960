"""rosbag2 ``metadata.yaml`` (version 9) and offered-QoS profiles, as ``ros2 bag`` on ROS 2 Jazzy reads them.

A rosbag2 bag is a directory: ``metadata.yaml`` plus storage files. This module writes and reads that file
(atomically: temp file + rename) and normalises QoS profiles to the version-9 form (a YAML list of dicts with
policy names such as ``keep_last``). Times are integer nanoseconds (since the Unix epoch for time stamps).
"""
import dataclasses
import os

import yaml

#: metadata.yaml format version written (rosbag2 on Jazzy writes 9).
METADATA_VERSION = 9

#: File name of the bag metadata inside a bag directory.
METADATA_FILE = "metadata.yaml"

#: ROS distribution recorded in the metadata.
ROS_DISTRO = "jazzy"

#: rmw's "infinite" duration as rosbag2 writes it into QoS profiles.
INFINITE_DURATION = {"sec": 9223372036, "nsec": 854775807}

#: QoS policy name for each rmw enum value (the integers rosbag2 metadata version < 9 stores).
QOS_POLICY_NAMES = {
    "history": {0: "system_default", 1: "keep_last", 2: "keep_all", 3: "unknown"},
    "reliability": {0: "system_default", 1: "reliable", 2: "best_effort", 3: "unknown", 4: "best_available"},
    "durability": {0: "system_default", 1: "transient_local", 2: "volatile", 3: "unknown", 4: "best_available"},
    "liveliness": {0: "system_default", 1: "automatic", 2: "manual_by_node", 3: "manual_by_topic",
                   4: "unknown", 5: "best_available"},
}

_DURATION_KEYS = ("deadline", "lifespan", "liveliness_lease_duration")

#: The profile of a default rclpy publisher (depth 10, reliable, volatile); missing keys are taken from it.
DEFAULT_QOS = {
    "history": "keep_last",
    "depth": 10,
    "reliability": "reliable",
    "durability": "volatile",
    "deadline": dict(INFINITE_DURATION),
    "lifespan": dict(INFINITE_DURATION),
    "liveliness": "automatic",
    "liveliness_lease_duration": dict(INFINITE_DURATION),
    "avoid_ros_namespace_conventions": False,
}


class BagError(ValueError):
    """A bag directory or storage file is missing, truncated or corrupt; the message names the file."""


def _policy_name(policy, value):
    names = QOS_POLICY_NAMES[policy]
    if isinstance(value, bool):
        raise ValueError(f"QoS {policy} must be a policy name or rmw enum integer, got {value!r}")
    if isinstance(value, int) or (hasattr(value, "value") and isinstance(value.value, int)):
        number = int(getattr(value, "value", value))
        if number not in names:
            raise ValueError(f"QoS {policy} enum value {number} is unknown (known: {sorted(names)})")
        return names[number]
    name = str(value).lower()
    if name not in names.values():
        raise ValueError(f"QoS {policy} {value!r} is unknown (known: {sorted(set(names.values()))})")
    return name


def _duration(policy, value):
    """Return ``{sec, nsec}`` for a duration given as such a dict or as integer nanoseconds."""
    if isinstance(value, dict):
        try:
            return {"sec": int(value["sec"]), "nsec": int(value["nsec"])}
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"QoS {policy} must be {{sec: int, nsec: int}}, got {value!r}") from exc
    if isinstance(value, int) and not isinstance(value, bool) and value >= 0:
        return {"sec": value // 1_000_000_000, "nsec": value % 1_000_000_000}
    raise ValueError(f"QoS {policy} must be {{sec, nsec}} or non-negative integer nanoseconds, got {value!r}")


def normalize_qos_profiles(profiles):
    """Return offered QoS profiles as version-9 dicts (policy names, ``{sec, nsec}`` durations).

    Parameters
    ----------
    profiles : list of dict, str or None
        Profiles as dicts (policy names or rmw enum integers; durations as ``{sec, nsec}`` or integer ns;
        missing keys from :data:`DEFAULT_QOS`), or a rosbag2 ``offered_qos_profiles`` YAML string of
        any metadata version. ``None`` or ``""`` means no profiles.
    """
    if profiles is None or profiles == "":
        return []
    if isinstance(profiles, str):
        try:
            profiles = yaml.safe_load(profiles)
        except yaml.YAMLError as exc:
            raise ValueError(f"offered_qos_profiles is not valid YAML: {exc}") from exc
        if profiles is None:
            return []
    if isinstance(profiles, dict) or not isinstance(profiles, (list, tuple)):
        raise ValueError(f"offered_qos_profiles must be a list of QoS dicts or a YAML list, got {profiles!r}")
    normalized = []
    for profile in profiles:
        if not isinstance(profile, dict):
            raise ValueError(f"each offered QoS profile must be a dict, got {profile!r}")
        unknown = set(profile) - set(DEFAULT_QOS)
        if unknown:
            raise ValueError(f"unknown QoS profile keys {sorted(unknown)} (known: {sorted(DEFAULT_QOS)})")
        merged = {**DEFAULT_QOS, **profile}
        out = {}
        for key, value in merged.items():
            if key in QOS_POLICY_NAMES:
                out[key] = _policy_name(key, value)
            elif key in _DURATION_KEYS:
                out[key] = _duration(key, value)
            elif key == "depth":
                out[key] = int(value)
            else:
                out[key] = bool(value)
        normalized.append(out)
    return normalized


def qos_profiles_yaml(profiles):
    """Return normalised profiles as the YAML string stored in an MCAP channel's ``offered_qos_profiles``."""
    return yaml.safe_dump(profiles, sort_keys=False, default_flow_style=False).strip()


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


def build_metadata(topics, files, *, storage_identifier="mcap", compression_format="", compression_mode="",
                   custom_data=None, ros_distro=ROS_DISTRO):
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


def dump_metadata(information):
    """Return ``information`` (a ``rosbag2_bagfile_information`` mapping) as YAML text, without the top key."""
    return yaml.safe_dump(information, sort_keys=False, default_flow_style=False)


def write_metadata(directory, information):
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


def read_metadata(directory):
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
            document = yaml.safe_load(stream)
    except FileNotFoundError as exc:
        raise BagError(f"{path}: missing; if the recorder was killed, run `rollability bag recover "
                       f"{directory}`") from exc
    except OSError as exc:
        raise BagError(f"{path}: cannot read: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise BagError(f"{path}: not valid YAML: {exc}") from exc
    information = document.get("rosbag2_bagfile_information") if isinstance(document, dict) else None
    required = ("version", "storage_identifier", "relative_file_paths", "topics_with_message_count")
    if not isinstance(information, dict) or any(key not in information for key in required):
        raise BagError(f"{path}: not rosbag2 metadata (needs rosbag2_bagfile_information with {', '.join(required)})")
    return information


def topics_from_metadata(information):
    """Return the :class:`TopicInfo` list of a ``rosbag2_bagfile_information`` mapping (QoS normalised)."""
    topics = []
    for entry in information.get("topics_with_message_count") or []:
        meta = entry["topic_metadata"]
        topics.append(TopicInfo(
            name=meta["name"],
            type_name=meta["type"],
            serialization_format=meta.get("serialization_format", "cdr"),
            offered_qos_profiles=normalize_qos_profiles(meta.get("offered_qos_profiles")),
            type_description_hash=meta.get("type_description_hash", ""),
            message_count=int(entry.get("message_count", 0)),
        ))
    return topics
