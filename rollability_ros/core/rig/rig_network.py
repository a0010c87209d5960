"""Who can reach the physical rig's nodes over DDS: the rig's default domain and discovery range, and warnings.

Jazzy's default discovery range (SUBNET) on the default domain (0) lets every ROS 2 process on the lab network
see, and call, the valve_controller. The session key (:mod:`~rollability_ros.core.rig.valve_auth`) keeps them from
arming or firing; keeping them off the rig's graph altogether is the second line: a physical bringup runs on
:data:`RIG_DOMAIN_ID` with localhost-only discovery unless the environment or ``config/bringup.yaml`` says otherwise.
"""
import re
import typing

#: One token of a ROS name: letters, digits and underscores, not starting with a digit.
_NAME_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")

#: The physical rig's default ROS domain (not 0, the domain every unconfigured ROS 2 process joins).
RIG_DOMAIN_ID = 73
RIG_DISCOVERY_RANGE = "LOCALHOST"
DISCOVERY_RANGES = ("SUBNET", "LOCALHOST", "OFF", "SYSTEM_DEFAULT")


def physical_rig_environment(environ: typing.Mapping[str, str], domain_id: int = RIG_DOMAIN_ID,
                             discovery_range: str = RIG_DISCOVERY_RANGE) -> dict:
    """The variables to add to ``environ`` for a physical rig: only those the operator has not set."""
    if discovery_range not in DISCOVERY_RANGES:
        raise ValueError(f"discovery range must be one of {DISCOVERY_RANGES}, got {discovery_range!r}")
    if not 0 <= int(domain_id) <= 232:
        raise ValueError(f"ROS domain id must be in 0..232, got {domain_id}")
    added = {}
    if environ.get("ROS_DOMAIN_ID"):
        check_domain_id(environ["ROS_DOMAIN_ID"])
    if not environ.get("ROS_DOMAIN_ID"):
        added["ROS_DOMAIN_ID"] = str(int(domain_id))
    if not environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE") and not environ.get("ROS_LOCALHOST_ONLY"):
        added["ROS_AUTOMATIC_DISCOVERY_RANGE"] = discovery_range
    return added


def exposure_warnings(environ: typing.Mapping[str, str]) -> list:
    """Plain-language warnings about who else on the network can discover the rig's nodes (empty: none)."""
    warnings = []
    scope = environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "")
    localhost_only = environ.get("ROS_LOCALHOST_ONLY", "") == "1"
    if scope in ("", "SUBNET", "SYSTEM_DEFAULT") and not localhost_only:
        warnings.append(f"discovery range {scope or 'unset (SUBNET)'}: every ROS 2 process on the local network "
                        "on this domain sees the valve_controller and can call it (refused without the session "
                        "key) or e-stop it; set ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST on the rig computer")
    if environ.get("ROS_STATIC_PEERS"):
        warnings.append(f"static peers {environ['ROS_STATIC_PEERS']} can reach the rig's nodes")
    if environ.get("ROS_DOMAIN_ID", "") in ("", "0"):
        warnings.append(f"ROS domain 0 is the one every unconfigured ROS 2 process joins; use the rig's own "
                        f"(export ROS_DOMAIN_ID={RIG_DOMAIN_ID})")
    return warnings


def check_domain_id(text: str) -> int:
    """The ROS domain id ``text`` (``ROS_DOMAIN_ID``) as an int; ``ValueError`` unless it is an integer in 0..232."""
    try:
        domain = int(text)
    except (TypeError, ValueError):
        domain = -1
    if not 0 <= domain <= 232:
        raise ValueError(f"ROS_DOMAIN_ID must be an integer in 0..232, got {text!r}")
    return domain


def check_namespace(namespace: str) -> str:
    """``namespace`` as an absolute ROS namespace (``rollability`` -> ``/rollability``, "" -> "/"); ``ValueError``
    naming the problem for anything rcl would refuse with an exception (spaces, ``!``, ``//``, a leading digit)."""
    if not isinstance(namespace, str) or len(namespace) > 200:
        raise ValueError(f"namespace must be a ROS namespace of at most 200 characters, got {namespace!r}")
    tokens = namespace.strip("/").split("/") if namespace.strip("/") else []
    if "//" in namespace or not all(_NAME_TOKEN.match(token) for token in tokens):
        raise ValueError(f"namespace {namespace!r} is not a ROS namespace: use names of letters, digits and "
                         "underscores (not starting with a digit) separated by single '/', e.g. /rollability")
    return "/" + "/".join(tokens)
