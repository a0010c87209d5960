"""What a simulated launch reports: its :class:`LaunchResult`, its phases and the callbacks that follow it
(:mod:`rollability_ros.core.sim.launch`)."""
import dataclasses
import typing

from rollability_ros.core.records import NO_SEED, NOT_MEASURED


#: Phases reported through ``on_phase``, in order.
PHASES = ("fired", "in_flight", "settling", "classifying")

#: ``on_phase(phase)``: called with each of :data:`PHASES` once, in order.
PhaseCallback = typing.Callable[[str], None]

#: ``on_pose(t_s, position (x, y, z) m, orientation (x, y, z, w))``: the base pose at ``pose_rate_hz``.
PoseCallback = typing.Callable[[float, typing.Sequence[float], typing.Sequence[float]], None]

@dataclasses.dataclass(frozen=True)
class LaunchResult:
    """One simulated launch. Times are simulated seconds from the push; positions metres, world frame.

    ``final_orientation`` is the chassis base (x, y, z, w) at the end; ``launch_speed_mps`` and
    ``launch_angle_deg`` the drawn actual values; ``travel_time_s``, ``measured_speed_mps``, ``flight_time_s``
    and ``landing_position_m`` are as in the package docstring, NaN when the event did not happen;
    ``landing_position_m`` is the base origin at the first foam contact; ``peak_deceleration_mps2`` the largest change of the base's velocity over one step
    from the step of that contact on, divided by the step (m/s^2): the impact an accelerometer on the chassis
    would see. ``edge_speed_mps`` is the base's speed along the push when its foremost point crosses the edge
    (NaN if it never does). ``invalid_reason`` is "" for a valid launch, else why it is no launch (it did not
    leave the ledge, it landed outside the foam); ``attempts`` counts the launches :func:`simulate_valid_launch`
    made to get this one, and ``seed`` is the seed this launch was simulated with (the kept retry's
    :func:`attempt_seed`): :func:`simulate_launch` with it repeats this launch exactly. ``decided``: ended by the
    early decision (``trial.early_decision``, :func:`step_launch`): ``upright`` is the decided outcome, ``settled``
    true, ``tilt_deg`` and ``final_orientation`` those at the decision.

    ``upright`` is the rig's verdict (:func:`rig_verdict`, package docstring "Outcome"): at rest on its wheels,
    wherever. Beside it, as data that never decides it: ``rest_surface`` where it came to rest ("pad": the base
    origin over the foam pad's extent, "floor": beyond it, "ledge": it never went over), ``rest_position_m`` the
    base origin at the end (x, y, z), ``rest_distance_m`` its horizontal distance from where it crossed the edge
    line, ``time_to_rest_s`` from the first landing until the rest rule held (NaN when it hit the time cap, never
    landed, or the early decision ended it: a decided launch's ``rest_*`` are where it was at the decision, clear of
    the pad's edges by the decision's rule), and ``plate_speed_mps`` the speed the cylinder drove the plate at
    (the stroke model's solved speed for this launch's set speed, :func:`launch_drive`).
    """

    upright: bool
    final_orientation: tuple
    travel_time_s: float
    measured_speed_mps: float
    launch_speed_mps: float
    settled: bool
    sim_time_s: float
    steps: int
    tilt_deg: float
    launch_angle_deg: float = 0.0
    flight_time_s: float = NOT_MEASURED
    landing_position_m: tuple = (NOT_MEASURED,) * 3
    peak_deceleration_mps2: float = 0.0
    edge_speed_mps: float = NOT_MEASURED
    invalid_reason: str = ""
    attempts: int = 1
    seed: int = NO_SEED
    decided: bool = False
    rest_surface: str = ""
    rest_position_m: tuple = (NOT_MEASURED,) * 3
    rest_distance_m: float = NOT_MEASURED
    time_to_rest_s: float = NOT_MEASURED
    plate_speed_mps: float = NOT_MEASURED

    @property
    def valid(self) -> bool:
        """True when the launch happened as the rig launches: the chassis left the ledge and landed on the foam."""
        return not self.invalid_reason

    @property
    def final_orientation_xyzw(self) -> tuple:
        """``final_orientation``, under the name :func:`rollability_ros.core.rig.rig_session.simulated_outcome` reads."""
        return self.final_orientation
