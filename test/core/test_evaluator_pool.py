"""EvaluatorPool: spreading, retries (rejected, silent, vanished, malformed), waiting with no evaluator, pause,
close, and an optimization run over a flaky pool that equals the run over the evaluator itself."""
import dataclasses
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
    pool = make_pool(graph, ["a_slow", "b"], settings=PoolSettings(timeout_s=0.2, retry_delay_s=5, split_trials=False))
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
    """Evaluators answering with the synthetic fitness, trial by trial over the range asked for (trial j of a
    seed: its draw ``u_j``, as :class:`SyntheticEvaluator`); every third request to 'flaky' is rejected."""

    def __init__(self, synthetic):
        super().__init__({"flaky": self.flaky, "steady": self.steady}, delay_s=0.001)
        self.synthetic = synthetic
        self.count = 0

    def answer(self, request, ticket, name):
        from rollability_ros.core.sim.trial_engine import TrialOutcome

        draws = np.random.default_rng(request.seed).random(request.first_trial + request.trials)
        p = self.synthetic.success_probability(np.asarray(request.heights))
        outcomes = [TrialOutcome(j, request.seed, bool(draws[j] < p), True, 0, 0.0) for j in request.trial_range]
        ticket.succeed(sum(o.upright for o in outcomes), request.trials, 0.0, name, trial_results=outcomes)

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
    # no rest after a failure: both evaluators are idle when each generation's lone re-evaluation is queued, so it
    # is split every time (with FAST's 20 ms rest, a failure just before it left 'flaky' resting: a timing race)
    pool = make_pool(graph, ["flaky", "steady"], dataclasses.replace(FAST, retry_delay_s=0.0))
    stored = {}
    for name, evaluate_batch in (("direct", synthetic), ("pool", pool.batch_evaluator(12))):
        run = optimization_run.OptimizationRun(tmp_path / name, optimization_run.run_config(parameters), grid, evaluate_batch)
        run.run()
        stored[name] = [(c.generation, c.index, c.heights, c.successes, c.trials, c.seed)
                        for c in run.store.candidates(run_id=name)]
        run.close()
    assert len(stored["pool"]) == 5 * 7 and stored["pool"] == stored["direct"]
    assert graph.count >= 3 and {name for name, _ in graph.sent} == {"flaky", "steady"}
    assert sum(r.first_trial > 0 for _, r in graph.sent) >= 5, "a generation's re-evaluation was not split"


def test_an_evaluator_that_keeps_failing_rests_longer_each_time():
    sent_at = []
    graph = FakeGraph({"a": lambda request, ticket: (sent_at.append(time.monotonic()), ticket.fail("aborted"))},
                      delay_s=0.0)
    pool = make_pool(graph, ["a"], settings=PoolSettings(timeout_s=5, max_attempts=5, retry_delay_s=0.05))
    with pytest.raises(EvaluationFailed, match="failed 5 attempt"):
        pool.evaluate(requests(1))
    gaps = np.diff(sent_at)
    assert all(gap >= 0.05 * 2 ** i - 0.01 for i, gap in enumerate(gaps)), gaps


# --- splitting a request's trials over idle evaluators ----------------------------------------------------------
def trial_outcomes(request):
    """Deterministic per-trial outcomes: trial i depends only on (heights, seed, i), as the evaluators' trials do."""
    from rollability_ros.core.sim.evaluation import trial_seed
    from rollability_ros.core.sim.trial_engine import TrialOutcome

    outcomes = []
    for index in request.trial_range:
        seed = trial_seed(request.seed, index)
        upright = (seed + int(sum(request.heights) * 1000)) % 3 != 0
        outcomes.append(TrialOutcome(index=index, seed=seed, upright=upright, settled=True, steps=seed % 997,
                                     tilt_deg=float(seed % 90)))
    return outcomes


class TrialGraph(FakeGraph):
    """Evaluators that run the trial range they are asked for and report each trial; ``fail_first``: the names
    whose first attempt at a part fails."""

    def __init__(self, names, delay_s=0.01, fail_first=()):
        super().__init__({name: self.answer for name in names}, delay_s)
        self.fail_first = set(fail_first)

    def answer(self, request, ticket):
        name = ticket.evaluator
        if name in self.fail_first:
            self.fail_first.discard(name)
            ticket.fail("aborted")
            return
        outcomes = trial_outcomes(request)
        ticket.succeed(sum(o.upright for o in outcomes), request.trials, 0.25 * request.trials, f"/{name}",
                       trial_results=outcomes)


def unsplit(request, graph_names=("a",)):
    """The request's result on one evaluator, never split."""
    graph = TrialGraph(graph_names)
    pool = make_pool(graph, graph_names[:1], settings=dataclasses.replace(FAST, split_trials=False))
    (result,) = pool.evaluate([request])
    assert [r for _, r in graph.sent] == [request]
    return result


def test_a_lone_request_on_idle_evaluators_is_split_and_merged_into_the_unsplit_result():
    request = EvaluationRequest((0.1, 0.2), 60, 11)
    graph = TrialGraph(["a", "b", "c"])
    (merged,) = make_pool(graph, ["a", "b", "c"]).evaluate([request])
    whole = unsplit(request)
    assert sorted((r.first_trial, r.trials) for _, r in graph.sent) == [(0, 20), (20, 20), (40, 20)]
    assert {name for name, _ in graph.sent} == {"a", "b", "c"}
    assert (merged.successes, merged.trials, merged.trial_results) == (whole.successes, whole.trials,
                                                                       whole.trial_results)
    assert [t.index for t in merged.trial_results] == list(range(60))
    assert merged.evaluator == "/a+/b+/c" and whole.evaluator == "/a"
    assert merged.eval_time_s == pytest.approx(whole.eval_time_s)   # the parts' evaluator time, summed


def test_a_full_batch_is_not_split():
    graph = TrialGraph(["a", "b"])
    reqs = requests(4, trials=10)
    results = make_pool(graph, ["a", "b"]).evaluate(reqs)
    assert all(r.first_trial == 0 and r.trials == 10 for _, r in graph.sent) and len(graph.sent) == 4
    assert [r.trial_results for r in results] == [unsplit(q).trial_results for q in reqs]


def test_the_tail_of_a_batch_is_split_over_the_evaluators_left_idle():
    """Three requests on four evaluators: one request is split in two, the others run whole."""
    graph = TrialGraph(["a", "b", "c", "d"])
    reqs = requests(3, trials=9)
    results = make_pool(graph, ["a", "b", "c", "d"]).evaluate(reqs)
    assert sorted((r.heights, r.first_trial, r.trials) for _, r in graph.sent) == sorted(
        [(reqs[0].heights, 0, 5), (reqs[0].heights, 5, 4), (reqs[1].heights, 0, 9), (reqs[2].heights, 0, 9)])
    assert [(r.successes, r.trial_results) for r in results] == \
        [(w.successes, w.trial_results) for w in map(unsplit, reqs)]


def test_a_failed_part_is_retried_and_the_batch_still_equals_the_unsplit_result():
    messages = []
    request = EvaluationRequest((0.3, 0.1), 30, 5)
    graph = TrialGraph(["a", "b"], fail_first=["b"])
    pool = make_pool(graph, ["a", "b"], log=lambda level, message: messages.append(message))
    (merged,) = pool.evaluate([request])
    whole = unsplit(request)
    assert (merged.successes, merged.trials, merged.trial_results) == (whole.successes, whole.trials,
                                                                       whole.trial_results)
    assert any("candidate 0 (trials 15..29) on b failed (aborted)" in m for m in messages), messages
    assert ("b", 15, 15) in [(name, r.first_trial, r.trials) for name, r in graph.sent]
    assert len(graph.sent) >= 3 and merged.evaluator.startswith("/a")   # the failed part ran again


def test_a_part_whose_trials_are_not_its_range_is_a_failed_attempt():
    """An evaluator that ignores first_trial (runs trials 0.. for every part) never gets a merged result in."""
    def ignores_first_trial(request, ticket):
        outcomes = trial_outcomes(dataclasses.replace(request, first_trial=0))
        ticket.succeed(sum(o.upright for o in outcomes), request.trials, 0.1, "/old", trial_results=outcomes)

    messages = []
    graph = TrialGraph(["good"])
    graph.behaviours["old"] = ignores_first_trial
    pool = make_pool(graph, ["good", "old"], log=lambda level, message: messages.append(message))
    request = EvaluationRequest((0.2, 0.2), 10, 9)
    (merged,) = pool.evaluate([request])
    assert merged.trial_results == unsplit(request).trial_results
    assert any("returned trials 0..4 (5) for trials 5..9 requested" in m for m in messages), messages


def test_a_part_without_trial_results_is_a_failed_attempt():
    graph = FakeGraph({"a": "ok", "b": "ok"})   # "ok" answers successes only
    pool = make_pool(graph, ["a", "b"], settings=PoolSettings(timeout_s=5, max_attempts=2, retry_delay_s=0.0))
    with pytest.raises(EvaluationFailed, match="no per-trial results for a part of a split request"):
        pool.evaluate(requests(1))


@pytest.mark.parametrize("whole, split_trials", [(True, True), (False, False)])
def test_a_whole_request_or_a_pool_that_does_not_split_sends_one_goal(whole, split_trials):
    graph = TrialGraph(["a", "b"])
    pool = make_pool(graph, ["a", "b"], settings=dataclasses.replace(FAST, split_trials=split_trials))
    request = EvaluationRequest((0.1, 0.1), 12, 3, whole=whole)
    (result,) = pool.evaluate([request])
    assert [r for _, r in graph.sent] == [request] and result.trial_results == unsplit(request).trial_results


def test_split_counts_fill_the_idle_evaluators_and_never_exceed_the_trials():
    from rollability_ros.core.optimization.evaluator_pool import split_counts, split_request

    assert split_counts([60], 2) == [2] and split_counts([60], 12) == [12]
    assert split_counts([2], 5) == [2]                      # at least one trial per part
    assert split_counts([None, 30], 4) == [1, 3]            # a whole request keeps one evaluator
    assert split_counts([10, 30], 4) == [1, 3] and split_counts([10, 10], 3) == [2, 1]
    parts = split_request(EvaluationRequest((0.0,), 7, 1, first_trial=3), 3)
    assert [(p.first_trial, p.trials) for p in parts] == [(3, 3), (6, 2), (8, 2)]


def test_raced_stages_are_sent_whole_and_the_raced_run_equals_the_run_over_the_evaluator(tmp_path):
    """The optimizer node hands racing (``evaluate_trials``) ``fidelity_evaluator("", whole=True)``: with three
    evaluators and a race whose later stages have fewer candidates than evaluators, no stage's request is split,
    and the stored candidates are those of the run over the evaluator itself."""
    grid = ProfileGrid(rows=3, cols=2)
    parameters = {"optimizer.popsize": 4, "optimizer.trials": 12, "optimizer.max_generations": 3,
                  "optimizer.seed": 4, "optimizer.race_looks": [4], "optimizer.race_survivors": 1,
                  "optimizer.reevaluate_incumbent": False}
    synthetic = SyntheticEvaluator(np.full(grid.n_variables, 0.2), 12)

    def direct(heights_list, seed, trials):
        return [(s, t, 0.0, "direct") for s, t, _, _ in
                SyntheticEvaluator(np.full(grid.n_variables, 0.2), trials)(heights_list, seed)]

    graph = FakeGraph({name: lambda request, ticket: ticket.succeed(
        *direct([np.asarray(request.heights)], request.seed, request.trials)[0][:2], 0.0)
        for name in ("a", "b", "c")}, delay_s=0.001)
    pool = make_pool(graph, ["a", "b", "c"])
    stored = {}
    for name, evaluate_batch, evaluate_trials in (("direct", synthetic, direct),
                                                  ("pool", pool.batch_evaluator(12),
                                                   pool.fidelity_evaluator("", whole=True))):
        run = optimization_run.OptimizationRun(tmp_path / name, optimization_run.run_config(parameters), grid,
                                               evaluate_batch, evaluate_trials=evaluate_trials)
        run.run()
        stored[name] = [(c.generation, c.index, c.heights, c.successes, c.trials, c.seed)
                        for c in run.store.candidates(run_id=name)]
        run.close()
    assert stored["pool"] == stored["direct"] and len(stored["pool"]) == 3 * 4
    stage_sizes = [r.trials for _, r in graph.sent]
    assert 8 in stage_sizes, "the race never reached its second stage"
    assert all(r.first_trial == 0 and r.whole for _, r in graph.sent)
