"""Robust fitness (every trial under its own draw of the unknowns) and the sensitivity study."""
import dataclasses

import pytest

from rollability_ros.core.config import check_settings
from rollability_ros.core.sim import evaluation
from rollability_ros.core.sim.robustness import RobustSettings, draw, robust_settings_for
from rollability_ros.core.sim.sensitivity import DEFAULT_LEVELS, sensitivity_rows, with_factor


def robust_settings(**changes):
    settings = evaluation.EvaluatorSettings()
    robust = RobustSettings(enabled=True, **changes)
    return dataclasses.replace(settings, objective=dataclasses.replace(settings.objective, robust=robust))


def test_draws_are_common_random_numbers_spread_over_the_stated_ranges():
    robust = RobustSettings(enabled=True)
    draws = [draw(seed, robust, -0.015, 0.06) for seed in range(400)]
    assert draw(7, robust, -0.015, 0.06) == draws[7]          # the same trial seed, the same unknowns
    scales = [d.disturbance_scale for d in draws]
    assert 0.5 <= min(scales) < 0.6 and 1.8 < max(scales) <= 2.0
    assert {d.start_roll_deg for d in draws} == {180.0, 90.0}
    assert {d.contact_model for d in draws} == {"per_contact", "per_body"}
    assert all(abs(d.com_offset_z_m) < 0.45 * 0.06 for d in draws)
    perturbed = robust_settings_for(evaluation.EvaluatorSettings(), 7, robust)
    assert perturbed.trial.torque_max_nm == pytest.approx(2.0 * draws[7].disturbance_scale)
    assert perturbed.trial.start_roll_deg == draws[7].start_roll_deg
    assert perturbed.physics.contact_model == draws[7].contact_model


def test_bad_robust_settings_are_refused():
    with pytest.raises(ValueError, match="contact_models must list some of"):
        RobustSettings(contact_models=["glue"]).validate()
    with pytest.raises(ValueError, match="disturbance_scale_min"):
        RobustSettings(disturbance_scale_min=3.0).validate()


def test_robust_evaluation_runs_each_trial_under_its_own_draw():
    pytest.importorskip("pybullet")
    from rollability_ros.core.sim.trial_engine import run_trial

    settings = robust_settings()
    result = evaluation.evaluate_profile(None, 3, 11, settings)
    for outcome in result.trial_results:
        own = robust_settings_for(settings, outcome.seed, settings.objective.robust)
        direct = run_trial(own.robot_model(), None, outcome.index, outcome.seed, own.trial, own.physics)
        assert direct == outcome
    plain = evaluation.evaluate_profile(None, 3, 11, evaluation.EvaluatorSettings())
    assert [o.steps for o in plain.trial_results] != [o.steps for o in result.trial_results]


def test_sensitivity_varies_one_factor_at_a_time_and_adds_the_robust_fitness():
    pytest.importorskip("pybullet")
    base = evaluation.EvaluatorSettings()
    assert with_factor(base, "disturbance_scale", 2.0).trial.force_max_n == 2 * base.trial.force_max_n
    assert with_factor(base, "start_roll_deg", 90.0).trial.start_roll_deg == 90.0
    assert with_factor(base, "start_roll_deg", 90.0).physics == base.physics
    with pytest.raises(ValueError, match="unknown factor 'wind'"):
        with_factor(base, "wind", 1.0)
    rows = sensitivity_rows({"baseline": None}, base, 2, 3, levels={"start_roll_deg": (180.0, 90.0)})
    assert [(r["factor"], r["level"]) for r in rows] == [("start_roll_deg", 180.0), ("start_roll_deg", 90.0),
                                                         ("robust", "all factors drawn")]
    assert all(r["trials"] == 2 and r["ci_low"] <= r["fitness"] <= r["ci_high"] for r in rows)
    assert set(DEFAULT_LEVELS) == {"disturbance_scale", "start_roll_deg", "contact_model", "com_offset_z_m"}


def test_robust_trial_runs_on_the_evaluations_engine():
    """The robust trial goes through the engine seam: on MuJoCo it gives MuJoCo's outcomes, not PyBullet's."""
    pytest.importorskip("pybullet")
    pytest.importorskip("mujoco")
    from rollability_ros.core.sim.mujoco_trials import MujocoTrialWorld

    settings = robust_settings()
    on = {engine: evaluation.evaluate_profile(None, 4, 3, dataclasses.replace(
        settings, physics=dataclasses.replace(settings.physics, engine=engine))).trial_results
        for engine in ("pybullet", "mujoco")}
    assert [o.steps for o in on["pybullet"]] != [o.steps for o in on["mujoco"]]
    mujoco = dataclasses.replace(settings, physics=dataclasses.replace(settings.physics, engine="mujoco"))
    for outcome in on["mujoco"][:2]:   # each robust MuJoCo trial is the MuJoCo trial of its own draw
        own = robust_settings_for(mujoco, outcome.seed, settings.objective.robust)
        world = MujocoTrialWorld(own.robot_model(), None, own.trial, own.physics)
        assert world.run(outcome.index, outcome.seed) == outcome


def test_an_engine_that_cannot_run_a_trial_kind_is_refused_in_one_line(monkeypatch):
    from rollability_ros.core.sim import engines

    monkeypatch.setattr(engines.TRIAL_ENGINES, "_entries",     # a table with PyBullet only
                        {"pybullet": engines.TRIAL_ENGINES._entries["pybullet"]})
    settings = robust_settings()
    mujoco = dataclasses.replace(settings, physics=dataclasses.replace(settings.physics, engine="mujoco"))
    with pytest.raises(ValueError, match=r"^sim.engine 'mujoco' cannot run disturbance trials \(engines that can: "
                                         r"pybullet\)$"):
        evaluation.evaluate_profile(None, 1, 3, mujoco)


def test_robust_launches_reuse_one_mujoco_twin_and_match_a_fresh_build():
    """A robustness draw (contact reading, foam, centre of mass) is applied to the compiled MuJoCo twin instead of
    a new model: the same model as one compiled for the drawn settings (to the URDF's printed precision of the
    centre of mass), and bit-identical launches whatever was launched before."""
    pytest.importorskip("mujoco")
    import numpy as np
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.sim.launch import mujoco_twin
    from rollability_ros.core.sim.launch.drive import launch_drive
    from rollability_ros.core.sim.launch.placement import sized_for_robot
    from rollability_ros.core.sim.launch.settings import load_launch_twin_settings

    twin = load_launch_twin_settings()
    twin = sized_for_robot(dataclasses.replace(
        twin, physics=dataclasses.replace(twin.physics, engine="mujoco"),
        trial=dataclasses.replace(twin.trial, early_decision=False)))[0]
    robust = RobustSettings(enabled=True)
    first, drawn = (robust_settings_for(twin, seed, robust) for seed in (4, 9))
    assert first.robot.com_offset_z_m != drawn.robot.com_offset_z_m and first.twin.foam != drawn.twin.foam
    assert first.twin.foam.lateral_friction != drawn.twin.foam.lateral_friction
    assert first.twin.foam.rolling_friction != drawn.twin.foam.rolling_friction
    assert first.twin.wheel_drag_torque_nm != drawn.twin.wheel_drag_torque_nm
    condition = LaunchCondition("baseline", 0.75, 0.8, 0.0)

    def launch(settings, seed):
        return mujoco_twin.MujocoLaunch.simulate(condition, settings, seed, None,
                                                 drive=launch_drive(settings, condition.speed_mps))
    mujoco_twin._cache.clear()
    launch(first, 3)
    reused = mujoco_twin.twin_for(drawn, None)
    assert len(mujoco_twin._cache) == 1
    fresh = mujoco_twin.MujocoLaunchTwin(drawn, None)
    for name in ("geom_friction", "geom_solref", "geom_solimp", "body_ipos", "body_inertia", "body_mass",
                 "dof_frictionloss", "dof_invweight0", "body_invweight0"):
        assert np.allclose(getattr(reused.model, name), getattr(fresh.model, name), rtol=1e-6, atol=1e-7), name
    # a draw's launch never depends on the draws launched before it in the process (a resumed run launches alike)
    for settings in (drawn, dataclasses.replace(drawn, robot=first.robot)):
        mujoco_twin._cache.clear()
        alone = repr(launch(settings, 3))
        mujoco_twin._cache.clear()
        launch(first, 5)
        assert repr(launch(settings, 3)) == alone


def test_launch_draws_cover_foam_friction_rolling_and_wheel_drag_and_keep_the_older_draws():
    """The wheel-on-foam unknowns are drawn log-uniform over their stated ranges, from the trial seed's own stream
    after the older unknowns (whose values do not move), and reach the settings of the wheels the twin uses."""
    from rollability_ros.core.sim.launch.settings import LaunchTwinSettings

    robust = RobustSettings(enabled=True)
    draws = [draw(seed, robust, -0.015, 0.06) for seed in range(400)]
    for field, (low, high) in (("foam_lateral_friction", (0.6, 2.5)), ("foam_rolling_friction_m", (0.002, 0.05)),
                               ("wheel_drag_nm", (0.0005, 0.02))):
        values = sorted(getattr(d, field) for d in draws)
        assert low <= values[0] < low * 1.1 and high / 1.1 < values[-1] <= high, field
        below_middle = sum(v < (low * high) ** 0.5 for v in values)   # log-uniform: half below the log midpoint
        assert 160 < below_middle < 240, field
    # the older unknowns of trial seed 7 as drawn before the new ones were added (values from that version)
    assert (draws[7].disturbance_scale, draws[7].start_roll_deg, draws[7].contact_model, draws[7].com_offset_z_m,
            draws[7].foam_stiffness_factor, draws[7].foam_restitution) == pytest.approx(
        (1.6553459542991664, 180.0, "per_contact", -0.011239781177851415, 0.6389950123778069, 0.27143211935986666))
    twin = robust_settings_for(LaunchTwinSettings(), 7, robust)
    assert (twin.twin.foam.lateral_friction, twin.twin.foam.rolling_friction, twin.twin.wheel_drag_torque_nm) == (
        draws[7].foam_lateral_friction, draws[7].foam_rolling_friction_m, draws[7].wheel_drag_nm)
    own_wheels = LaunchTwinSettings()
    own_wheels.twin.wheel_model = "robot"
    drawn = robust_settings_for(own_wheels, 7, robust)
    assert drawn.robot.wheel_drag_torque_nm == draws[7].wheel_drag_nm   # the drag acts on the wheels in use
    assert drawn.twin.wheel_drag_torque_nm == own_wheels.twin.wheel_drag_torque_nm
    with pytest.raises(ValueError, match=r"^objective.robust.wheel_drag_min_nm out of range: 0.0 is not in \(0.0, "):
        check_settings(RobustSettings(wheel_drag_min_nm=0.0), "objective.robust")
    with pytest.raises(ValueError, match="need wheel_drag_min <= wheel_drag_max"):
        check_settings(RobustSettings(wheel_drag_min_nm=0.5), "objective.robust")



def test_the_robots_restitution_is_drawn_on_pybullet_and_mujoco_refuses_any_value_but_the_papers():
    """The robot's restitution (its bounce off the ledge edge) is a drawn unknown of a launch on PyBullet; MuJoCo,
    which has no restitution, keeps the paper's value it runs as its known difference, and a launch or trial there
    that sets another value is refused in one line before anything is built."""
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.sim.launch.settings import LaunchTwinSettings
    from rollability_ros.core.sim.launch.twin import simulate_launch
    from rollability_ros.core.sim.trial_engine import make_trial_world

    robust = RobustSettings(enabled=True)
    draws = [draw(seed, robust, -0.015, 0.06) for seed in range(400)]
    values = sorted(d.robot_restitution for d in draws)
    assert 0.0 <= values[0] < 0.02 and 0.48 < values[-1] <= 0.5 and 160 < sum(v < 0.25 for v in values) < 240
    assert draws[7].launcher_model == "stroke" and draws[7].foam_restitution == pytest.approx(0.27143211935986666)
    on_bullet = robust_settings_for(LaunchTwinSettings(), 7, robust)
    assert on_bullet.physics.restitution == draws[7].robot_restitution != 0.3
    mujoco = LaunchTwinSettings()
    mujoco.physics.engine = "mujoco"
    on_mujoco = robust_settings_for(mujoco, 7, robust)
    assert on_mujoco.physics.restitution == 0.3 and on_mujoco.twin.foam == on_bullet.twin.foam   # the rest alike
    assert robust_settings_for(evaluation.EvaluatorSettings(), 7, robust).physics.restitution == 0.3   # no launch
    with pytest.raises(ValueError, match=r"^sim.engine 'mujoco' cannot represent restitution .*0.12 is refused"):
        simulate_launch(LaunchCondition("A", 0.75, 0.8, 0.0), dataclasses.replace(
            on_mujoco, physics=dataclasses.replace(on_mujoco.physics, restitution=0.12)), seed=1)
    settings = evaluation.EvaluatorSettings()
    with pytest.raises(ValueError, match="cannot represent restitution"):
        make_trial_world(None, None, settings.trial, dataclasses.replace(settings.physics, engine="mujoco",
                                                                         restitution=0.0))
    with pytest.raises(ValueError, match="need robot_restitution_min <= robot_restitution_max"):
        RobustSettings(robot_restitution_min=0.6).validate()
    from rollability_ros.core.sim.sensitivity import with_launch_factor
    assert with_launch_factor(LaunchTwinSettings(), "robot_restitution", 0.5).physics.restitution == 0.5
    with pytest.raises(ValueError, match="robot_restitution cannot be varied on 'mujoco'"):
        with_launch_factor(mujoco, "robot_restitution", 0.5)


def test_launcher_and_profile_mass_unknowns_are_drawn_and_weigh_the_trials_profile():
    """The launcher's unknowns (base plate rolling friction, speed-setting bias, the model when listed) and the
    profile's mass multiplier are drawn over their ranges and reach the twin and the trial's profile body."""
    import numpy as np

    from rollability_ros.core.robots import ProfileBody
    from rollability_ros.core.sim.launch.settings import LaunchTwinSettings
    from rollability_ros.core.sim.robustness import scaled_profile

    robust = RobustSettings(enabled=True, launcher_models=["stroke", "push_through"])
    draws = [draw(seed, robust, -0.015, 0.06) for seed in range(400)]
    scales = sorted(d.profile_mass_scale for d in draws)
    # log-uniform in [0.15, 1.5]: half below the geometric mean (0.474), log(1/0.15)/log(10) = 82 % below 1
    assert 0.15 <= scales[0] < 0.17 and 1.35 < scales[-1] <= 1.5
    assert 160 < sum(v < 0.474 for v in scales) < 240 and 290 < sum(v < 1.0 for v in scales) < 370
    assert all(0 <= d.ledge_rolling_friction_m <= 0.01 and -0.15 <= d.speed_bias_fraction <= 0.15 for d in draws)
    assert {d.launcher_model for d in draws} == {"stroke", "push_through"}
    assert {draw(s, RobustSettings(enabled=True), -0.015, 0.06).launcher_model for s in range(50)} == {"stroke"}
    twin = LaunchTwinSettings()
    drawn = robust_settings_for(twin, 7, robust)
    launcher = drawn.twin.launcher
    assert (launcher.ledge_rolling_friction, launcher.speed_bias_fraction, launcher.model) == (
        draws[7].ledge_rolling_friction_m, draws[7].speed_bias_fraction, draws[7].launcher_model)
    assert drawn.robot.profile_mass_scale == draws[7].profile_mass_scale
    body = ProfileBody(np.zeros((4, 3)), 0.2, np.zeros(3), np.eye(3) * 1e-4)
    weighed = scaled_profile(body, twin, drawn)
    assert weighed.mass_kg == pytest.approx(0.2 * draws[7].profile_mass_scale)
    assert weighed.inertia_kgm2[0, 0] == pytest.approx(1e-4 * draws[7].profile_mass_scale)
    assert scaled_profile(None, twin, drawn) is None
    with pytest.raises(ValueError, match="launcher_models must list some of stroke, push_through"):
        RobustSettings(launcher_models=["catapult"]).validate()


def test_launch_sensitivity_rows_are_real_launches_at_each_end_of_an_unknowns_range():
    """Tiny counts: the bare robot and a block profile, four launches at each end of the foam-friction range and
    robustly; a row's count is the count of the same launches made directly, and the gains table has each design
    minus the bare robot at every level."""
    pytest.importorskip("pybullet")
    import trimesh

    from rollability_ros.core.results import gain_lines
    from rollability_ros.core.results.sensitivity_table import gain_rows
    from rollability_ros.core.sim.evaluation import mesh_job, settings_at_fidelity, trial_seed
    from rollability_ros.core.sim.launch.twin import simulate_valid_launch
    from rollability_ros.core.sim.sensitivity import (LAUNCH_FACTORS, launch_levels, launch_sensitivity_rows,
                                                      with_launch_factor)

    robust = RobustSettings(enabled=True)
    levels = launch_levels(robust, -0.015)
    assert tuple(levels) == LAUNCH_FACTORS and levels["foam_lateral_friction"] == (0.6, 2.5)
    assert levels["com_offset_z_m"] == pytest.approx((-0.021, -0.009))
    block = trimesh.creation.box((0.12, 0.16, 0.05))
    block.apply_translation((0.0, 0.0, 0.025))
    settings = evaluation.load_settings()   # with the launch twin and conditions the objective's files name
    rows = launch_sensitivity_rows({"baseline": None, "block": block}, settings, 4, 1,
                                   levels={"foam_lateral_friction": (0.6, 2.5)})
    assert [(r["configuration"], r["factor"], r["level"]) for r in rows] == [
        (label, factor, level) for label in ("baseline", "block")
        for factor, level in (("foam_lateral_friction", 0.6), ("foam_lateral_friction", 2.5),
                              ("robust", "all unknowns drawn"))]
    job = mesh_job(None, settings_at_fidelity(settings, "launch"))
    twin = with_launch_factor(job.launch.twin, "foam_lateral_friction", 2.5)
    assert twin.twin.foam.lateral_friction == 2.5
    direct = sum(simulate_valid_launch(job.launch.condition(i), twin, trial_seed(1, i), profile=None,
                                       use_profile=True).upright for i in range(4))
    assert rows[1]["successes"] == direct > 0 and rows[1]["trials"] == 4
    gains = gain_rows(rows)
    assert [(g["factor"], g["level"], g["configuration"]) for g in gains] == [
        ("foam_lateral_friction", 0.6, "block"), ("foam_lateral_friction", 2.5, "block"),
        ("robust", "all unknowns drawn", "block")]
    assert all(g["gain_low"] <= g["gain"] <= g["gain_high"] for g in gains)
    assert gain_lines(rows)[0].startswith("sensitivity (simulated launches on the twin)")
    with pytest.raises(ValueError, match="unknown launch factor 'wind'"):
        with_launch_factor(job.launch.twin, "wind", 1.0)


def test_any_numeric_twin_setting_can_be_varied_and_a_robot_setting_weighs_the_profile():
    """``--vary``: a dotted settings name reaches the twin (and, for robot.*, the candidate's profile mass); a path
    that is not a numeric setting, or a value its group refuses, is refused naming it."""
    import trimesh

    from rollability_ros.core.sim.evaluation import settings_at_fidelity
    from rollability_ros.core.sim.sensitivity import _setting_case, with_setting

    block = trimesh.creation.box((0.1, 0.1, 0.05))
    plain = settings_at_fidelity(evaluation.load_settings(), "launch")
    light = _setting_case(block, plain, "robot.profile_print.infill_fraction", 0.05)
    heavy = _setting_case(block, plain, "robot.profile_print.infill_fraction", 0.8)
    assert 0 < light.profile.mass_kg < heavy.profile.mass_kg   # the print weighs the candidate's profile
    assert light.launch.twin.robot.profile_print.infill_fraction == 0.05
    assert not light.launch.twin.trial.early_decision   # every row launches with the full rest rule
    thin = _setting_case(None, plain, "twin.foam.thickness_m", 0.02)
    assert thin.launch.twin.twin.foam.thickness_m == 0.02 and thin.profile is None
    with pytest.raises(ValueError, match="'twin.foam.thick' is not a launch twin setting"):
        with_setting(thin.launch.twin, "twin.foam.thick", 1.0)
    with pytest.raises(ValueError, match="twin.wheel_model is not a numeric setting"):
        with_setting(thin.launch.twin, "twin.wheel_model", 1.0)
    with pytest.raises(ValueError, match=r"^twin.wheel_side_friction_factor out of range: 3.0 is not in \[0.0, 1.0\]$"):
        with_setting(thin.launch.twin, "twin.wheel_side_friction_factor", 3.0)


def test_the_stroke_launchers_speed_solve_holds_under_a_draw_of_strong_coast_resistance():
    """Trial seed 1's draw (wheel drag 0.012 N m, base plate rolling friction 0.007 m) stalls the coasting robot
    below a plate speed of about 1.1 x the set speed: the solve still finds the speed at which the gate reads the
    set speed (proportional steps alone oscillated between a stall and 2 x the set speed and refused)."""
    pytest.importorskip("pybullet")
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.sim.launch.drive import launch_drive
    from rollability_ros.core.sim.launch.placement import sized_for_robot
    from rollability_ros.core.sim.launch.settings import load_launch_twin_settings
    from rollability_ros.core.sim.launch.twin import simulate_launch

    twin = sized_for_robot(load_launch_twin_settings())[0]
    drawn = robust_settings_for(twin, 1, RobustSettings(enabled=True))
    assert drawn.twin.wheel_drag_torque_nm > 0.01 and drawn.twin.launcher.ledge_rolling_friction > 0.005
    drive = launch_drive(drawn, 0.8)
    assert drive.speed_ratio > 1.1
    exact = dataclasses.replace(drawn, twin=dataclasses.replace(
        drawn.twin, speed_sigma_fraction=0.0, angle_sigma_deg=0.0,
        launcher=dataclasses.replace(drawn.twin.launcher, speed_bias_fraction=0.0)))
    gate = simulate_launch(LaunchCondition("baseline", 0.75, 0.8, 0.0), exact, 0).measured_speed_mps
    assert gate == pytest.approx(0.8, rel=0.005)
