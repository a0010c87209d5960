"""The campaign loop: for each remaining trial, tell the operator what to change, launch, and count it once stored.

The loop is the same for every route; the caller passes how a trial is launched and how its outcome is known to
be stored:

- in-process (``rollability campaign`` without ROS): ``launch`` runs the rig sequence or the launch twin here and
  ``confirm_stored`` writes the durable store itself (:func:`store_writer`): the only writer on that route;
- through the node graph: ``launch`` sends a Launch goal to the ``rig`` node, whose outcome reaches the
  ``outcome_logger`` (the only writer on that route), and ``confirm_stored`` polls the store file until the
  logger has committed the trial (:class:`StoreWatcher`), so a trial counts as done only once it is on disk.

A trial that fails (valve fault, operator timeout, outcome never stored) stops the campaign: nothing was stored
for it, so a resumed run (``remaining_trials``) launches it again, and every trial stored before stays stored.
"""
import dataclasses
import math
import threading
import time

from rollability_ros.core.campaign.plan import CampaignProgress, changes_between
from rollability_ros.core.config import from_mapping, section
from rollability_ros.core.rig.rig_session import (ASK_OUTCOME, ASK_REGULATOR, LaunchAborted, OperatorChannel,
                                              PhysicalLaunch, RigSettings, SimulatedLaunch, parse_outcome_answer)
from rollability_ros.core.rig.speed_gate import SpeedGateConfig, make_speed_gate
from rollability_ros.core.results.store import Store
from rollability_ros.core.rig.valve import ValveConfig
from rollability_ros.core.rig.valve_backends import make_controller


class NotStored(RuntimeError):
    """A launch outcome did not reach the durable store in time."""


@dataclasses.dataclass(frozen=True)
class CampaignReport:
    """How a campaign session ended: trials stored this session, totals, and why it stopped early ("" if not)."""

    stored_now: int
    done: int
    total: int
    stopped_reason: str = ""

    @property
    def complete(self):
        """True when every planned trial is stored."""
        return self.done == self.total


def store_writer(store):
    """``confirm_stored`` for the in-process route: write the outcome (a duplicate counts as stored)."""
    def confirm_stored(outcome):
        store.add_launch_outcome(outcome)
    return confirm_stored


class StoreWatcher:
    """``confirm_stored`` for the node-graph route: waits until another process has stored the trial.

    Parameters
    ----------
    path : path
        The store file (or run directory) the ``outcome_logger`` writes.
    timeout_s : float
        Longest wait for a trial to appear after its launch ended, s.
    """

    def __init__(self, path, timeout_s=10.0, poll_s=0.05):
        self.store = Store(path)
        self.timeout_s = timeout_s
        self.poll_s = poll_s

    def __call__(self, outcome):
        deadline = time.monotonic() + self.timeout_s
        while outcome.trial_id not in self.store.trial_ids(outcome.run_id):
            if time.monotonic() > deadline:
                raise NotStored(f"outcome of {outcome.trial_id} did not reach the store {self.store.path} within "
                                f"{self.timeout_s:g} s: is an outcome_logger writing to it?")
            time.sleep(self.poll_s)

    def close(self):
        """Close the store connection."""
        self.store.close()


def _operator_ready(ask, say, previous, trial, pressure_psi_by_speed):
    """Tell the operator what to change before ``trial``; return False if the operator stops the campaign."""
    for instruction in changes_between(previous, trial, pressure_psi_by_speed):
        say(f"  - {instruction}")
    answer = ask(f"place the chassis for {trial.trial_id} on the launcher; Enter to launch, q to stop: ")
    return answer.strip().lower() not in ("q", "quit", "stop")


def run_campaign(plan, run_id, stored_ids, launch, confirm_stored, ask=None, say=print,
                 pressure_psi_by_speed=None, clock=time.monotonic):
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
    """
    todo = [trial for trial in plan if trial.trial_id not in stored_ids]
    progress = CampaignProgress(len(plan), len(plan) - len(todo))
    say(f"campaign {run_id}: {progress.text()}")
    previous, stored_now = None, 0

    def report(reason):
        return CampaignReport(stored_now, progress.done, progress.total, reason)

    for trial in todo:
        try:
            ready = ask is None or _operator_ready(ask, say, previous, trial, pressure_psi_by_speed)
        except EOFError:
            ready = False
        if not ready:
            return report("stopped by the operator")
        started = clock()
        try:
            outcome = launch(trial)
            if (outcome.run_id, outcome.trial_id) != (run_id, trial.trial_id):
                raise LaunchAborted(f"the rig answered {outcome.run_id}/{outcome.trial_id} for "
                                    f"{run_id}/{trial.trial_id}")
            confirm_stored(outcome)
        except (LaunchAborted, NotStored, ValueError) as exc:
            say(f"trial {trial.trial_id} not done: {exc}")
            return report(f"{trial.trial_id}: {exc}")
        except EOFError:
            return report(f"{trial.trial_id}: the operator's input closed")
        stored_now += 1
        progress.trial_done(clock() - started)
        verdict = outcome.note if not outcome.valid else ("upright" if outcome.upright else "NOT upright")
        say(f"{trial.trial_id}: {verdict}"
            f"{' (speed flagged)' if outcome.speed_out_of_tolerance else ''}; {progress.text()}")
        previous = trial
    return report("")



@dataclasses.dataclass
class RunnerSettings:
    """``runner.*``: how the campaign_runner node reaches the rig and the store."""

    backend: str = "sim"
    store_path: str = "runs/outcomes.sqlite"
    resume: bool = False
    store_timeout_s: float = 10.0
    server_timeout_s: float = 30.0

    def validate(self):
        """Raise ``ValueError`` naming the first unusable field."""
        if self.backend not in ("sim", "physical"):
            raise ValueError(f"backend must be 'sim' (unattended) or 'physical' (operator), got {self.backend!r}")
        if not self.store_path:
            raise ValueError("store_path must name the outcome_logger's store")
        if not 0 < self.store_timeout_s < math.inf or not 0 < self.server_timeout_s < math.inf:
            raise ValueError("store_timeout_s and server_timeout_s must be finite and > 0")


def report_exit_code(report, say=print):
    """Print how a session ended; return the exit code: 0 when complete, 3 when stopped early."""
    if report.stopped_reason:
        say(f"campaign stopped: {report.stopped_reason} ({report.done}/{report.total} stored; resume to continue)")
        return 3
    say(f"campaign complete: {report.done}/{report.total} trials stored")
    return 0


def resume_refusal(stored_count, resume, run_id):
    """Why a session must not start ("" if it may): stored trials of ``run_id`` need an explicit resume."""
    if stored_count and not resume:
        return (f"run {run_id} already has {stored_count} stored trials: pass --resume (runner.resume) to continue "
                "it, or choose another run id")
    return ""


def answer_rig(phase, detail, ask):
    """Ask the operator what the rig waits for, from a feedback ``(phase, detail)``.

    Returns ``("confirm", None)`` (regulator set), ``("outcome", OperatorOutcome)`` or None when the phase asks
    nothing. Invalid outcome answers are asked again.
    """
    if phase == "waiting_for_operator" and detail.startswith(ASK_REGULATOR):
        ask(f"{detail}: Enter when done: ")
        return "confirm", None
    if phase == "classifying" and detail.startswith(ASK_OUTCOME):
        prompt = f"{detail}: y/n [travel time s] [note]: "
        while True:
            try:
                return "outcome", parse_outcome_answer(ask(prompt))
            except ValueError as exc:
                prompt = f"{exc}; again: "
    return None


class LocalRig:
    """The rig in this process (no ROS): the launch twin, or the physical launcher driven directly.

    Physical: a :class:`~rollability_ros.core.rig.valve.ValveController` on ``valve.*`` with a heartbeat thread for
    its watchdog, the ``speed_gate.*`` gate, and the operator answering the terminal (``ask``).

    Parameters
    ----------
    backend : str
        ``"sim"`` or ``"physical"``.
    parameters : dict
        Flat rig parameters (``load_parameters(["rig"])``): ``rig.*``, ``valve.*``, ``speed_gate.*``.
    ask, say : callable
        Terminal input / output (physical only).
    """

    def __init__(self, backend, parameters, ask=input, say=print):
        rig = section(parameters, "rig")
        rig["backend"] = backend
        if backend == "physical" and rig.get("outcome_source", "operator") != "operator":
            raise ValueError("the in-process physical rig takes outcomes from the operator only (no IMU topic)")
        self.settings = from_mapping(RigSettings, rig, "rig")
        speed_config = from_mapping(SpeedGateConfig, section(parameters, "speed_gate"), "speed_gate")
        self._ask, self._say = ask, say
        self._stop = threading.Event()
        self.valve = None
        if backend == "sim":
            self._rig = SimulatedLaunch(self.settings, speed_config)
            return
        valve_config = from_mapping(ValveConfig, section(parameters, "valve"), "valve")
        self.valve = make_controller(valve_config)
        self._heartbeat_thread = threading.Thread(
            target=self._beat, args=(valve_config.heartbeat_period_ms / 1000.0,), daemon=True)
        self._heartbeat_thread.start()
        self._rig = PhysicalLaunch(self.settings, self.valve, make_speed_gate(speed_config, ask), speed_config,
                                   valve_config.launch_pulse_ms, valve_config.regulator, OperatorChannel())

    def _beat(self, period_s):
        while not self._stop.wait(period_s):
            self.valve.heartbeat()

    def _on_phase(self, phase, detail):
        self._say(f"  {phase}: {detail}")
        reply = answer_rig(phase, detail, self._ask)
        if reply is not None:
            kind, outcome = reply
            if kind == "confirm":
                self._rig.operator.confirm()
            else:
                self._rig.operator.record_outcome(outcome)

    def launch(self, run_id, trial):
        """Launch ``trial`` (a PlannedTrial) and return its outcome; :class:`LaunchAborted` when none."""
        if isinstance(self._rig, SimulatedLaunch):
            return self._rig.launch(run_id, trial.trial_id, trial.condition)
        return self._rig.launch(run_id, trial.trial_id, trial.condition, self._on_phase, self._stop.is_set)

    def close(self):
        """Stop the heartbeat and shut the valve down (closed)."""
        self._stop.set()
        if self.valve is not None:
            self.valve.shutdown()
