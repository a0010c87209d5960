"""What the engine-neutral launch loop (:func:`~rollability_ros.core.sim.launch.loop.step_launch`) asks of an
engine's twin: its world (:class:`LaunchWorld`), its push plate (:class:`LaunchPlate`), and how the cylinder drives
that plate (:class:`LaunchDrive`). Each engine's module (``pybullet_twin``, ``mujoco_twin``) implements them."""
import dataclasses
import math
import typing

from rollability_ros.core.sim.launch.settings import PushPlateSpec


@dataclasses.dataclass(frozen=True)
class LaunchDrive:
    """How the cylinder drives the push plate in launches of one set speed (package docstring, "Launch"): the
    plate's speed is ``speed_ratio`` x the launch's drawn gate speed, reached with at most ``force_n`` (from rest,
    within ``ramp_s``), and held until the plate has travelled ``stroke_m`` (inf: until the robot goes over the
    edge, ``push_through``) or the robot goes over the edge."""

    model: str
    speed_ratio: float
    force_n: float
    stroke_m: float
    ramp_s: float

    def plate_speed_mps(self, gate_speed_mps: float) -> float:
        """The plate's speed (m/s) for a launch whose drawn gate speed is ``gate_speed_mps``."""
        return self.speed_ratio * gate_speed_mps

    def plate_spec(self, spec: PushPlateSpec) -> PushPlateSpec:
        """``spec`` with this drive's force and ramp (what the twins' plates read)."""
        return dataclasses.replace(spec, max_force_n=self.force_n, ramp_s=self.ramp_s)

class LaunchPlate(typing.Protocol):
    """What :func:`step_launch` drives of a twin's push plate (:class:`PushPlate`, the MuJoCo twin's plate)."""

    driving: bool

    def drive(self, speed_mps: float, time_s: float) -> None:
        """Drive along the push at ``time_s`` (s) after the fire, ramping to ``speed_mps`` (m/s) over ``ramp_s``."""

    def reached_edge(self) -> bool:
        """True once the plate's face has reached the edge line x = 0."""

    def travel_m(self) -> float:
        """How far the plate has moved along the push from its start (m)."""

    def stop(self) -> None:
        """Brake the plate to rest."""

class LaunchWorld:
    """What the launch loop (:func:`step_launch`) needs of an engine's world holding the twin: the robot's base
    pose and velocity, its first contacts, one step, the rest rule (the PyBullet and MuJoCo twins implement it)."""

    def pose(self) -> typing.Tuple[typing.Sequence[float], typing.Sequence[float]]:
        """The base origin (x, y, z) (m) and orientation (x, y, z, w) now."""
        raise NotImplementedError

    def velocity(self) -> typing.Sequence[float]:
        """The base origin's linear velocity (3,) in the world frame, m/s."""
        raise NotImplementedError

    def touching(self) -> typing.Tuple[bool, bool]:
        """``(on the foam, on the floor)``: whether the robot touches each now."""
        raise NotImplementedError

    def step(self) -> None:
        """Advance the world by one time step."""
        raise NotImplementedError

    def settled(self, steps: int) -> bool:
        """After step number ``steps``: True once the robot has stayed at rest for the trials' hold time."""
        raise NotImplementedError

    def advance(self, steps: int, dt: float, velocity: typing.Sequence[float]
                ) -> typing.Tuple[float, typing.Sequence[float]]:
        """Step ``steps`` times with nothing to watch but the base's velocity; return ``(largest change of the
        base velocity over one step / dt, m/s^2, the velocity after the last step)``, ``velocity`` the one before
        the first. :func:`step_launch` uses it once the robot has landed and the plate has stopped."""
        peak = 0.0
        for _ in range(steps):
            self.step()
            now = tuple(self.velocity())
            peak = max(peak, math.dist(now, velocity) / dt)
            velocity = now
        return peak, velocity

    def decide(self, remaining_s: float) -> typing.Optional[bool]:
        """The early decision now (True / False: the outcome is fixed upright / not upright; None: still open, or
        no early decision in this world), ``remaining_s`` before the time cap (:func:`decided_on_foam`).
        :func:`step_launch` asks only once the robot has landed on the foam and the plate has stopped: from then
        on only gravity and passive contacts act."""
        return None
