"""Only the rig computer's operator side can arm, keep alive or fire the valve: a per-session arming key.

The valve_controller creates a fresh key at every start (:func:`create_session_key`): a random session id and 32
random bytes in a file of mode 0600 in a folder of mode 0700, on the rig computer, never published. The rig node
(when its launch sequence arms, after the operator's confirmation) and ``rollability rig`` on the same computer,
running as the same user, read it (:func:`load_session_key`) and sign every arm / disarm / fire request and every
heartbeat with HMAC-SHA256 over ``session``, a ``counter`` and the command (:class:`RequestSigner`). The
valve_controller accepts a request only if its MAC is right for the current session, its counter is fresh and
was never accepted before (:class:`RequestVerifier`).

So a participant on the same DDS domain that cannot read the key file (a test script, a fuzzer, a second lab's
graph on another computer or another user account) cannot arm, keep alive, fire or clear a fault: it does not know
the key, a captured request cannot be replayed, and a heartbeat from an earlier session does not count. This guard
holds whatever the RMW does (no DDS security needed); its boundary is the operating-system user account that owns
the key file. Anyone may still e-stop (``valve/estop`` is deliberately unauthenticated: stopping is always safe).

The counter is the signer's ``CLOCK_MONOTONIC`` in ns: the signers and the valve_controller share one computer,
so the valve_controller can check freshness (within :data:`FRESH_WINDOW_NS`) without a shared counter, and
remembers the counters it accepted within that window so none is accepted twice.
"""
import dataclasses
import hashlib
import hmac
import os
import secrets
import stat
import threading
import time

KEY_BYTES = 32
#: A request's counter must be within this many ns of the valve_controller's monotonic clock.
FRESH_WINDOW_NS = 5_000_000_000
COMMANDS = ("arm", "disarm", "fire", "heartbeat")


class AuthError(ValueError):
    """A key file that cannot be trusted or read, or a request that does not authenticate."""


@dataclasses.dataclass(frozen=True)
class SessionKey:
    """One valve_controller session: its id (public) and its key (secret)."""

    session: str
    key: bytes = dataclasses.field(repr=False)


@dataclasses.dataclass(frozen=True)
class Signature:
    """The authentication fields of one request (``msg/ValveAuth.msg``)."""

    session: str
    counter: int
    mac: str


def default_key_path(namespace: str = "", domain_id: str | None = None) -> str:
    """The key file of the valve_controller in ``namespace`` on ROS domain ``domain_id`` (default: the env's).

    ``$XDG_RUNTIME_DIR/rollability/`` (a per-user tmpfs, gone at logout) when set, else
    ``~/.cache/rollability/``; the name carries the domain and namespace so two graphs on one computer never share
    a key.
    """
    domain = os.environ.get("ROS_DOMAIN_ID", "0") if domain_id is None else domain_id
    base = os.environ.get("XDG_RUNTIME_DIR") or os.path.join(os.path.expanduser("~"), ".cache")
    label = "".join(c if c.isalnum() else "_" for c in namespace.strip("/")) or "root"
    return os.path.join(base, "rollability", f"valve_session.domain{domain or '0'}.{label}.key")


def _private_folder(folder):
    os.makedirs(folder, mode=0o700, exist_ok=True)
    info = os.stat(folder)
    if info.st_uid != os.geteuid() or info.st_mode & 0o022:
        raise AuthError(f"key folder {folder} must belong to this user and not be group/world writable")


def create_session_key(path: str) -> SessionKey:
    """Write a fresh session key to ``path`` (mode 0600, atomically) and return it."""
    _private_folder(os.path.dirname(os.path.abspath(path)))
    session_key = SessionKey(secrets.token_hex(8), secrets.token_bytes(KEY_BYTES))
    tmp = f"{path}.{os.getpid()}.tmp"
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    try:
        os.write(fd, f"{session_key.session} {session_key.key.hex()}\n".encode("ascii"))
        os.fsync(fd)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    return session_key


def load_session_key(path: str) -> SessionKey:
    """Read the key file at ``path``; :class:`AuthError` if missing, malformed or readable by others."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError as exc:
        raise AuthError(f"cannot read the valve session key {path}: {exc.strerror} (is the valve_controller "
                        "running on this computer, as this user?)") from exc
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode) or info.st_uid != os.geteuid() or info.st_mode & 0o077:
            raise AuthError(f"valve session key {path} must be a regular file of this user with mode 0600")
        text = os.read(fd, 4096).decode("ascii", errors="replace")
    finally:
        os.close(fd)
    words = text.split()
    try:
        if len(words) != 2 or len(words[0]) != 16 or len(words[1]) != 2 * KEY_BYTES:
            raise ValueError
        int(words[0], 16)
        return SessionKey(words[0], bytes.fromhex(words[1]))
    except ValueError:
        raise AuthError(f"valve session key {path} is malformed") from None


def remove_session_key(path: str, session_key: SessionKey) -> None:
    """Delete ``path`` if it still holds ``session_key`` (a newer session's file is left alone)."""
    try:
        if load_session_key(path) == session_key:
            os.remove(path)
    except (AuthError, OSError):
        pass


def _mac(key: bytes, session: str, counter: int, command: str) -> str:
    return hmac.new(key, f"{session}\n{counter}\n{command}".encode("utf-8"), hashlib.sha256).hexdigest()


def mac_matches(session_key: SessionKey, signature: Signature, text: str) -> bool:
    """True when ``signature`` carries the right MAC of ``text`` for ``session_key`` (no freshness check)."""
    mac = signature.mac.lower()
    return (signature.session == session_key.session and mac.isascii()   # compare_digest refuses non-ASCII text
            and hmac.compare_digest(_mac(session_key.key, session_key.session, signature.counter, text), mac))


def command_text(command: str, pulse_ms: int | None = None) -> str:
    """The signed text of a command: ``arm``, ``disarm``, ``heartbeat`` or ``fire <pulse_ms>``."""
    if command not in COMMANDS:
        raise ValueError(f"unknown valve command {command!r}")
    if command != "fire":
        return command
    if pulse_ms is None:
        raise ValueError("fire needs pulse_ms")
    return f"fire {int(pulse_ms)}"


class RequestSigner:
    """Signs requests with one :class:`SessionKey` (thread-safe; counters strictly increase)."""

    def __init__(self, session_key: SessionKey, clock_ns=time.monotonic_ns):
        self.session_key = session_key
        self._clock_ns = clock_ns
        self._lock = threading.Lock()
        self._last = 0

    def sign(self, command: str, pulse_ms: int | None = None) -> Signature:
        """A :class:`Signature` for ``command`` (``pulse_ms`` for ``fire``)."""
        return self.sign_text(command_text(command, pulse_ms))

    def sign_text(self, text: str) -> Signature:
        """A :class:`Signature` over any request ``text`` (the rig's requests, :mod:`~.rig_auth`)."""
        with self._lock:
            self._last = counter = max(self._clock_ns(), self._last + 1)
        key = self.session_key
        return Signature(key.session, counter, _mac(key.key, key.session, counter, text))


class RequestVerifier:
    """Checks signed requests for one session: right MAC, fresh counter, never seen before (thread-safe)."""

    def __init__(self, session_key: SessionKey, clock_ns=time.monotonic_ns, window_ns: int = FRESH_WINDOW_NS,
                 not_before_ns: int = 0):
        self.session_key = session_key
        self._clock_ns = clock_ns
        self._window_ns = window_ns
        self._not_before_ns = not_before_ns   # counters signed before this (a restarted verifier's start) refused
        self._lock = threading.Lock()
        self._seen: dict = {}  # counter -> accepted, pruned once older than the window
        self.rejected = 0

    def verify(self, signature: Signature, command: str, pulse_ms: int | None = None) -> tuple:
        """``(True, "")`` for an authentic fresh request, else ``(False, reason)`` (and counts the rejection)."""
        return self.verify_text(signature, command_text(command, pulse_ms))

    def verify_text(self, signature: Signature, text: str) -> tuple:
        """:meth:`verify` for any request ``text`` (the rig's requests, :mod:`~.rig_auth`)."""
        reason = self._check(signature, text)
        if reason:
            with self._lock:
                self.rejected += 1
            return False, f"not authenticated: {reason}"
        return True, ""

    def _check(self, signature, text):
        key = self.session_key
        if not signature.session or not signature.mac:
            return "no session key signature (only the rig computer's operator side may do this)"
        if signature.session != key.session:
            return f"signed for session {signature.session!r}, the valve runs session {key.session!r}"
        if not mac_matches(key, signature, text):
            return "wrong MAC"
        now = self._clock_ns()
        if abs(now - signature.counter) > self._window_ns:
            return f"stale request (counter {(now - signature.counter) / 1e9:+.1f} s from now)"
        if signature.counter <= self._not_before_ns:
            return "signed before this verifier started (a request captured earlier and replayed)"
        with self._lock:
            self._seen = {c: t for c, t in self._seen.items() if now - t <= 2 * self._window_ns}
            if signature.counter in self._seen:
                return "replayed request"
            self._seen[signature.counter] = now
        return ""
