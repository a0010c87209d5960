"""The trial-engine seam (core/sim/trial_engine.py): one contract, one table, one factory. A new engine is one file
plus one registration line (replay_engine.py), and it runs through the same evaluation as PyBullet and MuJoCo."""
import ast
import dataclasses
import pathlib

import pytest

from rollability_ros.core.sim import trial_engine

SIM = pathlib.Path(__file__).resolve().parents[2] / "rollability_ros" / "core" / "sim"


@pytest.fixture
def engines(monkeypatch):
    """TRIAL_ENGINES as it is, restored after the test."""
    monkeypatch.setattr(trial_engine.TRIAL_ENGINES, "_entries", dict(trial_engine.TRIAL_ENGINES._entries))
    return trial_engine.TRIAL_ENGINES


def test_a_replay_engine_is_one_file_and_one_registration_line(engines):
    pytest.importorskip("pybullet")
    from replay_engine import ReplayTrialWorld
    from rollability_ros.core.sim import evaluation

    trial_engine.register_trial_engine("replay", ReplayTrialWorld)     # the one registration line
    settings = evaluation.EvaluatorSettings()
    real = evaluation.evaluate_profile(None, 4, 7, settings)            # PyBullet, the paper's engine
    ReplayTrialWorld.recorded = {outcome.seed: outcome for outcome in real.trial_results}
    replay = dataclasses.replace(settings, physics=dataclasses.replace(settings.physics, engine="replay"))
    replayed = evaluation.evaluate_profile(None, 4, 7, replay)
    assert replayed.trial_results == real.trial_results and (replayed.successes, replayed.trials) == (
        real.successes, 4)
    with pytest.raises(ValueError, match=r"^replay engine: no recorded trial for seed \d+$"):
        evaluation.evaluate_profile(None, 4, 8, replay)
    # what it cannot run is refused in one line, never run in another engine
    with pytest.raises(ValueError, match=r"^sim.engine 'replay' cannot run launch trials \(engines that can: "
                                         r"pybullet, mujoco\)$"):
        trial_engine.check_engine("launch", "replay")


def test_an_unknown_engine_is_refused_by_the_settings_and_the_factory(engines):
    from rollability_ros.core.sim.world import PhysicsParams

    with pytest.raises(ValueError, match=r"^engine must be one of pybullet, mujoco, got 'replay'$"):
        PhysicsParams(engine="replay").validate()
    with pytest.raises(ValueError, match=r"^sim.engine 'replay' cannot run disturbance trials"):
        trial_engine.make_trial_world(None, None, None, None, PhysicsParams(engine="replay"))
    with pytest.raises(TypeError, match="not a TrialEngine"):
        trial_engine.register_trial_engine("wrong", "rollability_ros.core.sim.world:PhysicsParams")
        trial_engine.TRIAL_ENGINES.get("wrong")


def test_the_built_in_engines_are_on_the_contract():
    pytest.importorskip("pybullet")
    from rollability_ros.core.sim.mujoco_trials import MujocoTrialWorld
    from rollability_ros.core.sim.trials import TrialWorld

    assert trial_engine.TRIAL_ENGINES.get("pybullet") is TrialWorld
    assert trial_engine.TRIAL_ENGINES.get("mujoco") is MujocoTrialWorld


def test_only_the_tables_look_at_the_engine_name():
    """No module of core/sim compares an engine setting with an engine's name: the tables and their factories
    (make_trial_world, launch.twin.simulate_launch through LAUNCH_ENGINES) are the only lookups."""
    branches = []
    for path in sorted(SIM.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Compare) and any(isinstance(c, ast.Constant) and c.value in ("pybullet", "mujoco")
                                                     for c in [node.left, *node.comparators]):
                branches.append(f"{path.name}:{node.lineno}")
    assert branches == []


def test_the_launch_engines_are_on_their_contract():
    pytest.importorskip("mujoco")
    from rollability_ros.core.sim.launch.pybullet_twin import BulletLaunch
    from rollability_ros.core.sim.launch.mujoco_twin import MujocoLaunch

    assert trial_engine.LAUNCH_ENGINES.get("pybullet") is BulletLaunch
    assert trial_engine.LAUNCH_ENGINES.get("mujoco") is MujocoLaunch
    assert trial_engine.engine_names() == ("pybullet", "mujoco")
