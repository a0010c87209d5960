"""The trial-engine contract: :class:`TrialEngine` (one robot + profile in one physics engine's world), the
:class:`TrialOutcome` it returns, and :func:`make_trial_world`, which builds the engine ``sim.engine`` names from
:data:`~rollability_ros.core.sim.engines.TRIAL_ENGINES`.

A trial engine holds one robot + profile in one physics engine's world, built once per profile; ``run(index,
seed)`` then plays one disturbance trial (:mod:`~rollability_ros.core.sim.trials`, module docstring) and returns
its :class:`TrialOutcome`, which depends only on (robot + profile, seed, settings). Built in: ``pybullet``
(:class:`~rollability_ros.core.sim.pybullet_trials.TrialWorld`, the paper's) and ``mujoco``
(:class:`~rollability_ros.core.sim.mujoco_trials.MujocoTrialWorld`). Adding an engine is one module with a
``TrialEngine`` subclass plus one :func:`~rollability_ros.core.sim.engines.register_trial_engine` call or table
line (test/core/test_trial_engines.py adds a replay engine that way). Launches run on the launch twin, whose
engines are :data:`~rollability_ros.core.sim.engines.LAUNCH_ENGINES`
(:class:`~rollability_ros.core.sim.launch.contract.LaunchEngine`).

This module imports no physics library: the table names its entries as ``"module:Class"``, imported when chosen.
"""
import abc
import dataclasses
import typing

from rollability_ros.core.robots import ProfileBody, RobotModel
from rollability_ros.core.sim.engines import TRIAL_ENGINES, check_engine, check_restitution
from rollability_ros.core.sim.trials import TrialSettings
from rollability_ros.core.sim.world import PAPER_RESTITUTION, PhysicsParams


@dataclasses.dataclass(frozen=True)
class TrialOutcome:
    """Outcome of one trial (``msg/TrialResult.msg``): upright at the end, settled before the cap, steps, tilt
    (deg); ``decided``: ended by the early decision (not part of the message)."""

    index: int
    seed: int
    upright: bool
    settled: bool
    steps: int
    tilt_deg: float
    decided: bool = False


class TrialEngine(abc.ABC):
    """One robot + profile in one engine's world; ``run(index, seed)`` per trial (module docstring)."""

    #: True when a world owns all its state, so a process may keep the worlds of several profiles at once
    #: (evaluation.run_batch keeps the last ``MUJOCO_WORLD_CACHE``); False when the engine's worlds in one process
    #: share state (the ``pybullet`` engine's one client), so the caller keeps one at a time.
    owns_world: typing.ClassVar[bool] = False

    @classmethod
    def build(cls, robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]", settings: "TrialSettings",
              physics: "PhysicsParams") -> "TrialEngine":
        """The world of ``robot_model`` carrying ``profile`` (a ProfileBody, or None for the bare robot). The
        engine opens whatever its world needs (a physics client, a compiled model); the caller opens nothing."""
        return cls(robot_model, profile, settings, physics)  # type: ignore[call-arg]

    @abc.abstractmethod
    def run(self, index: int, seed: int) -> TrialOutcome:
        """Trial number ``index`` with random draws from ``seed``: the same outcome every time it is asked."""


def make_trial_world(robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]", settings: "TrialSettings",
                     physics: "PhysicsParams") -> TrialEngine:
    """The trial world of ``physics.engine`` (:data:`TRIAL_ENGINES`), built; every disturbance trial, plain or
    robust, is built here."""
    check_engine("disturbance", physics.engine)
    check_restitution(physics.engine, physics.restitution, PAPER_RESTITUTION)
    engine: typing.Type[TrialEngine] = TRIAL_ENGINES.get(physics.engine)
    return engine.build(robot_model, profile, settings, physics)


def run_trial(robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]", index: int, seed: int,
              settings: TrialSettings, physics: PhysicsParams) -> TrialOutcome:
    """Run one trial in a freshly built world of ``physics.engine`` (:func:`make_trial_world`) and return its
    :class:`TrialOutcome`."""
    return make_trial_world(robot_model, profile, settings, physics).run(index, seed)
