"""Campaign matrix, order, operator instructions, resume and progress."""
import collections
import dataclasses

import pytest

from rollability_ros.core.campaign.plan import (
    CampaignProgress,
    CampaignSpec,
    changed_levels,
    changes_between,
    load_campaign_spec,
    plan_trials,
    remaining_trials,
    trial_id_for,
)
from rollability_ros.core.config import ConfigError, from_mapping
from rollability_ros.core.records import LaunchCondition, LaunchOutcome
from rollability_ros.core.store import Store


def test_shipped_config_is_the_paper_matrix_of_400_trials():
    spec = load_campaign_spec()
    assert spec.configurations == ["baseline", "A", "B", "C"]
    assert spec.heights_m == [0.75, 1.30] and spec.speeds_mps == [0.8, 1.5]
    assert spec.angles_deg == [-60.0, -30.0, 0.0, 30.0, 60.0] and spec.repetitions == 5
    plan = plan_trials(spec)
    assert len(plan) == spec.trial_count == 400
    assert len({t.trial_id for t in plan}) == 400
    groups = collections.Counter(t.condition.group_key for t in plan)
    assert len(groups) == 80 and set(groups.values()) == {5}
    assert [t.index for t in plan] == list(range(400))


def test_order_is_configuration_height_angle_speed_repetition():
    plan = plan_trials(CampaignSpec())
    keys = [(CampaignSpec().configurations.index(t.condition.configuration), t.condition.height_m,
             t.condition.angle_deg, t.condition.speed_mps, t.condition.repetition) for t in plan]
    assert keys == sorted(keys)
    changes = collections.Counter(level for a, b in zip(plan, plan[1:]) for level in changed_levels(a.condition,
                                                                                                    b.condition))
    # a configuration is mounted 4 times (3 changes), the ledge moved once per configuration change + 4 times,
    # the angle changes 4 times per (configuration, height) block + at block starts, the speed every 5 trials
    assert changes == {"configuration": 3, "height_m": 7, "angle_deg": 39, "speed_mps": 79}


def test_random_order_shuffles_only_inside_blocks_and_is_reproducible():
    spec = CampaignSpec(random_order=True, random_seed=7)
    plan = plan_trials(spec)
    ordered = plan_trials(CampaignSpec())
    assert [t.trial_id for t in plan] != [t.trial_id for t in ordered]
    assert sorted(t.trial_id for t in plan) == sorted(t.trial_id for t in ordered)
    assert [t.trial_id for t in plan] == [t.trial_id for t in plan_trials(spec)]
    # blocks (configuration, height) come in matrix order, so ledge and mesh changes stay minimal
    blocks = [(t.condition.configuration, t.condition.height_m) for t in plan]
    assert sum(a != b for a, b in zip(blocks, blocks[1:])) == 7
    other_seed = plan_trials(dataclasses.replace(spec, random_seed=8))
    assert [t.trial_id for t in other_seed] != [t.trial_id for t in plan]


def test_trial_id_depends_on_the_condition_only():
    condition = LaunchCondition("B", 1.3, 0.8, -30.0, 2)
    assert trial_id_for(condition) == "B/h1.3m/v0.8mps/a-30deg/r2"
    assert trial_id_for(LaunchCondition("B", 1.30, 0.80, 30, 2)) == "B/h1.3m/v0.8mps/a+30deg/r2"


def test_changes_between_names_what_the_operator_changes():
    first = LaunchCondition("A", 0.75, 0.8, -60.0, 4)
    assert changes_between(None, first, {0.8: 30.0}) == [
        "mount configuration A", "set the ledge height to 0.75 m", "set the launch angle to -60 deg",
        "set the launch speed to 0.8 m/s (regulator 30 psi)"]
    assert changes_between(first, dataclasses.replace(first, repetition=0)) == []
    assert changes_between(first, dataclasses.replace(first, speed_mps=1.5), {1.5: 60.0}) == [
        "set the launch speed to 1.5 m/s (regulator 60 psi) (was 0.8 m/s)"]
    assert changes_between(first, dataclasses.replace(first, height_m=1.3, angle_deg=30.0)) == [
        "set the ledge height to 1.30 m (was 0.75 m)", "set the launch angle to +30 deg (was -60 deg)"]


@pytest.mark.parametrize("mapping, message", [
    ({"repetitions": 0}, "repetitions"),
    ({"heights_m": [0.75, 0.75]}, "duplicate"),
    ({"speeds_mps": [0.0]}, "speed_mps"),
    ({"angles_deg": []}, "at least one"),
    ({"configurations": ["A B"]}, "without spaces"),
    ({"random_block": "colour"}, "random_block"),
    ({"repetition": 5}, "unknown"),
])
def test_bad_campaign_settings_are_refused(mapping, message):
    with pytest.raises(ConfigError, match=message):
        from_mapping(CampaignSpec, mapping, "campaign")


def _store_outcome(store, run_id, trial):
    return store.add_launch_outcome(LaunchOutcome(run_id, trial.trial_id, trial.condition, "sim", True))


def test_resume_skips_exactly_the_stored_trials_even_when_reshuffled(tmp_path):
    spec = CampaignSpec(configurations=["A", "B"], repetitions=2, random_order=True)
    plan = plan_trials(spec)
    with Store(tmp_path) as store:
        for trial in plan[:13]:
            _store_outcome(store, spec.run_id, trial)
        _store_outcome(store, "another-run", plan[20])
        left = remaining_trials(plan, store, spec.run_id)
        assert left == plan[13:]
        reshuffled = plan_trials(dataclasses.replace(spec, random_seed=99))
        left = remaining_trials(reshuffled, store, spec.run_id)
        assert len(left) == len(plan) - 13
        assert {t.trial_id for t in left} | {t.trial_id for t in plan[:13]} == {t.trial_id for t in plan}


def test_progress_counts_and_estimates_time_left():
    progress = CampaignProgress(total=10, done=4)
    assert progress.remaining == 6 and progress.eta_s is None
    assert progress.text() == "4/10 done, 6 remaining, time left unknown"
    for duration_s in (30.0, 30.0, 600.0):  # one long pause must not dominate the estimate
        progress.trial_done(duration_s)
    assert progress.done == 7 and progress.eta_s == pytest.approx(3 * 30.0)
    assert progress.text() == "7/10 done, 3 remaining, about 2 min left"
    for _ in range(3):
        progress.trial_done(30.0)
    assert progress.eta_s == 0.0
    with pytest.raises(ValueError, match="already done"):
        progress.trial_done(1.0)
    with pytest.raises(ValueError):
        CampaignProgress(total=3, done=4)
