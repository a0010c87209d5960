"""The launch backend contract: what the rig node and the in-process campaign call, whichever backend runs.

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
import typing

from rollability_ros.core.records import LaunchCondition, LaunchOutcome

if typing.TYPE_CHECKING:  # annotations only: rig_session imports this module
    from rollability_ros.core.imu import ImuOutcomeConfig
    from rollability_ros.core.rig.rig_session import ImuOutcome, OperatorChannel, RigSettings
    from rollability_ros.core.rig.speed_gate import SpeedGate, SpeedGateConfig
    from rollability_ros.core.rig.valve import ValveConfig, ValveStatus
    from rollability_ros.core.sim import LaunchResult

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

    def close(self) -> None:
        """Stop what the ports started (keep-alive, valve shut down); idempotent."""
