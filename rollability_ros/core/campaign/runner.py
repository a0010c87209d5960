"""The campaign loop: for each remaining trial, tell the operator what to change, launch, and count it once stored.

The loop is the same for every route; the caller passes how a trial is launched and how its outcome is known to
be stored:

- in-process (``rollability campaign`` without ROS): ``launch`` runs the rig sequence or the launch twin here and
  ``confirm_stored`` writes the durable store itself (:func:`store_writer`): the only writer on that route;
- through the node graph: ``launch`` sends a Launch goal to the ``rig`` node, whose outcome reaches the
  ``outcome_logger`` (the only writer on that route), and ``confirm_stored`` waits for the logger's
  acknowledgement over ROS (:class:`StoreAcknowledgements`, fed from the ``outcomes_stored`` topic), so a trial
  counts as done only once it is on disk, and the logger may run elsewhere (another computer for simulated
  outcomes; physical ones are verified with the valve's session key, on the rig computer).

A trial that fails (valve fault, operator timeout, outcome never stored) stops the campaign: nothing was stored
for it, so a resumed run (``remaining_trials``) launches it again, and every trial stored before stays stored.
"""
import dataclasses
import math
import os
import threading
import time
import typing

from rollability_ros.core.campaign.plan import CampaignProgress, PlannedTrial, changes_between
from rollability_ros.core.config import as_list, check_given_files, edge_parse, load_parameters, settings_from_sections
from rollability_ros.core.imu import ImuOutcomeConfig
from rollability_ros.core.rig import (ASK_OUTCOME, ASK_REGULATOR, LAUNCH_BACKENDS, ImuOutcome, LaunchAborted,
                                      LaunchBackend, RigPorts, RigSettings, SpeedGate, SpeedGateConfig, ValveConfig,
                                      ValveController, launched_twin, make_controller, make_launch_backend,
                                      make_speed_gate, merge_twin, parse_outcome_answer)
from rollability_ros.core.records import INVALID_LAUNCH, LaunchOutcome
from rollability_ros.core.store import Store

if typing.TYPE_CHECKING:   # annotations only: the command parses the twin (the sim backend needs it)
    from rollability_ros.core.sim import LaunchTwinSettings


#: A campaign session stops once at least :data:`INVALID_STOP_MIN_LAUNCHES` launches were made and more than this
#: fraction of them were invalid (did not leave the ledge, landed off the foam): the rig is not launching the robot.
INVALID_STOP_FRACTION = 0.5
INVALID_STOP_MIN_LAUNCHES = 4
#: Words of an invalid launch's note -> the setting to change.
INVALID_LAUNCH_FIXES = (
    ("did not leave the ledge", "the launcher does not get the robot over the edge: set launch_twin.plate.height_m, "
                                "width_m and clearance_m to 0 (derived from the robot); a robot that coasts to a "
                                "stop after the cylinder's stroke needs launch_twin.launcher.model push_through (then "
                                "check launch_twin.plate.max_force_n)"),
    ("outside the foam", "the robot lands beyond the foam: enlarge launch_twin.foam.length_m / width_m"),
    ("never landed", "the robot never reaches the foam: check launch_twin.foam and the trial time cap "
                     "(trial.time_cap_s)"),
)


def invalid_launch_stop(notes: typing.Sequence[str]) -> str:
    """Why a campaign must stop for invalid launches ("" if it need not): ``notes`` are the notes of this session's
    launches, an invalid one starting with :data:`~rollability_ros.core.records.INVALID_LAUNCH`."""
    invalid = [note[len(INVALID_LAUNCH):] for note in notes if note.startswith(INVALID_LAUNCH)]
    if len(notes) < INVALID_STOP_MIN_LAUNCHES or len(invalid) <= INVALID_STOP_FRACTION * len(notes):
        return ""
    common = max(set(invalid), key=invalid.count)
    fix = next((text for words, text in INVALID_LAUNCH_FIXES if words in common), "check the rig's set-up")
    return (f"{len(invalid)} of {len(notes)} launches were invalid (more than {INVALID_STOP_FRACTION:.0%}; most "
            f"often: {common}): {fix}")


class NotStored(RuntimeError):
    """A launch outcome did not reach the durable store in time."""


@dataclasses.dataclass(frozen=True)
class CampaignReport:
    """How a campaign session ended: trials stored this session, totals, and why it stopped early ("" if not);
    ``failed``: stopped because the rig does not launch this robot (:func:`invalid_launch_stop`)."""

    stored_now: int
    done: int
    total: int
    stopped_reason: str = ""
    failed: bool = False
    advice: str = ""          # what the operator must do before resuming (e.g. acknowledge a valve e-stop)
    decided: str = ""         # why the campaign's question was answered before its last trial (``stop_rule``)

    @property
    def complete(self) -> bool:
        """True when every planned trial is stored, or the campaign's question was decided (``decided``)."""
        return self.done == self.total or bool(self.decided)


def store_writer(store: Store) -> typing.Callable[[LaunchOutcome], None]:
    """``confirm_stored`` for the in-process route: write the outcome (a duplicate counts as stored)."""
    def confirm_stored(outcome: LaunchOutcome) -> None:
        store.add_launch_outcome(outcome)
    return confirm_stored


def record_campaign_run(store: Store, run_id: str, backend: str, design_sources: dict,
                        twin_config: typing.Sequence[str] = ()) -> None:
    """Describe campaign ``run_id`` in ``store``'s run info: its backend, where its profiles come from
    (:meth:`~rollability_ros.core.rig.launch_backend.LaunchBackend.design_sources`), which is where a report
    looks for the run's design meshes, and its twin (``twin_config``, the files ``rig.twin_config`` lists, none
    for a rig that simulates nothing: :func:`~rollability_ros.core.campaign.twin_record.launched_twin`), which a
    re-simulation loads; keeps what an earlier session recorded, and marks a twin that differs from an earlier
    session's (:func:`~rollability_ros.core.campaign.twin_record.merge_twin`)."""
    described = store.run_info(run_id)
    info = dict(described["info"]) if described else {}
    info["backend"] = backend
    if design_sources:
        info["designs"] = design_sources
    merge_twin(info, launched_twin(backend, twin_config, design_sources), os.path.dirname(os.path.abspath(store.path)))
    store.set_run_info(run_id, described["kind"] if described else "campaign", info)


class StoreAcknowledgements:
    """``confirm_stored`` for the node-graph route: waits for the outcome_logger's acknowledgement of a trial.

    The caller feeds :meth:`acknowledge` (the campaign_runner node, from the logger's ``outcomes_stored`` topic);
    a call for an outcome returns once its (run id, trial id) was acknowledged, turning ``spin_once`` meanwhile.

    Parameters
    ----------
    spin_once : callable
        Processes pending messages for a short while (an executor's ``spin_once``); called while waiting.
    timeout_s : float
        Longest wait for a trial's acknowledgement after its launch ended, s.
    clock : callable
        Monotonic time, s.
    """

    def __init__(self, spin_once: typing.Callable[[], None], timeout_s: float = 10.0,
                 clock: typing.Callable[[], float] = time.monotonic):
        self._spin_once = spin_once
        self.timeout_s = timeout_s
        self._clock = clock
        self._lock = threading.Lock()
        self._acknowledged: set = set()

    def acknowledge(self, run_id: str, trial_id: str) -> None:
        """Record that the logger has stored (``run_id``, ``trial_id``)."""
        with self._lock:
            self._acknowledged.add((run_id, trial_id))

    def is_acknowledged(self, run_id: str, trial_id: str) -> bool:
        """True once (``run_id``, ``trial_id``) was acknowledged."""
        with self._lock:
            return (run_id, trial_id) in self._acknowledged

    def __call__(self, outcome: LaunchOutcome) -> None:
        deadline = self._clock() + self.timeout_s
        while not self.is_acknowledged(outcome.run_id, outcome.trial_id):
            if self._clock() > deadline:
                raise NotStored(f"no outcome_logger acknowledged storing {outcome.run_id}/{outcome.trial_id} within "
                                f"{self.timeout_s:g} s: is one running in this ROS domain?")
            self._spin_once()


def _operator_ready(ask, say, previous, trial, pressure_psi_by_speed):
    """Tell the operator what to change before ``trial``; return False if the operator stops the campaign."""
    for instruction in changes_between(previous, trial, pressure_psi_by_speed):
        say(f"  - {instruction}")
    answer = ask(f"place the chassis for {trial.trial_id} on the launcher; Enter to launch, q to stop: ")
    return answer.strip().lower() not in ("q", "quit", "stop")


def run_campaign(plan: typing.Sequence[PlannedTrial], run_id: str, stored_ids: typing.Collection[str],
                 launch: typing.Callable[[PlannedTrial], LaunchOutcome],
                 confirm_stored: typing.Callable[[LaunchOutcome], None],
                 ask: typing.Optional[typing.Callable[[str], str]] = None, say: typing.Callable[[str], None] = print,
                 pressure_psi_by_speed: typing.Optional[typing.Mapping[float, float]] = None,
                 clock: typing.Callable[[], float] = time.monotonic,
                 on_progress: typing.Optional[typing.Callable[[CampaignProgress], None]] = None,
                 stop_rule: typing.Optional[typing.Callable[[LaunchOutcome], str]] = None,
                 next_trial: typing.Optional[typing.Callable[[typing.Optional[LaunchOutcome]],
                                                             typing.Optional[PlannedTrial]]] = None) -> CampaignReport:
    """Run the trials of ``plan`` not yet stored, in plan order; returns a :class:`CampaignReport`.

    Parameters
    ----------
    plan : list of PlannedTrial
        :func:`~rollability_ros.core.campaign.plan.plan_trials` of the campaign.
    run_id : str
        Store key of the campaign.
    stored_ids : set of str
        Trial ids already stored for ``run_id`` (resume); they are skipped.
    launch : callable
        ``launch(trial) -> LaunchOutcome``; raises :class:`LaunchAborted` (or ``ValueError`` for a refused goal).
    confirm_stored : callable
        ``confirm_stored(outcome)`` returns once the outcome is durably stored; raises :class:`NotStored`.
    ask : callable, optional
        ``ask(prompt) -> str`` (the terminal's ``input``): attended runs (physical) tell the operator what to change
        and wait for Enter before each trial. None runs unattended (sim).
    say : callable
        Prints one line (instructions, progress).
    pressure_psi_by_speed : dict, optional
        ``{speed m/s: psi}`` to name the regulator pressure in the instructions.
    on_progress : callable, optional
        Called with the :class:`~rollability_ros.core.campaign.plan.CampaignProgress` at the start and after each
        stored trial (the graph campaign publishes it for ``bringup``'s progress line).
    stop_rule, next_trial : callable, optional
        ``stop_rule(outcome) -> str``: non-empty ends the campaign as decided (complete; ``sequential.
        comparison_stop_rule``). ``next_trial(last outcome or None) -> PlannedTrial or None``: an adaptive plan of
        up to ``len(plan)`` trials, each chosen once the previous is stored (``adaptive.adaptive_next_trial``).
    """
    last: typing.List[typing.Optional[LaunchOutcome]] = [None]
    todo, progress = _trials_to_run(plan, stored_ids, next_trial, last)
    say(f"campaign {run_id}: {progress.text()}")
    if on_progress is not None:
        on_progress(progress)
    previous, stored_now, notes = None, 0, []

    def report(reason: str, failed: bool = False, decided: str = "") -> CampaignReport:
        return CampaignReport(stored_now, progress.done, progress.total, reason, failed, decided=decided)

    for trial in todo:
        try:
            ready = ask is None or _operator_ready(ask, say, previous, trial, pressure_psi_by_speed)
        except EOFError:
            ready = False
        if not ready:
            return report("stopped by the operator")
        started = clock()
        try:
            outcome = _launch_and_store(trial, run_id, launch, confirm_stored)
        except (LaunchAborted, NotStored, ValueError) as exc:
            say(f"trial {trial.trial_id} not done: {exc}")
            return report(f"{trial.trial_id}: {exc}")
        except EOFError:
            return report(f"{trial.trial_id}: the operator's input closed")
        stored_now += 1
        progress.trial_done(clock() - started)
        if on_progress is not None:
            on_progress(progress)
        verdict = outcome.note if not outcome.valid else ("upright" if outcome.upright else "NOT upright")
        say(f"{trial.trial_id}: {verdict}"
            f"{' (speed flagged)' if outcome.speed_out_of_tolerance else ''}; {progress.text()}")
        previous = trial
        last[0] = outcome
        notes.append(outcome.note)
        invalid = invalid_launch_stop(notes)
        if invalid:
            return report(invalid, failed=True)
        if stop_rule is not None and (decided := stop_rule(outcome)):
            return report("", decided=decided)
    return report("")


def _trials_to_run(plan: typing.Sequence[PlannedTrial], stored_ids: typing.Collection[str],
                   next_trial: typing.Optional[typing.Callable[[typing.Optional[LaunchOutcome]],
                                                               typing.Optional[PlannedTrial]]],
                   last: typing.List[typing.Optional[LaunchOutcome]]
                   ) -> typing.Tuple[typing.Iterable[PlannedTrial], CampaignProgress]:
    """The trials a session runs and its progress: the plan's trials not stored yet, or (``next_trial``) up to
    ``len(plan)`` trials each chosen from the last stored outcome (``last[0]``, updated by the loop)."""
    if next_trial is None:
        remaining = [trial for trial in plan if trial.trial_id not in stored_ids]
        return remaining, CampaignProgress(len(plan), len(plan) - len(remaining))
    return _chosen_trials(lambda: next_trial(last[0]), len(plan)), CampaignProgress(len(plan), 0)


def _launch_and_store(trial: PlannedTrial, run_id: str, launch: typing.Callable[[PlannedTrial], LaunchOutcome],
                      confirm_stored: typing.Callable[[LaunchOutcome], None]) -> LaunchOutcome:
    """Launch ``trial`` and return its outcome once stored; :class:`LaunchAborted` when the rig answered another."""
    outcome = launch(trial)
    if (outcome.run_id, outcome.trial_id) != (run_id, trial.trial_id):
        raise LaunchAborted(f"the rig answered {outcome.run_id}/{outcome.trial_id} for {run_id}/{trial.trial_id}")
    confirm_stored(outcome)
    return outcome


def _chosen_trials(choose: typing.Callable[[], typing.Optional[PlannedTrial]],
                   budget: int) -> typing.Iterator[PlannedTrial]:
    """At most ``budget`` trials, each chosen by ``choose()`` when the loop asks for it (None ends them)."""
    for _ in range(budget):
        trial = choose()
        if trial is None:
            return
        yield trial


@dataclasses.dataclass
class RunnerSettings:
    """``runner.*``: how the campaign_runner node runs the campaign and waits for the rig and the logger."""

    backend: str = dataclasses.field(default="sim", metadata={
        "description": "which rig backend the campaign expects (sim or physical); the rig must match"})
    resume: bool = dataclasses.field(default=False, metadata={
        "description": "true: continue a campaign whose run_id already has stored outcomes; false: refuse to reuse the "
                       "id"})
    store_timeout_s: float = dataclasses.field(default=10.0, metadata={
        "description": "longest wait for the logger's acknowledgement that an outcome is stored, s",
        "range": (0.0, 3600.0), "exclusive": "low"})
    server_timeout_s: float = dataclasses.field(default=30.0, metadata={
        "description": "longest wait for the rig's Launch action server to appear, s",
        "range": (0.0, 86400.0), "exclusive": "low"})
    session_key_file: str = dataclasses.field(default="", metadata={
        "description": "physical: the valve_controller's session key file this runner signs goals and answers with "
                       "(rig_auth); \"\" = the default of valve.session_key_file for this ROS domain and namespace"})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if self.backend not in LAUNCH_BACKENDS:
            raise ValueError(f"backend must be 'sim' (unattended) or 'physical' (operator), got {self.backend!r}")


def resume_command(argv: typing.Sequence[str], program: str = "rollability") -> str:
    """The command line that resumes the campaign started with ``program argv``: the same arguments with
    ``--resume`` (once), quoted for a shell."""
    import shlex

    return shlex.join([program, *argv] + ([] if "--resume" in argv else ["--resume"]))


def report_exit_code(report: CampaignReport, say: typing.Callable[[str], None] = print, resume: str = "") -> int:
    """Print how a session ended; return the exit code: 0 when complete, 3 when stopped early, 4 when it failed
    (mostly invalid launches: the message names the setting to change). ``resume``: the exact command that
    continues the campaign (:func:`resume_command`), printed after a stop with the report's ``advice``."""
    if report.failed:
        say(f"campaign failed: {report.stopped_reason} ({report.done}/{report.total} stored)")
        return 4
    if report.stopped_reason:
        say(f"campaign stopped: {report.stopped_reason} ({report.done}/{report.total} stored)")
        if report.advice:
            say(f"before resuming: {report.advice}")
        say(f"to continue, type: {resume}" if resume else "resume to continue (the same command with --resume)")
        return 3
    if report.decided:
        say(f"campaign decided: {report.decided} ({report.done}/{report.total} stored; the rest are not needed)")
        return 0
    say(f"campaign complete: {report.done}/{report.total} trials stored")
    return 0


def plan_refusal(backend: LaunchBackend, run_id: str, plan: typing.Sequence[PlannedTrial]) -> str:
    """Why the campaign must not start ("" if every planned trial can run): the first reason the backend's
    ``check`` gives for a trial (e.g. a configuration the launch twin has no profile for), with how many trials
    it concerns, so a campaign does not stop a hundred launches in."""
    reasons: typing.Dict[str, list] = {}
    for trial in plan:
        reason = backend.check(run_id, trial.trial_id, trial.condition)
        if reason:
            reasons.setdefault(reason, []).append(trial.trial_id)
    if not reasons:
        return ""
    reason, trials = next(iter(reasons.items()))
    others = sum(len(t) for t in reasons.values()) - len(trials)
    return (f"campaign not started: {reason} ({len(trials)} planned trial(s), e.g. {trials[0]}"
            f"{f'; {others} more with other problems' if others else ''})")


def resume_refusal(stored_count: int, resume: bool, run_id: str) -> str:
    """Why a session must not start ("" if it may): stored trials of ``run_id`` need an explicit resume."""
    if stored_count and not resume:
        return (f"run {run_id} already has {stored_count} stored trials: pass --resume (runner.resume) to continue "
                "it, or choose another run id")
    return ""


def answer_rig(phase: str, detail: str,
               ask: typing.Callable[[str], str]) -> typing.Optional[typing.Tuple[str, typing.Any]]:
    """Ask the operator what the rig waits for, from a feedback ``(phase, detail)``.

    Returns ``("confirm", None)`` (regulator set), ``("outcome", OperatorOutcome)`` or None when the phase asks
    nothing. Invalid outcome answers are asked again.
    """
    if phase == "waiting_for_operator" and detail.startswith(ASK_REGULATOR):
        ask(f"{detail}: Enter when done: ")
        return "confirm", None
    if phase == "classifying" and detail.startswith(ASK_OUTCOME):
        prompt = f"{detail}: y/n [travel time s] [rolled=M] [note]: "
        while True:
            try:
                return "outcome", parse_outcome_answer(ask(prompt))
            except ValueError as exc:
                prompt = f"{exc}; again: "
    return None


class LocalRigPorts(RigPorts):
    """:class:`~rollability_ros.core.rig.launch_backend.RigPorts` in this process: a
    :class:`~rollability_ros.core.rig.valve.ValveController` on ``valve.*`` with a heartbeat thread for its
    watchdog, the ``speed_gate.*`` gate (the operator types travel times through ``ask``), no IMU, and the launch
    twin ``read_twin`` (the command's parse of the twin's files, called only by the simulated backend)."""

    def __init__(self, ask=input, read_twin: typing.Optional[typing.Callable[[typing.Sequence[str]],
                                                                              "LaunchTwinSettings"]] = None):
        self._ask = ask
        self._read_twin = read_twin
        self._stop = threading.Event()
        self.valve: typing.Optional[ValveController] = None

    def open_valve(self, valve_config: ValveConfig) -> ValveController:
        """A valve controller on ``valve.*`` whose watchdog this object keeps fed until :meth:`close`."""
        self.valve = make_controller(valve_config)
        threading.Thread(target=self._beat, args=(valve_config.heartbeat_period_ms / 1000.0,), daemon=True).start()
        return self.valve

    def _beat(self, period_s):
        valve = self.valve
        assert valve is not None   # started by open_valve
        while not self._stop.wait(period_s):
            valve.heartbeat()

    def open_speed_gate(self, speed_config: SpeedGateConfig) -> SpeedGate:
        """The configured speed gate (its ``operator`` backend asks at this terminal)."""
        return make_speed_gate(speed_config, self._ask)

    def open_imu(self, imu_outcome: ImuOutcome) -> None:
        """Refused: the in-process rig has no IMU topic."""
        raise ValueError("the in-process physical rig takes outcomes from the operator only (no IMU topic)")

    def open_twin(self, twin_config: typing.Sequence[str]) -> "LaunchTwinSettings":
        """The twin ``read_twin`` parses from ``twin_config``; ``ValueError`` when the command gave none."""
        if self._read_twin is None:
            raise ValueError("the in-process rig was given no launch twin to read (read_twin)")
        return self._read_twin(twin_config)

    def close(self) -> None:
        """Stop the heartbeat and shut the valve down (closed)."""
        self._stop.set()
        if self.valve is not None:
            self.valve.shutdown()


@dataclasses.dataclass(frozen=True)
class LocalRigSettings:
    """The typed sections an in-process rig is built from (``config/rig.yaml``), parsed once by the command that
    starts it (:func:`local_rig_settings`)."""

    rig: RigSettings = dataclasses.field(default_factory=RigSettings)
    speed_gate: SpeedGateConfig = dataclasses.field(default_factory=SpeedGateConfig)
    valve: ValveConfig = dataclasses.field(default_factory=ValveConfig)
    imu_outcome: ImuOutcomeConfig = dataclasses.field(default_factory=ImuOutcomeConfig)


@edge_parse
def local_rig_settings(backend: str, parameters: typing.Mapping[str, object]) -> LocalRigSettings:
    """Parse flat rig parameters (``load_parameters(["rig"])``: ``rig.*``, ``valve.*``, ``speed_gate.*``,
    ``imu_outcome.*``) once, with ``rig.backend`` set to ``backend`` (``"sim"`` or ``"physical"``, the command
    line's); a bad value raises ConfigError naming its parameter."""
    return settings_from_sections(LocalRigSettings, {**parameters, "rig.backend": backend})


@edge_parse
def local_rig_settings_from_files(backend: str, paths: typing.Optional[typing.Sequence[str]],
                                  command: str) -> LocalRigSettings:
    """:func:`local_rig_settings` of the rig parameter files a user gave ``command`` (None: the shipped
    ``config/rig.yaml``), once every parameter in them is one the rig applies (else ConfigError naming the file,
    parameter and command): its own sections (:class:`LocalRigSettings`) and the twin's, through ``rig.twin_config``,
    to which the files that set twin parameters are appended."""
    from rollability_ros.core.sim import TWIN_SECTIONS, twin_files

    paths = list(paths) if paths is not None else ["rig"]
    own = {field.name for field in dataclasses.fields(LocalRigSettings)}
    check_given_files(paths, own | TWIN_SECTIONS, command)
    parameters = load_parameters(paths)
    extra = twin_files(paths, TWIN_SECTIONS)
    if extra:
        twin = as_list(parameters.get("rig.twin_config", RigSettings().twin_config))
        parameters["rig.twin_config"] = [*twin, *(path for path in extra if path not in twin)]
    return local_rig_settings(backend, parameters)


class LocalRig:
    """The rig in this process (no ROS): the backend ``settings.rig.backend`` names on :class:`LocalRigPorts`, with
    the operator answering the rig's questions at the terminal (``ask``).

    Parameters
    ----------
    settings : LocalRigSettings
        The rig's typed sections (:func:`local_rig_settings`).
    ask, say : callable
        Terminal input / output.
    read_twin : callable(twin_config) -> LaunchTwinSettings, optional
        The command's parse of the twin's parameter files (``load_launch_twin_settings``), which the simulated
        backend calls once for ``rig.twin_config`` (:meth:`LocalRigPorts.open_twin`).
    """

    def __init__(self, settings: LocalRigSettings, ask: typing.Callable[[str], str] = input,
                 say: typing.Callable[[str], None] = print,
                 read_twin: typing.Optional[typing.Callable[[typing.Sequence[str]], "LaunchTwinSettings"]] = None
                 ) -> None:
        self._ask, self._say = ask, say
        self._stop = threading.Event()
        self.backend = make_launch_backend(settings.rig, settings.speed_gate, settings.valve, settings.imu_outcome,
                                           LocalRigPorts(ask, read_twin))

    def _on_phase(self, phase, detail):
        self._say(f"  {phase}: {detail}")
        reply = answer_rig(phase, detail, self._ask)
        if reply is not None:
            kind, outcome = reply
            if kind == "confirm":
                self.backend.operator.confirm()
            else:
                self.backend.operator.record_outcome(outcome)

    def launch(self, run_id: str, trial: PlannedTrial) -> LaunchOutcome:
        """Launch ``trial`` (a PlannedTrial) and return its outcome; :class:`LaunchAborted` when none."""
        return self.backend.launch(run_id, trial.trial_id, trial.condition, self._on_phase,
                                   cancelled=self._stop.is_set)

    def close(self) -> None:
        """Stop the backend (heartbeat, valve closed)."""
        self._stop.set()
        self.backend.close()
