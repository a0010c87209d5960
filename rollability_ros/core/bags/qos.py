"""Offered-QoS profiles of recorded topics: rosbag2's version-9 form, and the recorder's subscription QoS.

rosbag2 metadata version 9 stores each topic's offered QoS as a list of dicts with policy names
(``keep_last``, ``reliable``, ``transient_local`` ...) and ``{sec, nsec}`` durations; older versions stored
a YAML string with rmw enum integers. :func:`normalize_qos_profiles` reads all of these;
:func:`subscription_qos_for` picks the QoS a recorder subscribes with so it matches every publisher.
"""
import typing

import yaml

from rollability_ros.core import safe_yaml

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


class QosDuration(typing.TypedDict):
    """A QoS duration as rosbag2 writes it: whole seconds and nanoseconds."""

    sec: int
    nsec: int


class QosProfile(typing.TypedDict):
    """One offered QoS profile in rosbag2's version-9 form: policy names and ``{sec, nsec}`` durations."""

    history: str
    depth: int
    reliability: str
    durability: str
    deadline: QosDuration
    lifespan: QosDuration
    liveliness: str
    liveliness_lease_duration: QosDuration
    avoid_ros_namespace_conventions: bool

#: The profile of a default rclpy publisher (depth 10, reliable, volatile); missing keys are taken from it.
DEFAULT_QOS = QosProfile(
    history="keep_last",
    depth=10,
    reliability="reliable",
    durability="volatile",
    deadline=QosDuration(sec=INFINITE_DURATION["sec"], nsec=INFINITE_DURATION["nsec"]),
    lifespan=QosDuration(sec=INFINITE_DURATION["sec"], nsec=INFINITE_DURATION["nsec"]),
    liveliness="automatic",
    liveliness_lease_duration=QosDuration(sec=INFINITE_DURATION["sec"], nsec=INFINITE_DURATION["nsec"]),
    avoid_ros_namespace_conventions=False,
)


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


def _duration(policy, value) -> QosDuration:
    """Return ``{sec, nsec}`` for a duration given as such a dict or as integer nanoseconds."""
    if isinstance(value, dict):
        try:
            return QosDuration(sec=int(value["sec"]), nsec=int(value["nsec"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"QoS {policy} must be {{sec: int, nsec: int}}, got {value!r}") from exc
    if isinstance(value, int) and not isinstance(value, bool) and value >= 0:
        return QosDuration(sec=value // 1_000_000_000, nsec=value % 1_000_000_000)
    raise ValueError(f"QoS {policy} must be {{sec, nsec}} or non-negative integer nanoseconds, got {value!r}")


def normalize_qos_profiles(profiles: typing.Union[typing.Sequence[typing.Mapping[str, object]], str, None]
                           ) -> typing.List[QosProfile]:
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
            profiles = safe_yaml.load(profiles)
        except yaml.YAMLError as exc:
            raise ValueError(f"offered_qos_profiles is not valid YAML: {safe_yaml.one_line(exc)}") from exc
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
        normalized.append(QosProfile(
            history=_policy_name("history", merged["history"]), depth=int(merged["depth"]),
            reliability=_policy_name("reliability", merged["reliability"]),
            durability=_policy_name("durability", merged["durability"]),
            deadline=_duration("deadline", merged["deadline"]), lifespan=_duration("lifespan", merged["lifespan"]),
            liveliness=_policy_name("liveliness", merged["liveliness"]),
            liveliness_lease_duration=_duration("liveliness_lease_duration", merged["liveliness_lease_duration"]),
            avoid_ros_namespace_conventions=bool(merged["avoid_ros_namespace_conventions"])))
    return normalized


def qos_profiles_yaml(profiles: typing.Sequence[typing.Mapping[str, object]]) -> str:
    """Return normalised profiles as the YAML string stored in an MCAP channel's ``offered_qos_profiles``."""
    return yaml.safe_dump(profiles, sort_keys=False, default_flow_style=False).strip()


def qos_dict_from_profile(profile: object) -> QosProfile:
    """Return a QoS dict from any object with rclpy ``QoSProfile`` attributes (durations with ``.nanoseconds``).

    Lets the recorder node pass ``TopicEndpointInfo.qos_profile`` without this module importing rclpy.
    """
    values = {}
    for key in DEFAULT_QOS:
        value = getattr(profile, key)
        values[key] = getattr(value, "nanoseconds", value) if key in _DURATION_KEYS else value
    (normalized,) = normalize_qos_profiles([values])
    return normalized


def subscription_qos_for(offered_profiles: typing.Union[typing.Sequence[typing.Mapping[str, object]], str, None],
                         depth: int = 1000) -> QosProfile:
    """Return the QoS dict a recorder subscribes with to receive from every offering publisher.

    Reliable only if every publisher is reliable (a reliable subscription does not match a best-effort
    publisher); transient-local only if every publisher is, so late joiners' latched messages are recorded.
    History is keep-last ``depth``: deep enough that a burst waiting for the writer is not dropped.

    Parameters
    ----------
    offered_profiles : list of dict or str
        The publishers' profiles (anything :func:`normalize_qos_profiles` takes); none gives the default.
    depth : int
        Subscription queue depth, messages (> 0).
    """
    if not isinstance(depth, int) or depth <= 0:
        raise ValueError(f"depth must be a positive integer, got {depth!r}")
    offers = normalize_qos_profiles(offered_profiles)
    reliable = all(p["reliability"] == "reliable" for p in offers)
    transient_local = bool(offers) and all(p["durability"] == "transient_local" for p in offers)
    qos = DEFAULT_QOS.copy()
    qos["depth"] = depth
    qos["reliability"] = "reliable" if reliable else "best_effort"
    qos["durability"] = "transient_local" if transient_local else "volatile"
    return qos
