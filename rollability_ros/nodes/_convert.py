"""rclpy bindings of the one record <-> message mapping (:mod:`rollability_ros.core.record_messages`).

The field mapping and validation live in the core, shared with the bag reader; this module only names the rclpy
message classes and keeps the short names the nodes call. Times: message stamps (``builtin_interfaces/Time``)
<-> float seconds since the Unix epoch. Messages are typed ``typing.Any``: the generated interfaces carry no type
information.
"""
import typing

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion
from std_msgs.msg import Header

from rollability_ros.core import record_messages as mapping
from rollability_ros.core.rig import Signature
from rollability_ros.core import records
from rollability_ros.core.records import RunProgress
from rollability_ros.msg import (CandidateResult, GenerationSummary, LaunchCondition, LaunchOutcome,
                                 OptimizerProgress, TipEvent, ValveAuth)

_CLASSES = {mapping.OUTCOME_TYPE: LaunchOutcome, mapping.CANDIDATE_TYPE: CandidateResult,
            mapping.GENERATION_TYPE: GenerationSummary, mapping.TIP_EVENT_TYPE: TipEvent,
            mapping.CONDITION_TYPE: LaunchCondition, mapping.TIME_TYPE: Time, mapping.HEADER_TYPE: Header,
            mapping.QUATERNION_TYPE: Quaternion, mapping.AUTH_TYPE: ValveAuth}


def make_message(type_name: str, **fields: typing.Any) -> typing.Any:
    """The rclpy message ``type_name`` with ``fields``."""
    return _CLASSES[type_name](**fields)


stamp_to_s = mapping.stamp_to_s
quaternion_to_tuple = mapping.quaternion_to_tuple
condition_from_msg = mapping.condition_from_message


def s_to_stamp(seconds: float) -> typing.Any:
    """Seconds (float, >= 0) -> ``builtin_interfaces/Time`` (NaN and negative -> 0)."""
    return mapping.make_stamp(make_message, seconds)


def tuple_to_quaternion(xyzw: typing.Sequence[float]) -> typing.Any:
    """``(x, y, z, w)`` -> ``geometry_msgs/Quaternion``."""
    return mapping.make_quaternion(make_message, xyzw)


def condition_to_msg(condition: records.LaunchCondition) -> typing.Any:
    """:class:`~rollability_ros.core.records.LaunchCondition` -> ``LaunchCondition``."""
    return mapping.condition_to_message(make_message, condition)


def record_to_msg(record: mapping.Record) -> typing.Any:
    """Any record -> its rclpy message."""
    return mapping.message_from_record(make_message, record)[1]


outcome_to_msg = candidate_to_msg = generation_to_msg = tip_event_to_msg = record_to_msg


def outcome_from_msg(msg: typing.Any) -> records.LaunchOutcome:
    """``LaunchOutcome`` -> validated record; ``ValueError`` names the bad field."""
    record = mapping.record_from_message(mapping.OUTCOME_TYPE, msg)
    assert isinstance(record, records.LaunchOutcome)   # the mapping of OUTCOME_TYPE
    return record


def candidate_from_msg(msg: typing.Any) -> mapping.Record:
    """``CandidateResult`` -> validated record (successes <= trials, finite heights, fitness in [0, 1])."""
    return mapping.record_from_message(mapping.CANDIDATE_TYPE, msg)


def generation_from_msg(msg: typing.Any) -> mapping.Record:
    """``GenerationSummary`` -> validated record."""
    return mapping.record_from_message(mapping.GENERATION_TYPE, msg)


def tip_event_from_msg(msg: typing.Any) -> mapping.Record:
    """``TipEvent`` -> validated record."""
    return mapping.record_from_message(mapping.TIP_EVENT_TYPE, msg)


def progress_to_msg(progress: RunProgress, stamp_s: float) -> typing.Any:
    """:class:`~rollability_ros.core.records.RunProgress` -> ``OptimizerProgress`` stamped ``stamp_s``."""
    msg = OptimizerProgress(run_id=progress.run_id, generation=progress.generation,
                            max_generations=progress.max_generations, best_so_far=float(progress.best_so_far),
                            trials=progress.trials, elapsed_s=float(progress.elapsed_s))
    msg.header.stamp = s_to_stamp(stamp_s)
    return msg


def progress_from_msg(msg: typing.Any) -> RunProgress:
    """``OptimizerProgress`` -> :class:`~rollability_ros.core.records.RunProgress`."""
    return RunProgress(msg.run_id, msg.generation, msg.max_generations, msg.best_so_far, msg.trials, msg.elapsed_s)


def auth_msg(signature: Signature) -> typing.Any:
    """:class:`~rollability_ros.core.rig.valve_auth.Signature` -> ``rollability_ros/ValveAuth``."""
    return ValveAuth(session=signature.session, counter=signature.counter, mac=signature.mac)


def signature_from_msg(auth: typing.Any) -> Signature:
    """``rollability_ros/ValveAuth`` -> :class:`~rollability_ros.core.rig.valve_auth.Signature`."""
    return Signature(auth.session, int(auth.counter), auth.mac)
