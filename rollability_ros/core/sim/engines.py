"""The engine tables of ``sim.engine``: the engines that run disturbance trials (:data:`TRIAL_ENGINES`) and launches
of the launch twin (:data:`LAUNCH_ENGINES`), and the checks of a ``sim.engine`` value against them, the only code
that looks at an engine's name.

The bottom of ``core/sim``: it imports no module of it. Each table names its entries and its contract as
``"module:Class"`` (imported when chosen), so the settings that name an engine
(:class:`~rollability_ros.core.sim.world.PhysicsParams` checks ``sim.engine`` here) and the contracts written in
those settings (:class:`~rollability_ros.core.sim.trial_engine.TrialEngine`,
:class:`~rollability_ros.core.sim.launch.contract.LaunchEngine`) both import this module, and no module needs a
reference back to its caller. Adding an engine is one module with the contract's subclass plus one table line or
:func:`register_trial_engine` call (test/core/test_trial_engines.py adds a replay engine that way); the typed
lookups are :func:`~rollability_ros.core.sim.trial_engine.make_trial_world` and
:func:`~rollability_ros.core.sim.launch.twin.simulate_launch`.
"""
import typing

from rollability_ros.core.registry import Registry

#: ``sim.engine`` -> its :class:`~rollability_ros.core.sim.trial_engine.TrialEngine` (disturbance trials).
TRIAL_ENGINES: Registry[typing.Any] = Registry("sim.engine", "rollability_ros.core.sim.trial_engine:TrialEngine", {
    "pybullet": "rollability_ros.core.sim.pybullet_trials:TrialWorld",
    "mujoco": "rollability_ros.core.sim.mujoco_trials:MujocoTrialWorld",
})

#: ``sim.engine`` -> its :class:`~rollability_ros.core.sim.launch.contract.LaunchEngine`: the engines the launch
#: twin runs in.
LAUNCH_ENGINES: Registry[typing.Any] = Registry(
    "sim.engine", "rollability_ros.core.sim.launch.contract:LaunchEngine", {
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


#: The engines whose contacts have no coefficient of restitution (a contact is a damped spring, critically damped:
#: an underdamped one rings for ever at rest). They run the paper's robot restitution (``sim.restitution`` 0.3) as
#: their declared known difference (docs/engines.md) and refuse any other value (:func:`check_restitution`); the
#: robust objective draws the robot's restitution only on the other engines (:mod:`~rollability_ros.core.sim.
#: robustness`).
ENGINES_WITHOUT_RESTITUTION = ("mujoco",)


def represents_restitution(engine: str) -> bool:
    """Whether ``sim.engine`` ``engine`` represents the robot's coefficient of restitution."""
    return engine not in ENGINES_WITHOUT_RESTITUTION


def check_restitution(engine: str, restitution: float, paper_value: float) -> None:
    """Raise ``ValueError`` (one line) when ``engine`` cannot represent restitution and ``restitution`` is not the
    paper's ``paper_value`` (the value it runs as its known difference): a setting a code path cannot honour is
    refused, never silently replaced."""
    if not represents_restitution(engine) and restitution != paper_value:
        raise ValueError(f"sim.engine {engine!r} cannot represent restitution (its contacts are damped springs): "
                         f"sim.restitution {restitution:g} is refused (it runs only the paper's {paper_value:g}, as "
                         f"its known difference: docs/engines.md); run this on pybullet")
