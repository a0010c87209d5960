"""The trial-engine seam: the :class:`TrialEngine` contract, its :data:`TRIAL_ENGINES` table (``sim.engine``) and
:func:`make_trial_world`, the only code that looks at the engine's name for disturbance trials.

A trial engine holds one robot + profile in one physics engine's world, built once per profile; ``run(index,
seed)`` then plays one disturbance trial (:mod:`~rollability_ros.core.sim.trials`, module docstring) and returns
its :class:`TrialOutcome`, which depends only on (robot + profile, seed, settings). Built in: ``pybullet``
(:class:`~rollability_ros.core.sim.trials.TrialWorld`, the paper's) and ``mujoco``
(:class:`~rollability_ros.core.sim.mujoco_trials.MujocoTrialWorld`). Adding an engine is one module with a
``TrialEngine`` subclass plus one :func:`register_trial_engine` call or table line (test/core/test_trial_engines.py
adds a replay engine that way). Launches run on the launch twin, whose engines are :data:`LAUNCH_ENGINES`
(:class:`LaunchEngine`: ``pybullet`` -> ``launch.pybullet_twin.BulletLaunch``, ``mujoco`` ->
``launch.mujoco_twin.MujocoLaunch``).

This module imports no physics library: the table names its entries as ``"module:Class"``, imported when chosen.
"""
import abc
import dataclasses
import typing

from rollability_ros.core.registry import Registry

if typing.TYPE_CHECKING:  # annotations only
    from rollability_ros.core.robots import ProfileBody, RobotModel
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.sim.launch.contract import LaunchDrive
    from rollability_ros.core.sim.launch.results import LaunchResult
    from rollability_ros.core.sim.launch.settings import LaunchTwinSettings
    from rollability_ros.core.sim.trials import TrialSettings
    from rollability_ros.core.sim.world import PhysicsParams


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

    #: True when a world owns all its state (not the caller's shared PyBullet client), so a process may keep the
    #: worlds of several profiles at once (evaluation.run_batch keeps the last ``MUJOCO_WORLD_CACHE``).
    owns_world: typing.ClassVar[bool] = False

    @classmethod
    def build(cls, client: int, robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]",
              settings: "TrialSettings", physics: "PhysicsParams") -> "TrialEngine":
        """The world of ``robot_model`` carrying ``profile`` (a ProfileBody, or None for the bare robot);
        ``client`` is the PyBullet client the caller opened (engines with their own world ignore it)."""
        return cls(client, robot_model, profile, settings, physics)  # type: ignore[call-arg]

    @abc.abstractmethod
    def run(self, index: int, seed: int) -> TrialOutcome:
        """Trial number ``index`` with random draws from ``seed``: the same outcome every time it is asked."""


#: ``sim.engine`` -> its :class:`TrialEngine` (``"module:Class"`` entries are imported when chosen).
TRIAL_ENGINES: Registry[TrialEngine] = Registry("sim.engine", TrialEngine, {
    "pybullet": "rollability_ros.core.sim.trials:TrialWorld",
    "mujoco": "rollability_ros.core.sim.mujoco_trials:MujocoTrialWorld",
})


class LaunchEngine(abc.ABC):
    """One launch of the launch twin in one engine (:func:`~rollability_ros.core.sim.launch.twin.simulate_launch`
    checks the condition, sizes the twin and picks the profile, then hands over here)."""

    @classmethod
    @abc.abstractmethod
    def simulate(cls, condition: "LaunchCondition", settings: "LaunchTwinSettings", seed: int,
                 profile: "typing.Optional[ProfileBody]",
                 on_phase: typing.Optional[typing.Callable[[str], None]] = None,
                 on_pose: typing.Optional[typing.Callable[..., None]] = None, *,
                 drive: "typing.Optional[LaunchDrive]" = None, until_edge: bool = False) -> "LaunchResult":
        """The ``LaunchResult`` of ``condition`` with ``seed`` on the twin ``settings`` carrying ``profile``, the
        push plate driven as ``drive`` says (None: ``launch.drive.launch_drive`` of the condition's speed on the
        sized ``settings``); ``until_edge``: stop once the robot's
        foremost point crosses the edge line (the speed gate has read the launch)."""


#: ``sim.engine`` -> its :class:`LaunchEngine`: the engines the launch twin runs in.
LAUNCH_ENGINES: Registry[LaunchEngine] = Registry("sim.engine", LaunchEngine, {
    "pybullet": "rollability_ros.core.sim.launch.pybullet_twin:BulletLaunch",
    "mujoco": "rollability_ros.core.sim.launch.mujoco_twin:MujocoLaunch",
})


def register_trial_engine(name: str, engine: typing.Union[str, type]) -> None:
    """Add an engine to :data:`TRIAL_ENGINES` at run time (a class or ``"module:Class"``)."""
    TRIAL_ENGINES.register(name, engine)


def engine_names() -> typing.Tuple[str, ...]:
    """Every ``sim.engine`` value some trial kind can run in (what ``sim.engine`` accepts)."""
    return tuple(dict.fromkeys(TRIAL_ENGINES.names() + LAUNCH_ENGINES.names()))


def engines_for(kind: str) -> typing.Tuple[str, ...]:
    """The ``sim.engine`` values that can run trials of ``kind`` (``disturbance`` or ``launch``)."""
    if kind == "disturbance":
        return TRIAL_ENGINES.names()
    if kind == "launch":
        return LAUNCH_ENGINES.names()
    raise ValueError(f"trial kind must be disturbance or launch, got {kind!r}")


def check_engine(kind: str, engine: str) -> None:
    """Raise ``ValueError`` (one line) unless ``sim.engine`` ``engine`` can run trials of ``kind``: a setting a
    code path cannot honour is refused, never replaced by another engine."""
    engines = engines_for(kind)
    if engine not in engines:
        raise ValueError(f"sim.engine {engine!r} cannot run {kind} trials (engines that can: {', '.join(engines)})")


def make_trial_world(client: int, robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]",
                     settings: "TrialSettings", physics: "PhysicsParams") -> TrialEngine:
    """The trial world of ``physics.engine`` (:data:`TRIAL_ENGINES`), built; every disturbance trial, plain or
    robust, is built here."""
    check_engine("disturbance", physics.engine)
    return TRIAL_ENGINES.get(physics.engine).build(client, robot_model, profile, settings, physics)
