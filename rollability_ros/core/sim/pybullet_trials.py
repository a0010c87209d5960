"""The ``pybullet`` trial engine (the paper's): :class:`TrialWorld`, one robot + profile in a PyBullet world built
once and restored before every trial; the trial itself is :mod:`~rollability_ros.core.sim.trials`'s (module
docstring)."""
import typing

from rollability_ros.core.optional import require
from rollability_ros.core.robots import ProfileBody, RobotModel
from rollability_ros.core.sim.trial_engine import TrialEngine, TrialOutcome
from rollability_ros.core.sim.trials import (EnergyMonitor, RestDetector, TrialSettings, build_trial_world,
                                             place_on_ground, sample_conditions)
from rollability_ros.core.sim.world import PhysicsParams, connect


#: The ``pybullet`` engine's own PyBullet client in this process (:func:`engine_client`), and per client the
#: :class:`TrialWorld` whose bodies it holds now (building a world empties the client).
_engine_client: typing.Optional[int] = None
_holders: typing.Dict[int, "TrialWorld"] = {}


def engine_client() -> int:
    """The PyBullet DIRECT client the ``pybullet`` trial engine builds its worlds in (:meth:`TrialWorld.build`),
    connected at the first world this process builds: callers of the engine seam open no client themselves."""
    global _engine_client
    if _engine_client is None:
        _engine_client = connect()
    return _engine_client


class TrialWorld(TrialEngine):
    """The ``pybullet`` trial engine: a world holding one robot + profile, saved once after building and restored
    before every trial.

    ``restoreState`` puts back the saved bodies, velocities and (empty) contact cache, so a trial starts from
    the same simulator state whatever ran before it in this client; building the world once saves the cost of
    creating the bodies per trial (see bench/bench_evaluator.py). Worlds built through the seam
    (:meth:`build`) share this process's :func:`engine_client`; building another world in the same client
    empties it, so a world that finds another one holding its client builds itself again before its trial.
    """

    @classmethod
    def build(cls, robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]", settings: TrialSettings,
              physics: PhysicsParams) -> "TrialWorld":
        """The world in this process's :func:`engine_client`."""
        return cls(engine_client(), robot_model, profile, settings, physics)

    def __init__(self, client: int, robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]",
                 settings: TrialSettings, physics: PhysicsParams) -> None:
        self.pybullet = require("pybullet", feature="the simulated evaluator")
        self.client, self.robot_model, self.settings, self.physics = client, robot_model, settings, physics
        self.profile = profile
        self._build()

    def _build(self) -> None:
        """Empty the client, build the ground and the robot, save the state and the early decision's barriers."""
        client, robot_model, settings, physics = self.client, self.robot_model, self.settings, self.physics
        self.ground, self.robot = build_trial_world(client, robot_model, self.profile, (0.0, 0.0, 0.0, 1.0),
                                                    settings, physics)
        self.saved_state = self.pybullet.saveState(physicsClientId=client)
        # the energy barriers hold for a rigid hull only: a compliant mount's trials run to rest
        self.energy = EnergyMonitor(client, robot_model, self.robot, physics.gravity_mps2,
                                    settings.early_decision_margin_m) \
            if settings.early_decision and self.robot.mount_spring is None else None
        _holders[client] = self

    def run(self, index: int, seed: int) -> TrialOutcome:
        """Run one trial (see the module docstring) and return its :class:`TrialOutcome`."""
        if _holders.get(self.client) is not self:   # another world was built in this client since
            self._build()
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
