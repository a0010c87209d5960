"""Cross-engine agreement: trial by trial, fitness ranks, designs robust to the engine."""
import math

import pytest

from rollability_ros.core.results.engine_agreement import rank_agreement, robust_to_engine, trial_agreement
from rollability_ros.core.sim.evaluation import EvaluationResult
from rollability_ros.core.sim.trials import TrialOutcome


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
    from rollability_ros.core.results.stats import wilson_interval
    low, high = wilson_interval(successes, trials)
    return EvaluationResult(successes / trials, successes, trials, low, high, 0.0, [])


def test_a_design_is_robust_only_if_its_advantage_holds_in_every_engine():
    by_engine = {"pybullet": {"baseline": result(2), "A": result(40), "B": result(30)},
                 "mujoco": {"baseline": result(3), "A": result(45), "B": result(5)}}
    assert robust_to_engine(by_engine, "baseline") == ["A"]
