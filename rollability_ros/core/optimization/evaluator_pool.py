"""Spread a batch of profile evaluations over the evaluators currently available, with retries and timeouts.

The optimizer node binds :class:`EvaluatorPool` to EvaluateProfile action clients; tests bind it to plain
functions. The pool knows evaluators only by name and reaches them through one injected function::

    submit(evaluator_name, request, ticket) -> cancel (callable or None)

``submit`` starts evaluating ``request`` (an :class:`EvaluationRequest`) on that evaluator and returns at once;
later, from any thread, it reports through ``ticket``: :meth:`Ticket.progress` whenever the evaluator shows it
is alive (goal accepted, feedback), then exactly one of :meth:`Ticket.succeed` or :meth:`Ticket.fail`. The
returned ``cancel()`` asks the evaluator to drop the request (best effort; a report after that is ignored).
If ``submit`` raises, that attempt failed.

Rules
-----
- At most one request in flight per evaluator; the rest of the batch waits in a queue.
- A failed attempt (rejected, aborted, a malformed result, no sign of life for ``timeout_s``, or the evaluator
  disappearing mid-request) is never a result: the request goes back to the front of the queue and is retried,
  on an evaluator it has not failed on while one exists, else on any. The evaluator that failed gets no new
  request for ``retry_delay_s``, doubled for each further failure in a row (at most 64x; a success resets it),
  so a dead evaluator still listed in the graph costs few timeouts. After ``max_attempts`` failed attempts of
  one request the batch raises :class:`EvaluationFailed` (0 = retry without limit).
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


@dataclasses.dataclass(frozen=True)
class EvaluationRequest:
    """One profile to evaluate: heights ``(n_variables,)`` in simulation units, trials, disturbance seed, and the
    evaluation fidelity (``""``/``screen``: the evaluator's objective; ``launch``: robust twin launches)."""

    heights: tuple
    trials: int
    seed: int
    fidelity: str = ""


@dataclasses.dataclass(frozen=True)
class PoolEvaluationResult:
    """A real result: upright trials out of ``trials``, evaluation wall time (s), the evaluator's name."""

    successes: int
    trials: int
    eval_time_s: float
    evaluator: str

    def as_tuple(self) -> tuple[int, int, float, str]:
        """``(successes, trials, eval_time_s, evaluator)``, the ``evaluate_batch`` contract of optimization_run."""
        return (self.successes, self.trials, self.eval_time_s, self.evaluator)


#: What ``evaluate_batch`` / ``evaluate`` return: ``(successes, trials, eval_time_s, evaluator)`` per candidate.
BatchResults = typing.List[typing.Tuple[int, int, float, str]]


def result_problem(request: EvaluationRequest, successes: int, trials: int) -> str | None:
    """Why a reported result cannot be the result of ``request`` (None if it can)."""
    if trials != request.trials:
        return f"returned {trials} trials for {request.trials} requested"
    if not 0 <= successes <= trials:
        return f"returned {successes} successes of {trials} trials"
    return None


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

    def succeed(self, successes: int, trials: int, eval_time_s: float, evaluator: str | None = None) -> None:
        """Report the result (``evaluator``: the name the result is credited to; default the pool's name)."""
        self._pool._finish(self, PoolEvaluationResult(int(successes), int(trials), float(eval_time_s),
                                                  str(evaluator or self.evaluator)), None)

    def fail(self, reason: str) -> None:
        """Report that this attempt produced no result, and why."""
        self._pool._finish(self, None, str(reason))


@dataclasses.dataclass(eq=False)
class _Job:
    index: int
    request: EvaluationRequest
    failures: list = dataclasses.field(default_factory=list)   # "evaluator: reason" per failed attempt
    failed_on: set = dataclasses.field(default_factory=set)


@dataclasses.dataclass(eq=False)
class _Evaluator:
    name: str
    ticket: typing.Optional[Ticket] = None
    resting_until_s: float = 0.0
    failures_in_a_row: int = 0


@dataclasses.dataclass(eq=False)
class _Batch:
    jobs: list
    queue: collections.deque
    results: dict = dataclasses.field(default_factory=dict)
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
        jobs = [_Job(index, request) for index, request in enumerate(requests)]
        with self._condition:
            if self._batch is not None:
                raise RuntimeError("EvaluatorPool.evaluate() is already running a batch")
            if self._closed:
                raise PoolClosed("the evaluator pool is closed")
            batch = self._batch = _Batch(jobs, collections.deque(jobs))
        try:
            while True:
                cancels = []
                with self._condition:
                    if self._closed:
                        raise PoolClosed("the evaluator pool was closed before the batch finished")
                    if batch.gave_up:
                        raise EvaluationFailed(batch.gave_up)
                    if len(batch.results) == len(jobs):
                        return [batch.results[job.index] for job in jobs]
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
                             if e.ticket is not None and e.ticket.job in jobs]
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

    def fidelity_evaluator(self, fidelity: str) -> Callable[[Iterable[Iterable[float]], int, int], BatchResults]:
        """``evaluate(heights_list, seed, trials)`` over this pool at evaluation ``fidelity`` (as
        :func:`optimization_run.fidelity_batch_evaluator`, over the graph's evaluators; each heights
        ``(n_variables,)``, simulation units)."""
        def evaluate(heights_list: Iterable[Iterable[float]], seed: int, trials: int) -> BatchResults:
            requests = [EvaluationRequest(tuple(float(h) for h in heights), int(trials), int(seed), fidelity)
                        for heights in heights_list]
            return [result.as_tuple() for result in self.evaluate(requests)]
        return evaluate

    # --- internals (the ``_locked`` methods run with the condition held) ----------------------------------------
    def _assign_locked(self, batch, now):
        """Pair idle, rested evaluators with queued jobs; return the new tickets (to send outside the lock)."""
        if self._paused:
            return []
        tickets = []
        for evaluator in sorted(self._evaluators.values(), key=lambda e: e.name):
            if not batch.queue:
                break
            if evaluator.ticket is not None or evaluator.resting_until_s > now:
                continue
            job = self._job_for_locked(batch, evaluator.name)
            if job is None:
                continue
            batch.queue.remove(job)
            evaluator.ticket = Ticket(self, job, evaluator.name, now)
            tickets.append(evaluator.ticket)
        return tickets

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
                reason = result_problem(ticket.request, result.successes, result.trials)
            if reason is not None:
                self._fail_locked(ticket, reason, self._clock())
            else:
                ticket.done = True
                evaluator = self._release_locked(ticket)
                if evaluator is not None:
                    evaluator.failures_in_a_row = 0
                if batch is not None and ticket.job in batch.jobs:
                    batch.results[ticket.job.index] = result
            self._condition.notify_all()

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
                batch.gave_up = (f"candidate {job.index} failed {attempts} attempt(s) (max_attempts {limit}): "
                                 + "; ".join(job.failures[-3:]))
        else:
            if batch is not None and job in batch.jobs:
                batch.queue.appendleft(job)
            self._log("warning", f"evaluation of candidate {job.index} on {ticket.evaluator} failed ({reason}); "
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
