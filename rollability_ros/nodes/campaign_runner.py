"""campaign_runner node: runs the launch campaign of ``config/campaign.yaml`` through the node graph, then exits.

Action client: ``launch`` (rollability_ros/Launch) of the ``rig`` node, one goal per remaining trial.
Service clients: ``stored_trials`` (rollability_ros/GetStoredTrials) of the ``outcome_logger``, once at start-up,
  for the trials already stored (resume); attended runs also call ``rig/confirm`` (ConfirmRegulator) and
  ``record_outcome`` (RecordOutcome) with what the operator types when the rig's feedback asks for the regulator
  or for the outcome.
Authentication: with ``runner.backend`` physical, goals, confirmations and outcomes are signed with the
  valve_controller's session key (``runner.session_key_file``; :mod:`rollability_ros.core.rig.rig_auth`), so this
  runner works on the rig computer as the valve_controller's user; a sim campaign signs nothing.
Publication: ``campaign_progress`` (rollability_ros/CampaignProgress, latched): trials stored of planned and the
  campaign's ETA, at the start and after each trial (``rollability bringup`` shows it).
Subscription: ``outcomes_stored`` (rollability_ros/OutcomeStored, reliable, transient-local): the logger's
  acknowledgements; a trial counts as done once the logger acknowledged storing it.
Parameters: ``campaign.*`` (:class:`~rollability_ros.core.campaign.plan.CampaignSpec`) and ``runner.*``
  (:class:`~rollability_ros.core.campaign.runner.RunnerSettings`: ``backend`` sim = unattended, physical = the
  terminal tells the operator what to change and waits for Enter; ``resume``; ``store_timeout_s``, the longest
  wait for an acknowledgement).

One writer, reached only over ROS: the outcome_logger stores the outcomes the rig publishes and acknowledges
them; this node never opens the store, so the logger may run in another directory (or, for a sim campaign, on
another computer: physical outcomes are verified with the valve's key on the rig computer).
Exit code: 0 when every trial is stored, 3 when the campaign stopped early (the reason is printed; rerun with
``runner.resume:=true``), 2 for bad parameters or no outcome_logger answering.
"""
import collections
import dataclasses
import functools
import math
import os
import queue
import signal
import sys
import time
import typing

import rclpy
from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from rollability_ros.action import Launch
from rollability_ros.core.campaign import (AnsweredElsewhere, CampaignSpec, RunnerSettings, StoreAcknowledgements,
                                           TerminalAsk, answer_rig, plan_trials, report_exit_code, resume_refusal,
                                           run_campaign)
from rollability_ros.core.config import ConfigError, SessionSettings
from rollability_ros.core.rig import (ANSWERED, AuthError, KeyFileSigner, LaunchAborted, default_key_path,
                                      describe_answer, launch_backend_class, load_session_key)
from rollability_ros.nodes import _convert
from rollability_ros.msg import CampaignProgress, OutcomeStored, ValveAuth, ValveState
from rollability_ros.nodes._support import (GOAL_RESEND_S, LATCHED_QOS, RECORD_QOS, ParameterError, declare_settings, init_ros,
                                            send_goal_resending)
from rollability_ros.srv import ConfirmRegulator, GetStoredTrials, RecordOutcome

#: How long after a launch's result the campaign still shows the rig's announcement of an answer, s.
LATE_FEEDBACK_S = 0.3
#: Longest wait for the valve's latched state before a launch (a valve_controller that publishes none: no wait
#: after that), s.
VALVE_STATE_WAIT_S = 5.0
#: Seconds the rig's action server may be missing from the graph before a running launch counts as lost.
SERVER_LOST_S = 3.0


class RigClient:
    """Sends Launch goals to the rig and relays the operator's answers to the rig's questions.

    The caller's thread spins ``executor`` while it waits: rclpy's ActionClient registers a goal's future only
    after sending the request, so an executor spinning in another thread can take the response first and drop it.

    Parameters
    ----------
    node : rclpy Node
    executor : rclpy Executor
        Holds ``node``; spun only by this object, in the calling thread.
    run_id : str
    ask : callable or None
        ``ask(prompt) -> str`` for attended runs; None leaves questions to another operator tool.
    say : callable
    server_timeout_s : float
        Longest wait for the rig's action server and services, s.
    signer : KeyFileSigner or None
        Signs goals and answers with the valve's session key (physical rig); None sends them unsigned (sim rig).
    session : str
        The runner's session (``session.id``), carried in every goal: a rig of another session aborts it.
    """

    def __init__(self, node, executor, run_id, ask, say, server_timeout_s, signer=None, session=""):
        self.signer = signer
        self.session = session
        self.executor = executor
        self.run_id = run_id
        self.ask, self.say = ask, say
        self.server_timeout_s = server_timeout_s
        self.node = node
        self.action = ActionClient(node, Launch, "launch")
        self.confirm_client = node.create_client(ConfirmRegulator, "rig/confirm")
        self.record_client = node.create_client(RecordOutcome, "record_outcome")
        self._pending: typing.Deque[typing.Any] = collections.deque()   # feedback read while a prompt waited
        self._said: typing.Optional[typing.Tuple[str, str]] = None     # the answer this terminal gave and showed
        self.valve_state = None
        self._waited_for_valve = False
        self._shown_fault = ""
        if ask is not None:   # an attended campaign shows the valve's stops as they happen
            if isinstance(ask, TerminalAsk) and ask.idle is None:   # messages arrive while a prompt waits
                ask.idle = lambda: executor.spin_once(timeout_sec=0)
            node.create_subscription(ValveState, "valve/state", self._on_valve_state, LATCHED_QOS)

    def _on_valve_state(self, msg):
        self.valve_state = msg
        if msg.fault and msg.fault_reason != self._shown_fault:
            self._shown_fault = msg.fault_reason
            self.say(f"\nVALVE STOPPED: {msg.fault_reason}. The valve is closed and nothing fires until it is "
                     f"acknowledged with: {self.disarm_command()}")
        elif not msg.fault and self._shown_fault:
            self._shown_fault = ""
            self.say("valve stop acknowledged (disarmed): the rig arms by itself at the next launch")

    def disarm_command(self) -> str:
        """The operator's command that acknowledges a valve stop of this rig: joining its session by name (a
        session id is ``<name>.<token>``), else naming its namespace."""
        if self.session:
            return f"rollability rig disarm --session {self.session.rsplit('.', 1)[0]}"
        return f"rollability rig disarm --namespace {self.node.get_namespace()}"

    def valve_advice(self) -> str:
        """What to do before resuming when the valve is stopped ("" when it is not)."""
        spin_until(self.executor, lambda: False, 0.2)   # a stop published just now arrives
        state = self.valve_state
        if state is None or not state.fault:
            return ""
        return (f"the valve is stopped ({state.fault_reason}): acknowledge it with `{self.disarm_command()}` (the "
                "valve stays closed; the rig arms by itself at the next launch, do not arm by hand)")

    def _wait_valve_ready(self):
        """Before a launch: while the valve is stopped, tell the operator how to acknowledge it and wait."""
        # the valve's latched state arrives once the subscription matched (a fresh process: a moment); waited for
        # once, so a graph whose valve publishes nothing is not held up at every launch
        if not self._waited_for_valve:
            self._waited_for_valve = True
            spin_until(self.executor, lambda: self.valve_state is not None, VALVE_STATE_WAIT_S)
        spin_until(self.executor, lambda: False, 0.05)
        while self.valve_state is not None and self.valve_state.fault:
            reason = self.valve_state.fault_reason
            if self.ask is None:
                raise LaunchAborted(f"the valve is stopped ({reason})")
            answer = self.ask(f"the valve is stopped ({reason}): acknowledge with `{self.disarm_command()}` in "
                              "another terminal, then Enter to launch (q to stop): ")
            if answer.strip().lower() in ("q", "quit", "stop"):
                raise LaunchAborted(f"stopped by the operator while the valve was stopped ({reason})")
            spin_until(self.executor, lambda: False, 0.3)   # the acknowledgement's new state arrives

    def _wait(self, future, what):
        deadline = time.monotonic() + self.server_timeout_s
        while not future.done():
            if time.monotonic() > deadline:
                raise LaunchAborted(f"the rig did not answer {what} within {self.server_timeout_s:g} s")
            self.executor.spin_once(timeout_sec=0.05)
        return future.result()

    def _moved_on(self, phase, detail, feedback, result_future):
        """While a prompt waits: the rig's next feedback that is not the question being asked (its answer, given
        in another place, or a later phase), or the launch's end; None while the question stands."""
        while True:
            try:
                self._pending.append(feedback.get_nowait().feedback)
            except queue.Empty:
                break
        for message in self._pending:
            if (message.phase, message.detail) != (phase, detail):
                return f"{message.phase}: {message.detail}"
        return "the launch ended" if result_future.done() else None

    def _answer(self, trial_id, phase, detail, feedback, result_future):
        if self.ask is None or detail.startswith(ANSWERED):
            return
        ask = self.ask
        if isinstance(ask, TerminalAsk):   # the other place may answer first: then stop waiting here
            ask = functools.partial(self.ask, interrupted=lambda: self._moved_on(phase, detail, feedback,
                                                                                 result_future))
        try:
            reply = answer_rig(phase, detail, ask)
        except AnsweredElsewhere:
            return   # the answer that counted is the next feedback, shown by _follow
        if reply is None:
            return
        kind, outcome = reply
        client = self.confirm_client if kind == "confirm" else self.record_client
        if not spin_until(self.executor, client.service_is_ready, self.server_timeout_s):
            raise LaunchAborted(f"the rig's {client.srv_name} service is not available")
        # signed once the service is there: a signature is fresh for a few seconds only
        if kind == "confirm":
            request = ConfirmRegulator.Request(trial_id=trial_id,
                                               auth=self._sign(lambda signer: signer.confirm(trial_id)))
        else:
            rolled_m = -1.0 if math.isnan(outcome.rest_distance_m) else outcome.rest_distance_m   # -1: not measured
            request = RecordOutcome.Request(trial_id=trial_id, upright=outcome.upright, note=outcome.note,
                                            travel_time_s=outcome.travel_time_s, rest_distance_m=rolled_m)
            request.auth = self._sign(lambda signer: signer.outcome(trial_id, request.upright, request.travel_time_s,
                                                                    request.note, request.rest_distance_m))
        response = self._wait(client.call_async(request), client.srv_name)
        accepted = response.success if kind == "confirm" else response.accepted
        if not accepted:
            self.say(f"  the rig refused the answer: {response.message}")
        elif response.message != "accepted":   # answered already, from the other place, with the same verdict
            self.say(f"  {response.message}")
        else:   # shown now: the rig's own announcement of it may come after the launch's result
            self._said = (phase, f"{ANSWERED}{describe_answer(kind, outcome)}")
            self.say(f"  {phase}: {self._said[1]}")

    def _sign(self, sign):
        """``sign(signer)`` as a ``ValveAuth`` (unsigned without a signer); LaunchAborted when the key is unreadable."""
        if self.signer is None:
            return ValveAuth()
        try:
            return _convert.auth_msg(sign(self.signer))
        except AuthError as exc:
            raise LaunchAborted(str(exc)) from exc

    def launch(self, trial: typing.Any) -> typing.Any:
        """Run ``trial`` on the rig; its :class:`~rollability_ros.core.records.LaunchOutcome`, or LaunchAborted."""
        if not spin_until(self.executor, self.action.server_is_ready, self.server_timeout_s):
            domain = os.environ.get("ROS_DOMAIN_ID") or "0"
            raise LaunchAborted(f"no rig serves the launch action in ROS domain {domain} namespace "
                                f"{self.node.get_namespace()} within {self.server_timeout_s:g} s")
        self._wait_valve_ready()
        self._pending.clear()
        feedback: queue.Queue = queue.Queue()
        def make_goal() -> Launch.Goal:
            goal = Launch.Goal(run_id=self.run_id, trial_id=trial.trial_id,
                               condition=_convert.condition_to_msg(trial.condition), session=self.session)
            goal.auth = self._sign(lambda signer: signer.launch(self.run_id, trial.trial_id, goal.condition))
            return goal

        handle = send_goal_resending(
            self.action, make_goal, lambda done, timeout_s: spin_until(self.executor, done, timeout_s),
            self.server_timeout_s, feedback_callback=feedback.put,
            on_resend=lambda copies: self.say(f"  the rig did not answer {trial.trial_id} within "
                                              f"{GOAL_RESEND_S * copies:g} s; sending it again"))
        if handle is None:
            raise LaunchAborted(f"the rig did not answer the goal within {self.server_timeout_s:g} s")
        if not handle.accepted:
            raise LaunchAborted(f"the rig rejected {trial.trial_id}")
        result_future = handle.get_result_async()
        try:
            self._follow(trial.trial_id, feedback, result_future, self._server_gids())
        except BaseException:
            handle.cancel_goal_async()  # do not leave the rig waiting for an operator who is gone
            raise
        wrapped = result_future.result()
        if wrapped.status != GoalStatus.STATUS_SUCCEEDED:
            raise LaunchAborted(wrapped.result.message or f"launch ended with goal status {wrapped.status}")
        return _convert.outcome_from_msg(wrapped.result.outcome)

    def _server_gids(self):
        """The endpoint ids of the launch action's status publishers: which rig process serves the action."""
        topic = self.node.resolve_topic_name("launch") + "/_action/status"
        return {bytes(info.endpoint_gid) for info in self.node.get_publishers_info_by_topic(topic)}

    def _follow(self, trial_id, feedback, result_future, serving):
        """Show the feedback and answer the rig's questions until the result arrives.

        ``serving``: :meth:`_server_gids` when the goal was accepted. A rig killed and restarted in the meantime
        serves the action again but knows nothing of the goal: once the accepting process has left the graph
        (its endpoints vanish), the launch is reported lost instead of awaited for ever.
        """
        missing_since, last = None, None
        next_check = time.monotonic() + SERVER_LOST_S
        while not result_future.done() or self._pending:
            if not self._pending:
                self.executor.spin_once(timeout_sec=0.05)
            try:
                message = self._pending.popleft() if self._pending else feedback.get_nowait().feedback
            except queue.Empty:
                if result_future.done():
                    break
                if serving and time.monotonic() > next_check:
                    next_check = time.monotonic() + SERVER_LOST_S
                    if not serving & self._server_gids():
                        raise LaunchAborted(f"the rig that accepted {trial_id} left the graph (killed or restarted); "
                                            "its launch is lost")
                if self.action.server_is_ready():
                    missing_since = None
                elif missing_since is None:
                    missing_since = time.monotonic()
                elif time.monotonic() - missing_since > SERVER_LOST_S:
                    raise LaunchAborted(f"the rig left the graph during {trial_id}")
                continue
            if (message.phase, message.detail) in (last, self._said):
                continue    # the rig repeats an open question until it is answered: ask the operator once
            last = (message.phase, message.detail)
            self.say(f"  {message.phase}: {message.detail}")
            self._answer(trial_id, message.phase, message.detail, feedback, result_future)
        self._show_late_answers(feedback, last)

    def _show_late_answers(self, feedback, last):
        """The rig's announcement of an answer given elsewhere may arrive after the launch's result (another
        topic): wait a moment for it, so this terminal always shows the answer that counted."""
        spin_until(self.executor, lambda: False, LATE_FEEDBACK_S)
        while True:
            try:
                message = feedback.get_nowait().feedback
            except queue.Empty:
                return
            if message.detail.startswith(ANSWERED) and (message.phase, message.detail) not in (last, self._said):
                last = (message.phase, message.detail)
                self.say(f"  {message.phase}: {message.detail}")


def spin_until(executor: typing.Any, predicate: typing.Callable[[], bool], timeout_s: float) -> bool:
    """Spin ``executor`` until ``predicate()`` or ``timeout_s``; returns its last value. (rclpy's wait_for_service
    and wait_for_server only sleep: meanwhile this node would not answer its parameter services.)"""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            return predicate()
        executor.spin_once(timeout_sec=0.05)
    return True


def _say(text):
    print(text, flush=True)   # a supervisor's log file or a pipe shows each line as it happens


def stored_trial_ids(node: Node, executor: typing.Any, run_id: str, timeout_s: float,
                     session: str = "") -> typing.Set[str]:
    """The trial ids the outcome_logger has stored for ``run_id`` (``stored_trials`` service, which also announces
    the run as one of ``session``'s); ``ValueError`` when no logger answers within ``timeout_s``, it cannot read its
    store, or it belongs to another session."""
    client = node.create_client(GetStoredTrials, "stored_trials")
    try:
        if not spin_until(executor, client.service_is_ready, timeout_s):
            domain = os.environ.get("ROS_DOMAIN_ID") or "0"
            raise ValueError(f"no outcome_logger serves {client.srv_name} in ROS domain {domain} namespace "
                             f"{node.get_namespace()} within {timeout_s:g} s: start one there, or join its session "
                             "(--session SESSION, --namespace)")
        future = client.call_async(GetStoredTrials.Request(run_id=run_id, session=session))
        deadline = time.monotonic() + timeout_s
        while not future.done():
            if time.monotonic() > deadline:
                raise ValueError(f"the outcome_logger did not answer {client.srv_name} within {timeout_s:g} s")
            executor.spin_once(timeout_sec=0.05)
        response = future.result()
        if not response.success:
            raise ValueError(f"the outcome_logger cannot list the stored trials: {response.message}")
        return set(response.trial_ids)
    finally:
        node.destroy_client(client)


def run_graph_campaign(node: Node, spec: CampaignSpec, settings: RunnerSettings,
                       ask: typing.Optional[typing.Callable[[str], str]] = None,
                       say: typing.Callable[[str], None] = _say, session: str = "",
                       comparison: typing.Optional[typing.Tuple[str, str]] = None, alpha: float = 0.05) -> typing.Any:
    """Run the campaign through the graph from ``node`` (spun here, in this thread) as a runner of ``session``
    (its ``session.id``; "" none); returns the CampaignReport. ``comparison`` (first, second): launch their trials
    in pairs and end once the comparison is decided at error rate ``alpha`` (``rollability campaign
    --stop-when-decided``)."""
    plan = plan_trials(spec)
    signer = None
    if launch_backend_class(settings.backend).authenticated:
        signer = KeyFileSigner(settings.session_key_file or default_key_path(node.get_namespace()))
        try:   # refused at once, before asking anyone: the physical rig takes no unsigned goal
            load_session_key(signer.path)
        except AuthError as exc:
            raise ValueError(f"a physical campaign signs its goals and answers: {exc}") from exc
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        acknowledgements = StoreAcknowledgements(lambda: executor.spin_once(timeout_sec=0.05),
                                                 settings.store_timeout_s)

        def on_stored(msg: typing.Any) -> None:
            acknowledgements.acknowledge(msg.run_id, msg.trial_id)

        node.create_subscription(OutcomeStored, "outcomes_stored", on_stored, RECORD_QOS)
        stored = stored_trial_ids(node, executor, spec.run_id, settings.server_timeout_s, session)
        refusal = resume_refusal(len(stored), settings.resume, spec.run_id)
        if refusal:
            raise ValueError(refusal)
        rig = RigClient(node, executor, spec.run_id, ask, say, settings.server_timeout_s, signer, session)
        progress_publisher = node.create_publisher(CampaignProgress, "campaign_progress", LATCHED_QOS)

        def publish_progress(progress: typing.Any) -> None:
            eta = progress.eta_s
            progress_publisher.publish(CampaignProgress(run_id=spec.run_id, done=progress.done, total=progress.total,
                                                        eta_s=math.nan if eta is None else float(eta)))

        stop_rule = None
        if comparison is not None:   # the logger holds the earlier outcomes: this session's pairs decide
            from rollability_ros.core.campaign import comparison_stop_rule, paired_order

            plan = paired_order(plan, *comparison)
            stop_rule = comparison_stop_rule([], *comparison, alpha)
        report = run_campaign(plan, spec.run_id, stored, rig.launch, acknowledgements, ask=ask, say=say,
                              on_progress=publish_progress, stop_rule=stop_rule)
        if report.stopped_reason and ask is not None:
            report = dataclasses.replace(report, advice=rig.valve_advice())
        return report
    finally:
        # while the context is valid: an executor left to the garbage collector after rclpy's shutdown prints an
        # InvalidHandle traceback at exit
        executor.shutdown()


def main(args: typing.Optional[typing.List[str]] = None) -> int:
    init_ros(args)
    node = None
    try:
        # a supervisor's SIGTERM ends the campaign as Ctrl-C does: the running goal is cancelled, the context stays
        # valid until the node is destroyed. SIGINT is set too: a process started in the background of a script
        # inherits SIGINT ignored, and Python keeps an ignored SIGINT ignored (run_node sets both for the other
        # nodes). Inside the try: a signal right after its handler is set is a stop, not a traceback
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, signal.default_int_handler)
        node = Node("campaign_runner")
        spec = declare_settings(node, "campaign", CampaignSpec)
        settings = declare_settings(node, "runner", RunnerSettings)
        session = declare_settings(node, "session", SessionSettings, read_only=True)
        ask = TerminalAsk() if launch_backend_class(settings.backend).attended else None
        return report_exit_code(run_graph_campaign(node, spec, settings, ask, session=session.id),
                                resume="the same command with -p runner.resume:=true")
    except (ParameterError, ConfigError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("campaign_runner: stopped by a stop signal", file=sys.stderr)
        return 130
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    raise SystemExit(main())
