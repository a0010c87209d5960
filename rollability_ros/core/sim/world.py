"""PyBullet physics parameters and world building: one DIRECT client per simulation, its id passed to every call.

Contact parameters and how Bullet combines them
-----------------------------------------------
Bullet combines the parameters of two touching bodies per contact: friction ``mu_a * mu_b``, restitution
``e_a * e_b``, rolling ``r_a * mu_b + r_b * mu_a`` and spinning likewise (btManifoldResult). ``contact_model``
says what the paper's numbers (``config/sim.yaml``) mean:

``per_contact`` (default)
    they are the values of the robot-ground contact: the robot gets them and the ground gets friction 1,
    restitution 1, rolling 0, spinning 0, so every combined value equals the configured one (a box slides on a
    slope steeper than atan(0.35) = 19.3 deg).
``per_body``
    every body gets them and Bullet multiplies: effective friction 0.35 * 0.35 = 0.1225 (slides above 7.0
    deg), restitution 0.09, rolling 2 * 0.01 * 0.35 = 0.007.

``test/core/test_physics.py`` puts a box on slopes either side of atan(mu_effective) in both models.
"""
import dataclasses
import math
import typing

from rollability_ros.core.optional import require
from rollability_ros.core.sim.engines import engine_names

CONTACT_MODELS = ("per_contact", "per_body")
#: The paper's coefficient of restitution (2.1.1): ``sim.restitution``'s default, and the one value an engine without
#: restitution runs (:func:`~rollability_ros.core.sim.engines.check_restitution`).
PAPER_RESTITUTION = 0.3
#: The engine names of the tables (core/sim/engines.py) when this module was imported, for code written
#: before them; ``engine_names()`` also holds an engine registered later (``sim.engine`` validation uses it).
ENGINES = engine_names()


@dataclasses.dataclass
class PhysicsParams:
    """Simulation constants (``config/sim.yaml``, section ``sim``); SI units, friction coefficients unitless."""

    gravity_mps2: float = dataclasses.field(default=-9.81, metadata={
        "description": "gravitational acceleration along world z, m/s^2 (negative = down)",
        "range": (-100.0, 0.0), "exclusive": "high"})
    time_step_s: float = dataclasses.field(default=1.0 / 240.0, metadata={
        "description": "physics time step, s (paper 1/240)", "range": (0.0, 0.05), "exclusive": "low"})
    lateral_friction: float = dataclasses.field(default=0.35, metadata={
        "description": "sliding friction coefficient (see sim.contact_model; paper 0.35)", "range": (0.0, 10.0)})
    rolling_friction: float = dataclasses.field(default=0.01, metadata={
        "description": "rolling friction coefficient (see sim.contact_model)", "range": (0.0, 10.0)})
    spinning_friction: float = dataclasses.field(default=0.02, metadata={
        "description": "spinning (torsional) friction coefficient (see sim.contact_model)", "range": (0.0, 10.0)})
    restitution: float = dataclasses.field(default=PAPER_RESTITUTION, metadata={
        "description": "coefficient of restitution of impacts (see sim.contact_model; paper 0.3)",
        "range": (0.0, 1.0)})
    contact_model: str = dataclasses.field(default="per_contact", metadata={
        "description": "how the paper's friction and restitution apply: per_contact (effective value between two "
                       "bodies) or per_body (Bullet multiplies two bodies' values)"})
    solver_iterations: int = dataclasses.field(default=50, metadata={
        "description": "Bullet constraint-solver iterations per time step (count)", "range": (1, 10000)})
    engine: str = dataclasses.field(default="pybullet", metadata={
        "description": "physics engine of the trials: pybullet (the paper's) or mujoco (faster; no restitution, "
                       "see docs/engines.md)"})

    def validate(self) -> None:
        """Raise ``ValueError`` for an unknown contact model or engine (each number's range is declared in its
        metadata and checked by :func:`~rollability_ros.core.config.check_settings`)."""
        if self.contact_model not in CONTACT_MODELS:
            raise ValueError(f"contact_model must be one of {', '.join(CONTACT_MODELS)}, got {self.contact_model!r}")
        if self.engine not in engine_names():
            raise ValueError(f"engine must be one of {', '.join(engine_names())}, got {self.engine!r}")

    def effective_friction(self) -> float:
        """The friction coefficient of a robot-ground contact under ``contact_model``."""
        return self.lateral_friction * (self.lateral_friction if self.contact_model == "per_body" else 1.0)

    def body_contact(self) -> typing.Dict[str, float]:
        """Contact parameters for a simulated object (robot, test box): pybullet ``changeDynamics`` keywords."""
        return {"lateralFriction": self.lateral_friction, "rollingFriction": self.rolling_friction,
                "spinningFriction": self.spinning_friction, "restitution": self.restitution}

    def ground_contact(self) -> typing.Dict[str, float]:
        """Contact parameters for the ground under ``contact_model`` (see the module docstring)."""
        if self.contact_model == "per_body":
            return self.body_contact()
        return {"lateralFriction": 1.0, "rollingFriction": 0.0, "spinningFriction": 0.0, "restitution": 1.0}


def connect() -> int:
    """Start a PyBullet physics server in DIRECT mode (no GUI) and return its client id."""
    pybullet = require("pybullet", feature="the simulated evaluator")
    return pybullet.connect(pybullet.DIRECT)


def disconnect(client: int) -> None:
    """Stop the physics server ``client``."""
    require("pybullet").disconnect(physicsClientId=client)


def reset_world(client: int, physics: PhysicsParams, slope_deg: float = 0.0) -> int:
    """Empty ``client``'s world, apply ``physics`` and add a ground plane; return the ground's body id.

    The ground is a static plane through the world origin, tilted by ``slope_deg`` about the world x axis (so
    "downhill" is -y for a positive slope).
    """
    pybullet = require("pybullet", feature="the simulated evaluator")
    pybullet.resetSimulation(physicsClientId=client)
    pybullet.setGravity(0.0, 0.0, physics.gravity_mps2, physicsClientId=client)
    pybullet.setPhysicsEngineParameter(fixedTimeStep=physics.time_step_s, numSolverIterations=physics.solver_iterations,
                                       deterministicOverlappingPairs=1, physicsClientId=client)
    plane = pybullet.createCollisionShape(pybullet.GEOM_PLANE, physicsClientId=client)
    orientation = pybullet.getQuaternionFromEuler([math.radians(slope_deg), 0.0, 0.0])
    ground = pybullet.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=plane, baseOrientation=orientation,
                                      physicsClientId=client)
    set_contact(client, ground, physics.ground_contact())
    return ground


def set_contact(client: int, body_id: int, contact: typing.Mapping[str, float]) -> None:
    """Apply ``contact`` (``changeDynamics`` keywords) to the base and every link of ``body_id``."""
    pybullet = require("pybullet", feature="the simulated evaluator")
    for link in range(-1, pybullet.getNumJoints(body_id, physicsClientId=client)):
        pybullet.changeDynamics(body_id, link, physicsClientId=client, **contact)
