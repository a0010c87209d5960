"""One disturbance trial: start state, randomised push, stepping to rest, upright test.

A trial's result depends only on (robot + profile, trial seed, settings): a :class:`TrialWorld` is built once
per profile and restored to its saved state before every trial, so nothing carries over from the trials run
before it in the same process (test_evaluation checks outcomes against a freshly built world and across orders),
and the serial, process-pool and Ray executors give identical outcomes.

Start state (``TrialSettings``)
    the robot rolled ``start_roll_deg`` (180 = upside down) about its x axis, then tilted by a random roll and
    pitch, each uniform in +-``start_tilt_max_deg``, turned to a yaw uniform in [0, 360) deg, and placed with its
    lowest point ``drop_height_m`` above the ground, at rest.
Disturbance
    after ``disturbance_delay_s`` (the drop has landed), for ``disturbance_duration_s``: a horizontal force at
    the base's centre of mass, azimuth uniform in [0, 360) deg, magnitude uniform in [``force_min_n``,
    ``force_max_n``], plus a tipping torque about a horizontal axis of azimuth uniform in [0, 360) deg, magnitude
    uniform in [``torque_min_nm``, ``torque_max_nm``], both in the world frame and constant while applied.
End
    once the disturbance is over, every ``check_interval_steps`` steps the base's linear and angular speed are
    compared with the rest thresholds; the trial ends when they have stayed below them for ``rest_hold_s``
    (settled) or at ``time_cap_s`` (not settled). The robot model then judges upright (tilt and wheel contact).
Early decision (``early_decision``, on by default)
    at the same checks, the trial also ends as soon as energy alone fixes its outcome: the robot's kinetic plus
    potential energy is below the barrier out of the region (upright, or not upright) it is in
    (:mod:`rollability_ros.core.sim.early_decision`). The outcome is then that region's, ``settled`` is true
    (it can no longer leave it), ``decided`` is true and ``tilt_deg`` is the tilt at the decision.
    The barriers assume a rigid hull, so a robot whose profile rides on a compliant mount
    (:class:`~rollability_ros.core.robots.robot.ProfileMountSpec`) always runs to rest.
"""
import dataclasses
import math
import typing

import numpy as np

from rollability_ros.core.optional import require
# the engine seam (TRIAL_ENGINES, check_engine, make_trial_world, TrialOutcome) is importable from here as before
from rollability_ros.core.sim.trial_engine import (TRIAL_ENGINES, TrialEngine, TrialOutcome, check_engine,  # noqa: F401
                                                   make_trial_world)
from rollability_ros.core.sim.world import PhysicsParams, reset_world, set_contact

if typing.TYPE_CHECKING:  # annotations only
    from rollability_ros.core.robots import ProfileBody, RobotModel


@dataclasses.dataclass
class TrialSettings:
    """Start state, disturbance and rest detection of a trial (``config/sim.yaml``, section ``trial``)."""

    start_roll_deg: float = dataclasses.field(default=180.0, metadata={
        "description": "roll of the starting pose, deg (180 = inverted)", "range": (-360.0, 360.0)})
    start_tilt_max_deg: float = dataclasses.field(default=10.0, metadata={
        "description": "extra random roll and pitch of the start, each uniform in [-max, +max], deg",
        "range": (0.0, 90.0)})
    drop_height_m: float = dataclasses.field(default=0.005, metadata={
        "description": "clearance of the robot's lowest point above the ground at the start, m",
        "range": (0.0, 100.0)})
    disturbance_delay_s: float = dataclasses.field(default=0.1, metadata={
        "description": "time after the start when the random force and torque begin, s (the drop has landed)",
        "range": (0.0, 3600.0)})
    disturbance_duration_s: float = dataclasses.field(default=0.1, metadata={
        "description": "how long the random force and torque act, s", "range": (0.0, 3600.0)})
    force_min_n: float = dataclasses.field(default=0.0, metadata={
        "description": "lower bound of the random disturbance force magnitude, N", "range": (0.0, 1000000.0)})
    force_max_n: float = dataclasses.field(default=2.0, metadata={
        "description": "upper bound of the random disturbance force magnitude, N", "range": (0.0, 1000000.0)})
    torque_min_nm: float = dataclasses.field(default=1.0, metadata={
        "description": "lower bound of the random disturbance torque magnitude, N m", "range": (0.0, 1000000.0)})
    torque_max_nm: float = dataclasses.field(default=2.0, metadata={
        "description": "upper bound of the random disturbance torque magnitude, N m", "range": (0.0, 1000000.0)})
    rest_linear_speed_mps: float = dataclasses.field(default=0.01, metadata={
        "description": "at rest when the linear speed stays below this, m/s",
        "range": (0.0, 1000.0), "exclusive": "low"})
    rest_angular_speed_dps: float = dataclasses.field(default=5.0, metadata={
        "description": "at rest when the angular speed stays below this, deg/s",
        "range": (0.0, 100000.0), "exclusive": "low"})
    rest_hold_s: float = dataclasses.field(default=0.25, metadata={
        "description": "the robot must stay at rest this long for the trial to end, s",
        "range": (0.0, 3600.0), "exclusive": "low"})
    time_cap_s: float = dataclasses.field(default=8.0, metadata={
        "description": "simulated time after which an undecided trial stops and counts as not upright, s",
        "range": (0.0, 86400.0), "exclusive": "low"})
    check_interval_steps: int = dataclasses.field(default=4, metadata={
        "description": "physics steps between two rest checks (count)", "range": (1, 100000)})
    early_decision: bool = dataclasses.field(default=True, metadata={
        "description": "true: end a trial once its energy cannot reach a resting pose of the other outcome "
                       "(verified to change no outcome, docs/engines.md); false: the full rest rule"})
    early_decision_margin_m: float = dataclasses.field(default=0.002, metadata={
        "description": "safety margin taken off every energy barrier of the early decision, m of height",
        "range": (0.0, 1.0)})

    def validate(self) -> None:
        """Raise ``ValueError`` for a rule that spans fields (each number's range is declared in its metadata and
        checked by :func:`~rollability_ros.core.config.check_settings`)."""
        if self.force_max_n < self.force_min_n or self.torque_max_nm < self.torque_min_nm:
            raise ValueError("need force_min_n <= force_max_n and torque_min_nm <= torque_max_nm")
        if self.time_cap_s <= self.disturbance_delay_s + self.disturbance_duration_s + self.rest_hold_s:
            raise ValueError("time_cap_s must exceed disturbance_delay_s + disturbance_duration_s + rest_hold_s")


@dataclasses.dataclass(frozen=True)
class TrialConditions:
    """The random draws of one trial: start orientation (x, y, z, w) and world-frame force (N) and torque (N m)."""

    orientation: tuple
    force_n: np.ndarray
    torque_nm: np.ndarray


def sample_conditions(seed: int, settings: TrialSettings) -> TrialConditions:
    """Draw a trial's start orientation and disturbance from ``seed`` (see the module docstring)."""
    pybullet = require("pybullet", feature="the simulated evaluator")
    rng = np.random.default_rng(seed)
    tilt = math.radians(settings.start_tilt_max_deg)
    roll, pitch = rng.uniform(-tilt, tilt, size=2)
    yaw = rng.uniform(0.0, 2 * math.pi)
    # flip about the body x axis first, then tilt and yaw in the world
    flip = pybullet.getQuaternionFromEuler([math.radians(settings.start_roll_deg), 0.0, 0.0])
    turn = pybullet.getQuaternionFromEuler([roll, pitch, yaw])
    _, orientation = pybullet.multiplyTransforms([0, 0, 0], turn, [0, 0, 0], flip)
    azimuth = rng.uniform(0.0, 2 * math.pi)
    force = rng.uniform(settings.force_min_n, settings.force_max_n) * np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
    axis_azimuth = rng.uniform(0.0, 2 * math.pi)
    torque = rng.uniform(settings.torque_min_nm, settings.torque_max_nm) * np.array(
        [math.cos(axis_azimuth), math.sin(axis_azimuth), 0.0])
    return TrialConditions(orientation=tuple(orientation), force_n=force, torque_nm=torque)


def place_on_ground(client: int, body_id: int, orientation: typing.Sequence[float], clearance_m: float,
                    xy_m: typing.Sequence[float] = (0.0, 0.0), ground_z_m: float = 0.0) -> None:
    """Put ``body_id`` with ``orientation`` at ``xy_m`` (base origin, metres) so that its lowest point is
    ``clearance_m`` above the surface z = ``ground_z_m``, at rest."""
    pybullet = require("pybullet", feature="the simulated evaluator")
    x, y = xy_m
    pybullet.resetBasePositionAndOrientation(body_id, [x, y, 0], orientation, physicsClientId=client)
    lowest = min(pybullet.getAABB(body_id, link, physicsClientId=client)[0][2]
                 for link in range(-1, pybullet.getNumJoints(body_id, physicsClientId=client)))
    pybullet.resetBasePositionAndOrientation(body_id, [x, y, ground_z_m + clearance_m - lowest], orientation,
                                             physicsClientId=client)


def build_trial_world(client: int, robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]",
                      orientation: typing.Sequence[float],
                      settings: TrialSettings, physics: PhysicsParams) -> typing.Tuple[int, typing.Any]:
    """Empty the world, add the ground and the robot in its start pose; return ``(ground_id, spawned robot)``."""
    ground = reset_world(client, physics)
    robot = robot_model.spawn(client, profile, (0.0, 0.0, 1.0), orientation, time_step_s=physics.time_step_s)
    set_contact(client, robot.body_id, physics.body_contact())
    place_on_ground(client, robot.body_id, orientation, settings.drop_height_m)
    return ground, robot


class RestDetector:
    """Says when a body has come to rest (see "End" in the module docstring); shared by trials and the launch twin.

    ``settings`` supplies ``rest_linear_speed_mps``, ``rest_angular_speed_dps``, ``rest_hold_s`` and
    ``check_interval_steps`` (a :class:`TrialSettings`); ``time_step_s`` is the simulation step (s).
    """

    def __init__(self, settings, time_step_s):
        self.linear_mps = settings.rest_linear_speed_mps
        self.angular_radps = math.radians(settings.rest_angular_speed_dps)
        self.interval_steps = settings.check_interval_steps
        self.hold_steps = round(settings.rest_hold_s / time_step_s)
        self._rest_since = None
        self._pybullet = require("pybullet", feature="the simulated evaluator")

    def settled(self, client: int, body_id: int, steps: int) -> bool:
        """Call after step number ``steps``: True once ``body_id``'s base speeds have stayed below the thresholds
        for the hold time (checked every ``check_interval_steps`` steps)."""
        if steps % self.interval_steps:
            return False
        linear, angular = self._pybullet.getBaseVelocity(body_id, physicsClientId=client)
        if math.hypot(*linear) < self.linear_mps and math.hypot(*angular) < self.angular_radps:
            self._rest_since = steps if self._rest_since is None else self._rest_since
            return steps - self._rest_since >= self.hold_steps
        self._rest_since = None
        return False


class EnergyMonitor:
    """Reads a spawned robot's energy height and down direction and asks its basin map for a decision.

    Built once per :class:`TrialWorld` (the robot at its saved pose): per-link masses and principal inertias,
    and the :class:`~rollability_ros.core.sim.early_decision.BasinMap` of the robot + profile. ``ground_z_m`` is
    the height of the flat ground the barriers stand on (the launch twin's foam top); ``basins``, when given,
    is that robot + profile's map from an earlier build (the launch twin spawns its robot per launch).
    ``radius_m`` is the hull's largest distance from the centre of mass (m).
    """

    def __init__(self, client, robot_model, robot, gravity_mps2, margin_m, ground_z_m=0.0, basins=None):
        from rollability_ros.core.sim.early_decision import build_basin_map
        from rollability_ros.core.sim._body_points import link_points

        pybullet = self.pybullet = require("pybullet", feature="the simulated evaluator")
        self.client, self.body = client, robot.body_id
        points, masses, centres = link_points(client, self.body, sections=24)
        position, orientation = pybullet.getBasePositionAndOrientation(self.body, physicsClientId=client)
        rotation = np.asarray(pybullet.getMatrixFromQuaternion(orientation)).reshape(3, 3)
        origin = np.asarray(position)
        in_base = {link: (world - origin) @ rotation for link, world in points.items()}
        self.mass_kg = float(sum(masses.values()))
        com_world = sum(masses[link] * centres[link] for link in masses) / self.mass_kg
        self.links = [link for link in masses if link >= 0]
        order = [-1] + self.links
        self.masses = [float(masses[link]) for link in order]
        self.inertias = [tuple(pybullet.getDynamicsInfo(self.body, link, physicsClientId=client)[2])
                         for link in order]
        self.gravity_mps2 = abs(gravity_mps2)
        self.ground_z_m = ground_z_m
        com_in_base = (com_world - origin) @ rotation
        self.radius_m = max(float(np.linalg.norm(points - com_in_base, axis=1).max()) for points in in_base.values())
        self.basins = basins if basins is not None else build_basin_map(
            in_base, robot.wheel_links, com_in_base, self.mass_kg, rotation.T @ robot_model.up_axis(client, robot),
            robot_model.upright_tilt_deg, robot_model.min_wheels_in_contact, robot_model.contact_tolerance_m,
            margin_m=margin_m)
        self.com_in_base = tuple(float(value) for value in self.basins.com_m)
        self.highest_barrier_m = self.basins.highest_barrier_m()

    def decide(self) -> typing.Optional[bool]:
        """True / False once the trial's outcome is fixed (upright / not), else None."""
        # plain floats: a few numbers per link, where numpy's per-call cost would exceed a simulation step
        pybullet, client, body = self.pybullet, self.client, self.body
        position, orientation = pybullet.getBasePositionAndOrientation(body, physicsClientId=client)
        linear, angular = pybullet.getBaseVelocity(body, physicsClientId=client)
        base = pybullet.getMatrixFromQuaternion(orientation)
        kinetic = self._kinetic_j(self.masses[0], self.inertias[0], base, linear, angular)
        if self.links:
            states = pybullet.getLinkStates(body, self.links, computeLinkVelocity=1, physicsClientId=client)
            for mass, inertia, state in zip(self.masses[1:], self.inertias[1:], states):
                kinetic += self._kinetic_j(mass, inertia, pybullet.getMatrixFromQuaternion(state[1]), state[6],
                                           state[7])
        cx, cy, cz = self.com_in_base
        com_z = position[2] + base[6] * cx + base[7] * cy + base[8] * cz - self.ground_z_m
        energy_height_m = self.energy_height_m = com_z + kinetic / (self.mass_kg * self.gravity_mps2)
        if energy_height_m >= self.highest_barrier_m:  # cheap first test
            return None
        return self.basins.decide(np.array([-base[6], -base[7], -base[8]]), energy_height_m)

    def com_xy_m(self) -> typing.Tuple[float, float]:
        """The robot's centre of mass (x, y) in the world now (m)."""
        position, orientation = self.pybullet.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        base = np.asarray(self.pybullet.getMatrixFromQuaternion(orientation)).reshape(3, 3)
        com = np.asarray(position) + base @ np.asarray(self.com_in_base)
        return float(com[0]), float(com[1])

    @staticmethod
    def _kinetic_j(mass, inertia, rotation, linear, angular):
        """Kinetic energy (J) of one link: ``rotation`` its inertia frame (row-major 9-tuple), world velocities."""
        wx, wy, wz = angular
        energy = mass * (linear[0] ** 2 + linear[1] ** 2 + linear[2] ** 2)
        for axis in range(3):  # angular velocity about each principal axis (a column of the rotation)
            spin = rotation[axis] * wx + rotation[3 + axis] * wy + rotation[6 + axis] * wz
            energy += inertia[axis] * spin * spin
        return 0.5 * energy


class TrialWorld(TrialEngine):
    """The ``pybullet`` trial engine: a world holding one robot + profile, saved once after building and restored
    before every trial.

    ``restoreState`` puts back the saved bodies, velocities and (empty) contact cache, so a trial starts from
    the same simulator state whatever ran before it in this client; building the world once saves the cost of
    creating the bodies per trial (see bench/bench_evaluator.py). Building another world in the same client
    (or any ``resetSimulation``) invalidates this one.
    """

    def __init__(self, client, robot_model, profile, settings, physics):
        self.pybullet = require("pybullet", feature="the simulated evaluator")
        self.client, self.robot_model, self.settings, self.physics = client, robot_model, settings, physics
        self.ground, self.robot = build_trial_world(client, robot_model, profile, (0.0, 0.0, 0.0, 1.0), settings,
                                                    physics)
        self.saved_state = self.pybullet.saveState(physicsClientId=client)
        # the energy barriers hold for a rigid hull only: a compliant mount's trials run to rest
        self.energy = EnergyMonitor(client, robot_model, self.robot, physics.gravity_mps2,
                                    settings.early_decision_margin_m) \
            if settings.early_decision and self.robot.mount_spring is None else None

    def run(self, index: int, seed: int) -> TrialOutcome:
        """Run one trial (see the module docstring) and return its :class:`TrialOutcome`."""
        pybullet, client, settings, body = self.pybullet, self.client, self.settings, self.robot.body_id
        conditions = sample_conditions(seed, settings)
        pybullet.restoreState(self.saved_state, physicsClientId=client)
        place_on_ground(client, body, conditions.orientation, settings.drop_height_m)
        dt = self.physics.time_step_s
        push_start = round(settings.disturbance_delay_s / dt)
        push_end = push_start + max(1, round(settings.disturbance_duration_s / dt))
        cap = round(settings.time_cap_s / dt)
        rest = RestDetector(settings, dt)
        force, torque = conditions.force_n.tolist(), conditions.torque_nm.tolist()
        step_simulation = pybullet.stepSimulation
        before_step = self.robot.before_step
        settled = False
        decision = None
        steps = 0
        energy = self.energy
        interval = settings.check_interval_steps
        while steps < cap:
            if push_start <= steps < push_end:
                centre, _ = pybullet.getBasePositionAndOrientation(body, physicsClientId=client)
                pybullet.applyExternalForce(body, -1, force, centre, pybullet.WORLD_FRAME, physicsClientId=client)
                pybullet.applyExternalTorque(body, -1, torque, pybullet.WORLD_FRAME, physicsClientId=client)
            before_step()
            step_simulation(physicsClientId=client)
            steps += 1
            if steps >= push_end:
                if energy is not None and steps % interval == 0:
                    decision = energy.decide()
                    if decision is not None:
                        settled = True
                        break
                if rest.settled(client, body, steps):
                    settled = True
                    break
        if decision is not None:
            return TrialOutcome(index=index, seed=seed, upright=decision, settled=True, steps=steps,
                                tilt_deg=self.robot_model.tilt_deg(client, self.robot), decided=True)
        upright, tilt = self.robot_model.is_upright(client, self.robot, self.ground)
        return TrialOutcome(index=index, seed=seed, upright=upright, settled=settled, steps=steps, tilt_deg=tilt)


def run_trial(client: int, robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]",
              index: int, seed: int, settings: TrialSettings,
              physics: PhysicsParams) -> TrialOutcome:
    """Run one trial in a freshly built world of ``physics.engine``
    (:func:`~rollability_ros.core.sim.trial_engine.make_trial_world`; a PyBullet world is built in ``client``)
    and return its :class:`TrialOutcome`."""
    return make_trial_world(client, robot_model, profile, settings, physics).run(index, seed)
