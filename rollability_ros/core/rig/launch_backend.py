"""The launch backend contract: what the rig node and the in-process campaign call, whichever backend runs, with
the types it is written in: the rig's settings (:class:`RigSettings`, ``rig.*``), the operator channel and its
answers (:class:`OperatorChannel`, :class:`OperatorOutcome`) and the :data:`LAUNCH_BACKENDS` table
(``rig.backend``); the IMU outcome a physical launch waits on comes from the module below it,
:class:`~rollability_ros.core.rig.outcome_sources.ImuOutcome`.

A :class:`LaunchBackend` launches one trial at a time and returns its
:class:`~rollability_ros.core.records.LaunchOutcome`; the outcome's ``backend`` field is the only place a
caller learns which implementation ran. Two implementations live in :mod:`rollability_ros.core.rig.rig_session`:
``SimulatedLaunch`` (the launch twin in PyBullet) and ``PhysicalLaunch`` (valve, speed gate, operator or IMU), and
:func:`~rollability_ros.core.rig.rig_session.make_launch_backend` picks one from ``rig.backend``.

What a backend needs from the world it runs in (a valve, a speed gate, an IMU stream) comes from :class:`RigPorts`,
which the caller implements once (the rig node over ROS services and topics, the CLI in this process). A backend
opens only the ports it uses, so the simulated backend never touches a valve and a caller never asks which backend
it got.
"""
import abc
import dataclasses
import math
import threading
import time
import typing

from rollability_ros.core.imu import ImuOutcomeConfig
from rollability_ros.core.records import NOT_MEASURED, LaunchCondition, LaunchOutcome
from rollability_ros.core.registry import Registry
from rollability_ros.core.rig.outcome_sources import ROLLED_WORD, ImuOutcome, check_rest_distance
from rollability_ros.core.rig.speed_gate import SpeedGate, SpeedGateConfig
from rollability_ros.core.rig.valve import ValveStatus
from rollability_ros.core.rig.valve_contract import ValveConfig

if typing.TYPE_CHECKING:  # annotations only: the sim face's twin result (the twin is imported when it launches)
    from rollability_ros.core.sim import LaunchResult, LaunchTwinSettings

#: ``on_phase(phase, detail)``: one feedback phase of the Launch action and a sentence for the operator.
PhaseCallback = typing.Callable[[str, str], None]
#: ``on_pose(t_s, position_m, orientation_xyzw)``: the chassis pose, s after the push, m, (x, y, z, w).
PoseCallback = typing.Callable[[float, typing.Sequence[float], typing.Sequence[float]], None]


class LaunchAborted(RuntimeError):
    """A launch ended without an outcome (valve refused or cut the pulse, operator timeout, cancel)."""


def no_phase(phase: str, detail: str) -> None:
    """Default ``on_phase``: ignore."""


def not_cancelled() -> bool:
    """Default ``cancelled``: never."""
    return False


@dataclasses.dataclass(frozen=True)
class OperatorOutcome:
    """The operator's classification of a launch: upright, optional travel time (s, NaN if not timed), note."""

    upright: bool
    travel_time_s: float = NOT_MEASURED
    note: str = ""
    rest_distance_m: float = NOT_MEASURED   # m from the ledge's edge to where it came to rest, as the operator measured


def parse_outcome_answer(text: str) -> "OperatorOutcome":
    """Parse a typed outcome ``"y|n [travel time s] [rolled=M] [note...]"`` into an :class:`OperatorOutcome`.

    ``y``/``yes``/``u``/``upright`` mean upright, ``n``/``no``/``t``/``tipped`` not; ``rolled=0.35`` anywhere after the
    verdict is the distance from the ledge's edge to where the chassis came to rest, m, as measured (>= 0); raises
    ``ValueError`` otherwise.
    """
    words = text.split()
    rolled = [word for word in words[1:] if word.lower().startswith(ROLLED_WORD)]
    if len(rolled) > 1:
        raise ValueError(f"give the distance rolled once ({ROLLED_WORD}M), got {' '.join(rolled)}")
    rest_distance_m = NOT_MEASURED
    if rolled:
        rest_distance_m = check_rest_distance(rolled[0][len(ROLLED_WORD):])
        words = [word for word in words if word is not rolled[0]]
    if not words:
        raise ValueError("type y (upright) or n (not upright), optionally the travel time in s and a note")
    verdict = words[0].lower()
    if verdict not in ("y", "yes", "u", "upright", "n", "no", "t", "tipped"):
        raise ValueError(f"first word must be y (upright) or n (not upright), got {words[0]!r}")
    travel_time_s, rest = NOT_MEASURED, words[1:]
    if rest:
        try:
            travel_time_s = float(rest[0])
            rest = rest[1:]
        except ValueError:
            pass
        if not (math.isnan(travel_time_s) or 0 < travel_time_s < math.inf):
            raise ValueError(f"travel time must be > 0 s, got {travel_time_s}")
    return OperatorOutcome(verdict in ("y", "yes", "u", "upright"), travel_time_s, " ".join(rest), rest_distance_m)


def describe_answer(kind: str, answer: typing.Union[bool, OperatorOutcome, None]) -> str:
    """An operator answer in words: ``regulator confirmed`` or ``upright, travel time 0.42 s, note: ...``."""
    if kind == "confirm":
        return "regulator confirmed"
    assert isinstance(answer, OperatorOutcome), "an outcome answer carries the outcome"
    parts = ["upright" if answer.upright else "tipped"]
    if not math.isnan(answer.travel_time_s):
        parts.append(f"travel time {answer.travel_time_s:g} s")
    if not math.isnan(answer.rest_distance_m):
        parts.append(f"rolled {answer.rest_distance_m:g} m")
    if answer.note:
        parts.append(f"note: {answer.note}")
    return ", ".join(parts)


class OperatorChannel:
    """One pending question to the operator (regulator confirmation or launch outcome) and its answer.

    The launch opens a question, announces it (feedback), then waits; answers come from any thread (the operator
    may answer from the ``rollability rig`` CLI or from the campaign terminal: the first answer counts). An answer
    with no open question of its kind is refused with a reason, so a late or stray service call changes nothing;
    a late answer to the question just answered (same kind and trial) is compared with the answer that counted:
    the same verdict is accepted as already given (it changes nothing), a different one is refused naming both.
    """

    def __init__(self):
        self._cond = threading.Condition()
        self._kind = None      # "confirm" | "outcome" | None
        self._trial_id = ""
        self._answer = None
        self._last: typing.Dict[str, typing.Tuple[str, typing.Any]] = {}   # kind -> (trial id, answer that counted)

    def open(self, kind: str, trial_id: str = "") -> None:
        """Start waiting for a ``"confirm"`` or an ``"outcome"`` (of ``trial_id``)."""
        if kind not in ("confirm", "outcome"):
            raise ValueError(f"kind must be 'confirm' or 'outcome', got {kind!r}")
        with self._cond:
            self._kind, self._trial_id, self._answer = kind, trial_id, None

    def close(self) -> None:
        """Stop waiting; later answers are refused."""
        with self._cond:
            self._kind, self._answer = None, None
            self._cond.notify_all()

    def _late(self, kind, answer, trial_id):
        """``(accepted, message)`` for a late answer to the question of ``kind`` answered last, or None."""
        if kind not in self._last or (self._kind == kind and self._answer is None):
            return None
        answered_trial, counted = self._last[kind]
        if trial_id and trial_id != answered_trial:
            return None
        given = describe_answer(kind, counted)
        if kind == "confirm" or counted.upright == answer.upright:
            return True, f"already answered for {answered_trial}: {given} (this answer agrees; nothing changed)"
        return False, (f"already answered for {answered_trial}: {given}; this answer ({describe_answer(kind, answer)}) "
                       "differs and is refused (the first answer counts)")

    def _deliver(self, kind, answer, trial_id=""):
        with self._cond:
            late = self._late(kind, answer, trial_id)
            if late is not None:
                return late
            if self._kind != kind:
                what = "a regulator confirmation" if kind == "confirm" else "an outcome"
                return False, f"the rig is not waiting for {what}" + (
                    f" (it waits for {'a confirmation' if self._kind == 'confirm' else 'an outcome'})"
                    if self._kind else "")
            if trial_id and trial_id != self._trial_id:
                what = "a regulator confirmation" if kind == "confirm" else "the outcome"
                return False, f"the rig waits for {what} of {self._trial_id!r}, not {trial_id!r}"
            self._answer = answer
            self._last[kind] = (self._trial_id, answer)
            self._cond.notify_all()
            return True, "accepted"

    def confirm(self, trial_id: str = "") -> typing.Tuple[bool, str]:
        """Answer an open regulator confirmation (of ``trial_id``, "" = the current one). Returns
        ``(accepted, message)``."""
        return self._deliver("confirm", True, trial_id)

    def record_outcome(self, outcome: OperatorOutcome, trial_id: str = "") -> typing.Tuple[bool, str]:
        """Answer an open outcome question with an :class:`OperatorOutcome` (``trial_id`` "" = the current one)."""
        return self._deliver("outcome", outcome, trial_id)

    def wait(self, timeout_s: float, cancelled: typing.Callable[[], bool] = not_cancelled,
             poll_s: float = 0.05) -> typing.Union[bool, OperatorOutcome, None]:
        """Return the answer once given (True: the regulator confirmed; the outcome), or None on timeout /
        ``cancelled()``; the question stays open."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while self._answer is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0 or cancelled() or self._kind is None:
                    return None
                self._cond.wait(min(poll_s, remaining))
            return self._answer


class LaunchBackend(abc.ABC):
    """One way of launching a trial; sim and physical implement it and nobody else needs to know which.

    Attributes
    ----------
    name : str
        The value of the outcomes' ``backend`` field (``"sim"`` or ``"physical"``).
    attended : bool
        True when an operator must be at the rig (to place the chassis and answer questions); an attended campaign
        tells the operator what to change before each trial.
    authenticated : bool
        True when goals, operator answers and outcome records must be signed with the valve's session key
        (:mod:`rollability_ros.core.rig.rig_auth`): a backend that moves hardware or writes physical records.
    operator : OperatorChannel
        Where operator answers (regulator confirmation, outcome) are delivered from any thread; a backend that
        never asks refuses every answer with a reason.
    """

    name: str = ""
    attended: bool = False
    authenticated: bool = False
    operator: "OperatorChannel"

    @abc.abstractmethod
    def check(self, run_id: str, trial_id: str, condition: LaunchCondition) -> str:
        """Why this goal cannot run ("" when it can): empty ids, bad condition, unknown configuration, ..."""

    @abc.abstractmethod
    def launch(self, run_id: str, trial_id: str, condition: LaunchCondition, on_phase: PhaseCallback = no_phase,
               *, on_pose: typing.Optional[PoseCallback] = None,
               cancelled: typing.Callable[[], bool] = not_cancelled) -> LaunchOutcome:
        """Run one launch and return its outcome.

        ``on_phase(phase, detail)`` reports progress, ``on_pose`` receives chassis poses when the backend has any,
        ``cancelled()`` is polled at every wait. Raises ``ValueError`` for a goal :meth:`check` refuses and
        :class:`LaunchAborted` when no outcome was obtained.
        """

    @classmethod
    def from_ports(cls, settings: "RigSettings", speed_config: "SpeedGateConfig", valve_config: "ValveConfig",
                   imu_config: "ImuOutcomeConfig", ports: "RigPorts") -> "LaunchBackend":
        """The backend for these settings, opening only the ``ports`` it uses (what ``make_launch_backend`` calls);
        ``ValueError`` for settings it cannot honour."""
        raise TypeError(f"launch backend {cls.__name__} does not implement from_ports")

    def describe(self) -> str:
        """One line for the start-up log."""
        return f"backend {self.name}"

    def design_sources(self) -> dict:
        """Where this backend's profiles come from, for the campaign's run info (reports draw and link the designs
        of that run only): ``{"designs_file": absolute path or "", "mesh_files": {label: absolute path}}``, or
        ``{}`` when it does not know (an operator mounts printed parts)."""
        return {}

    def twin_config(self) -> typing.List[str]:
        """The parameter files of the launch twin this backend simulates in (``rig.twin_config``), for the
        campaign's run info (a re-simulation loads them); ``[]`` when it simulates nothing."""
        return []

    def launched_twin(self) -> dict:
        """This backend's record of the twin it launches in, for the campaign's run info
        (:func:`~rollability_ros.core.rig.launched_twin.launched_twin` of :meth:`twin_config` and
        :meth:`design_sources`; ``{NO_TWIN: name}`` when it simulates nothing)."""
        from rollability_ros.core.rig.launched_twin import launched_twin

        return launched_twin(self.name, self.twin_config(), self.design_sources())

    def close(self) -> None:
        """Release what the backend opened (valve closed, heartbeat stopped); idempotent."""

    @classmethod
    def resimulate_refusal(cls) -> str:
        """Why this backend cannot re-run a stored launch from its seed ("" when it can; default: it cannot)."""
        return f"a {cls.name} launch cannot be re-run: it has no twin seed"

    def resimulate(self, condition: LaunchCondition, seed: int) -> "LaunchResult":
        """The launch of ``condition`` with twin ``seed`` again (the launch a stored outcome was classified from);
        by default refused with :meth:`resimulate_refusal` as a ``ValueError``."""
        raise ValueError(self.resimulate_refusal())


class ValvePort(typing.Protocol):
    """The valve as a physical launch uses it: a :class:`~rollability_ros.core.rig.valve.ValveController` in this
    process, or the rig node's signed service calls to the valve_controller node. Each command returns ``(ok,
    message)``."""

    def arm(self) -> typing.Tuple[bool, str]: ...

    def disarm(self) -> typing.Tuple[bool, str]: ...

    def fire(self, pulse_ms: int) -> typing.Tuple[bool, str]: ...

    def status(self) -> "ValveStatus": ...


class RigPorts(abc.ABC):
    """The world a physical launch runs in, provided by the caller; each port is opened only when a backend uses it."""

    @abc.abstractmethod
    def open_valve(self, valve_config: "ValveConfig") -> ValvePort:
        """The valve (``arm``, ``fire``, ``disarm``, ``status``) with its keep-alive running; see ``PhysicalLaunch``."""

    @abc.abstractmethod
    def open_speed_gate(self, speed_config: "SpeedGateConfig") -> "SpeedGate":
        """The speed gate (``arm(target_mps)``, ``read_travel_time(timeout_s)``) for ``speed_config``."""

    @abc.abstractmethod
    def open_imu(self, imu_outcome: "ImuOutcome") -> None:
        """Feed :meth:`ImuOutcome.feed` from the IMU stream; ``ValueError`` when this caller has no IMU."""

    @abc.abstractmethod
    def open_twin(self, twin_config: typing.Sequence[str]) -> "LaunchTwinSettings":
        """The launch twin a simulated launch runs in: its typed settings, parsed by the caller (the node or the
        command, the edge) from the parameter files ``twin_config`` (``rig.twin_config``) once; ``ValueError``
        (:class:`~rollability_ros.core.config.ConfigError`) naming a bad file or value."""

    def close(self) -> None:
        """Stop what the ports started (keep-alive, valve shut down); idempotent."""


#: ``rig.backend`` -> the :class:`LaunchBackend` implementation.
LAUNCH_BACKENDS: Registry[LaunchBackend] = Registry("backend", LaunchBackend, {
    "sim": "rollability_ros.core.rig.rig_session:SimulatedLaunch",
    "physical": "rollability_ros.core.rig.rig_session:PhysicalLaunch",
})


#: ``rig.backend`` values.
#: ``rig.outcome_source`` values (physical backend).
OUTCOME_SOURCES = ("operator", "imu")


@dataclasses.dataclass
class RigSettings:
    """``rig.*``: the rig node's own settings (the valve, speed gate and IMU have their own namespaces)."""

    backend: str = dataclasses.field(default="sim", metadata={
        "description": "launch backend: sim (the launch twin in PyBullet) or physical (valve, speed gate, operator / "
                       "IMU)"})
    configurations: typing.List[str] = dataclasses.field(default_factory=lambda: ["baseline", "A", "B", "C"], metadata={
        "description": "configuration ids the rig accepts in a Launch goal (profile meshes mounted by the operator)"})
    outcome_source: str = dataclasses.field(default="operator", metadata={
        "description": "who classifies a physical launch: operator (record_outcome service) or imu (settled chassis "
                       "IMU)"})
    countdown_s: float = dataclasses.field(default=1.0, metadata={
        "description": "countdown between arming and firing so people stand clear, s", "range": (0.0, 600.0)})
    operator_timeout_s: float = dataclasses.field(default=600.0, metadata={
        "description": "longest wait for an operator answer (regulator confirmation, outcome) before the launch aborts,"
                       " s", "range": (0.0, 86400.0), "exclusive": "low"})
    question_repeat_s: float = dataclasses.field(default=2.0, metadata={
        "description": "period of the open question's feedback while the rig waits for the operator, s; a client "
                       "whose feedback subscription matched after the first one (a loaded machine's discovery) or an "
                       "operator's view that joined late still sees it", "range": (0.05, 3600.0)})
    imu_override_s: float = dataclasses.field(default=2.0, metadata={
        "description": "window in which the operator may override the IMU's outcome, s", "range": (0.0, 3600.0)})
    confirmation_valid_s: float = dataclasses.field(default=300.0, metadata={
        "description": "a regulator confirmation holds for later launches at the same speed this long, s (0: ask "
                       "before every launch); an aborted launch always forgets it", "range": (0.0, 86400.0)})
    valve_timeout_s: float = dataclasses.field(default=5.0, metadata={
        "description": "longest wait for the valve_controller's arm / fire / disarm services, s",
        "range": (0.0, 600.0), "exclusive": "low"})
    seed: int = dataclasses.field(default=0, metadata={
        "description": "seed of the simulated rig's launch twin and speed noise (integer >= 0)",
        "range": (0, 2147483647)})
    twin_config: typing.List[str] = dataclasses.field(default_factory=lambda: ["sim", "robot", "launch_twin"], metadata={
        "description": "parameter files (shipped names or paths) that configure the sim backend's launch twin, later "
                       "files win"})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        LAUNCH_BACKENDS.check(self.backend)
        if not self.configurations or not all(self.configurations):
            raise ValueError("configurations must list the configuration ids the rig can launch")
        if self.outcome_source not in OUTCOME_SOURCES:
            raise ValueError(f"outcome_source must be one of {OUTCOME_SOURCES}, got {self.outcome_source!r}")
