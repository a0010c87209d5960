"""The two :class:`~rollability_ros.core.rig.launch_backend.LaunchBackend` implementations and their factory,
without ROS: goal checks, phases, operator answers, IMU outcome, speed.

:func:`make_launch_backend` builds the backend ``rig.backend`` names (:class:`SimulatedLaunch` or
:class:`PhysicalLaunch`) on the caller's :class:`~rollability_ros.core.rig.launch_backend.RigPorts`; callers
(the ``rig`` node, the in-process campaign) use only the contract.

:class:`PhysicalLaunch` runs one physical launch against ports the caller provides (the ``rig`` node wires them to
ROS services and topics; tests and the in-process CLI wire them to a :class:`~rollability_ros.core.rig.valve.
ValveController` and a simulated speed gate):

- ``valve``: ``arm() -> (ok, reason)``, ``fire(pulse_ms) -> (ok, reason)``, ``disarm() -> (ok, reason)`` and
  ``status()`` (anything with ``armed`` and ``fault``), e.g. a ``ValveController``;
- ``speed_gate``: ``arm(target_mps)``, ``read_travel_time(timeout_s)`` (:mod:`rollability_ros.core.rig.speed_gate`);
- ``operator``: an :class:`OperatorChannel`, answered from another thread (the ``record_outcome`` and
  ``rig/confirm`` services) or from inside ``on_phase`` (a terminal);
- ``imu``: an :class:`ImuOutcome` fed with samples, when ``outcome_source`` is ``imu``.

Sequence: confirm the regulator (phase ``waiting_for_operator``) at each change of speed, and again once
``confirmation_valid_s`` passed since the last confirmation or after a launch aborted, arm (``armed``), count down
``countdown_s`` so people stand clear, fire one ``launch_pulse_ms`` pulse (``fired``), read the speed gate
(``in_flight``), disarm, wait for the chassis to settle (``settling``), classify (``classifying``: the IMU with an
operator override window, or the operator). A fire that is refused or cut (e-stop, watchdog) aborts the launch
with :class:`LaunchAborted`; the rig never disarms a faulted valve, because disarming acknowledges the fault and
that is the operator's decision.

:func:`simulated_outcome` turns the launch twin's result into an outcome for the ``sim`` backend.
"""
import importlib
import math
import os
import time
import types
import typing
import zlib

from rollability_ros.core import config
from rollability_ros.core.imu import ImuOutcomeConfig, LaunchMotion
from rollability_ros.core.records import (INVALID_LAUNCH, NO_SEED, NOT_MEASURED, UNKNOWN_ORIENTATION,
                                          LaunchCondition, LaunchOutcome, check_twin_seed)
from rollability_ros.core.rig.launch_backend import (LAUNCH_BACKENDS, LaunchAborted, LaunchBackend, OperatorChannel,
                                                     OperatorOutcome, PhaseCallback, PoseCallback, RigPorts,
                                                     RigSettings, describe_answer, no_phase, not_cancelled)
from rollability_ros.core.rig.outcome_sources import ImuOutcome, simulated_continuous_outcomes
from rollability_ros.core.rig.speed_gate import SpeedGateConfig, SpeedMeasurement
from rollability_ros.core.rig.valve_contract import ValveConfig

if typing.TYPE_CHECKING:  # annotations only: the twin is imported when a simulated launch runs
    from rollability_ros.core.sim import LaunchResult, LaunchTwinSettings

#: Feedback phases of the Launch action, in order.
PHASES = ("waiting_for_operator", "armed", "fired", "in_flight", "settling", "classifying")
#: Start of the ``classifying`` feedback detail while the rig waits for the operator's outcome.
ASK_OUTCOME = "record the outcome"
#: Start of the ``waiting_for_operator`` detail while the rig waits for the regulator confirmation.
ASK_REGULATOR = "set the regulator"
#: Start of the feedback detail that closes a question: the answer that counted (from whichever place gave it).
ANSWERED = "answered: "
#: Start of a physical outcome's note part that names where its travel time (and so its speed) came from.
TRAVEL_TIME_NOTE = "travel time: "


def check_goal(run_id: str, trial_id: str, condition: LaunchCondition,
               configurations: typing.Sequence[str]) -> str:
    """Refuse a launch goal that cannot run; returns the reason ("" when acceptable).

    Parameters
    ----------
    run_id, trial_id : str
        Must be non-empty (the outcome is stored under them).
    condition : LaunchCondition
        Checked with :meth:`LaunchCondition.validate` (NaN, negative height, ...).
    configurations : sequence of str
        Configuration ids this rig knows.
    """
    if not run_id or not trial_id:
        return "run_id and trial_id must be non-empty"
    try:
        condition.validate()
    except ValueError as exc:
        return f"bad condition: {exc}"
    if condition.configuration not in configurations:
        return f"unknown configuration {condition.configuration!r} (known: {', '.join(configurations)})"
    return ""


class PhysicalLaunch(LaunchBackend):
    """The ``physical`` :class:`LaunchBackend`: launches on the rig through its ports (see the module docstring).

    Parameters
    ----------
    settings : RigSettings
    valve, speed_gate, operator, imu
        The ports; ``imu`` may be None when ``settings.outcome_source == "operator"``.
    speed_config : SpeedGateConfig
        Run length, tolerance and gate timeout.
    launch_pulse_ms : int
        Valve pulse per launch, ms.
    regulator : RegulatorConfig
        Pressure per target speed; the operator confirms it at each change of speed, after
        ``settings.confirmation_valid_s`` and after an aborted launch.
    """

    def __init__(self, settings, valve, speed_gate, speed_config, launch_pulse_ms, regulator, operator, imu=None):
        if settings.outcome_source == "imu" and imu is None:
            raise ValueError("outcome_source 'imu' needs an ImuOutcome")
        self.settings = settings
        self.valve = valve
        self.speed_gate = speed_gate
        self.speed_config = speed_config
        self.launch_pulse_ms = launch_pulse_ms
        self.regulator = regulator
        self.operator = operator
        self.imu = imu
        self._confirmed = None   # (psi, time.monotonic() of the confirmation) or None
        self._ports = None

    name = "physical"
    attended = True
    authenticated = True

    @classmethod
    def from_ports(cls, settings: "RigSettings", speed_config: SpeedGateConfig, valve_config: ValveConfig,
                   imu_config: ImuOutcomeConfig, ports: RigPorts) -> "PhysicalLaunch":
        """Open the valve, speed gate and (for ``outcome_source`` imu) IMU ports; :meth:`close` closes them."""
        if settings.countdown_s >= valve_config.arm_timeout_s:
            raise ValueError(f"rig.countdown_s ({settings.countdown_s:g} s) must be shorter than valve.arm_timeout_s "
                             f"({valve_config.arm_timeout_s:g} s): the valve would disarm before the fire")
        imu = None
        try:
            if settings.outcome_source == "imu":
                imu = ImuOutcome(imu_config)
                ports.open_imu(imu)
            backend = cls(settings, ports.open_valve(valve_config), ports.open_speed_gate(speed_config),
                          speed_config, valve_config.launch_pulse_ms, valve_config.regulator, OperatorChannel(), imu)
        except BaseException:
            ports.close()
            raise
        backend._ports = ports
        return backend

    def describe(self) -> str:
        """One line for the start-up log: the backend, where outcomes and travel times come from."""
        gate = self.speed_gate
        return (f"backend physical, outcome from {self.settings.outcome_source}, travel time from {gate.source}"
                + ("" if gate.measures else ": WARNING, not a measurement; physical records store the speed as not "
                                            "measured (set speed_gate.backend gpio or operator)"))

    def close(self) -> None:
        """Stop waiting for the operator and close the ports this backend opened (keep-alive, valve)."""
        self.operator.close()
        if self._ports is not None:
            self._ports.close()

    def check(self, run_id: str, trial_id: str, condition: LaunchCondition) -> str:
        """:func:`check_goal` plus a configured regulator pressure for the speed; returns the reason or ""."""
        reason = check_goal(run_id, trial_id, condition, self.settings.configurations)
        if reason:
            return reason
        try:
            self.regulator.pressure_psi(condition.speed_mps)
        except ValueError as exc:
            return str(exc)
        return ""

    def confirmation_holds(self, pressure_psi: float) -> bool:
        """True when the operator confirmed ``pressure_psi`` less than ``confirmation_valid_s`` ago and no launch
        aborted since."""
        if self._confirmed is None:
            return False
        psi, confirmed_at = self._confirmed
        return psi == pressure_psi and time.monotonic() - confirmed_at < self.settings.confirmation_valid_s

    def _ask(self, kind, trial_id, phase, detail, on_phase, cancelled):
        """Announce a question (feedback ``phase``, ``detail``), repeated every ``question_repeat_s`` until the
        operator answers: a feedback sent before a client's subscription matched is lost, not queued."""
        self.operator.open(kind, trial_id)
        deadline = time.monotonic() + self.settings.operator_timeout_s
        answer = None
        try:
            while answer is None and not cancelled():
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
                on_phase(phase, detail)
                answer = self.operator.wait(min(self.settings.question_repeat_s, remaining), cancelled)
        finally:
            self.operator.close()
        if answer is None:
            raise LaunchAborted("cancelled while waiting for the operator" if cancelled()
                                else f"no operator answer within {self.settings.operator_timeout_s:g} s ({detail})")
        # every place that shows the question learns at once that it was answered, and how
        on_phase(phase, f"{ANSWERED}{describe_answer(kind, answer)}")
        return answer

    def _disarm_unless_faulted(self):
        status = self.valve.status()
        if status.armed and not status.fault:
            self.valve.disarm()

    def launch(self, run_id: str, trial_id: str, condition: LaunchCondition, on_phase: PhaseCallback = no_phase,
               *, on_pose: typing.Optional[PoseCallback] = None,
               cancelled: typing.Callable[[], bool] = not_cancelled) -> LaunchOutcome:
        """Run one launch and return its :class:`LaunchOutcome` (``backend="physical"``).

        ``on_phase(phase, detail)`` reports progress; ``cancelled()`` aborts at the next wait; ``on_pose`` is not
        called (the rig has no pose source). Raises ``ValueError`` for a goal :meth:`check` refuses and
        :class:`LaunchAborted` when no outcome was obtained.
        """
        reason = self.check(run_id, trial_id, condition)
        if reason:
            raise ValueError(reason)
        pressure_psi = self.regulator.pressure_psi(condition.speed_mps)
        if not self.confirmation_holds(pressure_psi):
            self._confirmed = None
            self._ask("confirm", trial_id, "waiting_for_operator",
                      f"{ASK_REGULATOR} to {pressure_psi:g} psi for {condition.speed_mps:g} m/s, then confirm",
                      on_phase, cancelled)
            self._confirmed = (pressure_psi, time.monotonic())
        try:
            travel_time_s = self._fire(condition, on_phase, cancelled)
            on_phase("settling", "waiting for the chassis to come to rest")
            operator, reading = self._classify(trial_id, on_phase, cancelled)
        except BaseException:
            self._confirmed = None   # after an e-stop, a fault or a cancel the operator confirms the pressure again
            raise
        # what the IMU saw, even when it never settled and the operator answered (its peak, then, without a tilt)
        motion = self.imu.motion() if self.imu is not None else LaunchMotion()
        travel_time_s, source = self.travel_time_source(travel_time_s, operator)
        speed = self.speed_config.measure(condition.speed_mps, travel_time_s)
        notes = [source, speed_note(speed, condition.speed_mps, self.speed_config.tolerance_fraction)]
        if operator is not None and reading is not None and operator.upright != reading.upright:
            notes.append(f"operator overrode the IMU ({'upright' if reading.upright else 'not upright'}, "
                         f"tilt {reading.tilt_deg:.1f} deg)")
        if operator is not None and operator.note:
            notes.append(operator.note)
        return LaunchOutcome(
            run_id=run_id, trial_id=trial_id, condition=condition, backend="physical",
            upright=operator.upright if operator is not None else reading.upright,
            travel_time_s=speed.travel_time_s, measured_speed_mps=speed.measured_speed_mps,
            speed_out_of_tolerance=speed.speed_out_of_tolerance,
            final_orientation=tuple(reading.orientation) if reading is not None else UNKNOWN_ORIENTATION,
            classified_by="operator" if operator is not None else "imu", note="; ".join(filter(None, notes)),
            stamp_s=time.time(), **motion.outcome_fields(),
            rest_distance_m=operator.rest_distance_m if operator is not None else NOT_MEASURED)

    def travel_time_source(self, gate_s: float, operator: typing.Optional[OperatorOutcome]
                           ) -> typing.Tuple[float, str]:
        """The travel time a physical record stores (s, NaN when not measured) and the note naming its source:
        the gate's when it measures (:attr:`SpeedGate.measures`), else the operator's typed one, else none. A
        simulated gate's made-up time is never stored on a physical record."""
        gate = self.speed_gate
        if not math.isnan(gate_s) and gate.measures:
            return gate_s, f"{TRAVEL_TIME_NOTE}{gate.source}"
        if operator is not None and not math.isnan(operator.travel_time_s):
            return operator.travel_time_s, f"{TRAVEL_TIME_NOTE}typed by the operator (rig outcome --travel-time-s)"
        why = f" ({gate.source} makes times up: not stored)" if not gate.measures else ""
        return NOT_MEASURED, f"{TRAVEL_TIME_NOTE}not measured{why}"

    def _fire(self, condition, on_phase, cancelled):
        """Arm, count down, fire, read the speed gate, disarm; returns the gate's travel time (s, NaN if none)."""
        ok, reason = self.valve.arm()
        if not ok:
            raise LaunchAborted(f"valve refused to arm: {reason}")
        try:
            countdown_s = self.settings.countdown_s
            on_phase("armed", countdown_text(countdown_s))
            self.speed_gate.arm(condition.speed_mps)
            if self.imu is not None:
                self.imu.reset()
            # the countdown always runs out: a fault reported on the valve's state topic (which any participant can
            # publish) never shortens it; if the fault is real, the valve refuses the fire below with its reason.
            # Each whole second left is announced, so every place that shows the launch shows the countdown
            deadline = time.monotonic() + countdown_s
            shown = math.ceil(countdown_s)
            while time.monotonic() < deadline:
                if cancelled():
                    raise LaunchAborted("cancelled before firing")
                left = math.ceil(deadline - time.monotonic())
                if 1 <= left < shown:
                    shown = left
                    on_phase("armed", countdown_text(left))
                time.sleep(min(0.02, max(0.0, deadline - time.monotonic())))
            ok, reason = self.valve.fire(self.launch_pulse_ms)
            if not ok:
                raise LaunchAborted(f"valve did not fire: {reason}")
            on_phase("fired", f"valve pulsed {self.launch_pulse_ms} ms")
            on_phase("in_flight", "timing the run over the light gates")
            return self.speed_gate.read_travel_time(self.speed_config.timeout_s)
        finally:
            self._disarm_unless_faulted()

    def _classify(self, trial_id, on_phase, cancelled):
        """Return ``(operator outcome or None, IMU reading or None)``; at least one is not None."""
        if self.settings.outcome_source == "imu":
            # operator answers are accepted from now on: an override may come at any time before the verdict
            self.operator.open("outcome", trial_id)
            try:
                reading = self.imu.wait_settled(self.imu.config.settle_timeout_s, cancelled)
                if cancelled():
                    raise LaunchAborted("cancelled while the chassis settled")
                if reading is not None:
                    on_phase("classifying", f"IMU: {'upright' if reading.upright else 'not upright'} (tilt "
                                            f"{reading.tilt_deg:.1f} deg); operator may override within "
                                            f"{self.settings.imu_override_s:g} s")
                    return self.operator.wait(self.settings.imu_override_s, cancelled), reading
            finally:
                self.operator.close()
        detail = f"{ASK_OUTCOME} of {trial_id}: upright or not" + (
            " (the IMU did not see the chassis settle)" if self.settings.outcome_source == "imu" else "")
        return self._ask("outcome", trial_id, "classifying", detail, on_phase, cancelled), None


class SimulatedLaunch(LaunchBackend):
    """The ``sim`` :class:`LaunchBackend`: launches on the launch twin (``rollability_ros.core.sim.launch``, through the
    ``rollability_ros.core.sim`` face),
    imported at the first launch (or :meth:`load`) so the physical rig runs without pybullet installed.

    Parameters
    ----------
    settings : RigSettings
        ``seed`` is mixed with each trial id (:func:`launch_seed`), so a trial's outcome is reproducible;
        ``twin_config`` lists the twin's parameter files (shipped names or paths).
    speed_config : SpeedGateConfig
        Tolerance of the speed check on the twin's travel time.
    twin_settings : LaunchTwinSettings
        The twin of ``twin_config``'s files, parsed by the caller (:meth:`RigPorts.open_twin`).
    """

    name = "sim"
    attended = False

    def __init__(self, settings: "RigSettings", speed_config: SpeedGateConfig,
                 twin_settings: "LaunchTwinSettings") -> None:
        self.settings = settings
        self.speed_config = speed_config
        self.operator = OperatorChannel()   # never opened: the twin asks nothing, so every answer is refused
        self._twin: typing.Optional[types.ModuleType] = None
        self._twin_settings = twin_settings

    @classmethod
    def from_ports(cls, settings: "RigSettings", speed_config: SpeedGateConfig, valve_config: ValveConfig,
                   imu_config: ImuOutcomeConfig, ports: RigPorts) -> "SimulatedLaunch":
        """A twin backend on the twin ``ports`` reads from ``rig.twin_config`` now (fails early on a bad file, and
        on a launcher that does not fit the robot); opens no hardware port."""
        backend = cls(settings, speed_config, ports.open_twin(settings.twin_config))
        backend.load()
        return backend

    def load(self) -> types.ModuleType:
        """Import the twin and check its launcher against the robot, and its designs file's print against the
        robot's print, now (a node does it at start-up to fail early: ``ValueError`` naming the setting)."""
        if self._twin is None:
            twin = importlib.import_module("rollability_ros.core.sim")
            twin.check_launcher(self._twin_settings)
            designs_file = self._twin_settings.twin.designs.designs_file
            if designs_file and os.path.isfile(designs_file):   # a missing one: every goal names it (check)
                from rollability_ros.core.profile import check_printed_with

                check_printed_with(designs_file, self._twin_settings.print_instructions())
            self._twin = twin
        return self._twin

    def check(self, run_id: str, trial_id: str, condition: LaunchCondition) -> str:
        """:func:`check_goal` against ``rig.configurations``, then whether the twin has a profile for the
        configuration (its ``launch_twin.designs``); returns the reason or ""."""
        reason = check_goal(run_id, trial_id, condition, self.settings.configurations)
        if reason:
            return reason
        from rollability_ros.core.profile import configuration_ids

        self.load()
        try:
            known = configuration_ids(self._twin_settings.twin.designs)
        except (ValueError, OSError) as exc:   # an unreadable designs file: every goal names it
            return f"the launch twin's designs cannot be read: {exc}"
        if condition.configuration not in known:
            return (f"unknown configuration {condition.configuration!r}: the launch twin knows {', '.join(known)} "
                    "(set launch_twin.designs.designs_file or mesh_labels / mesh_files)")
        return ""

    def design_sources(self) -> dict:
        """The twin's ``launch_twin.designs`` (relative paths are from the working directory), made absolute."""
        self.load()
        designs = self._twin_settings.twin.designs
        return {"designs_file": os.path.abspath(designs.designs_file) if designs.designs_file else "",
                "mesh_files": {label: os.path.abspath(path) for label, path in designs.meshes().items()}}

    def twin_config(self) -> typing.List[str]:
        """``rig.twin_config``: the files this twin was read from."""
        return list(self.settings.twin_config)

    def launch(self, run_id: str, trial_id: str, condition: LaunchCondition, on_phase: PhaseCallback = no_phase,
               *, on_pose: typing.Optional[PoseCallback] = None,
               cancelled: typing.Callable[[], bool] = not_cancelled) -> LaunchOutcome:
        """Simulate one launch and return its :class:`LaunchOutcome` (``backend="sim"``).

        ``on_pose(t_s, position_m, orientation_xyzw)`` receives the chassis pose (simulated s from the push);
        ``cancelled()`` is checked before the launch (a simulated launch takes a fraction of a second).
        """
        reason = self.check(run_id, trial_id, condition)
        if reason:
            raise ValueError(reason)
        if cancelled():
            raise LaunchAborted("cancelled before the launch")
        twin = self.load()
        result = twin.simulate_valid_launch(condition, self._twin_settings, launch_seed(self.settings.seed, trial_id),
                                            on_phase=lambda phase: on_phase(phase, "launch twin"), on_pose=on_pose)
        return simulated_outcome(run_id, trial_id, condition, result, self.speed_config)

    @classmethod
    def resimulate_refusal(cls) -> str:
        """None: a simulated launch is re-run from its seed."""
        return ""

    def resimulate(self, condition: LaunchCondition, seed: int) -> "LaunchResult":
        """The launch twin result of one launch of ``condition`` with twin ``seed``: given a stored outcome's
        condition and ``seed`` (and these twin settings), the launch that outcome was classified from, again."""
        return self.load().simulate_launch(condition, self._twin_settings, check_twin_seed(seed))


def launch_backend_class(name: str) -> typing.Type[LaunchBackend]:
    """The :class:`LaunchBackend` class for a ``rig.backend`` value; ``ValueError`` names the known ones."""
    return LAUNCH_BACKENDS.get(name)


def make_launch_backend(settings: RigSettings, speed_config: SpeedGateConfig, valve_config: ValveConfig,
                        imu_config: ImuOutcomeConfig, ports: RigPorts) -> LaunchBackend:
    """The backend ``settings.backend`` names, opened on ``ports`` (the only place that looks at the name).

    Raises ``ValueError`` for unusable settings (a bad twin configuration, an IMU the caller cannot provide) and
    ``ImportError`` when the simulated backend's dependencies are missing.
    """
    config.check_settings(settings, "rig")
    return launch_backend_class(settings.backend).from_ports(settings, speed_config, valve_config, imu_config, ports)


def countdown_text(left_s: float) -> str:
    """The ``armed`` feedback detail with ``left_s`` seconds before the fire, and how to stop it."""
    return (f"valve armed; firing in {left_s:g} s, stand clear (stop: e in `rollability rig console`, or "
            "`rollability rig estop`; cancel: c in the console)")


def speed_note(speed: SpeedMeasurement, target_mps: float, tolerance_fraction: float) -> str:
    """The outcome note for a flagged :class:`~rollability_ros.core.rig.speed_gate.SpeedMeasurement` ("" if not)."""
    if not speed.speed_out_of_tolerance:
        return ""
    return (f"speed {speed.measured_speed_mps:.3f} m/s is more than {tolerance_fraction:.0%} off the target "
            f"{target_mps:g} m/s")


def launch_seed(base_seed: int, trial_id: str) -> int:
    """The seed of a simulated launch, reproducible in every process (unlike ``hash``): ``base_seed`` mixed with
    the trial id by CRC-32. (Not :func:`rollability_ros.core.sim.evaluation.trial_seed`, which numbers the trials
    of one profile evaluation; each keeps its algorithm so stored results stay reproducible.)"""
    return (zlib.crc32(trial_id.encode("utf-8")) ^ (base_seed & 0xFFFFFFFF)) & 0x7FFFFFFF


def simulated_outcome(run_id: str, trial_id: str, condition: LaunchCondition, result: "LaunchResult",
                      speed_config: SpeedGateConfig) -> LaunchOutcome:
    """The :class:`LaunchOutcome` of a launch twin result (``upright``, ``final_orientation_xyzw``,
    ``travel_time_s`` and the continuous outcomes, :func:`simulated_continuous_outcomes`), with the speed flagged
    against ``speed_config``'s tolerance; an invalid launch (``invalid_reason``) is stored not upright with a note
    starting with :data:`INVALID_LAUNCH`."""
    travel_time_s = float(getattr(result, "travel_time_s", NOT_MEASURED))
    if not travel_time_s > 0:
        travel_time_s = NOT_MEASURED
    speed = speed_config.measure(condition.speed_mps, travel_time_s)
    note = speed_note(speed, condition.speed_mps, speed_config.tolerance_fraction)
    invalid_reason = getattr(result, "invalid_reason", "")
    if invalid_reason:
        attempts = getattr(result, "attempts", 1)
        note = f"{INVALID_LAUNCH}{invalid_reason} ({attempts} attempt{'s' if attempts != 1 else ''})"
    return LaunchOutcome(
        run_id=run_id, trial_id=trial_id, condition=condition, backend="sim",
        upright=bool(result.upright) and not invalid_reason,
        travel_time_s=speed.travel_time_s, measured_speed_mps=speed.measured_speed_mps,
        speed_out_of_tolerance=speed.speed_out_of_tolerance,
        final_orientation=tuple(float(v) for v in result.final_orientation_xyzw), classified_by="sim", note=note,
        stamp_s=time.time(), seed=int(getattr(result, "seed", NO_SEED)), **simulated_continuous_outcomes(result))
