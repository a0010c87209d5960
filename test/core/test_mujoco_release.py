"""A dropped MuJoCo world is freed at once: nothing it holds refers back to it (no reference cycle), so a long search
does not keep every evicted launch twin's compiled model and data until a rare full garbage collection."""
import dataclasses
import gc
import weakref

import pytest

from rollability_ros.core.records import LaunchCondition
from rollability_ros.core.sim.launch.placement import sized_for_robot
from rollability_ros.core.sim.launch.settings import load_launch_twin_settings
from rollability_ros.core.sim.trials import TrialSettings
from rollability_ros.core.sim.world import PhysicsParams

pytest.importorskip("mujoco")
from rollability_ros.core.sim.launch import mujoco_twin  # noqa: E402
from rollability_ros.core.sim.mujoco_trials import MujocoTrialWorld  # noqa: E402


@pytest.fixture
def no_cycle_collector():
    """The cyclic garbage collector off: what is freed is freed by reference counting alone."""
    gc.collect()
    gc.disable()
    yield
    gc.enable()


def early_decision_settings(stiffness_npm):
    """The shipped MuJoCo launch twin with the early decision on (each foam stiffness a twin of its own, as each
    robustness draw of a robust launch is) and foam stiffness ``stiffness_npm``."""
    settings = load_launch_twin_settings(overrides={"twin.foam.contact_stiffness_npm": stiffness_npm})
    return sized_for_robot(dataclasses.replace(settings, physics=dataclasses.replace(settings.physics, engine="mujoco"),
                                               trial=dataclasses.replace(settings.trial, early_decision=True)))[0]


def test_a_launched_twin_evicted_from_the_cache_is_freed_by_reference_counting(monkeypatch, no_cycle_collector):
    monkeypatch.setattr(mujoco_twin, "_cache", type(mujoco_twin._cache)())
    twin = mujoco_twin.twin_for(early_decision_settings(20000.0), None)
    assert twin.energy is not None
    twin.launch(LaunchCondition("baseline", 0.75, 0.8, 0.0), 0)   # a launch leaves its push plate on the twin
    dropped = weakref.ref(twin)
    del twin
    for index in range(mujoco_twin.CACHE_SIZE):   # as many other twins as the cache keeps: the first is evicted
        mujoco_twin.twin_for(early_decision_settings(21000.0 + 1000.0 * index), None)
    assert dropped() is None


def test_a_dropped_trial_world_with_the_early_decision_is_freed_by_reference_counting(no_cycle_collector):
    world = MujocoTrialWorld(load_launch_twin_settings().robot_model(), None, TrialSettings(early_decision=True),
                             PhysicsParams(engine="mujoco"))
    assert world.energy is not None
    dropped = weakref.ref(world)
    del world
    assert dropped() is None
