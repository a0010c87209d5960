"""EvaluatorPool: spreading, retries (rejected, silent, vanished, malformed), waiting with no evaluator, pause,
close, and an optimization run over a flaky pool that equals the run over the evaluator itself."""
import threading
import time

import numpy as np
import pytest

from doubles import SyntheticEvaluator
from rollability_ros.core.optimization import optimization_run as optimization_run
from rollability_ros.core.optimization.evaluator_pool import (EvaluationFailed, EvaluationRequest, EvaluatorPool, PoolClosed,
                                                 PoolSettings)
from rollability_ros.core.profile.geometry import ProfileGrid

FAST = PoolSettings(timeout_s=0.3, max_attempts=6, retry_delay_s=0.02, waiting_log_period_s=0.1)


def true_successes(request):
    """A deterministic stand-in for physics: successes depend only on (heights, seed)."""
    return int(round(sum(request.heights) * 7 + request.seed)) % (request.trials + 1)


class FakeGraph:
    """Evaluators as threads; each name has a behaviour: ok, reject, silent, wrong_trials or a callable."""

    def __init__(self, behaviours, delay_s=0.01):
        self.behaviours = dict(behaviours)
        self.delay_s = delay_s
        self.lock = threading.Lock()
        self.in_flight = {}
        self.max_in_flight = 0
        self.sent = []        # (evaluator, request)
        self.cancelled = []   # evaluator names

    def submit(self, name, request, ticket):
        with self.lock:
            self.sent.append((name, request))
            self.in_flight[name] = self.in_flight.get(name, 0) + 1
            self.max_in_flight = max(self.max_in_flight, self.in_flight[name])
        behaviour = self.behaviours[name]

        def work():
            time.sleep(self.delay_s)
            ticket.progress()
            with self.lock:
                self.in_flight[name] -= 1
            if behaviour == "ok":
                ticket.succeed(true_successes(request), request.trials, 0.5, f"/{name}/node")
            elif behaviour == "reject":
                ticket.fail("goal rejected")
            elif behaviour == "wrong_trials":
                ticket.succeed(0, request.trials + 1, 0.5)
            elif callable(behaviour):
                behaviour(request, ticket)
            # "silent": never answers

        threading.Thread(target=work, daemon=True).start()
        return lambda: self.cancelled.append(name)


def requests(n, trials=10, seed=3):
    return [EvaluationRequest((0.1 * i, 0.2), trials, seed) for i in range(n)]


def expected(reqs):
    return [true_successes(r) for r in reqs]


def make_pool(graph, names, settings=FAST, log=None):
    pool = EvaluatorPool(graph.submit, settings, log=log or (lambda level, message: None))
    pool.set_evaluators(names)
    return pool


def test_a_batch_is_spread_one_request_per_evaluator_at_a_time():
    graph = FakeGraph({"a": "ok", "b": "ok"}, delay_s=0.02)
    pool = make_pool(graph, ["a", "b"])
    reqs = requests(8)
    results = pool.evaluate(reqs)
    assert [r.successes for r in results] == expected(reqs)
    assert {r.evaluator for r in results} == {"/a/node", "/b/node"}
    assert graph.max_in_flight == 1 and len(graph.sent) == 8


@pytest.mark.parametrize("bad", ["reject", "silent", "wrong_trials"])
def test_failed_attempts_are_retried_elsewhere_and_never_scored(bad):
    messages = []
    graph = FakeGraph({"good": "ok", "bad": bad})
    pool = make_pool(graph, ["bad", "good"], log=lambda level, message: messages.append(message))
    reqs = requests(5)
    results = pool.evaluate(reqs)
    assert [r.successes for r in results] == expected(reqs)
    assert all(r.evaluator == "/good/node" for r in results)
    assert any(name == "bad" for name, _ in graph.sent), "the bad evaluator was never tried"
    assert any("bad failed" in m and "retried" in m for m in messages), messages
    if bad == "silent":
        assert "bad" in graph.cancelled and any("no reply" in m for m in messages)


def test_an_evaluator_that_vanishes_mid_request_is_replaced():
    graph = FakeGraph({"a": "silent", "b": "ok"})
    pool = make_pool(graph, ["a"], settings=PoolSettings(timeout_s=60, retry_delay_s=0.0))
    reqs = requests(3)
    outcome = {}
    worker = threading.Thread(target=lambda: outcome.setdefault("results", pool.evaluate(reqs)))
    worker.start()
    deadline = time.monotonic() + 5
    while not graph.sent and time.monotonic() < deadline:
        time.sleep(0.01)
    pool.set_evaluators(["b"])   # "a" left the graph with a request in flight
    worker.join(10)
    assert [r.successes for r in outcome["results"]] == expected(reqs)
    assert graph.cancelled == ["a"]


def test_with_no_evaluator_the_batch_waits_and_says_so():
    messages = []
    graph = FakeGraph({"late": "ok"})
    pool = make_pool(graph, [], log=lambda level, message: messages.append((level, message)))
    reqs = requests(2)
    outcome = {}
    worker = threading.Thread(target=lambda: outcome.setdefault("results", pool.evaluate(reqs)))
    worker.start()
    time.sleep(0.3)
    assert worker.is_alive() and not graph.sent
    assert any(level == "warning" and "no evaluator available" in m for level, m in messages), messages
    pool.set_evaluators(["late"])
    worker.join(10)
    assert [r.successes for r in outcome["results"]] == expected(reqs)


def test_too_many_failures_raise_instead_of_guessing():
    graph = FakeGraph({"a": "reject", "b": "reject"})
    pool = make_pool(graph, ["a", "b"], settings=PoolSettings(timeout_s=1, max_attempts=3, retry_delay_s=0.0))
    with pytest.raises(EvaluationFailed, match="failed 3 attempt"):
        pool.evaluate(requests(2))
    graph.behaviours.update(a="ok", b="ok")   # the pool is usable again afterwards
    assert [r.successes for r in pool.evaluate(requests(2))] == expected(requests(2))


def test_pause_holds_new_requests_and_resume_releases_them():
    graph = FakeGraph({"a": "ok"})
    pool = make_pool(graph, ["a"])
    pool.pause()
    outcome = {}
    worker = threading.Thread(target=lambda: outcome.setdefault("results", pool.evaluate(requests(2))))
    worker.start()
    time.sleep(0.2)
    assert not graph.sent and pool.status()["queued"] == 2
    pool.resume()
    worker.join(10)
    assert len(outcome["results"]) == 2


def test_close_ends_a_waiting_batch_and_cancels_what_is_in_flight():
    graph = FakeGraph({"a": "silent"})
    pool = make_pool(graph, ["a"], settings=PoolSettings(timeout_s=60))
    errors = []

    def run():
        try:
            pool.evaluate(requests(1))
        except PoolClosed as exc:
            errors.append(exc)

    worker = threading.Thread(target=run)
    worker.start()
    time.sleep(0.1)
    pool.close()
    worker.join(5)
    assert errors and graph.cancelled == ["a"]


def test_a_late_report_after_a_timeout_is_ignored():
    tickets = []
    graph = FakeGraph({"a_slow": lambda request, ticket: tickets.append(ticket), "b": "ok"})
    pool = make_pool(graph, ["a_slow", "b"], settings=PoolSettings(timeout_s=0.2, retry_delay_s=5))
    reqs = requests(1)
    results = pool.evaluate(reqs)
    tickets[0].succeed(0, reqs[0].trials, 0.1)   # after the timeout: must not change anything
    assert results[0].evaluator == "/b/node" and results[0].successes == expected(reqs)[0]


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match=r"^evaluator.timeout_s out of range: 0.0 is not in \(0.0, 604800.0\]$"):
        EvaluatorPool(lambda *a: None, PoolSettings(timeout_s=0))
    with pytest.raises(ValueError, match=r"^evaluator.max_attempts out of range: -1 is not in \[0, 1000000\]$"):
        EvaluatorPool(lambda *a: None, PoolSettings(max_attempts=-1))


class SyntheticGraph(FakeGraph):
    """Evaluators answering with the synthetic fitness; every third request to 'flaky' is rejected."""

    def __init__(self, synthetic):
        super().__init__({"flaky": self.flaky, "steady": self.steady}, delay_s=0.001)
        self.synthetic = synthetic
        self.count = 0

    def answer(self, request, ticket, name):
        ((successes, trials, _, _),) = self.synthetic([np.asarray(request.heights)], request.seed)
        ticket.succeed(successes, trials, 0.0, name)

    def steady(self, request, ticket):
        self.answer(request, ticket, "steady")

    def flaky(self, request, ticket):
        self.count += 1
        if self.count % 3 == 0:
            ticket.fail("aborted")
        else:
            self.answer(request, ticket, "flaky")


def test_a_run_over_a_flaky_pool_equals_the_run_over_the_evaluator_itself(tmp_path):
    grid = ProfileGrid(rows=3, cols=2)
    parameters = {"optimizer.popsize": 6, "optimizer.trials": 12, "optimizer.max_generations": 5,
                  "optimizer.seed": 4}
    synthetic = SyntheticEvaluator(np.full(grid.n_variables, 0.2), 12)
    graph = SyntheticGraph(synthetic)
    pool = make_pool(graph, ["flaky", "steady"])
    stored = {}
    for name, evaluate_batch in (("direct", synthetic), ("pool", pool.batch_evaluator(12))):
        run = optimization_run.OptimizationRun(tmp_path / name, optimization_run.run_config(parameters), grid, evaluate_batch)
        run.run()
        stored[name] = [(c.generation, c.index, c.heights, c.successes, c.trials, c.seed)
                        for c in run.store.candidates(run_id=name)]
        run.close()
    assert len(stored["pool"]) == 5 * 7 and stored["pool"] == stored["direct"]
    assert graph.count >= 3 and {name for name, _ in graph.sent} == {"flaky", "steady"}


def test_an_evaluator_that_keeps_failing_rests_longer_each_time():
    sent_at = []
    graph = FakeGraph({"a": lambda request, ticket: (sent_at.append(time.monotonic()), ticket.fail("aborted"))},
                      delay_s=0.0)
    pool = make_pool(graph, ["a"], settings=PoolSettings(timeout_s=5, max_attempts=5, retry_delay_s=0.05))
    with pytest.raises(EvaluationFailed, match="failed 5 attempt"):
        pool.evaluate(requests(1))
    gaps = np.diff(sent_at)
    assert all(gap >= 0.05 * 2 ** i - 0.01 for i, gap in enumerate(gaps)), gaps
