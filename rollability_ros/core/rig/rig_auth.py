"""Only the operator's tools launch the physical rig, answer its questions or store a physical outcome.

The valve_controller's per-session key (:mod:`~rollability_ros.core.rig.valve_auth`) signs, besides the valve's
own arm / fire / heartbeat requests, every request to the rig that can move hardware or write a physical record:

- a ``launch`` goal (:func:`launch_text`: run, trial and the whole condition),
- the regulator confirmation ``rig/confirm`` (:func:`confirm_text`: bound to the trial it confirms, or to "the
  launch waiting now" when the operator's tool does not name one),
- the operator's outcome ``record_outcome`` (:func:`outcome_text`: trial, verdict, travel time, note),
- the physical :class:`~rollability_ros.core.records.LaunchOutcome` the rig publishes for the outcome_logger
  (:func:`record_text`: every stored field).

The operator's tools (``rollability rig``, ``rollability campaign --graph``, the campaign_runner node) read the key
file and sign (:class:`KeyFileSigner`). The rig verifies goals and answers with a :class:`RequestGuard`: right MAC
for the valve's current session, a counter within :data:`~.valve_auth.FRESH_WINDOW_NS` of the rig's clock and
never accepted before, and signed after the guard was created (a goal captured before a rig restart and sent to
the new rig is refused too). Only a verified goal gives a :class:`LaunchTicket`, and only a ticket signs the
launch's outcome record: the rig never signs on behalf of a caller it did not authenticate. The outcome_logger
stores a physical outcome only with a valid record signature (:class:`RecordGuard`); records carry no freshness
window (a logger may receive them late) because the store keeps one record per run and trial id, so a replayed
authentic record is a duplicate, never a new one.

The simulated rig (``rig.backend: sim``) moves no hardware and its outcomes are labelled ``sim``: it needs no key
(:class:`OpenGuard`), so a simulated campaign runs on any computer.

Every text is ``rig-<kind>``, a newline and the fields as one JSON value, so no rig signature is ever a valid valve
command (``arm``, ``fire 150``...) or another kind of rig request, and no two sets of fields share a text.
"""
import dataclasses
import json
import math
import os
import threading
import time
import typing

from rollability_ros.core.records import LaunchOutcome
from rollability_ros.core.rig import valve_auth
from rollability_ros.core.rig.valve_auth import AuthError, Signature

class ConditionFields(typing.Protocol):
    """The fields of a launch condition a launch goal signs: a :class:`~rollability_ros.core.records.LaunchCondition`,
    or the ``LaunchCondition`` message of a goal as it arrives."""

    @property
    def configuration(self) -> str:
        """The configuration id."""

    @property
    def height_m(self) -> float:
        """The ledge height above the foam, m."""

    @property
    def speed_mps(self) -> float:
        """The nominal launch speed, m/s."""

    @property
    def angle_deg(self) -> float:
        """The launch angle, deg."""

    @property
    def repetition(self) -> int:
        """The repetition number of the cell."""


#: The signature of an unsigned request or record (what a sim rig sends).
UNSIGNED = Signature("", 0, "")


def _number(value: float) -> str:
    """An exact, platform-independent text of a float64 (``float.hex``; NaN and infinities included)."""
    return float(value).hex()


def _text(kind: str, fields: typing.Any) -> str:
    """``rig-<kind>`` and the fields as one JSON value: no field can bleed into the next (a newline in a note)."""
    return f"rig-{kind}\n" + json.dumps(fields, sort_keys=True, ensure_ascii=True)


def launch_text(run_id: str, trial_id: str, condition: ConditionFields) -> str:
    """The signed text of a launch goal: run, trial and every field of its ``LaunchCondition``."""
    return _text("launch", [run_id, trial_id, condition.configuration, _number(condition.height_m),
                            _number(condition.speed_mps), _number(condition.angle_deg), int(condition.repetition)])


def confirm_text(trial_id: str) -> str:
    """The signed text of a regulator confirmation for ``trial_id`` ("" = the launch the rig waits on now)."""
    return _text("confirm", [trial_id])


def outcome_text(trial_id: str, upright: bool, travel_time_s: float, note: str,
                 rest_distance_m: float = math.nan) -> str:
    """The signed text of an operator's outcome for ``trial_id`` ("" = the launch the rig waits on now); the distance
    rolled is signed when measured (>= 0), so an answer without one signs the text it always did."""
    measured = rest_distance_m >= 0   # False for NaN and for the service's -1 (not measured)
    return _text("outcome", [trial_id, bool(upright), _number(travel_time_s), note]
                 + ([_number(rest_distance_m)] if measured else []))


def record_text(outcome: LaunchOutcome) -> str:
    """The signed text of a stored :class:`~rollability_ros.core.records.LaunchOutcome`: all its fields."""
    def exact(value: typing.Any) -> typing.Any:
        if isinstance(value, float):
            return _number(value)
        if isinstance(value, dict):
            return {k: exact(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [exact(v) for v in value]
        return value
    return _text("record", exact(dataclasses.asdict(outcome)))


class SessionKeys:
    """The valve's session keys read from ``path``: the file is read again whenever it changed (a restarted
    valve_controller replaces it) or a signature names another session than the newest read. Requests need the
    current session (:meth:`current`); records may name an earlier one read before (:meth:`known`: a record of the
    previous session)."""

    def __init__(self, path: str, load=valve_auth.load_session_key):
        self.path = path
        self._load = load
        self._lock = threading.Lock()
        self._newest: typing.Optional[valve_auth.SessionKey] = None
        self._file_stamp: typing.Optional[typing.Tuple[int, int, int]] = None
        self._keys: dict = {}

    def _lookup(self, session, current_only):
        with self._lock:
            if not current_only and session in self._keys:
                return self._keys[session]
            try:
                info = os.stat(self.path)
                stamp = (info.st_ino, info.st_mtime_ns, info.st_size)
            except OSError:
                stamp = None     # gone (the valve_controller stopped): the load below says so
            if self._newest is None or stamp is None or stamp != self._file_stamp or self._newest.session != session:
                self._newest, self._file_stamp = self._load(self.path), stamp
                self._keys[self._newest.session] = self._newest
            key = self._newest if self._newest.session == session else (
                None if current_only else self._keys.get(session))
            if key is None:
                raise AuthError(f"signed for session {session!r}, the valve runs session {self._newest.session!r}")
            return key

    def current(self, session: str) -> valve_auth.SessionKey:
        """The key of ``session`` if it is the valve's current one; :class:`AuthError` otherwise or when the key
        file cannot be read."""
        return self._lookup(session, True)

    def known(self, session: str) -> valve_auth.SessionKey:
        """The key of ``session``, current or read before; :class:`AuthError` otherwise."""
        return self._lookup(session, False)


@dataclasses.dataclass(frozen=True)
class LaunchTicket:
    """An authenticated launch goal: the only thing that signs that launch's outcome record."""

    run_id: str
    trial_id: str
    session_key: typing.Optional[valve_auth.SessionKey] = dataclasses.field(default=None, repr=False)

    def sign_record(self, outcome: LaunchOutcome) -> Signature:
        """The record signature of ``outcome`` (a LaunchOutcome of this ticket's run and trial); unsigned (sim)
        when the ticket came from an :class:`OpenGuard`."""
        if (outcome.run_id, outcome.trial_id) != (self.run_id, self.trial_id):
            raise AuthError(f"outcome {outcome.run_id}/{outcome.trial_id} is not the authenticated launch "
                            f"{self.run_id}/{self.trial_id}")
        if self.session_key is None:
            return UNSIGNED
        return valve_auth.RequestSigner(self.session_key).sign_text(record_text(outcome))


class RequestGuard:
    """Verifies the rig's requests with the valve's session key at ``key_path`` (the physical rig).

    Each ``check_*`` returns ``(ok, reason)``; :meth:`check_launch` returns ``(ticket or None, reason)``.
    """

    required = True

    def __init__(self, key_path: str, clock_ns=time.monotonic_ns, window_ns: int = valve_auth.FRESH_WINDOW_NS,
                 load=valve_auth.load_session_key):
        self._keys = SessionKeys(key_path, load)
        self._clock_ns = clock_ns
        self._window_ns = window_ns
        self._not_before_ns = clock_ns()   # anything signed before this guard existed was captured, not sent now
        self._lock = threading.Lock()
        self._verifiers: dict = {}   # session -> RequestVerifier (its accepted counters)
        self.rejected = 0

    def _verify(self, signature: Signature, text: str) -> typing.Tuple[typing.Optional[valve_auth.SessionKey], str]:
        if not signature.session or not signature.mac:
            reason = "no session key signature (only the operator's tools on the rig computer may do this)"
        else:
            try:
                key = self._keys.current(signature.session)
            except AuthError as exc:
                reason = str(exc)
            else:
                with self._lock:
                    verifier = self._verifiers.get(key.session)
                    if verifier is None:
                        verifier = self._verifiers[key.session] = valve_auth.RequestVerifier(
                            key, self._clock_ns, self._window_ns, self._not_before_ns)
                ok, reason = verifier.verify_text(signature, text)
                if ok:
                    return key, ""
                reason = reason.removeprefix("not authenticated: ")
        with self._lock:
            self.rejected += 1
        return None, f"not authenticated: {reason}"

    def check_launch(self, signature: Signature, run_id: str, trial_id: str,
                     condition: ConditionFields) -> typing.Tuple[typing.Optional[LaunchTicket], str]:
        """A :class:`LaunchTicket` for an authentic fresh launch goal, else ``(None, reason)``."""
        key, reason = self._verify(signature, launch_text(run_id, trial_id, condition))
        return (LaunchTicket(run_id, trial_id, key), "") if key is not None else (None, reason)

    def check_confirm(self, signature: Signature, trial_id: str) -> typing.Tuple[bool, str]:
        """An authentic fresh regulator confirmation for ``trial_id``?"""
        key, reason = self._verify(signature, confirm_text(trial_id))
        return key is not None, reason

    def check_outcome(self, signature: Signature, trial_id: str, upright: bool, travel_time_s: float,
                      note: str, rest_distance_m: float = math.nan) -> typing.Tuple[bool, str]:
        """An authentic fresh operator outcome?"""
        key, reason = self._verify(signature, outcome_text(trial_id, upright, travel_time_s, note, rest_distance_m))
        return key is not None, reason


class OpenGuard:
    """The simulated rig's guard: every request passes, tickets sign nothing (sim outcomes move no hardware and
    are stored labelled ``sim``)."""

    required = False
    rejected = 0

    def check_launch(self, signature: Signature, run_id: str, trial_id: str,
                     condition: ConditionFields) -> typing.Tuple[LaunchTicket, str]:
        """Always a ticket (that signs nothing)."""
        return LaunchTicket(run_id, trial_id, None), ""

    def check_confirm(self, signature: Signature, trial_id: str) -> typing.Tuple[bool, str]:
        """Always passes (the sim rig never asks; its operator channel refuses every answer)."""
        return True, ""

    def check_outcome(self, signature: Signature, trial_id: str, upright: bool, travel_time_s: float,
                      note: str, rest_distance_m: float = math.nan) -> typing.Tuple[bool, str]:
        """Always passes (the sim rig never asks; its operator channel refuses every answer)."""
        return True, ""


def request_guard(authenticated: bool, key_path: str) -> typing.Union[RequestGuard, OpenGuard]:
    """The guard of a rig whose backend needs authentication (``LaunchBackend.authenticated``), or of one that
    does not."""
    return RequestGuard(key_path) if authenticated else OpenGuard()


class RecordGuard:
    """Verifies outcome records before the outcome_logger stores them: a ``sim`` outcome needs no signature; any
    other needs the rig's record signature, made with a key of the valve's session at ``key_path``."""

    def __init__(self, key_path: str, load=valve_auth.load_session_key):
        self._keys = SessionKeys(key_path, load)
        self.rejected = 0

    def check(self, signature: Signature, outcome: LaunchOutcome) -> typing.Tuple[bool, str]:
        """``(True, "")`` for a sim outcome or an authentic physical one, else ``(False, reason)``."""
        if outcome.backend == "sim":
            return True, ""
        if not signature.session or not signature.mac:
            reason = ("no record signature (only the rig signs the outcome of a launch the operator's tools "
                      "authenticated)")
        else:
            try:
                key = self._keys.known(signature.session)
                reason = "" if valve_auth.mac_matches(key, signature, record_text(outcome)) else "wrong MAC"
            except AuthError as exc:
                reason = str(exc)
        if not reason:
            return True, ""
        self.rejected += 1
        return False, f"not authenticated: {reason}"


class KeyFileSigner:
    """The operator's tools' side: signs rig requests with the key file at ``path``, re-read at every signature
    (a restarted valve_controller writes a new session); :class:`AuthError` when it cannot be read."""

    def __init__(self, path: str, load=valve_auth.load_session_key):
        self.path = path
        self._load = load
        self._signer: typing.Optional[valve_auth.RequestSigner] = None

    def _sign(self, text: str) -> Signature:
        key = self._load(self.path)
        if self._signer is None or self._signer.session_key != key:
            self._signer = valve_auth.RequestSigner(key)
        return self._signer.sign_text(text)

    def launch(self, run_id: str, trial_id: str, condition: ConditionFields) -> Signature:
        """The signature of a launch goal."""
        return self._sign(launch_text(run_id, trial_id, condition))

    def confirm(self, trial_id: str = "") -> Signature:
        """The signature of a regulator confirmation for ``trial_id`` ("" = the launch waiting now)."""
        return self._sign(confirm_text(trial_id))

    def outcome(self, trial_id: str, upright: bool, travel_time_s: float = math.nan, note: str = "",
                rest_distance_m: float = math.nan) -> Signature:
        """The signature of an operator outcome."""
        return self._sign(outcome_text(trial_id, upright, travel_time_s, note, rest_distance_m))
