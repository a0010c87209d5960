"""outcome_logger node: stores every launch outcome, candidate, generation and tip event before acknowledging it.

Subscriptions (reliable, deep queue; :data:`RECORD_QOS`):
  ``launch_outcomes`` (rollability_ros/LaunchOutcome), ``candidates`` (rollability_ros/CandidateResult),
  ``generations`` (rollability_ros/GenerationSummary), ``tip_events`` (rollability_ros/TipEvent).
Publications:
  ``summary`` (rollability_ros/OutcomeSummary, latched): every run's counts and per-configuration success rates,
  published at start-up and after every stored outcome or candidate.
  ``outcomes_stored`` (rollability_ros/OutcomeStored, reliable, transient-local, deep history; :data:`RECORD_QOS`):
  one acknowledgement per launch outcome committed to the store (or found already stored), keyed by run and
  trial id; the campaign runner counts a trial as done on it, so it never needs the logger's disk.
Services:
  ``get_summary`` (rollability_ros/GetSummary): the same summary, optionally for one run.
  ``stored_trials`` (rollability_ros/GetStoredTrials): the trial ids stored for a run (what a resumed campaign
  skips).
Parameters:
  ``store_path`` (string, default ``runs/outcomes.sqlite``): SQLite store file or run directory; fixed at
  start-up.
  ``session_key_file`` (string, default "": ``valve.session_key_file``'s default for this domain and namespace):
  the valve_controller's key file, to verify physical outcomes.
  ``session.id`` (string, default "": none) and ``session_runs`` (string array): the logger of a session stores
  only its session's runs (:class:`~rollability_ros.core.results.outcome_log.SessionGate`): a ``stored_trials``
  request of another session is refused, and a launch outcome of a run not of this session, or a candidate or
  generation whose ``session`` is another's, is refused, logged once per run, never stored nor acknowledged.

Physical outcomes are stored only with the rig's record signature (``auth``, made with the valve's session key for
a launch whose goal the operator's tools signed: :mod:`rollability_ros.core.rig.rig_auth`); an unsigned or forged
one is refused with a warning, not stored and not acknowledged. So a logger that stores physical outcomes runs on
the rig computer, as the user of the valve_controller (sim outcomes need no key: any computer).

Run info: with each new launch outcome the logger records its campaign in the store's runs table (backend, and the
twin the rig says it launched in, ``LaunchOutcome.twin``, filed relative to the store's folder:
:func:`~rollability_ros.core.rig.launched_twin.merge_twin`), which ``rollability campaign --resimulate`` reads; it
never reads the rig's files.

Acknowledgement: a record is acknowledged -- the INFO line ``stored <kind> <key>``, for outcomes the
``outcomes_stored`` message, and for outcomes and candidates the summary that counts it -- only after the store has committed (fsynced) it, so every
acknowledged record survives ``kill -9``. A duplicate key (same run and trial id, ...) is stored once and logged
as a duplicate; a malformed message is logged with the reason and skipped; a store failure (disk full, locked)
is logged as an error and the record is not acknowledged.
"""
import typing

from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node

from rollability_ros.core.config import SessionSettings
from rollability_ros.core.results import OutcomeLog, OutcomeLoggerSettings, SessionGate, StoreFailure
from rollability_ros.core.store import unique_key
from rollability_ros.core.rig import RecordGuard, default_key_path, twin_from_text
from rollability_ros.msg import (CandidateResult, ConfigurationSummary, GenerationSummary, LaunchOutcome,
                                 OutcomeStored, OutcomeSummary, TipEvent)
from rollability_ros.nodes import _convert
from rollability_ros.nodes._support import LATCHED_QOS, RECORD_QOS, ParameterError, declare_settings, run_node
from rollability_ros.srv import GetStoredTrials, GetSummary

#: topic -> (message type, message -> record, what the log calls it)
_RECORD_TOPICS = {
    "launch_outcomes": (LaunchOutcome, _convert.outcome_from_msg, "launch outcome"),
    "candidates": (CandidateResult, _convert.candidate_from_msg, "candidate"),
    "generations": (GenerationSummary, _convert.generation_from_msg, "generation summary"),
    "tip_events": (TipEvent, _convert.tip_event_from_msg, "tip event"),
}


def summary_to_msg(summary: typing.Any) -> typing.Any:
    """:class:`~rollability_ros.core.results.outcome_log.LogSummary` -> ``OutcomeSummary``."""
    msg = OutcomeSummary(trials=summary.trials, candidates=summary.candidates)
    msg.header.stamp = _convert.s_to_stamp(summary.latest_stamp_s)
    msg.configurations = [
        ConfigurationSummary(configuration=tally.configuration, trials=tally.trials, successes=tally.successes,
                             success_rate=float(tally.success_rate), ci_low=float(tally.ci_low),
                             ci_high=float(tally.ci_high))
        for tally in summary.configurations]
    return msg


class OutcomeLoggerNode(Node):
    """Thin adapter: messages -> records -> :class:`OutcomeLog`; summary topic and service."""

    def __init__(self):
        super().__init__("outcome_logger")
        settings = declare_settings(self, "", OutcomeLoggerSettings, read_only=True)
        try:
            self.log = OutcomeLog.open(settings.store_path)
        except ValueError as exc:
            raise ParameterError(f"store_path: {exc}") from exc
        session = declare_settings(self, "session", SessionSettings, read_only=True)
        self.session_gate = SessionGate(session.id, settings.session_runs, self.log.store)
        self.record_guard = RecordGuard(
            settings.session_key_file or default_key_path(self.get_namespace()))
        self.add_on_set_parameters_callback(self._refuse_store_change)
        self.summary_publisher = self.create_publisher(OutcomeSummary, "summary", LATCHED_QOS)
        self.stored_publisher = self.create_publisher(OutcomeStored, "outcomes_stored", RECORD_QOS)
        records_group = MutuallyExclusiveCallbackGroup()   # one writer: records are stored in arrival order
        for topic, (msg_type, convert, kind) in _RECORD_TOPICS.items():
            self.create_subscription(msg_type, topic, self._make_callback(convert, kind), RECORD_QOS,
                                     callback_group=records_group)
        self.create_service(GetSummary, "get_summary", self._get_summary, callback_group=ReentrantCallbackGroup())
        self.create_service(GetStoredTrials, "stored_trials", self._stored_trials,
                            callback_group=ReentrantCallbackGroup())
        summary = self.log.summary()
        self.summary_publisher.publish(summary_to_msg(summary))
        self.get_logger().info(f"storing to {self.log.store.path}: {summary.trials} launch outcomes and "
                               f"{summary.candidates} candidates already stored")

    def _refuse_store_change(self, params):
        fixed = [p.name for p in params if p.name in ("store_path", "session_key_file")]
        if fixed:
            return SetParametersResult(successful=False, reason=f"{fixed[0]} is fixed at start-up; restart the node")
        return SetParametersResult(successful=True)

    def _make_callback(self, convert, kind):
        def on_message(msg: typing.Any) -> None:
            self._store(msg, convert, kind)
        return on_message

    def _store(self, msg, convert, kind):
        logger = self.get_logger()
        try:
            record = convert(msg)
            key = "/".join(str(part) for part in unique_key(record))
            refusal = self.session_gate.refusal(record)
            if refusal:
                if self.session_gate.first_refusal(record.run_id):
                    logger.warning(f"refused {kind} {key}: {refusal}; NOT stored (later refusals of run "
                                   f"{record.run_id} are not logged)")
                return
            if kind == "launch outcome":
                authentic, reason = self.record_guard.check(_convert.signature_from_msg(msg.auth), record)
                if not authentic:
                    logger.warning(f"refused {record.backend} {kind} {key}: {reason}; NOT stored",
                                   throttle_duration_sec=1.0)
                    return
                stored = self.log.add(record, self._twin(msg, key))
            else:
                stored = self.log.add(record)
        except (ValueError, TypeError) as exc:
            logger.warning(f"skipped malformed {kind}: {exc}")
            return
        except StoreFailure as exc:
            logger.error(f"STORE FAILURE: {kind} {key} NOT stored and NOT acknowledged: {exc}")
            return
        if kind == "launch outcome":
            self._acknowledge(record, duplicate=not stored)
        if not stored:
            logger.warning(f"duplicate {kind} {key}: already stored, ignored")
            return
        logger.info(f"stored {kind} {key}")
        if kind in ("launch outcome", "candidate"):
            self.summary_publisher.publish(summary_to_msg(self.log.summary()))

    def _twin(self, msg, key):
        """The twin the rig says it launched in (``msg.twin``); None, with a warning, when it is malformed (the
        outcome is stored all the same: the run then records no twin, and a re-simulation says so)."""
        try:
            return twin_from_text(msg.twin)
        except ValueError as exc:
            self.get_logger().warning(f"launch outcome {key}: {exc}; its run's twin NOT recorded",
                                      throttle_duration_sec=1.0)
            return None

    def _acknowledge(self, outcome, duplicate):
        """Tell the graph the outcome is on disk (a duplicate is too: its first copy is)."""
        msg = OutcomeStored(run_id=outcome.run_id, trial_id=outcome.trial_id, duplicate=duplicate)
        msg.header.stamp = self.get_clock().now().to_msg()
        self.stored_publisher.publish(msg)

    def _stored_trials(self, request, response):
        if not request.run_id:
            response.success, response.message = False, "run_id must be non-empty"
            return response
        try:
            refusal = self.session_gate.announce(request.session, request.run_id)
            if refusal:
                if self.session_gate.first_refusal(request.run_id):
                    self.get_logger().warning(f"stored_trials: {refusal}")
                response.success, response.message = False, refusal
                return response
            response.trial_ids = sorted(self.log.store.trial_ids(request.run_id))
        except Exception as exc:  # a service must answer: the caller gets the reason instead of a timeout
            response.success, response.message = False, f"store {self.log.store.path} not readable: {exc}"
            return response
        response.success = True
        return response

    def _get_summary(self, request, response):
        response.summary = summary_to_msg(self.log.summary(request.run_id or None))
        return response

    def close(self) -> None:
        """Close the store (run_node calls this before destroying the node)."""
        self.log.close()


def main(args: typing.Optional[typing.List[str]] = None) -> int:
    return run_node(OutcomeLoggerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
