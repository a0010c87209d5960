"""Cross-engine agreement: trial by trial, fitness ranks, designs robust to the engine."""
import math

import pytest

from rollability_ros.core.results.engine_agreement import (TABLE_COLUMNS, TABLE_FILENAME, rank_agreement,
                                                          rank_agreement_p_value, read_table, robust_to_engine,
                                                          table_rows, trial_agreement, write_table)
from rollability_ros.core.sim.evaluation import EvaluationResult
from rollability_ros.core.sim.trial_engine import TrialOutcome


def outcomes(uprights, seed_offset=0):
    return [TrialOutcome(index=i, seed=100 + i + seed_offset, upright=u, settled=True, steps=10, tilt_deg=0.0)
            for i, u in enumerate(uprights)]


def test_trial_agreement_counts_each_kind_of_disagreement():
    agreement = trial_agreement(outcomes([True, True, False, False]), outcomes([True, False, True, False]))
    assert (agreement.agreed, agreement.both_upright, agreement.only_first_upright,
            agreement.only_second_upright) == (2, 1, 1, 1)
    assert agreement.fraction == 0.5 and agreement.ci_low < 0.5 < agreement.ci_high


def test_trial_agreement_refuses_different_trials():
    with pytest.raises(ValueError, match="same"):
        trial_agreement(outcomes([True]), outcomes([True], seed_offset=1))


def test_rank_agreement_is_spearman():
    assert rank_agreement({"a": {"x": 0.1, "y": 0.5, "z": 0.9}, "b": {"x": 0.2, "y": 0.3, "z": 0.8}}) == 1.0
    assert rank_agreement({"a": {"x": 0.1, "y": 0.5, "z": 0.9}, "b": {"x": 0.8, "y": 0.3, "z": 0.2}}) == -1.0
    assert math.isnan(rank_agreement({"a": {"x": 0.5, "y": 0.5}, "b": {"x": 0.1, "y": 0.2}}))


def result(successes, trials=60):
    from rollability_ros.core.stats import wilson_interval
    low, high = wilson_interval(successes, trials)
    return EvaluationResult(successes / trials, successes, trials, low, high, 0.0, [])


def test_a_design_is_robust_only_if_its_advantage_holds_in_every_engine():
    by_engine = {"pybullet": {"baseline": result(2), "A": result(40), "B": result(30)},
                 "mujoco": {"baseline": result(3), "A": result(45), "B": result(5)}}
    assert robust_to_engine(by_engine, "baseline") == ["A"]


def evaluated(uprights):
    from rollability_ros.core.stats import wilson_interval

    low, high = wilson_interval(sum(uprights), len(uprights))
    return EvaluationResult(sum(uprights) / len(uprights), sum(uprights), len(uprights), low, high, 0.0,
                            outcomes(uprights))


def test_rank_p_value_is_the_exact_permutation_share():
    same = {"x": 1.0, "y": 2.0, "z": 3.0, "w": 4.0}
    assert rank_agreement_p_value({"a": same, "b": dict(same)}) == pytest.approx(1 / 24)   # only 1 of 4! orderings
    reversed_order = {"x": 3.0, "y": 2.0, "z": 1.0}
    assert rank_agreement_p_value({"a": {"x": 1.0, "y": 2.0, "z": 3.0}, "b": reversed_order}) == 1.0
    with pytest.raises(ValueError, match="3 to 8 designs"):
        rank_agreement_p_value({"a": {"x": 1.0, "y": 2.0}, "b": {"x": 1.0, "y": 2.0}})


def test_table_round_trips_and_the_report_shows_it(tmp_path):
    from rollability_ros.core.results import report, report_writer
    from rollability_ros.core.results import write_outcome_csv
    from rollability_ros.core.records import LaunchCondition, LaunchOutcome

    results = {"baseline": {"pybullet": evaluated([False] * 10), "mujoco": evaluated([False] * 9 + [True])},
               "A": {"pybullet": evaluated([True] * 8 + [False] * 2), "mujoco": evaluated([True] * 9 + [False])},
               "B": {"pybullet": evaluated([True] * 4 + [False] * 6), "mujoco": evaluated([True] * 2 + [False] * 8)}}
    designs = tmp_path / "designs"
    designs.mkdir()
    (designs / "designs.yaml").write_text("designs: {}\n")
    path = write_table(str(designs / TABLE_FILENAME), table_rows(results, seed=7))
    rows = read_table(path)
    assert [(r.design, r.engine, r.successes, r.agreed_trials) for r in rows] == [
        ("baseline", "pybullet", 0, 9), ("baseline", "mujoco", 1, 9), ("A", "pybullet", 8, 9), ("A", "mujoco", 9, 9),
        ("B", "pybullet", 4, 8), ("B", "mujoco", 2, 8)]
    # a report of outcomes next to the designs folder carries the section, its table and its figure
    csv_path = str(tmp_path / "outcomes.csv")
    write_outcome_csv(csv_path, [LaunchOutcome("r", f"t{i}", LaunchCondition("A", 0.75, 0.8, 0.0, i), "sim", i % 2)
                                 for i in range(1, 6)])
    built = report_writer.build_report(report.load_report_data(csv_path), str(tmp_path / "report"))
    assert "same outcome 9/10 trials" in built.summary and "robust to the engine" in built.summary
    assert "rank agreement across 3 designs: Spearman rho +1.00 (exact one-sided permutation p = 0.167)" \
        in built.summary     # same order in both engines; 1 of the 3! orderings is that good
    assert any(p.endswith("engine_agreement.png") for p in built.figure_paths)
    assert "Cross-engine agreement" in open(built.html_path, encoding="utf-8").read()
    robust_line = [line for line in built.summary.splitlines() if "robust to the engine" in line][0]
    assert robust_line.endswith(": A")          # B is above the baseline in pybullet only


def test_a_damaged_table_is_one_clear_error(tmp_path):
    path = tmp_path / TABLE_FILENAME
    path.write_text(",".join(TABLE_COLUMNS) + "\nA,pybullet,10,11,0.5,0.2,0.8,0,9,0.5,0.9\n")
    with pytest.raises(ValueError, match="unusable engine agreement table: line 2: counts or rates out of range"):
        read_table(str(path))
    path.write_text("design,engine\nA,pybullet\n")
    with pytest.raises(ValueError, match="unusable engine agreement table: columns"):
        read_table(str(path))
