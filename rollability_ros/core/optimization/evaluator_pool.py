"""Spread a batch of profile evaluations over the evaluators currently available, with retries and timeouts.

The optimizer node binds :class:`EvaluatorPool` to EvaluateProfile action clients; tests bind it to plain
functions. The pool knows evaluators only by name and reaches them through one injected function::

    submit(evaluator_name, request, ticket) -> cancel (callable or None)

``submit`` starts evaluating ``request`` (an :class:`EvaluationRequest`: trials ``first_trial`` ..
``first_trial + trials - 1`` of the evaluation with ``seed``) on that evaluator and returns at once; later, from
any thread, it reports through ``ticket``: :meth:`Ticket.progress` whenever the evaluator shows it is alive (goal
accepted, feedback), then exactly one of :meth:`Ticket.succeed` or :meth:`Ticket.fail`. The returned
``cancel()`` asks the evaluator to drop the request (best effort; a report after that is ignored). If ``submit``
raises, that attempt failed.

Rules
-----
- At most one request in flight per evaluator; the rest of the batch waits in a queue.
- Splitting: when fewer requests are queued than evaluators are idle (a lone re-evaluation, the last survivors of
  a race), the queued requests' trials are split into contiguous trial-index ranges, one per idle evaluator
  (shares as equal as whole trials allow, at least one trial each), and the parts' results are merged back into
  one result per request. Trial ``i`` of an evaluation always runs with ``trial_seed(seed, i)`` and, for every
  fidelity, its kind, launch condition and draws depend on nothing but ``i`` and that seed
  (:mod:`rollability_ros.core.sim.evaluation`), so the merged successes, trials and per-trial results are those
  of the unsplit evaluation. A part must report its per-trial results, and their indices must be exactly its
  range (else the attempt failed). A request marked ``whole`` (the optimizer's raced stages) is never split, nor
  is anything with ``PoolSettings.split_trials`` off. A merged result's ``eval_time_s`` is the sum of its parts'
  (the evaluator time it cost, as an unsplit evaluation's is; its wall span was shorter) and its ``evaluator``
  names the parts' evaluators in trial order joined by ``+``.
- A failed attempt (rejected, aborted, a malformed result, no sign of life for ``timeout_s``, or the evaluator
  disappearing mid-request) is never a result: the request (or the part) goes back to the front of the queue and
  is retried, on an evaluator it has not failed on while one exists, else on any. The evaluator that failed gets
  no new request for ``retry_delay_s``, doubled for each further failure in a row (at most 64x; a success resets
  it), so a dead evaluator still listed in the graph costs few timeouts. After ``max_attempts`` failed attempts
  of one request (a part counts the failures of the request it came from) the batch raises
  :class:`EvaluationFailed` (0 = retry without limit).
- With no evaluator available the batch waits (and says so through ``log`` every ``waiting_log_period_s``);
  it never guesses a result. :meth:`EvaluatorPool.pause` holds back new requests (those in flight finish).
- :meth:`EvaluatorPool.close` makes a waiting batch raise :class:`PoolClosed` and cancels what is in flight.
"""
import collections
import dataclasses
import logging
import threading
import time
import typing
from collections.abc import Callable, Iterable

from rollability_ros.core import config


#: Largest multiple of ``retry_delay_s`` an evaluator rests after consecutive failures.
MAX_BACKOFF = 64


class EvaluationFailed(RuntimeError):
    """A batch cannot get real results: one request failed ``max_attempts`` times (the message lists why)."""


class PoolClosed(EvaluationFailed):
    """The pool was closed while a batch was waiting for results."""


@dataclasses.dataclass(frozen=True)
class PoolSettings:
    """How patiently the pool waits and retries (the optimizer node's ``evaluator_*`` parameters).

    ``timeout_s``: an attempt with no sign of life (accept, feedback, result) for this long, s, is given up.
    ``max_attempts``: failed attempts of one request before the batch fails; 0 = retry without limit.
    ``retry_delay_s``: an evaluator that failed an attempt gets no new request for this long, s (doubled per
    further consecutive failure of that evaluator, at most :data:`MAX_BACKOFF` times).
    ``waiting_log_period_s``: how often a batch waiting with no evaluator says so, s.
    ``split_trials``: split the queued requests' trials over idle evaluators when fewer requests are queued than
    evaluators are idle (module docstring); the merged results equal the unsplit ones.
    """

    timeout_s: float = dataclasses.field(default=120.0, metadata={
        "description": "s without any reply (accept, feedback, result) after which an evaluation is given up and "
                       "retried elsewhere", "range": (0.0, 604800.0), "exclusive": "low"})
    max_attempts: int = dataclasses.field(default=10, metadata={
        "description": "failed attempts of one candidate before the run pauses and reports; 0 = retry without limit",
        "range": (0, 1000000)})
    retry_delay_s: float = dataclasses.field(default=1.0, metadata={
        "description": "s an evaluator that failed gets no new evaluation", "range": (0.0, 3600.0)})
    waiting_log_period_s: float = dataclasses.field(default=30.0, metadata={
        "description": "s between two messages of a batch waiting with no evaluator", "range": (0.0, 86400.0),
        "exclusive": "low"})
    split_trials: bool = dataclasses.field(default=True, metadata={
        "description": "split a request's trials over idle evaluators when a batch has fewer requests than idle "
                       "evaluators (the merged result equals the unsplit one)"})


@dataclasses.dataclass(frozen=True)
class EvaluationRequest:
    """One profile to evaluate: heights ``(n_variables,)`` in simulation units, trials, disturbance seed, and the
    evaluation fidelity (``""``/``screen``: the evaluator's objective; ``launch``: robust twin launches;
    ``world:<seed>``: launches in one world).

    ``first_trial``: the request runs trials ``first_trial`` .. ``first_trial + trials - 1`` of the evaluation with
    ``seed`` (0 = from the first; the pool sets it on the parts of a split request). ``whole``: never split it.
    """

    heights: tuple
    trials: int
    seed: int
    fidelity: str = ""
    first_trial: int = 0
    whole: bool = False

    @property
    def trial_range(self) -> range:
        """The trial indices this request runs."""
        return range(self.first_trial, self.first_trial + self.trials)


class TrialReport(typing.Protocol):
    """What the pool reads of one trial's reported outcome (a TrialOutcome, a TrialResult message)."""

    @property
    def index(self) -> int:
        """The trial's index in its evaluation."""

    @property
    def upright(self) -> bool:
        """True when the trial ended upright."""


@dataclasses.dataclass(frozen=True)
class PoolEvaluationResult:
    """A real result: upright trials out of ``trials``, evaluation time (s), the evaluator's name, and the
    per-trial outcomes by index when the evaluator reported them (``()`` otherwise).

    A result merged from the parts of a split request (module docstring) has the parts' summed times (the
    evaluator time it cost) and their evaluators' names joined by ``+`` in trial order.
    """

    successes: int
    trials: int
    eval_time_s: float
    evaluator: str
    trial_results: tuple = ()

    def as_tuple(self) -> tuple[int, int, float, str]:
        """``(successes, trials, eval_time_s, evaluator)``, the ``evaluate_batch`` contract of optimization_run."""
        return (self.successes, self.trials, self.eval_time_s, self.evaluator)


#: What ``evaluate_batch`` / ``evaluate`` return: ``(successes, trials, eval_time_s, evaluator)`` per candidate.
BatchResults = typing.List[typing.Tuple[int, int, float, str]]


def result_problem(request: EvaluationRequest, successes: int, trials: int,
                   trial_results: typing.Sequence[TrialReport] = (), part: bool = False) -> str | None:
    """Why a reported result cannot be the result of ``request`` (None if it can): the trial count, the successes,
    and the per-trial results when given (their indices must be exactly ``request.trial_range``, their upright ones
    the successes); a ``part`` of a split request must give them."""
    if trials != request.trials:
        return f"returned {trials} trials for {request.trials} requested"
    if not 0 <= successes <= trials:
        return f"returned {successes} successes of {trials} trials"
    if not trial_results:
        return "returned no per-trial results for a part of a split request" if part else None
    wanted = request.trial_range
    indices = [int(trial.index) for trial in trial_results]
    if indices != list(wanted):
        shown = f"{indices[0]}..{indices[-1]}" if indices else "none"
        return (f"returned trials {shown} ({len(indices)}) for trials {wanted.start}..{wanted.stop - 1} requested "
                "(an evaluator that ignores first_trial?)")
    upright = sum(bool(trial.upright) for trial in trial_results)
    if upright != successes:
        return f"returned {successes} successes but {upright} upright trials"
    return None


def merged_result(parts: typing.Sequence[tuple[EvaluationRequest, PoolEvaluationResult]]) -> PoolEvaluationResult:
    """One result of a split request from its parts' ``(request, result)``: summed successes, trials and times,
    the per-trial results joined in trial order, the evaluators' names joined by ``+`` (each once, trial order)."""
    ordered = sorted(parts, key=lambda part: part[0].first_trial)
    if len(ordered) == 1:
        return ordered[0][1]
    results = [result for _, result in ordered]
    names = list(dict.fromkeys(result.evaluator for result in results))
    return PoolEvaluationResult(sum(r.successes for r in results), sum(r.trials for r in results),
                                sum(r.eval_time_s for r in results), "+".join(names),
                                tuple(trial for r in results for trial in r.trial_results))


def split_request(request: EvaluationRequest, parts: int) -> list[EvaluationRequest]:
    """``request`` as ``parts`` requests of contiguous trial ranges in order (sizes differ by at most one trial;
    at most ``request.trials`` parts)."""
    parts = max(1, min(int(parts), request.trials))
    size, extra = divmod(request.trials, parts)
    pieces, first = [], request.first_trial
    for number in range(parts):
        trials = size + (number < extra)
        pieces.append(dataclasses.replace(request, first_trial=first, trials=trials))
        first += trials
    return pieces


def split_counts(trials: typing.Sequence[int | None], evaluators: int) -> list[int]:
    """How many parts each of the queued requests of ``trials`` trials (None: may not be split) is split into so
    that the parts fill ``evaluators`` idle evaluators: one each, then one more at a time to the request whose
    parts would stay largest (never more parts than trials)."""
    counts = [1] * len(trials)
    splittable = [(i, n) for i, n in enumerate(trials) if n is not None]
    for _ in range(evaluators - len(trials)):
        room = [(n / counts[i], -i) for i, n in splittable if counts[i] < n]
        if not room:
            break
        counts[-max(room)[1]] += 1   # the widest parts; ties: the earlier request
    return counts


class Ticket:
    """One attempt of one request on one evaluator; ``submit`` reports through it, from any thread."""

    def __init__(self, pool: "EvaluatorPool", job: "_Job", evaluator: str, now_s: float) -> None:
        self._pool = pool
        self.job = job
        self.evaluator = evaluator
        self.deadline_s = now_s + pool.settings.timeout_s
        self.cancel: Callable[[], object] | None = None
        self.done = False

    @property
    def request(self) -> EvaluationRequest:
        """The :class:`EvaluationRequest` being attempted."""
        return self.job.request

    def progress(self) -> None:
        """The evaluator is alive and working on it: restart the timeout."""
        self._pool._touch(self)

    def succeed(self, successes: int, trials: int, eval_time_s: float, evaluator: str | None = None,
                trial_results: typing.Sequence[TrialReport] = ()) -> None:
        """Report the result (``evaluator``: the name the result is credited to; default the pool's name;
        ``trial_results``: each trial's outcome, by index, required of a part of a split request)."""
        self._pool._finish(self, PoolEvaluationResult(int(successes), int(trials), float(eval_time_s),
                                                      str(evaluator or self.evaluator), tuple(trial_results)), None)

    def fail(self, reason: str) -> None:
        """Report that this attempt produced no result, and why."""
        self._pool._finish(self, None, str(reason))


@dataclasses.dataclass(eq=False)
class _Job:
    index: int                  # the batch position of the request (a part's: the request it came from)
    request: EvaluationRequest  # what is sent: the request, or a part's trial range of it
    failures: list = dataclasses.field(default_factory=list)   # "evaluator: reason" per failed attempt
    failed_on: set = dataclasses.field(default_factory=set)
    part: bool = False          # a part of a split request

    @property
    def name(self) -> str:
        """How messages name it: ``candidate <index>``, with a part's trial range."""
        trials = self.request.trial_range
        return f"candidate {self.index}" + (f" (trials {trials.start}..{trials.stop - 1})" if self.part else "")


@dataclasses.dataclass(eq=False)
class _Evaluator:
    name: str
    ticket: typing.Optional[Ticket] = None
    resting_until_s: float = 0.0
    failures_in_a_row: int = 0


@dataclasses.dataclass(eq=False)
class _Batch:
    requests: list              # the batch's requests, by index
    queue: collections.deque    # jobs waiting for an evaluator
    jobs: list                  # every job of the batch, the parts of split requests included
    parts: dict = dataclasses.field(default_factory=dict)     # index -> [(request, result)] of finished jobs
    results: dict = dataclasses.field(default_factory=dict)   # index -> the request's (merged) result
    gave_up: str = ""


def _default_log(level, message):
    getattr(logging.getLogger(__name__), level)(message)


class EvaluatorPool:
    """Evaluates batches of :class:`EvaluationRequest` on the named evaluators; see the module docstring.

    Parameters
    ----------
    submit : callable(evaluator_name, EvaluationRequest, Ticket) -> cancel callable or None
    settings : PoolSettings
    log : callable(level, message), optional
        ``level`` is ``"info"``, ``"warning"`` or ``"error"``; default: the ``logging`` module.
    clock : callable, optional
        Monotonic clock, s.

    One batch at a time (:meth:`evaluate` is called by one optimization thread); evaluators are updated from any
    thread with :meth:`set_evaluators`.
    """

    def __init__(self, submit: Callable[[str, EvaluationRequest, Ticket], Callable[[], object] | None],
                 settings: PoolSettings | None = None, log: Callable[[str, str], None] = _default_log,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.settings = settings or PoolSettings()
        config.check_settings(self.settings, "evaluator")   # the optimizer node's evaluator_* parameters
        self._submit = submit
        self._log = log
        self._clock = clock
        self._condition = threading.Condition()
        self._evaluators: dict[str, _Evaluator] = {}
        self._batch: _Batch | None = None
        self._paused = False
        self._closed = False
        self._waiting_logged_s: float | None = None

    # --- evaluators and control -------------------------------------------------------------------------------
    def set_evaluators(self, names: Iterable[str]) -> tuple[list[str], list[str]]:
        """Make ``names`` the available evaluators; return ``(added, removed)`` (sorted name lists).

        A removed evaluator's request in flight counts as a failed attempt and is retried elsewhere.
        """
        names = set(names)
        cancels = []
        with self._condition:
            added = sorted(names - set(self._evaluators))
            removed = sorted(set(self._evaluators) - names)
            now = self._clock()
            for name in removed:
                ticket = self._evaluators[name].ticket
                if ticket is not None:
                    cancels.append(self._fail_locked(ticket, "the evaluator disappeared from the graph", now))
                del self._evaluators[name]
            for name in added:
                self._evaluators[name] = _Evaluator(name)
            self._condition.notify_all()
        self._cancel(cancels)
        return added, removed

    @property
    def evaluators(self) -> list[str]:
        """Names of the available evaluators, sorted."""
        with self._condition:
            return sorted(self._evaluators)

    def status(self) -> dict[str, int | bool]:
        """``{"evaluators": n, "busy": n, "queued": n, "done": n, "paused": bool}`` of the current batch."""
        with self._condition:
            batch = self._batch
            return {"evaluators": len(self._evaluators),
                    "busy": sum(e.ticket is not None for e in self._evaluators.values()),
                    "queued": len(batch.queue) if batch else 0, "done": len(batch.results) if batch else 0,
                    "paused": self._paused}

    @property
    def paused(self) -> bool:
        """True between :meth:`pause` and :meth:`resume`."""
        return self._paused

    def pause(self) -> None:
        """Send no new requests until :meth:`resume` (requests in flight finish and are kept)."""
        with self._condition:
            self._paused = True
            self._condition.notify_all()

    def resume(self) -> None:
        """Send requests again after :meth:`pause`."""
        with self._condition:
            self._paused = False
            self._condition.notify_all()

    def close(self) -> None:
        """Make a waiting batch raise :class:`PoolClosed`; cancel the requests in flight. Idempotent."""
        with self._condition:
            self._closed = True
            self._condition.notify_all()

    # --- batches -----------------------------------------------------------------------------------------------
    def evaluate(self, requests: Iterable[EvaluationRequest]) -> list[PoolEvaluationResult]:
        """Return one :class:`PoolEvaluationResult` per request, in order, once every request has a real result.

        Raises :class:`EvaluationFailed` when a request failed ``max_attempts`` times and :class:`PoolClosed`
        when the pool is closed; requests still in flight are then cancelled.
        """
        requests = list(requests)
        jobs = [_Job(index, request) for index, request in enumerate(requests)]
        with self._condition:
            if self._batch is not None:
                raise RuntimeError("EvaluatorPool.evaluate() is already running a batch")
            if self._closed:
                raise PoolClosed("the evaluator pool is closed")
            batch = self._batch = _Batch(requests, collections.deque(jobs), list(jobs))
        try:
            while True:
                cancels = []
                with self._condition:
                    if self._closed:
                        raise PoolClosed("the evaluator pool was closed before the batch finished")
                    if batch.gave_up:
                        raise EvaluationFailed(batch.gave_up)
                    if len(batch.results) == len(requests):
                        return [batch.results[index] for index in range(len(requests))]
                    now = self._clock()
                    cancels = self._expire_locked(now)
                    assigned = self._assign_locked(batch, now)
                    if not assigned and not cancels:
                        self._note_waiting_locked(batch, now)
                        self._condition.wait(self._wait_s_locked(now))
                self._cancel(cancels)
                for ticket in assigned:
                    self._send(ticket)
        finally:
            with self._condition:
                in_flight = [e.ticket for e in self._evaluators.values()
                             if e.ticket is not None and e.ticket.job in batch.jobs]
                for evaluator in self._evaluators.values():
                    if evaluator.ticket in in_flight:
                        evaluator.ticket = None
                for ticket in in_flight:
                    ticket.done = True
                self._batch = None
                self._waiting_logged_s = None
            self._cancel([t.cancel for t in in_flight])

    def batch_evaluator(self, trials: int) -> Callable[[Iterable[Iterable[float]], int], BatchResults]:
        """``evaluate_batch(heights_list, seed)`` of :mod:`optimization_run` over this pool, ``trials`` each (each
        heights ``(n_variables,)``, simulation units)."""
        evaluate = self.fidelity_evaluator("")

        def evaluate_batch(heights_list: Iterable[Iterable[float]], seed: int) -> BatchResults:
            return evaluate(heights_list, seed, trials)
        return evaluate_batch

    def fidelity_evaluator(self, fidelity: str,
                           whole: bool = False) -> Callable[[Iterable[Iterable[float]], int, int], BatchResults]:
        """``evaluate(heights_list, seed, trials)`` over this pool at evaluation ``fidelity`` (as
        :func:`batch_evaluation.fidelity_batch_evaluator`, over the graph's evaluators; each heights
        ``(n_variables,)``, simulation units); ``whole``: its requests are never split (module docstring)."""
        def evaluate(heights_list: Iterable[Iterable[float]], seed: int, trials: int) -> BatchResults:
            requests = [EvaluationRequest(tuple(float(h) for h in heights), int(trials), int(seed), fidelity,
                                          whole=whole)
                        for heights in heights_list]
            return [result.as_tuple() for result in self.evaluate(requests)]
        return evaluate

    # --- internals (the ``_locked`` methods run with the condition held) ----------------------------------------
    def _assign_locked(self, batch, now):
        """Pair idle, rested evaluators with queued jobs (split first if fewer are queued than evaluators are
        idle); return the new tickets (to send outside the lock)."""
        if self._paused:
            return []
        idle = [evaluator for evaluator in sorted(self._evaluators.values(), key=lambda e: e.name)
                if evaluator.ticket is None and evaluator.resting_until_s <= now]
        if self.settings.split_trials and 0 < len(batch.queue) < len(idle):
            self._split_locked(batch, len(idle))
        tickets = []
        for evaluator in idle:
            if not batch.queue:
                break
            job = self._job_for_locked(batch, evaluator.name)
            if job is None:
                continue
            batch.queue.remove(job)
            evaluator.ticket = Ticket(self, job, evaluator.name, now)
            tickets.append(evaluator.ticket)
        return tickets

    def _split_locked(self, batch, evaluators):
        """Split the queued jobs' trial ranges so that they fill ``evaluators`` idle evaluators (module docstring);
        a part keeps the failures of the job it came from."""
        queued = list(batch.queue)
        counts = split_counts([None if job.request.whole else job.request.trials for job in queued], evaluators)
        batch.queue.clear()
        for job, count in zip(queued, counts):
            if count == 1:
                batch.queue.append(job)
                continue
            for request in split_request(job.request, count):
                part = _Job(job.index, request, list(job.failures), set(job.failed_on), part=True)
                batch.jobs.append(part)
                batch.queue.append(part)
            batch.jobs.remove(job)

    def _job_for_locked(self, batch, name):
        """The first queued job ``name`` should take: one it has not failed, or one every evaluator has failed."""
        for job in batch.queue:
            if name not in job.failed_on or set(self._evaluators) <= job.failed_on:
                return job
        return None

    def _send(self, ticket):
        try:
            cancel = self._submit(ticket.evaluator, ticket.request, ticket)
        except Exception as exc:  # the submitter's problem is this attempt's failure, not the batch's
            ticket.fail(f"could not send the request: {exc!r}")
            return
        with self._condition:
            ticket.cancel = cancel
            cancel_now = ticket.done and cancel is not None
        if cancel_now:   # it failed (timed out, evaluator removed) before submit returned
            self._cancel([cancel])

    def _touch(self, ticket):
        with self._condition:
            if not ticket.done:
                ticket.deadline_s = self._clock() + self.settings.timeout_s

    def _finish(self, ticket, result, reason):
        with self._condition:
            if ticket.done:
                return
            batch = self._batch
            if result is not None:
                reason = result_problem(ticket.request, result.successes, result.trials, result.trial_results,
                                        ticket.job.part)
            if reason is not None:
                self._fail_locked(ticket, reason, self._clock())
            else:
                ticket.done = True
                evaluator = self._release_locked(ticket)
                if evaluator is not None:
                    evaluator.failures_in_a_row = 0
                if batch is not None and ticket.job in batch.jobs:
                    self._record_locked(batch, ticket.job, result)
            self._condition.notify_all()

    @staticmethod
    def _record_locked(batch, job, result):
        """Keep a finished job's result; once its request's trials are all done, the request's (merged) result."""
        parts = batch.parts.setdefault(job.index, [])
        parts.append((job.request, result))
        if sum(request.trials for request, _ in parts) == batch.requests[job.index].trials:
            batch.results[job.index] = merged_result(parts)

    def _release_locked(self, ticket):
        evaluator = self._evaluators.get(ticket.evaluator)
        if evaluator is not None and evaluator.ticket is ticket:
            evaluator.ticket = None
        return evaluator

    def _fail_locked(self, ticket, reason, now):
        """Record a failed attempt and requeue its job; return the ticket's cancel callable (call it unlocked)."""
        ticket.done = True
        evaluator = self._release_locked(ticket)
        if evaluator is not None:
            evaluator.failures_in_a_row += 1
            backoff = min(2 ** (evaluator.failures_in_a_row - 1), MAX_BACKOFF)
            evaluator.resting_until_s = now + self.settings.retry_delay_s * backoff
        job, batch = ticket.job, self._batch
        job.failures.append(f"{ticket.evaluator}: {reason}")
        job.failed_on.add(ticket.evaluator)
        attempts = len(job.failures)
        limit = self.settings.max_attempts
        if limit and attempts >= limit:
            if batch is not None and not batch.gave_up:
                batch.gave_up = (f"{job.name} failed {attempts} attempt(s) (max_attempts {limit}): "
                                 + "; ".join(job.failures[-3:]))
        else:
            if batch is not None and job in batch.jobs:
                batch.queue.appendleft(job)
            self._log("warning", f"evaluation of {job.name} on {ticket.evaluator} failed ({reason}); "
                                 f"attempt {attempts}{f' of {limit}' if limit else ''}, it will be retried")
        self._condition.notify_all()
        return ticket.cancel

    def _expire_locked(self, now):
        cancels = []
        for evaluator in list(self._evaluators.values()):
            ticket = evaluator.ticket
            if ticket is not None and now >= ticket.deadline_s:
                cancels.append(self._fail_locked(
                    ticket, f"no reply for {self.settings.timeout_s:g} s (evaluator_timeout_s)", now))
        return cancels

    def _note_waiting_locked(self, batch, now):
        if self._evaluators or not batch.queue:
            self._waiting_logged_s = None
            return
        if self._waiting_logged_s is None or now - self._waiting_logged_s >= self.settings.waiting_log_period_s:
            self._waiting_logged_s = now
            self._log("warning", f"no evaluator available: waiting with {len(batch.queue)} candidate(s) queued "
                                 "until an EvaluateProfile action server (a sim_evaluator node) appears")

    def _wait_s_locked(self, now):
        """How long to sleep before something can change without a notification: a deadline or a rest ending."""
        moments = [self.settings.waiting_log_period_s]
        for evaluator in self._evaluators.values():
            if evaluator.ticket is not None:
                moments.append(evaluator.ticket.deadline_s - now)
            elif evaluator.resting_until_s > now:
                moments.append(evaluator.resting_until_s - now)
        return max(0.001, min(moments))

    def _cancel(self, cancels):
        for cancel in cancels:
            if cancel is None:
                continue
            try:
                cancel()
            except Exception as exc:  # cancelling is best effort; the attempt is already given up
                self._log("warning", f"cancelling an evaluation failed: {exc!r}")
