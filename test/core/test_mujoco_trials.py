"""The MuJoCo trial engine: contact values shown live on a slope, the trial's semantics, the factory."""
import dataclasses
import math

import numpy as np
import pytest

from rollability_ros.core.sim.evaluation import EvaluatorSettings, evaluate_profile
from rollability_ros.core.sim.trial_engine import make_trial_world
from rollability_ros.core.sim.pybullet_trials import TrialWorld
from rollability_ros.core.sim.world import PhysicsParams

mujoco = pytest.importorskip("mujoco")
pytest.importorskip("pybullet")
from rollability_ros.core.sim.mujoco_trials import MujocoTrialWorld, set_geom_contact  # noqa: E402

SETTINGS = dataclasses.replace(EvaluatorSettings(), physics=PhysicsParams(engine="mujoco"))


def mujoco_slide_distance_m(physics, slope_deg, duration_s=1.0):
    """Distance a 0.1 x 0.1 x 0.04 m, 1 kg box placed at rest on a slope travels in ``duration_s`` (MuJoCo)."""
    spec = mujoco.MjSpec()
    spec.option.timestep = physics.time_step_s
    spec.option.gravity = [0.0, 0.0, physics.gravity_mps2]
    tilt = math.radians(slope_deg)
    ground = spec.worldbody.add_geom()
    ground.type = mujoco.mjtGeom.mjGEOM_PLANE
    ground.size = [0.0, 0.0, 1.0]
    ground.quat = [math.cos(tilt / 2), math.sin(tilt / 2), 0.0, 0.0]
    set_geom_contact(ground, physics, ground=True)
    body = spec.worldbody.add_body()
    body.pos = [0.0, -0.02 * math.sin(tilt), 0.02 * math.cos(tilt)]  # resting on the plane, along its normal
    body.quat = [math.cos(tilt / 2), math.sin(tilt / 2), 0.0, 0.0]
    body.add_freejoint()
    box = body.add_geom()
    box.type = mujoco.mjtGeom.mjGEOM_BOX
    box.size = [0.05, 0.05, 0.02]
    box.mass = 1.0
    set_geom_contact(box, physics)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    start = data.qpos[0:3].copy()
    for _ in range(round(duration_s / physics.time_step_s)):
        mujoco.mj_step(model, data)
    return float(np.linalg.norm(data.qpos[0:3] - start))


@pytest.mark.parametrize("contact_model, critical_deg", [("per_contact", 19.29), ("per_body", 6.99)])
def test_mujoco_box_slides_only_on_slopes_steeper_than_atan_of_effective_friction(contact_model, critical_deg):
    physics = PhysicsParams(contact_model=contact_model, engine="mujoco")
    assert mujoco_slide_distance_m(physics, critical_deg - 2.5) < 0.005      # static friction holds it
    assert mujoco_slide_distance_m(physics, critical_deg + 2.5) > 0.2       # it accelerates down the slope


def test_factory_picks_the_engine_and_callers_do_not_branch():
    assert isinstance(make_trial_world(SETTINGS.robot_model(), None, SETTINGS.trial, SETTINGS.physics),
                      MujocoTrialWorld)
    assert isinstance(make_trial_world(SETTINGS.robot_model(), None, SETTINGS.trial, PhysicsParams()), TrialWorld)
    with pytest.raises(ValueError, match="engine"):
        PhysicsParams(engine="ode").validate()


def test_a_mujoco_evaluation_opens_no_pybullet_client():
    """The evaluation opens only the engine its settings name (issue 43): in a fresh process, a MuJoCo evaluation
    leaves PyBullet with no client connected (before, every batch opened one)."""
    import os
    import pathlib
    import subprocess
    import sys

    script = ("import dataclasses\n"
              "from rollability_ros.core.sim import evaluation\n"
              "from rollability_ros.core.sim.world import PhysicsParams\n"
              "settings = dataclasses.replace(evaluation.EvaluatorSettings(), physics=PhysicsParams(engine='mujoco'))\n"
              "assert evaluation.evaluate_profile(None, 2, 3, settings).trials == 2\n"
              "import pybullet\n"
              "print('connected', pybullet.getConnectionInfo(0)['isConnected'])\n")
    root = pathlib.Path(__file__).resolve().parents[2]
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300,
                            env=dict(os.environ, PYTHONPATH=str(root)))
    assert result.returncode == 0, result.stderr
    assert "connected 0" in result.stdout


def test_a_chassis_at_rest_on_its_wheels_stays_upright_and_settles():
    still = dataclasses.replace(SETTINGS, trial=dataclasses.replace(
        SETTINGS.trial, start_roll_deg=0.0, start_tilt_max_deg=0.0, force_max_n=0.0, torque_min_nm=0.0,
        torque_max_nm=0.0, early_decision=False))
    result = evaluate_profile(None, 5, 3, still)
    assert all(o.upright and o.settled and o.tilt_deg < 1.0 for o in result.trial_results)
    assert max(o.steps for o in result.trial_results) < 200  # rest is detected, not the time cap


def test_bare_chassis_laid_inverted_stays_inverted_in_mujoco_too():
    result = evaluate_profile(None, 30, 7, SETTINGS)
    assert result.successes <= 3
    assert all(o.settled for o in result.trial_results)


def test_mujoco_early_decision_changes_no_outcome():
    from test_early_decision import dome_heights, early
    heights = dome_heights(SETTINGS.grid)
    full = evaluate_profile(heights, 40, 11, early(SETTINGS, False)).trial_results
    fast = evaluate_profile(heights, 40, 11, early(SETTINGS, True)).trial_results
    assert [o.upright for o in fast] == [o.upright for o in full]
    assert any(o.decided for o in fast) and sum(o.steps for o in fast) < sum(o.steps for o in full)


def test_evaluate_engines_prints_both_fitnesses_and_the_agreement(capsys):
    from rollability_ros.cli import main
    assert main(["evaluate", "--baseline", "--trials", "6", "--workers", "1", "--engines", "pybullet,mujoco"]) == 0
    out = capsys.readouterr().out
    assert "pybullet  fitness" in out and "mujoco    fitness" in out and "agreement " in out and "/6 trials" in out
    assert main(["evaluate", "--baseline", "--engines", "pybullet,ode"]) == 2
    assert "--engines needs two different engines" in capsys.readouterr().err


def test_evaluate_designs_in_two_engines_writes_the_table_the_report_reads(tmp_path, capsys):
    import numpy as np
    import yaml

    from rollability_ros.cli import main
    from rollability_ros.core.optimization.design_set import designs_document
    from rollability_ros.core.optimization.selection import PooledDesign, SelectedDesign, SelectionResult
    from rollability_ros.core.profile.geometry import ProfileGrid
    from rollability_ros.core.results.engine_agreement import read_table

    grid = ProfileGrid(rows=4, cols=3)
    chosen = [SelectedDesign("A", PooledDesign(np.repeat(np.linspace(0.05, 0.4, grid.rows), grid.cols), 9, 10, 1, 1),
                             mesh=None, metrics=None, reason="a ramp")]
    designs = tmp_path / "designs.yaml"
    designs.write_text(yaml.safe_dump(designs_document(
        SelectionResult(designs=chosen, requested=1, considered=1, rejected={}), grid, "run-1")))
    assert main(["evaluate", "--designs", str(designs), "--engines", "pybullet,mujoco", "--trials", "4",
                 "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "cross-engine agreement (simulated" in out and "a rank statistic needs at least 3" in out
    rows = read_table(str(tmp_path / "engine_agreement.csv"))
    assert sorted((r.design, r.engine) for r in rows) == [("A", "mujoco"), ("A", "pybullet"),
                                                          ("baseline", "mujoco"), ("baseline", "pybullet")]
    assert all(r.trials == 4 for r in rows)
    assert main(["evaluate", "--designs", str(designs), "--trials", "4"]) == 2      # without --engines
    assert "--designs compares engines" in capsys.readouterr().err
