"""Racing by successive halving (core/optimization/racing.py): the stopping rule, common random numbers, the budget."""
import numpy as np
import pytest

from rollability_ros.core.optimization import racing


def fixed(rates):
    """An evaluator whose candidate ``c`` succeeds on the first ``round(rates[c] * trials)`` trials; it records its
    calls (ids, seed, trials)."""
    calls = []

    def evaluate(ids, seed, trials):
        calls.append((list(ids), seed, trials))
        return [(int(round(rates[c] * trials)), trials) for c in ids]
    return evaluate, calls


def test_a_candidate_clearly_worse_than_the_leader_stops_after_the_first_round():
    # 2/20 has Wilson upper bound 0.30 < the leader's lower bound 0.70 (18/20): stopped by the racing rule; 12/20
    # (upper 0.78) overlaps and stays; halving keeps max(min_keep, ceil(0.5 x 3)) = 3 here, so nothing else stops
    evaluate, calls = fixed({"a": 0.9, "b": 0.6, "c": 0.1, "d": 0.55, "base": 0.3})
    result = racing.race(["a", "b", "c", "d"], evaluate, [20, 20], [11, 12], keep_fraction=0.5, min_keep=3,
                         reference="base")
    assert result.stopped["c"][0] == 1 and "clearly worse" in result.stopped["c"][1]
    assert result.survivors == ["a", "b", "d"]
    assert result.totals["a"] == (36, 40) and result.totals["c"] == (2, 20)
    assert result.first_round == {"a": (18, 20), "b": (12, 20), "c": (2, 20), "d": (11, 20)}
    assert result.reference == (12, 40)          # the reference runs every round and never stops
    assert calls[0] == (["a", "b", "c", "d", "base"], 11, 20) and calls[1] == (["a", "b", "d", "base"], 12, 20)
    assert result.trials_spent == 5 * 20 + 4 * 20


def test_halving_keeps_the_better_half_but_never_fewer_than_min_keep():
    rates = {i: 0.4 + 0.02 * i for i in range(10)}        # close rates: the racing rule stops none of them
    evaluate, _ = fixed(rates)
    result = racing.race(list(range(10)), evaluate, [20, 20, 20], [1, 2, 3], keep_fraction=0.5, min_keep=3)
    assert [r["running"] for r in result.rounds] == [10, 5, 3]
    assert set(result.survivors) == {7, 8, 9}
    assert all("halving" in reason for _, reason in result.stopped.values())
    assert result.trials_spent == (10 + 5 + 3) * 20


def test_every_candidate_of_a_round_meets_the_same_draws():
    """Common random numbers: with a seeded noisy evaluator, two identical candidates get identical results in
    every round, so neither is stopped in favour of the other by luck."""
    def evaluate(ids, seed, trials):
        draws = np.random.default_rng(seed).random(trials)
        return [(int(np.sum(draws < (0.5 if c != "bad" else 0.05))), trials) for c in ids]

    result = racing.race(["x", "y", "bad"], evaluate, [30, 30], [5, 6], min_keep=2)
    assert result.totals["x"] == result.totals["y"] and "bad" in result.stopped


def test_bad_race_settings_are_refused():
    evaluate, _ = fixed({"a": 0.5})
    with pytest.raises(ValueError, match="one seed per round"):
        racing.race(["a"], evaluate, [20, 20], [1])
    with pytest.raises(ValueError, match="at least one trial"):
        racing.race(["a"], evaluate, [0], [1])
    with pytest.raises(ValueError, match="distinct"):
        racing.race(["a", "a"], evaluate, [20], [1])


def test_the_optimizer_stops_candidates_clearly_worse_than_the_incumbent_after_their_first_trials(tmp_path):
    pytest.importorskip("cma")
    from rollability_ros.core.optimization.optimization_run import OptimizationRun
    from rollability_ros.core.profile.geometry import ProfileGrid
    from rollability_ros.core.results.store import Store

    grid = ProfileGrid(rows=2, cols=2)

    def good(heights):
        return float(np.mean(heights)) > 0.26         # good designs always right themselves, the others never

    def evaluate_trials(heights_list, seed, trials):
        return [(trials if good(h) else 0, trials, 0.0, "fake") for h in heights_list]

    def evaluate_batch(heights_list, seed):
        return evaluate_trials(heights_list, seed, 30)

    parameters = {"optimizer.method": "cmaes", "optimizer.max_generations": 5, "optimizer.seed": 4,
                  "optimizer.trials": 30, "optimizer.race_first_trials": 10, "optimizer.popsize": 8,
                  "optimizer.sigma0": 0.15, "optimizer.initial_mean_screen": 0, "optimizer.target_fitness": 2.0,
                  "optimizer.stagnation_generations": 0,
                  "profile.rows": grid.rows, "profile.cols": grid.cols}
    stores = []
    for name in ("a", "b"):
        run = OptimizationRun(str(tmp_path / name), parameters, grid, evaluate_batch, evaluate_trials=evaluate_trials)
        run.run()
        run.close()
        with Store(str(tmp_path / name)) as store:
            stores.append([(c.generation, c.index, c.successes, c.trials, c.seed) for c in store.candidates()])
    assert stores[0] == stores[1]                         # deterministic, so a resumed generation decides alike
    population = [c for c in stores[0] if c[1] < 8]
    assert all(trials == 30 for generation, _, _, trials, _ in population if generation == 1)   # no incumbent yet
    later = [c for c in population if c[0] > 1]
    # an incumbent at 30/30 (pooled: lower 95% bound > 0.88): 0/10 (upper bound 0.28) stops, a good one goes on
    assert {(successes, trials) for _, _, successes, trials, _ in later} <= {(0, 10), (30, 30)}
    assert any(trials == 10 for *_, trials, _ in later) and any(trials == 30 for *_, trials, _ in later)
    with pytest.raises(ValueError, match="race_first_trials needs an evaluator"):
        OptimizationRun(str(tmp_path / "c"), parameters, grid, evaluate_batch)
