"""A session's isolation and how to join it: every ``rollability study`` and ``rollability bringup`` runs its graph
on a ROS domain of its own with localhost discovery, and writes ``<session dir>/session.yaml`` saying how to reach
it; the joining verbs (``rollability rig``, ``campaign --graph``, ``view`` with ``--session``) read it back here.

Why a domain and not a namespace (docs/sessions.md): DDS never delivers across domains, so two sessions on one
computer cannot reach each other's nodes, whatever topic, service or action names they use (an optimizer
discovers every ``evaluate_profile`` server of its domain, in any namespace). Localhost discovery keeps every
other computer out. The domain is claimed like the tests' (:func:`~rollability_ros.core.graph._ros_domain.claim_domain`,
a lock held for the life of the session's process), in :data:`SESSION_DOMAINS`, never the physical rig's
(:data:`~rollability_ros.core.rig.rig_network.RIG_DOMAIN_ID`) nor the one the shell names (``ROS_DOMAIN_ID``, where
a physical rig or a user's own tools run). The physical rig keeps its own domain (73) and localhost discovery.

Pure: no rclpy. :func:`load_session` resolves what a user typed (a session directory, its ``session.yaml``, or the
name the session printed, looked up under ``bringup.output_dir``) to a :class:`SessionInfo`.
"""
import dataclasses
import os
import secrets
import typing

import yaml

from rollability_ros.core import safe_yaml
from rollability_ros.core.graph._ros_domain import claim_domain
from rollability_ros.core.optimization import atomic_write_bytes

#: The file a session writes in its directory.
SESSION_FILE = "session.yaml"
#: Domains a session claims (inclusive): above 0 (every unconfigured ROS 2 process), at most 101 (higher domains'
#: DDS ports run into Linux's ephemeral port range).
SESSION_DOMAINS = (1, 101)
#: Discovery of a session's graph: this computer only.
SESSION_DISCOVERY_RANGE = "LOCALHOST"
#: Environment variables a session sets in its own process (its nodes inherit them) and a joining verb sets in its.
_CLEARED = ("ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS")


@dataclasses.dataclass
class SessionInfo:
    """What ``session.yaml`` holds: enough to reach the session's graph and its files."""

    name: str
    id: str                        # session.id of its nodes: the name and a random token, new at every start
    directory: str
    kind: str                      # "study" | "bringup"
    ros_domain_id: int
    discovery_range: str
    namespace: str
    valve_key_file: str
    store_path: str
    rig_backend: str = "sim"
    pid: int = 0

    def environment(self) -> typing.Dict[str, str]:
        """The variables that put a process on the session's graph."""
        return {"ROS_DOMAIN_ID": str(self.ros_domain_id), "ROS_AUTOMATIC_DISCOVERY_RANGE": self.discovery_range}

    def apply(self, environ: typing.MutableMapping[str, str]) -> None:
        """Put ``environ`` (``os.environ`` of a joining verb, before ROS starts) on the session's graph."""
        for name in _CLEARED:
            environ.pop(name, None)
        environ.update(self.environment())

    def running(self) -> bool:
        """True while the session's process (``pid``, on this computer: discovery is localhost) still runs."""
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:   # another user's process: it runs
            return True
        return self.pid > 0

    def join_lines(self) -> typing.List[str]:
        """What the session prints: how our verbs join it, and the raw settings for any other ROS 2 tool."""
        raw = " ".join(f"{name}={value}" for name, value in self.environment().items())
        return [f"join: rollability rig --session {self.directory} <action> | rollability campaign --graph --session "
                f"{self.directory} ... | rollability view --session {self.directory}",
                f"join (other ROS 2 tools): {raw} with namespace {self.namespace}, e.g. `{raw} ros2 topic list`"]

    def to_document(self) -> typing.Dict[str, typing.Any]:
        """The ``session.yaml`` mapping."""
        return {"session": dataclasses.asdict(self)}

    def write(self) -> str:
        """Write ``<directory>/session.yaml`` atomically (a joining verb never reads half a file); its path."""
        path = os.path.join(self.directory, SESSION_FILE)
        os.makedirs(self.directory, exist_ok=True)
        atomic_write_bytes(path, yaml.safe_dump(self.to_document(), sort_keys=False).encode("utf-8"))
        return path


def claim_session_domain(environ: typing.Mapping[str, str]) -> typing.Tuple[int, typing.TextIO]:
    """``(domain, lock handle)``: a domain in :data:`SESSION_DOMAINS` that no other claimant holds, never the
    physical rig's nor the one ``environ`` names; hold the handle for the life of the session."""
    from rollability_ros.core.rig import RIG_DOMAIN_ID

    skip = {RIG_DOMAIN_ID}
    if (environ.get("ROS_DOMAIN_ID") or "").strip().isdigit():
        skip.add(int(environ["ROS_DOMAIN_ID"]))
    try:
        return claim_domain(*SESSION_DOMAINS, skip=skip)
    except RuntimeError as exc:   # every session domain of this computer is taken: one line, nothing started
        raise ValueError(f"cannot isolate the session: {exc}") from None


def hold_domain(domain: int) -> typing.Optional[typing.TextIO]:
    """Claim ``domain`` itself (the physical rig's) so that no session takes it; None when another process holds
    it already (e.g. a test run that set it): the session runs there all the same."""
    try:
        return claim_domain(domain, domain)[1]
    except RuntimeError:
        return None


def session_key_path(name: str, namespace: str, domain: int) -> str:
    """The valve session key file of session ``name``: in the user's private key folder (as the default), named
    after the session as well as the domain and namespace, so two sessions never share one."""
    from rollability_ros.core.rig import default_key_path

    default = default_key_path(namespace, str(domain))
    stem, extension = os.path.splitext(default)
    return f"{stem}.{name}{extension}"


def load_session(argument: str, output_dir: str = "runs") -> SessionInfo:
    """The :class:`SessionInfo` of ``argument``: a session directory, its ``session.yaml``, or a session name under
    ``output_dir``; ``ValueError`` naming what was looked for and where."""
    if not argument:
        raise ValueError("--session needs a session directory, its session.yaml, or the name the session printed")
    if os.path.isfile(argument):
        path = argument
    elif os.path.isdir(argument):
        path = os.path.join(argument, SESSION_FILE)
        if not os.path.isfile(path):
            raise ValueError(f"no {SESSION_FILE} in {argument} (is it the directory a study or bringup printed?)")
    else:
        path = os.path.join(output_dir, argument, SESSION_FILE)
        if not os.path.isfile(path):
            raise ValueError(f"no session {argument!r}: neither a directory nor a file of that name, and no "
                             f"{path}")
    try:
        with open(path, encoding="utf-8") as stream:
            document = safe_yaml.load(stream)
        fields = dict(document["session"])
        info = SessionInfo(**{field.name: fields[field.name] for field in dataclasses.fields(SessionInfo)
                              if field.name in fields})
        check_session(info)
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{path} is not a session file: {exc}") from None
    return info


def check_session(info: SessionInfo) -> None:
    """``ValueError`` naming the first field of ``info`` a joining process could not use."""
    from rollability_ros.core.rig import DISCOVERY_RANGES, check_domain_id, check_namespace

    check_domain_id(str(info.ros_domain_id))
    if info.discovery_range not in DISCOVERY_RANGES:
        raise ValueError(f"discovery_range must be one of {DISCOVERY_RANGES}, got {info.discovery_range!r}")
    check_namespace(info.namespace)
    for name in ("name", "id", "directory", "valve_key_file", "store_path", "kind"):
        if not isinstance(getattr(info, name), str) or not getattr(info, name):
            raise ValueError(f"{name} must be a non-empty string")


def discovery_range_of(environ: typing.Mapping[str, str]) -> str:
    """The discovery range ``environ`` gives a ROS 2 process (Jazzy: ``ROS_AUTOMATIC_DISCOVERY_RANGE``, else the
    deprecated ``ROS_LOCALHOST_ONLY=1``, else SUBNET)."""
    if environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE"):
        return environ["ROS_AUTOMATIC_DISCOVERY_RANGE"]
    return "LOCALHOST" if environ.get("ROS_LOCALHOST_ONLY") == "1" else "SUBNET"


def start_session(kind: str, directory: str, namespace: str, environ: typing.MutableMapping[str, str],
                  own_domain: bool = True, rig_backend: str = "sim", store_path: str = ""
                  ) -> typing.Tuple[SessionInfo, typing.Optional[typing.TextIO]]:
    """Put this process (``environ``, before ROS starts; the nodes it starts inherit it) on the session's graph and
    write ``<directory>/session.yaml``; returns the :class:`SessionInfo` and the domain's lock handle (keep it open
    for the life of the session).

    ``own_domain``: claim a free domain (:func:`claim_session_domain`) with localhost discovery; False (the
    physical rig): stay on the domain ``environ`` already names (``ROS_DOMAIN_ID``), holding it when free.
    """
    from rollability_ros.core.rig import check_domain_id

    handle: typing.Optional[typing.TextIO]
    if own_domain:
        domain, handle = claim_session_domain(environ)
        for name in _CLEARED:
            environ.pop(name, None)
        environ["ROS_DOMAIN_ID"] = str(domain)
        environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = SESSION_DISCOVERY_RANGE
    else:
        domain = check_domain_id(environ.get("ROS_DOMAIN_ID") or "0")
        handle = hold_domain(domain)
    name = os.path.basename(os.path.normpath(directory))
    info = SessionInfo(name=name, id=f"{name}.{secrets.token_hex(4)}", directory=os.path.normpath(directory),
                       kind=kind, ros_domain_id=domain,
                       discovery_range=discovery_range_of(environ), namespace=namespace,
                       valve_key_file=session_key_path(name, namespace, domain),
                       store_path=store_path or os.path.join(os.path.normpath(directory), "outcomes.sqlite"),
                       rig_backend=rig_backend, pid=os.getpid())
    info.write()
    return info, handle
