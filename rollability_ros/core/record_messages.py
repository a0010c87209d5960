"""The one mapping between records (:mod:`rollability_ros.core.records`) and their ROS messages.

Field by field, for any message implementation with the fields of ``msg/*.msg``: rclpy's generated classes (the
nodes, through ``nodes/_convert.py``) and rosbags' decoded dataclasses (the bag reader and writer, through
``core/bags/messages.py``). Reading needs only attribute access; building takes a ``make(type_name, **fields)``
callable that constructs the named message type of the caller's implementation (``float64[]`` fields are given as
lists of float).

Every record read from a message is validated (``validate()``), so a node and the bag reader refuse the same
malformed records. Times: ``builtin_interfaces/Time`` <-> float seconds since the Unix epoch; a time that cannot
be a stamp (NaN, infinite, negative) becomes 0 and nanoseconds are clamped to ``[0, 999_999_999]``. A
``LaunchOutcome`` decoded from a definition without ``seed`` (a bag recorded before the field existed) reads as
:data:`~rollability_ros.core.records.NO_SEED`, and one without the continuous outcomes (``final_tilt_deg`` ...)
with each not measured (NaN); a ``CandidateResult`` or ``GenerationSummary`` without
``session`` (recorded before the field existed) reads with session "".
"""
import math
import typing

from rollability_ros.core.records import (CONTINUOUS_OUTCOMES, NO_SEED, NOT_MEASURED, CandidateRecord,
                                          GenerationRecord, LaunchCondition, LaunchOutcome, TipEventRecord)

#: Any of the record classes.
Record = typing.Union[LaunchOutcome, CandidateRecord, GenerationRecord, TipEventRecord]
#: A message of the caller's implementation (rclpy's generated classes, rosbags' dataclasses): what ``make`` builds.
Message = typing.TypeVar("Message")
#: ``make(type_name, **fields) -> message`` of one message implementation (rclpy, rosbags); generic in the message.
MakeMessage = typing.Callable[..., Message]


class StampMessage(typing.Protocol):
    """A ``builtin_interfaces/Time`` as read: whole seconds and nanoseconds."""

    @property
    def sec(self) -> int: ...

    @property
    def nanosec(self) -> int: ...


class QuaternionMessage(typing.Protocol):
    """A ``geometry_msgs/Quaternion`` as read."""

    @property
    def x(self) -> float: ...

    @property
    def y(self) -> float: ...

    @property
    def z(self) -> float: ...

    @property
    def w(self) -> float: ...


class ConditionMessage(typing.Protocol):
    """A ``rollability_ros/LaunchCondition`` as read."""

    @property
    def configuration(self) -> str: ...

    @property
    def height_m(self) -> float: ...

    @property
    def speed_mps(self) -> float: ...

    @property
    def angle_deg(self) -> float: ...

    @property
    def repetition(self) -> int: ...

OUTCOME_TYPE = "rollability_ros/msg/LaunchOutcome"
CANDIDATE_TYPE = "rollability_ros/msg/CandidateResult"
GENERATION_TYPE = "rollability_ros/msg/GenerationSummary"
TIP_EVENT_TYPE = "rollability_ros/msg/TipEvent"
CONDITION_TYPE = "rollability_ros/msg/LaunchCondition"
TIME_TYPE = "builtin_interfaces/msg/Time"
HEADER_TYPE = "std_msgs/msg/Header"
QUATERNION_TYPE = "geometry_msgs/msg/Quaternion"
#: The signature field of a physical ``LaunchOutcome`` (the rig's; records carry none: built unsigned here).
AUTH_TYPE = "rollability_ros/msg/ValveAuth"
#: Record message type -> record class.
RECORD_TYPES = {OUTCOME_TYPE: LaunchOutcome, CANDIDATE_TYPE: CandidateRecord, GENERATION_TYPE: GenerationRecord,
                TIP_EVENT_TYPE: TipEventRecord}


def stamp_to_s(stamp: StampMessage) -> float:
    """``builtin_interfaces/Time`` (``sec``, ``nanosec``) -> seconds since the epoch (float)."""
    return stamp.sec + stamp.nanosec * 1e-9


def split_stamp(seconds: float) -> typing.Tuple[int, int]:
    """Seconds (float) -> ``(sec, nanosec)`` of a stamp: NaN, infinite or negative -> (0, 0); nanosec clamped."""
    if not math.isfinite(seconds) or seconds < 0:
        seconds = 0.0
    sec = int(seconds)
    return sec, min(max(int(round((seconds - sec) * 1e9)), 0), 999_999_999)


def make_stamp(make: MakeMessage[Message], seconds: float) -> Message:
    """A ``builtin_interfaces/Time`` of ``seconds`` (see :func:`split_stamp`)."""
    sec, nanosec = split_stamp(seconds)
    return make(TIME_TYPE, sec=sec, nanosec=nanosec)


def make_quaternion(make: MakeMessage[Message], xyzw: typing.Sequence[float]) -> Message:
    """A ``geometry_msgs/Quaternion`` from ``(x, y, z, w)``."""
    x, y, z, w = (float(v) for v in xyzw)
    return make(QUATERNION_TYPE, x=x, y=y, z=z, w=w)


def quaternion_to_tuple(q: QuaternionMessage) -> typing.Tuple[float, float, float, float]:
    """A ``geometry_msgs/Quaternion`` -> ``(x, y, z, w)``."""
    return (float(q.x), float(q.y), float(q.z), float(q.w))


def _header(make, stamp_s, frame_id=""):
    return make(HEADER_TYPE, stamp=make_stamp(make, stamp_s), frame_id=frame_id)


def condition_to_message(make: MakeMessage[Message], condition: LaunchCondition) -> Message:
    """:class:`LaunchCondition` -> ``LaunchCondition`` message."""
    return make(CONDITION_TYPE, configuration=condition.configuration, height_m=float(condition.height_m),
                speed_mps=float(condition.speed_mps), angle_deg=float(condition.angle_deg),
                repetition=int(condition.repetition))


def condition_from_message(msg: ConditionMessage) -> LaunchCondition:
    """``LaunchCondition`` message -> validated :class:`LaunchCondition`; ``ValueError`` names the bad field."""
    condition = LaunchCondition(configuration=msg.configuration, height_m=float(msg.height_m),
                                speed_mps=float(msg.speed_mps), angle_deg=float(msg.angle_deg),
                                repetition=int(msg.repetition))
    condition.validate()
    return condition


def _measured(value: typing.Any) -> float:
    """A float64 field that may say "not measured": NaN reads as :data:`~rollability_ros.core.records.NOT_MEASURED`."""
    value = float(value)
    return NOT_MEASURED if math.isnan(value) else value


def _outcome_from_message(msg):
    return LaunchOutcome(
        run_id=msg.run_id, trial_id=msg.trial_id, condition=condition_from_message(msg.condition),
        backend=msg.backend, upright=bool(msg.upright), travel_time_s=_measured(msg.travel_time_s),
        measured_speed_mps=_measured(msg.measured_speed_mps), speed_out_of_tolerance=bool(msg.speed_out_of_tolerance),
        final_orientation=quaternion_to_tuple(msg.final_orientation), classified_by=msg.classified_by,
        note=msg.note, stamp_s=stamp_to_s(msg.header.stamp),
        # a message decoded from a definition older than the seed field (an old bag) has no seed
        seed=int(getattr(msg, "seed", NO_SEED)),
        # nor the continuous outcomes: not measured, never a number made up
        **{name: _measured(getattr(msg, name, NOT_MEASURED)) for name in CONTINUOUS_OUTCOMES})


def _candidate_from_message(msg):
    return CandidateRecord(
        run_id=msg.run_id, generation=int(msg.generation), index=int(msg.index),
        heights=tuple(float(h) for h in msg.heights), fitness=float(msg.fitness), successes=int(msg.successes),
        trials=int(msg.trials), seed=int(msg.seed), eval_time_s=float(msg.eval_time_s), evaluator=msg.evaluator,
        stamp_s=stamp_to_s(msg.header.stamp), session=getattr(msg, "session", ""))


def _generation_from_message(msg):
    return GenerationRecord(
        run_id=msg.run_id, generation=int(msg.generation), best_fitness=float(msg.best_fitness),
        mean_fitness=float(msg.mean_fitness), best_so_far=float(msg.best_so_far), sigma=float(msg.sigma),
        best_heights=tuple(float(h) for h in msg.best_heights), evaluations=int(msg.evaluations),
        elapsed_s=float(msg.elapsed_s), stamp_s=stamp_to_s(msg.header.stamp), session=getattr(msg, "session", ""))


def _tip_event_from_message(msg):
    return TipEventRecord(
        robot=msg.robot, tipped_at_s=stamp_to_s(msg.tipped_at), duration_s=float(msg.duration_s),
        recovered=bool(msg.recovered), peak_tilt_deg=float(msg.peak_tilt_deg),
        peak_angular_rate_radps=float(msg.peak_angular_rate_radps),
        final_orientation=quaternion_to_tuple(msg.final_orientation), frame_id=msg.header.frame_id,
        stamp_s=stamp_to_s(msg.header.stamp))


_FROM_MESSAGE = {OUTCOME_TYPE: _outcome_from_message, CANDIDATE_TYPE: _candidate_from_message,
                 GENERATION_TYPE: _generation_from_message, TIP_EVENT_TYPE: _tip_event_from_message}


def record_from_message(type_name: str, msg: object) -> Record:
    """A record message of type ``type_name`` -> its validated record; ``ValueError`` names the bad field."""
    try:
        convert = _FROM_MESSAGE[type_name]
    except KeyError:
        raise ValueError(f"{type_name} is not a record message type ({', '.join(RECORD_TYPES)})") from None
    record = convert(msg)
    record.validate()
    return record


def message_from_record(make: MakeMessage[Message], record: Record) -> typing.Tuple[str, Message]:
    """``(type name, message)`` for a record, built with ``make``; the inverse of :func:`record_from_message`."""
    if isinstance(record, LaunchOutcome):
        return OUTCOME_TYPE, make(
            OUTCOME_TYPE, header=_header(make, record.stamp_s, "world"), run_id=record.run_id,
            trial_id=record.trial_id, condition=condition_to_message(make, record.condition), backend=record.backend,
            upright=bool(record.upright), travel_time_s=float(record.travel_time_s),
            measured_speed_mps=float(record.measured_speed_mps),
            speed_out_of_tolerance=bool(record.speed_out_of_tolerance),
            final_orientation=make_quaternion(make, record.final_orientation), classified_by=record.classified_by,
            note=record.note, seed=int(record.seed), auth=make(AUTH_TYPE, session="", counter=0, mac=""), twin="",
            **{name: float(value) for name, value in record.continuous().items()})
    if isinstance(record, CandidateRecord):
        return CANDIDATE_TYPE, make(
            CANDIDATE_TYPE, header=_header(make, record.stamp_s), run_id=record.run_id,
            generation=int(record.generation), index=int(record.index), heights=[float(h) for h in record.heights],
            fitness=float(record.fitness), successes=int(record.successes), trials=int(record.trials),
            seed=int(record.seed), eval_time_s=float(record.eval_time_s), evaluator=record.evaluator,
            session=record.session)
    if isinstance(record, GenerationRecord):
        return GENERATION_TYPE, make(
            GENERATION_TYPE, header=_header(make, record.stamp_s), run_id=record.run_id,
            generation=int(record.generation), best_fitness=float(record.best_fitness),
            mean_fitness=float(record.mean_fitness), best_so_far=float(record.best_so_far),
            sigma=float(record.sigma), best_heights=[float(h) for h in record.best_heights],
            evaluations=int(record.evaluations), elapsed_s=float(record.elapsed_s), session=record.session)
    if isinstance(record, TipEventRecord):
        return TIP_EVENT_TYPE, make(
            TIP_EVENT_TYPE, header=_header(make, record.stamp_s, record.frame_id), robot=record.robot,
            tipped_at=make_stamp(make, record.tipped_at_s), duration_s=float(record.duration_s),
            recovered=bool(record.recovered), peak_tilt_deg=float(record.peak_tilt_deg),
            peak_angular_rate_radps=float(record.peak_angular_rate_radps),
            final_orientation=make_quaternion(make, record.final_orientation))
    raise ValueError(f"no message type for {type(record).__name__}")
