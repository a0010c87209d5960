"""The outcome logger's bookkeeping: store a record durably before it is acknowledged, and keep a summary.

:class:`OutcomeLog` wraps a :class:`~rollability_ros.core.store.Store`. ``add(record)`` returns only after the
record is committed (the store fsyncs its write-ahead log), so a caller that acknowledges on return never
acknowledges a record a ``kill -9`` can lose. It says what happened in the way the caller must act on:

- returns True: stored now -- acknowledge it;
- returns False: a record with the same key (e.g. the run's trial id) is already stored -- stored once, a
  duplicate to report, not a new record;
- raises ``ValueError``: the record is malformed (names the field) -- skip it;
- raises :class:`StoreFailure`: the store could not write it (disk full, locked, read-only) -- do NOT
  acknowledge.

The running summary (per configuration: trials, upright trials, rate, Wilson 95 % interval) is rebuilt from
the store on opening and updated with each stored outcome, so it always describes exactly the stored records.
"""
import collections
import dataclasses
import os
import sqlite3
import threading
import typing

from rollability_ros.core.results.analysis import ConditionResult, summarise
from rollability_ros.core.records import CandidateRecord, GenerationRecord, LaunchOutcome, TipEventRecord
from rollability_ros.core.rig import NO_TWIN, launch_backend_class, merge_twin
from rollability_ros.core.store import Store, StoreDamaged, unique_key

if typing.TYPE_CHECKING:  # annotations only
    from rollability_ros.core.record_messages import Record

#: Store file used when no ``store_path`` is given (relative to the working directory).
DEFAULT_STORE_PATH = "runs/outcomes.sqlite"


class SessionGate:
    """Which records the outcome logger of session ``session_id`` stores (docs/sessions.md): launch outcomes of runs
    listed in ``runs``, of runs already in the store, and of runs a campaign runner of the same session announced
    (:meth:`announce`, recorded in the store's runs table so a restarted logger knows them); candidates and
    generations whose ``session`` (the optimizer's, carried in each message) is this session's, whatever their run
    id, so two sessions' runs of one id (a study's ``optimization``) never mix. Tip events are not runs: always
    stored. Without a session id, everything (a logger outside any session)."""

    def __init__(self, session_id: str, runs: typing.Sequence[str], store: Store) -> None:
        self.session_id = session_id
        self._store = store
        self._runs = set(runs) | (set(store.run_ids()) if session_id else set())
        self._refused: typing.Set[str] = set()

    def announce(self, session: str, run_id: str) -> str:
        """"" when a runner of this session announces ``run_id`` (it is then this session's run), else the refusal."""
        if not self.session_id:
            return ""
        if session != self.session_id:
            return (f"run {run_id} of session {session or '(none)'} refused: this outcome_logger stores session "
                    f"{self.session_id} only (join that session with --session)")
        if run_id not in self._runs:
            self._runs.add(run_id)
            if self._store.run_info(run_id) is None:
                self._store.set_run_info(run_id, "campaign", {"session": session})
        return ""

    def refusal(self, record: "Record") -> str:
        """"" when ``record`` belongs to this session, else why it is refused."""
        if not self.session_id or isinstance(record, TipEventRecord):
            return ""
        if isinstance(record, (CandidateRecord, GenerationRecord)):   # the optimizer names its session
            if record.session != self.session_id:
                return (f"run {record.run_id} of session {record.session or '(none)'} is not of session "
                        f"{self.session_id}")
            return ""
        if record.run_id in self._runs:
            return ""
        return f"run {record.run_id} is not a run of session {self.session_id}"

    def first_refusal(self, run_id: str) -> bool:
        """True the first time a record of ``run_id`` is refused (refusals are logged once per run)."""
        first = run_id not in self._refused
        self._refused.add(run_id)
        return first


class StoreFailure(RuntimeError):
    """The store could not write a well-formed record; it is not stored and must not be acknowledged."""


@dataclasses.dataclass(frozen=True)
class OutcomeLoggerSettings:
    """Settings of the outcome logger node."""

    store_path: str = dataclasses.field(default=DEFAULT_STORE_PATH, metadata={
        "description": "SQLite store file (or a run directory, then <dir>/store.sqlite); created with its "
                       f"parent directories if missing; relative to the working directory. "
                       f"Default {DEFAULT_STORE_PATH}. Fixed at start-up."})
    session_key_file: str = dataclasses.field(default="", metadata={
        "description": "the valve_controller's session key file, to verify the rig's signature on physical launch "
                       "outcomes (a physical outcome without a valid one is not stored); \"\" = the default of "
                       "valve.session_key_file for this ROS domain and namespace. Fixed at start-up."})
    session_runs: typing.List[str] = dataclasses.field(default_factory=list, metadata={
        "description": "with session.id: the run ids of this session whose launch outcomes are stored besides the "
                       "runs its campaign runners announce (stored_trials) and those already stored (candidates "
                       "and generations are stored when their session is this one, whatever their run). Fixed at "
                       "start-up."})

    def validate(self) -> None:
        """Raise ``ValueError`` for an unusable store path."""
        if not isinstance(self.store_path, str) or not self.store_path.strip():
            raise ValueError("store_path must be a non-empty path")
        if "\0" in self.store_path:
            raise ValueError("store_path must not contain NUL characters")
        if os.path.exists(self.store_path) and not (os.path.isfile(self.store_path)
                                                    or os.path.isdir(self.store_path)):
            raise ValueError(f"store_path {self.store_path} is neither a file nor a directory")


@dataclasses.dataclass(frozen=True)
class LogSummary:
    """What the store holds (every run, or one): counts, newest outcome stamp and per-configuration tallies."""

    trials: int                # launch outcomes stored
    candidates: int            # candidate results stored
    latest_stamp_s: float      # stamp of the newest stored outcome, s since the epoch; 0.0 when none
    configurations: tuple      # ConfigurationTally per configuration, sorted by id


@dataclasses.dataclass(frozen=True)
class ConfigurationTally:
    """Stored launch outcomes of one configuration: trials, upright ones, rate and its Wilson 95 % interval."""

    configuration: str
    trials: int
    successes: int
    success_rate: float        # successes / trials, [0, 1]; NaN with no trials
    ci_low: float
    ci_high: float


class RunningSummary:
    """Tallies of stored records per run: grouped conditions of launch outcomes, candidate counts, latest stamp.

    Not thread-safe by itself; :class:`OutcomeLog` guards it.
    """

    def __init__(self):
        self._conditions: typing.DefaultDict[str, typing.Dict[typing.Any, typing.Tuple[int, int]]] = \
            collections.defaultdict(dict)                                  # run_id -> {group_key: (successes, trials)}
        self._candidates: typing.Counter[str] = collections.Counter()      # run_id -> candidates stored
        self._latest_stamp_s = {}                                          # run_id -> newest outcome stamp, s

    def add_outcome(self, outcome: LaunchOutcome) -> None:
        """Count a stored :class:`LaunchOutcome` (an invalid launch is stored but not counted)."""
        self._latest_stamp_s[outcome.run_id] = max(self._latest_stamp_s.get(outcome.run_id, 0.0),
                                                   outcome.stamp_s)
        if not outcome.valid:
            return
        tally = self._conditions[outcome.run_id]
        successes, trials = tally.get(outcome.condition.group_key, (0, 0))
        tally[outcome.condition.group_key] = (successes + bool(outcome.upright), trials + 1)

    def add_candidate(self, candidate: CandidateRecord) -> None:
        """Count a stored :class:`CandidateRecord`."""
        self._candidates[candidate.run_id] += 1

    def _runs(self, table, run_id):
        return list(table.values()) if run_id is None else ([table[run_id]] if run_id in table else [])

    def trials(self, run_id: typing.Optional[str] = None) -> int:
        """Launch outcomes stored (every run, or ``run_id``)."""
        return sum(trials for tally in self._runs(self._conditions, run_id) for _, trials in tally.values())

    def candidates(self, run_id: typing.Optional[str] = None) -> int:
        """Candidate results stored (every run, or ``run_id``)."""
        return sum(self._runs(self._candidates, run_id))

    def latest_stamp_s(self, run_id: typing.Optional[str] = None) -> float:
        """Stamp of the newest stored outcome, s since the epoch; 0.0 when none."""
        return max(self._runs(self._latest_stamp_s, run_id), default=0.0)

    def conditions(self, run_id: typing.Optional[str] = None) -> typing.List[ConditionResult]:
        """Grouped conditions (:class:`~rollability_ros.core.results.analysis.ConditionResult`) of the stored outcomes."""
        counts: typing.Dict[typing.Tuple[str, float, float, float], typing.Tuple[int, int]] = {}
        for tally in self._runs(self._conditions, run_id):
            for key, (successes, trials) in tally.items():
                merged_successes, merged_trials = counts.get(key, (0, 0))
                counts[key] = (merged_successes + successes, merged_trials + trials)
        return [ConditionResult(*key, successes, trials) for key, (successes, trials) in sorted(counts.items())]

    def configurations(self, run_id: typing.Optional[str] = None) -> typing.List["ConfigurationTally"]:
        """One :class:`ConfigurationTally` per configuration id, sorted by id."""
        tallies = []
        for cell in summarise(self.conditions(run_id), by=("configuration",)):
            low, high = cell.trial_ci
            tallies.append(ConfigurationTally(cell.key["configuration"], cell.trials, cell.successes,
                                              cell.trial_rate, low, high))
        return tallies


def _check_record(record):
    """Raise ``ValueError`` naming the first field that makes ``record`` unstorable."""
    owner = unique_key(record)[0]
    if not owner:
        raise ValueError(f"{type(record).__name__}: {'robot' if isinstance(record, TipEventRecord) else 'run_id'}"
                         " must be non-empty")
    record.validate()


class OutcomeLog:
    """Durable, deduplicating log of run records with a running summary; thread-safe.

    Parameters
    ----------
    store : Store
        An open store; the summary is rebuilt from what it already holds.
    """

    def __init__(self, store):
        self.store = store
        self._lock = threading.Lock()
        self._summary = RunningSummary()
        for outcome in store.launch_outcomes():
            self._summary.add_outcome(outcome)
        for candidate in store.candidates():
            self._summary.add_candidate(candidate)
        self._writers = {LaunchOutcome: store.add_launch_outcome, CandidateRecord: store.add_candidate,
                         GenerationRecord: store.add_generation, TipEventRecord: store.add_tip_event}

    @classmethod
    def open(cls, path: str) -> "OutcomeLog":
        """Open (or create, with parent directories) the store at ``path``; ``ValueError`` if unusable."""
        directory = os.path.dirname(os.fspath(path))
        if directory:
            try:
                os.makedirs(directory, exist_ok=True)
            except OSError as exc:
                raise ValueError(f"cannot create the store directory {directory}: {exc}") from exc
        return cls(Store(path))

    def close(self) -> None:
        """Close the store (idempotent)."""
        self.store.close()

    def add(self, record: typing.Union[LaunchOutcome, CandidateRecord, GenerationRecord, TipEventRecord],
            twin: typing.Optional[dict] = None) -> bool:
        """Store ``record`` durably; True if stored now, False if its key was already stored. ``twin``: for a launch
        outcome, the rig's record of the twin it launched in (:func:`~rollability_ros.core.rig.launched_twin.
        launched_twin`), filed in the run's info with the outcome (None: the rig did not say).

        Raises ``ValueError`` for a malformed record and :class:`StoreFailure` when the store cannot write.
        """
        writer = self._writers.get(type(record))
        if writer is None:
            raise ValueError(f"the outcome log holds no {type(record).__name__} records")
        _check_record(record)
        with self._lock:
            try:
                stored = writer(record)
            except (sqlite3.Error, StoreDamaged, OSError) as exc:
                raise StoreFailure(f"{self.store.path}: {exc}") from exc
            if stored and isinstance(record, LaunchOutcome):
                self._summary.add_outcome(record)
                self._describe_campaign(record, twin or {})
            elif stored and isinstance(record, CandidateRecord):
                self._summary.add_candidate(record)
        return stored

    def _describe_campaign(self, outcome, twin):
        """Put ``outcome``'s campaign in the store's ``runs`` table (kind ``campaign``, its backend, the ``twin`` its
        rig launched in, filed relative to the store's folder: :func:`~rollability_ros.core.rig.launched_twin.
        merge_twin`) when no one described it so yet: a campaign run through the graph never opens the store, so
        the logger records every campaign it stores outcomes of. Keeps what the campaign itself recorded (designs);
        a run whose outcomes come from two backends says ``mixed``, from two twins ``differs_between_sessions``; a
        backend that re-simulates nothing (the physical rig) records that it launched on no twin. Lock held."""
        if launch_backend_class(outcome.backend).resimulate_refusal():
            # launched on no twin, whatever the message claims (a physical record's signature does not cover it)
            twin = {NO_TWIN: outcome.backend}
        try:
            described = self.store.run_info(outcome.run_id)
            info = dict(described["info"]) if described else {}
            backend = info.get("backend")
            changed = merge_twin(info, twin, os.path.dirname(os.path.abspath(self.store.path)))
            if described and backend in (outcome.backend, "mixed") and not changed:
                return
            if backend not in (outcome.backend, "mixed"):
                info["backend"] = outcome.backend if backend is None else "mixed"
            self.store.set_run_info(outcome.run_id, described["kind"] if described else "campaign", info)
        except (sqlite3.Error, StoreDamaged, OSError) as exc:
            raise StoreFailure(f"{self.store.path}: {exc}") from exc

    def summary(self, run_id: typing.Optional[str] = None) -> "LogSummary":
        """A :class:`LogSummary` of every run, or of ``run_id`` (empty for an unknown run)."""
        with self._lock:
            return LogSummary(self._summary.trials(run_id), self._summary.candidates(run_id),
                              self._summary.latest_stamp_s(run_id), tuple(self._summary.configurations(run_id)))
