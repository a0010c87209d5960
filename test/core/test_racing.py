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
