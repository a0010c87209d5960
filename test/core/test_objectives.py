"""Objectives of a candidate evaluation: disturbance trials, launches on the launch twin, or a mix."""
import dataclasses

import numpy as np
import pytest

from rollability_ros.core.config import ConfigError, load_parameters
from rollability_ros.core.sim import evaluation
from rollability_ros.core.sim.objectives import CANDIDATE, ObjectiveSettings, launch_conditions, launch_objective

CAMPAIGN = ("/**:\n  ros__parameters:\n    campaign:\n      heights_m: [0.75]\n      speeds_mps: [0.8]\n"
            "      angles_deg: [-30.0, 30.0]\n")


def settings_with(**objective):
    flat = load_parameters(["sim", "robot", "evaluator", "optimizer"])
    flat.update({f"objective.{name}": value for name, value in objective.items()})
    return evaluation.settings_from_parameters(flat)


def test_shipped_objective_is_the_papers_disturbance_trial():
    assert settings_with().objective == ObjectiveSettings()
    assert launch_objective(ObjectiveSettings()) is None


def test_mix_spreads_the_launch_share_evenly_and_cycles_the_conditions():
    objective = launch_objective(ObjectiveSettings(kind="mix", launch_weight=0.25))
    launches = [i for i in range(40) if objective.is_launch(i)]
    assert len(launches) == 10 and launches[:3] == [3, 7, 11]
    paper = launch_conditions(["campaign"])
    assert len(paper) == 20 and {c.configuration for c in paper} == {CANDIDATE}
    # the launches of an evaluation take the 20 conditions in turn
    assert [objective.condition(i) for i in launches] == list(paper[:10])
    only = launch_objective(ObjectiveSettings(kind="launch_twin"))
    assert all(only.is_launch(i) for i in range(25)) and only.condition(21) == paper[1]


def test_bad_objective_settings_are_refused():
    with pytest.raises(ConfigError, match="kind must be one of disturbance, launch_twin, mix"):
        settings_with(kind="rig")
    with pytest.raises(ConfigError, match="launch_weight must be in"):
        settings_with(kind="mix", launch_weight=0.0)


def test_launch_twin_objective_scores_launches_of_the_candidate_under_the_campaign_conditions(tmp_path):
    pytest.importorskip("pybullet")
    from rollability_ros.core.profile.geometry import profile_mesh
    from rollability_ros.core.results.records import LaunchCondition
    from rollability_ros.core.robots.robot import ProfileBody
    from rollability_ros.core.sim.launch_twin import load_launch_twin_settings, simulate_valid_launch

    campaign = tmp_path / "two_angles.yaml"
    campaign.write_text(CAMPAIGN)
    settings = settings_with(kind="launch_twin", campaign_config=[str(campaign)])
    heights = np.full(settings.grid.rows * settings.grid.cols, 0.3)
    result = evaluation.evaluate_profile(heights, 2, 5, settings)
    # the same launches made directly on the twin, with the candidate's profile mounted
    twin = load_launch_twin_settings()
    profile = ProfileBody.from_mesh(profile_mesh(heights, settings.grid), settings.profile_density_kgpm3())
    expected = []
    for index, angle_deg in enumerate((-30.0, 30.0)):
        condition = LaunchCondition(CANDIDATE, 0.75, 0.8, angle_deg)
        launch = simulate_valid_launch(condition, twin, evaluation.trial_seed(5, index), profile=profile,
                                       use_profile=True)
        expected.append(launch.valid and launch.upright)
    assert [o.upright for o in result.trial_results] == expected
    assert result.successes == sum(expected)
    # another base seed draws other launch scatter; the disturbance objective runs other trials altogether
    disturbance = evaluation.evaluate_profile(heights, 2, 5, dataclasses.replace(settings, objective=ObjectiveSettings()))
    assert [o.steps for o in disturbance.trial_results] != [o.steps for o in result.trial_results]


def test_launches_run_on_the_evaluations_engine_or_are_refused(monkeypatch):
    from rollability_ros.core.sim import trials

    assert launch_objective(ObjectiveSettings(kind="launch_twin"), "pybullet").twin.physics.engine == "pybullet"
    monkeypatch.setitem(trials.TRIAL_ENGINES, "launch", ("pybullet",))
    settings = settings_with(kind="mix", **{})
    settings = dataclasses.replace(settings, physics=dataclasses.replace(settings.physics, engine="mujoco"))
    with pytest.raises(ValueError, match=r"^sim.engine 'mujoco' cannot run launch trials"):
        evaluation.evaluate_profile(None, 2, 5, settings)
