"""Plain records exchanged between the core modules, the store, bags and the nodes.

Field names are the message field names of ``msg/*.msg`` (flattened where a message nests another), so one
word means one thing in config keys, message fields, store columns and CLI flags. Units: m, s, m/s, deg.
"""
import dataclasses
import math
import typing

#: Placeholder for "not measured" numeric fields (travel time, measured speed, the continuous outcomes): ``math.nan``
#: itself, the one NaN object the store, CSV and message readers give back, so records read back compare equal.
NOT_MEASURED = math.nan
#: ``LaunchOutcome.final_orientation`` when no sensor saw it (an operator-classified launch): all four NaN, never
#: the upright quaternion (0, 0, 0, 1), which would claim a tipped chassis ended on its wheels.
UNKNOWN_ORIENTATION = (NOT_MEASURED,) * 4
#: Start of the note of an invalid launch (no launch happened as the rig launches: the chassis did not leave the
#: ledge, landed outside the foam, ...): stored with its reason so nothing is lost, but never counted as an outcome.
INVALID_LAUNCH = "invalid launch: "
#: Largest departure of ``final_orientation``'s norm from 1 accepted (a hand-typed quaternion with 3-4 digits
#: is within it; 0,0,0,0 or a vector with a forgotten w is not).
QUATERNION_NORM_TOLERANCE = 0.01
#: ``LaunchOutcome.seed`` of a launch that has no twin seed: a physical launch, or one recorded before outcomes
#: carried their seed (old stores, CSVs and bags read back with it).
NO_SEED = -1
#: Largest twin seed a stored launch can hold (``LaunchOutcome.seed`` is int64 in the message and the store).
MAX_TWIN_SEED = 2**63 - 1
#: The launch conditions a rig can be asked for, one declaration for the campaign matrix (``campaign.heights_m``,
#: ``speeds_mps``, ``angles_deg``), every stored outcome and ``campaign --resimulate``: ledge height above the
#: impact surface, m, [low, high]; target launch speed, m/s, (low, high]; launch angle, deg, [low, high]. Far beyond
#: a bench launcher (paper: 0.75/1.30 m, 0.8/1.5 m/s, -60..+60 deg), far below values that break the twin's physics.
HEIGHT_RANGE_M = (0.0, 10.0)
SPEED_RANGE_MPS = (0.0, 10.0)
ANGLE_RANGE_DEG = (-180.0, 180.0)


def check_twin_seed(seed: object) -> int:
    """Return ``seed`` if it is a launch twin seed a stored launch can hold, [0, :data:`MAX_TWIN_SEED`], else raise
    ``ValueError`` (a physical launch has none: :data:`NO_SEED`)."""
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_TWIN_SEED:
        raise ValueError(f"seed must be a twin seed in [0, 2**63) (a physical launch has none: {NO_SEED}), got "
                         f"{seed!r}")
    return seed


@dataclasses.dataclass(frozen=True)
class LaunchCondition:
    """One cell of the launch matrix: configuration, ledge height (m), speed (m/s), angle (deg), repetition."""

    configuration: str
    height_m: float
    speed_mps: float
    angle_deg: float
    repetition: int = 0

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if not self.configuration:
            raise ValueError("configuration must be a non-empty id")
        for name in ("height_m", "speed_mps", "angle_deg"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"{name} must be a finite number, got {value!r}")
        if self.height_m < HEIGHT_RANGE_M[0]:
            raise ValueError(f"height_m must be >= {HEIGHT_RANGE_M[0]:g}, got {self.height_m}")
        if self.speed_mps <= SPEED_RANGE_MPS[0]:
            raise ValueError(f"speed_mps must be > {SPEED_RANGE_MPS[0]:g}, got {self.speed_mps}")
        if self.height_m > HEIGHT_RANGE_M[1]:   # no rig launches there: one declaration of the bounds
            raise ValueError(f"height_m must be <= {HEIGHT_RANGE_M[1]:g} m, got {self.height_m}")
        if self.speed_mps > SPEED_RANGE_MPS[1]:
            raise ValueError(f"speed_mps must be <= {SPEED_RANGE_MPS[1]:g} m/s, got {self.speed_mps}")
        if not ANGLE_RANGE_DEG[0] <= self.angle_deg <= ANGLE_RANGE_DEG[1]:
            raise ValueError(f"angle_deg must be within [{ANGLE_RANGE_DEG[0]:g}, {ANGLE_RANGE_DEG[1]:g}], got "
                             f"{self.angle_deg}")
        if self.repetition < 0:
            raise ValueError(f"repetition must be >= 0, got {self.repetition}")

    @property
    def group_key(self) -> typing.Tuple[str, float, float, float]:
        """The grouped condition (paper 2.2.6): everything but the repetition."""
        return (self.configuration, self.height_m, self.speed_mps, self.angle_deg)


def trial_id_for(condition: LaunchCondition) -> str:
    """Stable trial id of a condition, e.g. ``"B/h1.3m/v0.8mps/a-30deg/r2"`` (6 significant digits)."""
    def number(value: float, sign: str = "") -> str:
        return format(float(value), sign + ".6g")

    return (f"{condition.configuration}/h{number(condition.height_m)}m/v{number(condition.speed_mps)}mps/"
            f"a{number(condition.angle_deg, '+')}deg/r{condition.repetition}")


@dataclasses.dataclass(frozen=True)
class LaunchOutcome:
    """A classified launch (``msg/LaunchOutcome.msg``). ``final_orientation`` is (x, y, z, w), world z up, or
    :data:`UNKNOWN_ORIENTATION` (all NaN) when no sensor saw it (the operator classified the launch).

    ``seed``: for a simulated launch the launch twin seed of the launch as stored (the retry that was kept), so
    ``simulate_launch(condition, twin settings, seed)`` repeats it exactly; :data:`NO_SEED` for a physical one.

    The continuous outcomes (:data:`CONTINUOUS_OUTCOMES`, data beside the verdict, never deciding it), each NaN when
    nothing measured it (never invented): ``final_tilt_deg`` the angle between the body's up axis and world up at
    rest (0 upright, 180 inverted); ``rest_distance_m`` how far the chassis came to rest from where it went over the
    edge, horizontally (the twin's, or the distance the operator measured and typed); ``time_to_rest_s`` from the
    first landing until it was at rest; ``peak_deceleration_mps2`` the largest acceleration magnitude from the
    landing on (the impact an accelerometer on the chassis sees). Records written before these fields existed (old
    stores, CSVs, bags) read with NaN.
    """

    run_id: str
    trial_id: str
    condition: LaunchCondition
    backend: str                      # "sim" | "physical"
    upright: bool
    travel_time_s: float = NOT_MEASURED
    measured_speed_mps: float = NOT_MEASURED
    speed_out_of_tolerance: bool = False
    final_orientation: tuple = (0.0, 0.0, 0.0, 1.0)
    classified_by: str = "sim"        # "operator" | "imu" | "sim"
    note: str = ""
    stamp_s: float = 0.0              # time of classification, s since the Unix epoch
    seed: int = NO_SEED               # twin seed of a simulated launch; NO_SEED for a physical one
    final_tilt_deg: float = NOT_MEASURED          # deg, [0, 180]; NaN = not measured
    rest_distance_m: float = NOT_MEASURED         # m, >= 0; NaN = not measured
    time_to_rest_s: float = NOT_MEASURED          # s, >= 0; NaN = not measured
    peak_deceleration_mps2: float = NOT_MEASURED  # m/s^2, >= 0; NaN = not measured

    BACKENDS = ("sim", "physical")
    CLASSIFIERS = ("operator", "imu", "sim")

    @property
    def orientation_known(self) -> bool:
        """False when ``final_orientation`` is :data:`UNKNOWN_ORIENTATION` (no sensor saw the chassis at rest)."""
        return all(math.isfinite(v) for v in self.final_orientation)

    @property
    def valid(self) -> bool:
        """False for an invalid launch (``note`` starts with :data:`INVALID_LAUNCH`): analysis leaves it out."""
        return not self.note.startswith(INVALID_LAUNCH)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if not self.run_id or not self.trial_id:
            raise ValueError("run_id and trial_id must be non-empty")
        self.condition.validate()
        if self.backend not in self.BACKENDS:
            raise ValueError(f"backend must be one of {self.BACKENDS}, got {self.backend!r}")
        if self.classified_by not in self.CLASSIFIERS:
            raise ValueError(f"classified_by must be one of {self.CLASSIFIERS}, got {self.classified_by!r}")
        if len(self.final_orientation) != 4 or not (self.orientation_known or all(
                isinstance(v, float) and math.isnan(v) for v in self.final_orientation)):
            raise ValueError(f"final_orientation must be 4 finite numbers (x, y, z, w), or all 4 NaN (unknown), got "
                             f"{self.final_orientation!r}")
        norm = math.sqrt(sum(v * v for v in self.final_orientation))
        if self.orientation_known and abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
            raise ValueError(f"final_orientation must be a unit quaternion (x, y, z, w), got {self.final_orientation!r} "
                             f"(norm {norm:.4g})")
        for name in ("travel_time_s", "measured_speed_mps"):
            value = getattr(self, name)
            if not math.isnan(value) and not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be >= 0 (or not measured), got {value!r}")
        if not (math.isfinite(self.stamp_s) and self.stamp_s >= 0):
            raise ValueError(f"stamp_s must be a time >= 0, s since the epoch, got {self.stamp_s!r}")
        if self.seed != NO_SEED:
            check_twin_seed(self.seed)
        for name, (low, high) in CONTINUOUS_OUTCOMES.items():
            check_continuous_outcome(name, getattr(self, name), low, high)

    def continuous(self) -> typing.Dict[str, float]:
        """``{name: value}`` of the :data:`CONTINUOUS_OUTCOMES` (NaN = not measured)."""
        return {name: getattr(self, name) for name in CONTINUOUS_OUTCOMES}


#: The continuous outcomes a :class:`LaunchOutcome` carries beside its verdict -> their allowed range (own units:
#: deg, m, s, m/s^2); NaN means not measured.
CONTINUOUS_OUTCOMES: typing.Dict[str, typing.Tuple[float, float]] = {
    "final_tilt_deg": (0.0, 180.0), "rest_distance_m": (0.0, math.inf), "time_to_rest_s": (0.0, math.inf),
    "peak_deceleration_mps2": (0.0, math.inf)}


def check_continuous_outcome(name: str, value: object, low: float, high: float) -> float:
    """``value`` as a float if it is NaN (not measured) or a finite number in [``low``, ``high``], else ``ValueError``
    naming ``name`` (a negative time, an infinite distance, a tilt above 180 deg)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{name} must be a number (NaN when not measured), got {value!r}")
    value = float(value)
    if not math.isnan(value) and not (math.isfinite(value) and low <= value <= high):
        bounds = f">= {low:g}" if high == math.inf else f"in [{low:g}, {high:g}]"
        raise ValueError(f"{name} must be {bounds} (or NaN: not measured), got {value!r}")
    return value


@dataclasses.dataclass(frozen=True)
class CandidateRecord:
    """One evaluated candidate of an optimization run (``msg/CandidateResult.msg``)."""

    run_id: str
    generation: int
    index: int
    heights: tuple                    # half-grid vertex heights, simulation units
    fitness: float                    # successes / trials
    successes: int
    trials: int
    seed: int
    eval_time_s: float                # evaluator time, s: split over evaluators, the sum of the parts' wall times
    evaluator: str = ""               # the evaluator's name; split over evaluators, their names joined by "+"
    stamp_s: float = 0.0
    session: str = ""                 # the optimizer's session id (docs/sessions.md); "" = none, or recorded before

    def validate(self) -> None:
        """Raise ``ValueError`` for an inconsistent candidate (successes > trials, NaN heights, ...)."""
        if not self.run_id:
            raise ValueError("run_id is empty")
        if self.successes > self.trials:
            raise ValueError(f"successes {self.successes} > trials {self.trials}")
        if not all(math.isfinite(h) for h in self.heights):
            raise ValueError("heights contain NaN or infinity")
        if not (math.isfinite(self.fitness) and 0.0 <= self.fitness <= 1.0):
            raise ValueError(f"fitness {self.fitness} is not in [0, 1]")


@dataclasses.dataclass(frozen=True)
class GenerationRecord:
    """Summary of one completed generation (``msg/GenerationSummary.msg``)."""

    run_id: str
    generation: int
    best_fitness: float
    mean_fitness: float
    best_so_far: float
    sigma: float
    best_heights: tuple
    evaluations: int
    elapsed_s: float
    stamp_s: float = 0.0
    session: str = ""                 # the optimizer's session id (docs/sessions.md); "" = none, or recorded before

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if not self.run_id:
            raise ValueError("GenerationRecord: run_id must be non-empty")


@dataclasses.dataclass(frozen=True)
class RunProgress:
    """Where an optimization run stands (``msg/OptimizerProgress.msg``): what an orchestrator shows; not stored."""

    run_id: str
    generation: int                   # generations completed: the last one's number, 0 before the first
    max_generations: int = 0          # the run's cap, 0 = none
    best_so_far: float = math.nan     # fitness, [0, 1]; NaN before the first generation
    trials: int = 0                   # simulated trials evaluated in the run so far
    elapsed_s: float = 0.0            # s of optimizer wall time so far


@dataclasses.dataclass(frozen=True)
class TipEventRecord:
    """One tip-over seen in the field by tip_monitor (``msg/TipEvent.msg``)."""

    robot: str
    tipped_at_s: float                # s since the Unix epoch (or the IMU's clock)
    duration_s: float
    recovered: bool
    peak_tilt_deg: float
    peak_angular_rate_radps: float
    final_orientation: tuple = (0.0, 0.0, 0.0, 1.0)
    frame_id: str = ""
    stamp_s: float = 0.0

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if not self.robot:
            raise ValueError("TipEventRecord: robot must be non-empty")
        if not math.isfinite(self.tipped_at_s):
            raise ValueError(f"TipEvent: tipped_at must be a finite time, got {self.tipped_at_s}")
