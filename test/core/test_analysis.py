"""Aggregation against a hand-computed table (ties at the majority rule included), ranks, convergence."""
import math

import pytest

from rollability_ros.core.results.analysis import (
    average_ranks,
    cells_of,
    convergence,
    geometry_table,
    grid,
    group_conditions,
    kendall_tau_b,
    paper_views,
    sim_vs_experiment,
    spearman_rho,
    tip_event_summary,
)
from rollability_ros.core.records import (
    CandidateRecord,
    GenerationRecord,
    LaunchCondition,
    LaunchOutcome,
    TipEventRecord,
)
from rollability_ros.core.stats import wilson_interval

# (configuration, height m, speed m/s, angle deg): (upright repetitions, repetitions)
TALLIES = {
    ("A", 0.75, 0.8, 0.0): (3, 5),     # success
    ("A", 0.75, 0.8, 30.0): (2, 4),    # 2 vs 2: a tie is a failure
    ("A", 0.75, 1.5, 0.0): (5, 5),     # success
    ("A", 0.75, 1.5, 30.0): (0, 5),    # failure
    ("A", 1.3, 0.8, 0.0): (1, 3),      # failure
    ("A", 1.3, 1.5, 0.0): (2, 3),      # success
    ("B", 0.75, 0.8, 0.0): (2, 5),     # failure
    ("B", 0.75, 0.8, 30.0): (3, 5),    # success
}


def _outcomes():
    outcomes = []
    for (configuration, height, speed, angle), (successes, trials) in TALLIES.items():
        for repetition in range(trials):
            condition = LaunchCondition(configuration, height, speed, angle, repetition)
            # successes spread over the repetitions so that order does not matter
            upright = repetition % trials < successes
            outcomes.append(LaunchOutcome("run", f"{condition}", condition, "physical", upright))
    return outcomes[::-1]


def _rows(cells, *factors):
    return {tuple(cell.key[f] for f in factors): (cell.conditions_succeeded, cell.conditions, cell.successes,
                                                  cell.trials) for cell in cells}


def test_majority_rule_with_ties():
    conditions = {c.configuration + str((c.height_m, c.speed_mps, c.angle_deg)): c
                  for c in group_conditions(_outcomes())}
    assert conditions["A(0.75, 0.8, 30.0)"].successes == 2 and conditions["A(0.75, 0.8, 30.0)"].failures == 2
    assert not conditions["A(0.75, 0.8, 30.0)"].success  # tie
    assert [c.success for c in group_conditions(_outcomes())] == [True, False, True, False, False, True, False, True]


def test_views_match_the_hand_computed_table():
    views = paper_views(_outcomes())
    # Figure 9: configuration x height x angle, over both speeds
    assert _rows(views.height_angle, "configuration", "height_m", "angle_deg") == {
        ("A", 0.75, 0.0): (2, 2, 8, 10),
        ("A", 0.75, 30.0): (0, 2, 2, 9),
        ("A", 1.3, 0.0): (1, 2, 3, 6),
        ("B", 0.75, 0.0): (0, 1, 2, 5),
        ("B", 0.75, 30.0): (1, 1, 3, 5),
    }
    # Figures 10/11: configuration x speed x angle, over both heights
    assert _rows(views.speed_angle, "configuration", "speed_mps", "angle_deg") == {
        ("A", 0.8, 0.0): (1, 2, 4, 8),
        ("A", 0.8, 30.0): (0, 1, 2, 4),
        ("A", 1.5, 0.0): (2, 2, 7, 8),
        ("A", 1.5, 30.0): (0, 1, 0, 5),
        ("B", 0.8, 0.0): (0, 1, 2, 5),
        ("B", 0.8, 30.0): (1, 1, 3, 5),
    }
    # Figure 12
    assert _rows(views.by_speed, "configuration", "speed_mps") == {
        ("A", 0.8): (1, 3, 6, 12), ("A", 1.5): (2, 3, 7, 13), ("B", 0.8): (1, 2, 5, 10)}
    assert _rows(views.by_height, "configuration", "height_m") == {
        ("A", 0.75): (2, 4, 10, 19), ("A", 1.3): (1, 2, 3, 6), ("B", 0.75): (1, 2, 5, 10)}
    assert _rows(views.by_angle, "configuration", "angle_deg") == {
        ("A", 0.0): (3, 4, 11, 16), ("A", 30.0): (0, 2, 2, 9), ("B", 0.0): (0, 1, 2, 5), ("B", 30.0): (1, 1, 3, 5)}
    a, b = views.by_configuration
    assert (a.key, a.condition_rate, a.trial_rate) == ({"configuration": "A"}, 0.5, 13 / 25)
    assert (b.key, b.condition_rate, b.trial_rate) == ({"configuration": "B"}, 0.5, 0.5)
    assert a.trial_ci == wilson_interval(13, 25)
    row = a.row()
    assert row["configuration"] == "A" and row["trial_ci_low"] == pytest.approx(0.335, abs=0.002)


def test_configuration_order_and_grid():
    outcomes = _outcomes() + [LaunchOutcome("run", "x", LaunchCondition("baseline", 0.75, 0.8, 0.0), "sim", True)]
    views = paper_views(outcomes)
    assert [c.key["configuration"] for c in views.by_configuration] == ["baseline", "A", "B"]
    rows, columns, values = grid(cells_of(views.height_angle, configuration="A"), "height_m", "angle_deg")
    assert rows == [0.75, 1.3] and columns == [0.0, 30.0]
    assert values[0] == [1.0, 0.0] and values[1][0] == 0.5 and math.isnan(values[1][1])


def test_rank_correlations_with_ties_match_published_values():
    assert average_ranks([10, 20, 20, 5]) == [2.0, 3.5, 3.5, 1.0]
    # scipy.stats.spearmanr / kendalltau documentation examples
    assert spearman_rho([1, 2, 3, 4, 5], [5, 6, 7, 8, 7]) == pytest.approx(0.8207826816681233)
    assert kendall_tau_b([12, 2, 1, 12, 2], [1, 4, 7, 1, 0]) == pytest.approx(-0.47140452079103173)
    assert math.isnan(spearman_rho([1, 1, 1], [1, 2, 3])) and math.isnan(kendall_tau_b([1, 2], [3, 3]))
    with pytest.raises(ValueError, match="paired"):
        spearman_rho([1, 2], [1])


def test_paper_discussion_ranks_are_reversed():
    by_configuration = paper_views(
        [LaunchOutcome("r", f"{c}{i}", LaunchCondition(c, 0.75, 0.8, float(i)), "physical", i < good)
         for c, good in (("A", 3), ("B", 15), ("C", 12)) for i in range(20)]).by_configuration
    result = sim_vs_experiment({"A": 0.66, "B": 0.35, "C": 0.46, "D": 0.9}, by_configuration)
    assert [(r["configuration"], r["experimental_rate"], r["sim_rank"], r["experimental_rank"])
            for r in result.rows] == [("A", 0.15, 1.0, 3.0), ("B", 0.75, 3.0, 1.0), ("C", 0.6, 2.0, 2.0)]
    assert result.spearman_rho == pytest.approx(-1.0) and result.kendall_tau_b == pytest.approx(-1.0)


def test_convergence_from_generations_or_candidates():
    # the optimizer's pooled incumbent estimate (best_so_far) may fall when a lucky estimate is re-evaluated
    generations = [GenerationRecord("g", n, best, 0.1, pooled, 0.1, (), 8 * (n + 1), 1.0)
                   for n, best, pooled in ((1, 0.5, 0.45), (0, 0.2, 0.2), (2, 0.4, 0.42))]
    candidates = [CandidateRecord("c", gen, i, (), fit, 0, 10, 0, 1.0)
                  for gen, i, fit in ((0, 0, 0.3), (0, 1, 0.1), (1, 0, 0.2), (1, 1, 0.2))]
    points = convergence(generations, candidates + [CandidateRecord("g", 0, 0, (), 0.9, 0, 10, 0, 1.0)])
    assert [(p.run_id, p.generation, p.best_so_far) for p in points] == [
        ("c", 0, 0.3), ("c", 1, 0.3), ("g", 0, 0.2), ("g", 1, 0.45), ("g", 2, 0.42)]
    assert points[0].mean_fitness == pytest.approx(0.2) and points[1].evaluations == 4


def test_geometry_table_checks_rows():
    rows = geometry_table([{"configuration": "B", "length_m": "0.2", "width_m": 0.15, "max_height_m": 0.06},
                           {"configuration": "A", "length_m": 0.2, "width_m": 0.15, "max_height_m": 0.03,
                            "note": "x"}])
    assert [r["configuration"] for r in rows] == ["A", "B"] and rows[1]["length_m"] == 0.2 and rows[0]["note"] == "x"
    with pytest.raises(ValueError, match="row 1: missing width_m"):
        geometry_table([{"configuration": "A", "length_m": 1, "max_height_m": 1}])
    with pytest.raises(ValueError, match="max_height_m must be >= 0"):
        geometry_table([{"configuration": "A", "length_m": 1, "width_m": 1, "max_height_m": -1}])


def test_tip_event_summary():
    events = [TipEventRecord("r1", float(t), d, rec, tilt, 1.0) for t, d, rec, tilt in
              ((1, 2.0, True, 100.0), (2, 4.0, False, 170.0), (3, 3.0, True, 90.0))]
    (row,) = tip_event_summary(events)
    assert (row["events"], row["recovered"], row["median_duration_s"], row["max_peak_tilt_deg"]) == (3, 2, 3.0, 170.0)
    assert (row["ci_low"], row["ci_high"]) == wilson_interval(2, 3)


def test_rank_agreement_text_says_undefined_instead_of_nan():
    from rollability_ros.core.results.analysis import rank_agreement_text

    assert rank_agreement_text(0.95, 0.912) == "Spearman rho 0.95, Kendall tau-b 0.91"
    tied = rank_agreement_text(math.nan, math.nan)
    assert "nan" not in tied and tied.startswith("Spearman rho undefined, Kendall tau-b undefined")


def test_rank_statistics_need_three_configurations_and_come_with_a_permutation_p_value():
    from rollability_ros.core.results.analysis import CellSummary, rank_agreement_text, sim_vs_experiment, \
        spearman_p_value

    # exact permutation test: of the 4! orderings, 2 reach |rho| = 1 (the same and the reversed order)
    assert spearman_p_value([1, 2, 3, 4], [10, 20, 30, 40]) == pytest.approx(2 / 24)
    assert spearman_p_value([1, 2, 3], [3, 1, 2]) == pytest.approx(1.0)   # |rho| = 0.5: every ordering reaches it
    cells = [CellSummary({"configuration": c}, 1, 1, 10, k) for c, k in (("A", 3), ("B", 8), ("C", 5))]
    two = sim_vs_experiment({"A": 0.66, "B": 0.35}, cells, "trial_rate", "simulated")
    assert math.isnan(two.spearman_rho) and math.isnan(two.kendall_tau_b) and math.isnan(two.spearman_p)
    assert two.agreement_text() == "no rank statistic: 2 configuration(s), ranks need at least 3"
    three = sim_vs_experiment({"A": 0.66, "B": 0.35, "C": 0.46}, cells, "trial_rate")
    assert three.spearman_rho == pytest.approx(-1.0) and three.spearman_p == pytest.approx(2 / 6)
    assert three.agreement_text() == "Spearman rho -1.00 (permutation p = 0.333), Kendall tau-b -1.00"
    assert rank_agreement_text(0.5, 0.4, 0.2) == "Spearman rho 0.50 (permutation p = 0.200), Kendall tau-b 0.40"
