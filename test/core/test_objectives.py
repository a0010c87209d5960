"""Objectives of a candidate evaluation: disturbance trials, launches on the launch twin, or a mix."""
import dataclasses
import pickle

import numpy as np
import pytest

from rollability_ros.core import config
from rollability_ros.core.campaign_matrix import load_campaign_spec
from rollability_ros.core.config import ConfigError, load_parameters
from rollability_ros.core.sim import evaluation
from rollability_ros.core.sim.objectives import CANDIDATE, ObjectiveSettings, launch_conditions, launch_objective

CAMPAIGN = ("/**:\n  ros__parameters:\n    campaign:\n      heights_m: [0.75]\n      speeds_mps: [0.8]\n"
            "      angles_deg: [-30.0, 30.0]\n")


def settings_with(quick=False, **objective):
    """Settings of sim, robot, evaluator and optimizer.yaml: with the quick default's objective when ``quick``,
    else the objective's defaults (the paper's disturbance trial on sim.engine), with ``objective`` on top."""
    flat = load_parameters(["sim", "robot", "evaluator", "optimizer"])
    if not quick:
        flat = {name: value for name, value in flat.items() if not name.startswith("objective.")}
    flat.update({f"objective.{name}": value for name, value in objective.items()})
    return evaluation.settings_from_parameters(flat)


def test_the_default_objective_is_the_papers_disturbance_trial_and_the_quick_default_is_multi_fidelity():
    assert launch_objective(ObjectiveSettings(), None) is None and ObjectiveSettings().kind == "disturbance"
    # config/optimizer.yaml: the search scores robust launches on the MuJoCo twin, the race decides on sim.engine
    quick = settings_with(quick=True)
    assert (quick.objective.kind, quick.objective.robust.enabled, quick.objective.screen_engine,
            quick.objective.launch_engine) == ("launch_twin", True, "mujoco", "")
    assert evaluation.settings_at_fidelity(quick, "screen").physics.engine == "mujoco"
    assert evaluation.settings_at_fidelity(quick, "launch").physics.engine == "pybullet"


def test_mix_spreads_the_launch_share_evenly_and_cycles_the_conditions():
    resolved = evaluation.load_settings().resolved_launch   # the shipped twin and campaign files, read once
    objective = launch_objective(ObjectiveSettings(kind="mix", launch_weight=0.25), resolved)
    launches = [i for i in range(40) if objective.is_launch(i)]
    assert len(launches) == 10 and launches[:3] == [3, 7, 11]
    paper = launch_conditions(load_campaign_spec(("campaign",)))
    assert len(paper) == 20 and {c.configuration for c in paper} == {CANDIDATE}
    # the launches of an evaluation take the 20 conditions in turn
    assert [objective.condition(i) for i in launches] == list(paper[:10])
    only = launch_objective(ObjectiveSettings(kind="launch_twin"), resolved)
    assert all(only.is_launch(i) for i in range(25)) and only.condition(21) == paper[1]


def test_the_objectives_files_are_read_once_at_the_edge_and_a_launch_from_other_files_is_refused(tmp_path,
                                                                                                   monkeypatch):
    """The evaluator's edge parse reads the twin and campaign files the objective names into its settings; a trial
    job (what the workers are sent) takes them from there and opens no parameter file; settings whose objective
    names other files than were read are refused, never launched on a twin the files no longer describe."""
    campaign = tmp_path / "two_angles.yaml"
    campaign.write_text(CAMPAIGN)
    settings = settings_with(kind="launch_twin", campaign_config=[str(campaign)])
    assert [c.angle_deg for c in settings.resolved_launch.conditions] == [-30.0, 30.0]
    assert settings.resolved_launch.twin == evaluation.load_settings().resolved_launch.twin   # the shipped twin
    campaign.write_text(CAMPAIGN.replace("[-30.0, 30.0]", "[0.0]"))

    def no_file(path):
        raise AssertionError(f"the core read the parameter file {path}")

    with monkeypatch.context() as patch:
        patch.setattr(config, "read_parameter_file", no_file)
        job = evaluation.profile_job(None, evaluation.settings_at_fidelity(settings, "launch"))
    assert [c.angle_deg for c in job.launch.conditions] == [-30.0, 30.0]
    assert pickle.loads(pickle.dumps(job)) == job
    other = dataclasses.replace(settings.objective, campaign_config=["campaign"])
    with pytest.raises(ValueError, match=r"campaign_config \['campaign'\] were not read at the edge \(the settings "
                                         r"hold those of \['sim', 'robot', 'launch_twin'\], \['.*two_angles.yaml'\]\)"):
        evaluation.profile_job(None, dataclasses.replace(settings, objective=other))
    with pytest.raises(ValueError, match=r"were not read at the edge \(the settings hold none\)"):
        evaluation.profile_job(None, evaluation.EvaluatorSettings(objective=other))
    assert len(evaluation.profile_job(None, evaluation.with_objective(settings, other)).launch.conditions) == 20
    # an objective without launches that names no files is fine; asked for launches it is refused as before
    bare = evaluation.with_objective(settings, ObjectiveSettings(twin_config=[]))
    assert bare.resolved_launch is None and evaluation.profile_job(None, bare).launch is None
    with pytest.raises(ConfigError, match="twin_config must list the launch twin's parameter files"):
        evaluation.profile_job(None, evaluation.settings_at_fidelity(bare, "launch"))


def test_bad_objective_settings_are_refused():
    with pytest.raises(ConfigError, match="kind must be one of disturbance, launch_twin, mix"):
        settings_with(kind="rig")
    with pytest.raises(ConfigError, match=r"objective.launch_weight out of range: 0.0 is not in \(0.0, 1.0\]$"):
        settings_with(kind="mix", launch_weight=0.0)


def test_launch_twin_objective_scores_launches_of_the_candidate_under_the_campaign_conditions(tmp_path):
    pytest.importorskip("pybullet")
    from rollability_ros.core.profile.geometry import profile_mesh
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.sim.launch.settings import load_launch_twin_settings
    from rollability_ros.core.sim.launch.twin import simulate_valid_launch

    campaign = tmp_path / "two_angles.yaml"
    campaign.write_text(CAMPAIGN)
    settings = settings_with(kind="launch_twin", campaign_config=[str(campaign)])
    heights = np.full(settings.grid.rows * settings.grid.cols, 0.3)
    result = evaluation.evaluate_profile(heights, 2, 5, settings)
    # the same launches made directly on the twin, with the candidate's profile mounted
    twin = load_launch_twin_settings()
    profile = settings.profile_body(profile_mesh(heights, settings.grid))
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


def test_launches_run_on_the_evaluations_engine_or_are_refused(monkeypatch, tmp_path, capsys):
    pytest.importorskip("mujoco")
    from rollability_ros.cli import main
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.sim import engines
    from rollability_ros.core.sim.launch.twin import simulate_valid_launch

    campaign = tmp_path / "two_angles.yaml"
    campaign.write_text(CAMPAIGN)
    settings = settings_with(kind="launch_twin", campaign_config=[str(campaign)])
    on = {engine: evaluation.evaluate_profile(None, 2, 5, dataclasses.replace(
        settings, physics=dataclasses.replace(settings.physics, engine=engine))).trial_results
        for engine in ("pybullet", "mujoco")}
    assert [o.steps for o in on["pybullet"]] != [o.steps for o in on["mujoco"]]
    twin = launch_objective(settings.objective, settings.resolved_launch, "mujoco").twin
    assert twin.physics.engine == "mujoco"
    direct = simulate_valid_launch(LaunchCondition(CANDIDATE, 0.75, 0.8, -30.0), twin, evaluation.trial_seed(5, 0),
                                   profile=None, use_profile=True)
    assert (direct.steps, direct.valid and direct.upright) == (on["mujoco"][0].steps, on["mujoco"][0].upright)
    # cross-engine agreement of launches, reported as for the disturbance trial
    config = tmp_path / "launch_objective.yaml"
    config.write_text("/**:\n  ros__parameters:\n    objective:\n      kind: launch_twin\n"
                      f"      campaign_config: [{str(campaign)!r}]\n")
    assert main(["evaluate", "--baseline", "--trials", "2", "--seed", "5", "--workers", "1",
                 "--engines", "pybullet,mujoco", "--config", str(config)]) == 0
    out = capsys.readouterr().out
    assert "pybullet  fitness" in out and "mujoco    fitness" in out and "agreement " in out and "/2 trials" in out
    # an engine that cannot run launches is refused before any trial
    monkeypatch.setattr(engines.LAUNCH_ENGINES, "_entries",      # a table with the PyBullet twin only
                        {"pybullet": engines.LAUNCH_ENGINES._entries["pybullet"]})
    mix = settings_with(kind="mix")
    mix = dataclasses.replace(mix, physics=dataclasses.replace(mix.physics, engine="mujoco"))
    with pytest.raises(ValueError, match=r"^sim.engine 'mujoco' cannot run launch trials"):
        evaluation.evaluate_profile(None, 2, 5, mix)


def test_each_fidelity_runs_on_its_declared_engine_and_a_bad_one_is_refused(tmp_path, capsys):
    """The multi-fidelity split: the optimizer's screen on objective.screen_engine, the race's launches on
    objective.launch_engine, empty = sim.engine; nothing else changes engine."""
    from rollability_ros.cli import main
    from rollability_ros.core.sim.objectives import fidelity_engine

    settings = settings_with(kind="launch_twin", screen_engine="mujoco", launch_engine="")
    assert settings.physics.engine == "pybullet"
    screen = evaluation.settings_at_fidelity(settings, "screen")
    launch = evaluation.settings_at_fidelity(settings, "launch")
    assert (screen.physics.engine, launch.physics.engine) == ("mujoco", "pybullet")
    assert evaluation.settings_at_fidelity(settings, "") == screen
    assert launch.objective.kind == "launch_twin" and launch.objective.robust.enabled
    # the launch part of each job is the twin of that engine
    assert evaluation.profile_job(None, screen).launch.twin.physics.engine == "mujoco"
    assert evaluation.profile_job(None, launch).launch.twin.physics.engine == "pybullet"
    swapped = settings_with(kind="mix", screen_engine="pybullet", launch_engine="mujoco")
    assert evaluation.settings_at_fidelity(swapped, "launch").physics.engine == "mujoco"
    assert evaluation.settings_at_fidelity(swapped, "screen").physics.engine == "pybullet"
    # no engine named: the settings are returned as they are (every evaluation on sim.engine)
    plain = settings_with()
    assert evaluation.settings_at_fidelity(plain, "screen") is plain
    assert fidelity_engine(plain.objective, "launch", "mujoco") == "mujoco"
    with pytest.raises(ConfigError, match="screen_engine must be empty .* got 'bullet3'"):
        settings_with(screen_engine="bullet3")
    with pytest.raises(ValueError, match="unknown evaluation fidelity 'rig'"):
        evaluation.settings_at_fidelity(settings, "rig")
    # rollability evaluate runs the fidelity it is asked for, on that fidelity's engine, and says which
    config = tmp_path / "split.yaml"
    config.write_text("/**:\n  ros__parameters:\n    objective:\n      kind: disturbance\n"
                      "      screen_engine: mujoco\n")
    assert main(["evaluate", "--baseline", "--trials", "1", "--workers", "1", "--config", str(config)]) == 0
    assert "engine mujoco   fidelity screen" in capsys.readouterr().out
