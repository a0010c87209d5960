"""The engine-neutral launch loop (:func:`step_launch`) and what every twin's launch shares: the phases reported,
the events tracked (:class:`LaunchTracker`), the rig's verdict (:func:`rig_verdict`), invalid launches and the
:class:`~rollability_ros.core.sim.launch.results.LaunchResult` (:mod:`rollability_ros.core.sim.launch`, "Measurements
and phases", "Outcome", "Invalid launches")."""
import math
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core.records import NOT_MEASURED
from rollability_ros.core.robots import RobotModel
from rollability_ros.core.sim.launch.contract import LaunchPlate, LaunchWorld
from rollability_ros.core.sim.launch.results import PHASES, LaunchResult, PhaseCallback, PoseCallback
from rollability_ros.core.sim.launch.settings import FoamSpec, LaunchTwinSettings


class PhaseReporter:
    """Reports each of :data:`PHASES` once and in order, filling in any skipped before the one reached."""

    def __init__(self, on_phase: typing.Optional[PhaseCallback]) -> None:
        self._on_phase = on_phase
        self._next = 0

    def reach(self, phase: str) -> None:
        """Report ``phase`` (one of :data:`PHASES`), after any not yet reported before it; nothing if already."""
        target = PHASES.index(phase)
        while self._next <= target:
            if self._on_phase is not None:
                self._on_phase(PHASES[self._next])
            self._next += 1

class _EdgeCrossing:
    """When a point ``offset_m`` ahead (in x) of the base origin crosses the edge line x = 0 (s, interpolated)."""

    def __init__(self, offset_m: float) -> None:
        self._offset_m = offset_m
        self._previous_x: typing.Optional[float] = None
        self.time_s = NOT_MEASURED

    def update(self, steps: int, dt: float, base_x: float) -> bool:
        """Account for step number ``steps`` after which the base origin is at x = ``base_x``; True on crossing."""
        x = base_x + self._offset_m
        previous = self._previous_x
        crossed = x >= 0.0 and previous is not None and math.isnan(self.time_s)
        if crossed and previous is not None:
            self.time_s = (steps - 1 + -previous / (x - previous)) * dt
        self._previous_x = x
        return crossed

class LaunchTracker:
    """Follows one launch step by step: the foremost point crossing the edge (travel time), the base origin
    crossing it (going over: ``in_flight``), the first foam contact (``settling``), the hardest deceleration.

    Times are simulated seconds from the push, NaN until the event happens. ``world`` is the engine's launch world
    (:class:`LaunchWorld`): the tracker reads its base velocity and foam / floor contacts.
    """

    def __init__(self, world: "LaunchWorld", lead_m: float, phases: PhaseReporter, push: npt.ArrayLike) -> None:
        self._world = world
        self._push = np.asarray(push, dtype=np.float64)
        self.phases = phases
        self.edge_speed_mps = NOT_MEASURED
        self.floor_first = False
        self.front = _EdgeCrossing(lead_m)
        self.base = _EdgeCrossing(0.0)
        self.landed_s = NOT_MEASURED
        self.landing_m: typing.Tuple[float, ...] = (NOT_MEASURED,) * 3
        self.peak_deceleration_mps2 = 0.0
        self.edge_xy_m: typing.Tuple[float, float] = (0.0, 0.0)   # where the base origin crossed the edge line
        self._velocity: typing.Optional[typing.Tuple[float, ...]] = None

    @property
    def went_over(self) -> bool:
        """True once the base origin has crossed the edge line (the robot went over the edge)."""
        return not math.isnan(self.base.time_s)

    @property
    def settling_only(self) -> bool:
        """True once only the peak deceleration is left to watch per step (landed, after the crossings)."""
        return not math.isnan(self.landed_s) and self._velocity is not None

    @property
    def last_velocity(self) -> typing.Optional[typing.Tuple[float, ...]]:
        """The base velocity after the last step accounted for (m/s), or None before the robot went over."""
        return self._velocity

    def add_steps(self, peak_mps2: float, velocity: typing.Sequence[float]) -> None:
        """Account for steps :meth:`LaunchWorld.advance` took after the landing: their peak and last velocity."""
        self.peak_deceleration_mps2 = max(self.peak_deceleration_mps2, peak_mps2)
        self._velocity = tuple(velocity)

    @property
    def on_foam(self) -> bool:
        """True once the robot has landed, and its first landing was on the foam."""
        return not math.isnan(self.landed_s) and not self.floor_first

    def update(self, steps: int, dt: float, position: typing.Sequence[float]) -> None:
        """Account for step number ``steps`` (of ``dt`` s) after which the base origin is at ``position`` (3,), m."""
        if self.front.update(steps, dt, position[0]):
            self.edge_speed_mps = float(np.dot(self._world.velocity(), self._push))
        if math.isnan(self.base.time_s):
            if self.base.update(steps, dt, position[0]):
                self.edge_xy_m = (0.0, float(position[1]))
                self.phases.reach("in_flight")
            return
        velocity = tuple(self._world.velocity())   # plain floats: numpy's per-call cost exceeds a MuJoCo step
        if math.isnan(self.landed_s):
            on_foam, on_floor = self._world.touching()
            if on_foam or on_floor:
                self.floor_first = not on_foam
                self.landed_s, self.landing_m = steps * dt, tuple(float(v) for v in position)
                self.phases.reach("settling")
        if not math.isnan(self.landed_s) and self._velocity is not None:
            change = math.dist(velocity, self._velocity) / dt
            self.peak_deceleration_mps2 = max(self.peak_deceleration_mps2, change)
        self._velocity = velocity

def step_launch(world: LaunchWorld, plate: LaunchPlate, tracker: LaunchTracker, settings: LaunchTwinSettings,
                on_pose: typing.Optional[PoseCallback], speed_mps: float, stroke_m: float = math.inf,
                until_edge: bool = False) -> typing.Tuple[int, bool, typing.Optional[bool]]:
    """Step ``world`` (a :class:`LaunchWorld`) until the robot is at rest or the trials' time cap, driving ``plate``
    at ``speed_mps`` until it has travelled ``stroke_m`` (the cylinder's stroke; inf: push-through), the robot goes
    over the edge or the plate reaches it; return ``(steps, settled, decision)``. ``until_edge``: stop as soon as
    the robot's foremost point crosses the edge line (the gate's reading is then known: the speed solve of
    :func:`launch_drive`). Every twin runs its launches through this loop (the launch rules live here and in
    :class:`LaunchTracker`).

    Early decision (``trial.early_decision``): once the robot has landed on the foam and the plate has stopped,
    only gravity and passive contacts act on it, so the energy argument of
    :mod:`~rollability_ros.core.sim.early_decision` applies with the foam's top as the ground (barriers lowered by
    the foam's sinking, :func:`foam_sink_m`, as long as the robot cannot reach the foam's edges or the ledge,
    :func:`clear_of_foam_edges`, for as far as its energy can still carry it, :func:`decided_on_foam`). Every
    ``check_interval_steps`` the world's :meth:`LaunchWorld.decide` may end the launch with its outcome
    (``decision`` True / False; None when it ran to rest or the cap)."""
    dt = settings.physics.time_step_s
    cap = round(settings.trial.time_cap_s / dt)
    pose_every = max(1, round(1.0 / (settings.twin.pose_rate_hz * dt)))
    position, orientation = world.pose()
    tracker.update(0, dt, position)
    tracker.phases.reach("fired")
    if on_pose is not None:
        on_pose(0.0, position, orientation)
    steps = 0
    settled = False
    plate_started = False
    decision = None
    interval = settings.trial.check_interval_steps
    while steps < cap and not settled:
        velocity = tracker.last_velocity   # not None once settling_only
        if on_pose is None and tracker.settling_only and velocity is not None and not plate.driving:
            # landed, plate stopped: only the impact's peak is watched per step until the next look
            count = min(interval - steps % interval, cap - steps)
            tracker.add_steps(*world.advance(count, dt, velocity))
            steps += count
        else:
            steps = _one_step(world, plate, tracker, on_pose, speed_mps, steps, dt, pose_every, plate_started,
                              stroke_m)
            plate_started = True
            if until_edge and not math.isnan(tracker.front.time_s):
                break
        if steps % interval:   # the rest rule and the decision look every check_interval_steps only
            continue
        settled = world.settled(steps)
        if not settled and not plate.driving and tracker.on_foam:
            decision = world.decide((cap - steps) * dt)
            settled = decision is not None
    tracker.phases.reach("classifying")
    return steps, settled, decision

def _one_step(world, plate, tracker, on_pose, speed_mps, steps, dt, pose_every, plate_started, stroke_m):
    """One step of :func:`step_launch` with everything watched; returns the new step count."""
    if plate.driving or not plate_started:
        plate.drive(speed_mps, (steps + 1) * dt)
    world.step()
    steps += 1
    position, orientation = world.pose()
    tracker.update(steps, dt, position)
    if plate.driving and (not math.isnan(tracker.base.time_s) or plate.reached_edge() or plate.travel_m() >= stroke_m):
        plate.stop()
    if on_pose is not None and steps % pose_every == 0:
        on_pose(steps * dt, position, orientation)
    return steps

def launch_result(tracker: "LaunchTracker", settings: LaunchTwinSettings,
                  run: typing.Tuple[int, bool, typing.Optional[bool]],
                  classified: typing.Tuple[bool, float, typing.Sequence[float]], drawn: typing.Tuple[float, float],
                  seed: int, rest_position_m: typing.Sequence[float] = (NOT_MEASURED,) * 3,
                  plate_speed_mps: float = NOT_MEASURED) -> LaunchResult:
    """The :class:`LaunchResult` of a launch (every twin's): ``run`` = ``(steps, settled, decision)`` of
    :func:`step_launch`, ``classified`` = ``(upright, tilt_deg, final orientation (x, y, z, w))``, ``drawn`` =
    ``(launch speed m/s, angle deg)`` of :func:`launch_plan`, ``rest_position_m`` the base origin at the end (m),
    ``plate_speed_mps`` the cylinder's speed in this launch."""
    steps, settled, decision = run
    upright, tilt, orientation = classified
    speed_mps, angle_deg = drawn
    options = settings.twin
    travel_s = tracker.front.time_s
    sim_time_s = steps * settings.physics.time_step_s
    rest = tuple(float(v) for v in rest_position_m)
    foam = options.foam
    if not tracker.went_over:
        surface = "ledge"
    else:
        surface = "pad" if 0.0 <= rest[0] <= foam.length_m and abs(rest[1]) <= foam.width_m / 2 else "floor"
    rested = settled and decision is None and not math.isnan(tracker.landed_s)
    return LaunchResult(upright=bool(upright), final_orientation=tuple(float(v) for v in orientation),
                        travel_time_s=travel_s, measured_speed_mps=options.launcher.run_length_m / travel_s,
                        launch_speed_mps=speed_mps, settled=bool(settled),
                        sim_time_s=sim_time_s, steps=steps, tilt_deg=float(tilt),
                        launch_angle_deg=angle_deg, flight_time_s=tracker.landed_s - tracker.base.time_s,
                        landing_position_m=tracker.landing_m,
                        peak_deceleration_mps2=tracker.peak_deceleration_mps2, edge_speed_mps=tracker.edge_speed_mps,
                        invalid_reason=invalid_reason(tracker.went_over, tracker, options.foam), seed=int(seed),
                        decided=decision is not None, rest_surface=surface, rest_position_m=rest,
                        rest_distance_m=math.hypot(rest[0] - tracker.edge_xy_m[0], rest[1] - tracker.edge_xy_m[1]),
                        time_to_rest_s=sim_time_s - tracker.landed_s if rested else NOT_MEASURED,
                        plate_speed_mps=float(plate_speed_mps))

def rig_verdict(tilt_deg: float, wheels_down: int, robot_model: "RobotModel") -> bool:
    """The rig's outcome rule (package docstring, "Outcome"), every twin's verdict: at rest with the body's up axis
    within ``upright_tilt_deg`` of world up (``config/robot.yaml``; the rig's IMU classifier uses the same 30 deg,
    ``config/rig.yaml`` ``imu_outcome.tilt_threshold_deg``) and on its wheels: at least ``min_wheels_in_contact``
    wheels (``wheels_down``) within ``contact_tolerance_m`` of whatever surface it rests on (pad, floor or ledge)."""
    return tilt_deg <= robot_model.upright_tilt_deg and wheels_down >= robot_model.min_wheels_in_contact

def invalid_reason(went_over: bool, tracker: "LaunchTracker", foam: FoamSpec) -> str:
    """Why a launch is no launch ("" when it is one): see :attr:`LaunchResult.invalid_reason`."""
    if not went_over:
        return "did not leave the ledge"
    if tracker.floor_first:
        return "landed outside the foam (hit the floor first)"
    if math.isnan(tracker.landed_s):
        return "never landed on the foam"
    x, y, _ = tracker.landing_m
    if not (0.0 <= x <= foam.length_m and abs(y) <= foam.width_m / 2):
        return f"landed outside the foam (at x = {x:.2f} m, y = {y:.2f} m)"
    return ""
