"""Records read back from a recorded bag, and records as bag messages: the bag source of ``rollability report``.

Messages are recognised by type (``rollability_ros/msg/LaunchOutcome``, ``CandidateResult``,
``GenerationSummary``, ``TipEvent``), whatever topic they were recorded on; every other type is skipped. A
record repeated in the bag (a republished outcome) is kept once, under the same key as the store
(:func:`rollability_ros.core.results.store.unique_key`), first one wins, so a bag and the live store of one campaign
give the same records. Decoding uses rosbags' CDR codec with our interface files.
"""
import functools
import os

from rollability_ros.core.bags.msg_definitions import full_type_name, interface_text
from rollability_ros.core.results.records import (
    CandidateRecord,
    GenerationRecord,
    LaunchCondition,
    LaunchOutcome,
    TipEventRecord,
)
from rollability_ros.core.results.store import unique_key

OUTCOME_TYPE = "rollability_ros/msg/LaunchOutcome"
CANDIDATE_TYPE = "rollability_ros/msg/CandidateResult"
GENERATION_TYPE = "rollability_ros/msg/GenerationSummary"
TIP_EVENT_TYPE = "rollability_ros/msg/TipEvent"
RECORD_TYPES = {OUTCOME_TYPE: LaunchOutcome, CANDIDATE_TYPE: CandidateRecord, GENERATION_TYPE: GenerationRecord,
                TIP_EVENT_TYPE: TipEventRecord}


@functools.lru_cache(maxsize=1)
def typestore():
    """A rosbags type store of ROS 2 Jazzy's standard types plus this package's record messages."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for type_name in ("rollability_ros/msg/LaunchCondition",) + tuple(RECORD_TYPES):
        types.update(get_types_from_msg(interface_text(type_name), type_name))
    store.register(types)
    return store


def _seconds(time_msg):
    return time_msg.sec + time_msg.nanosec * 1e-9


def _time(seconds):
    sec = int(seconds // 1)
    return typestore().types["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((seconds - sec) * 1e9)))


def _quaternion(values):
    return typestore().types["geometry_msgs/msg/Quaternion"](*(float(v) for v in values))


def _header(stamp_s):
    return typestore().types["std_msgs/msg/Header"](stamp=_time(stamp_s), frame_id="")


def record_from_message(type_name, msg):
    """Convert a decoded record message to its records dataclass."""
    if type_name == OUTCOME_TYPE:
        c = msg.condition
        q = msg.final_orientation
        return LaunchOutcome(msg.run_id, msg.trial_id, LaunchCondition(c.configuration, c.height_m, c.speed_mps,
                                                                       c.angle_deg, c.repetition),
                             msg.backend, bool(msg.upright), msg.travel_time_s, msg.measured_speed_mps,
                             bool(msg.speed_out_of_tolerance), (q.x, q.y, q.z, q.w), msg.classified_by, msg.note,
                             _seconds(msg.header.stamp))
    if type_name == CANDIDATE_TYPE:
        return CandidateRecord(msg.run_id, msg.generation, msg.index, tuple(float(h) for h in msg.heights),
                               msg.fitness, msg.successes, msg.trials, msg.seed, msg.eval_time_s, msg.evaluator,
                               _seconds(msg.header.stamp))
    if type_name == GENERATION_TYPE:
        return GenerationRecord(msg.run_id, msg.generation, msg.best_fitness, msg.mean_fitness, msg.best_so_far,
                                msg.sigma, tuple(float(h) for h in msg.best_heights), msg.evaluations,
                                msg.elapsed_s, _seconds(msg.header.stamp))
    if type_name == TIP_EVENT_TYPE:
        q = msg.final_orientation
        return TipEventRecord(msg.robot, _seconds(msg.tipped_at), msg.duration_s, bool(msg.recovered),
                              msg.peak_tilt_deg, msg.peak_angular_rate_radps, (q.x, q.y, q.z, q.w),
                              msg.header.frame_id, _seconds(msg.header.stamp))
    raise ValueError(f"{type_name} is not a record message type ({', '.join(RECORD_TYPES)})")


def message_from_record(record):
    """``(type name, rosbags message)`` for a records dataclass; the inverse of :func:`record_from_message`."""
    import numpy

    types = typestore().types
    if isinstance(record, LaunchOutcome):
        condition = types["rollability_ros/msg/LaunchCondition"](**vars(record.condition))
        return OUTCOME_TYPE, types[OUTCOME_TYPE](
            _header(record.stamp_s), record.run_id, record.trial_id, condition, record.backend, record.upright,
            record.travel_time_s, record.measured_speed_mps, record.speed_out_of_tolerance,
            _quaternion(record.final_orientation), record.classified_by, record.note)
    if isinstance(record, CandidateRecord):
        return CANDIDATE_TYPE, types[CANDIDATE_TYPE](
            _header(record.stamp_s), record.run_id, record.generation, record.index,
            numpy.asarray(record.heights, dtype=numpy.float64), record.fitness, record.successes, record.trials,
            record.seed, record.eval_time_s, record.evaluator)
    if isinstance(record, GenerationRecord):
        return GENERATION_TYPE, types[GENERATION_TYPE](
            _header(record.stamp_s), record.run_id, record.generation, record.best_fitness, record.mean_fitness,
            record.best_so_far, record.sigma, numpy.asarray(record.best_heights, dtype=numpy.float64),
            record.evaluations, record.elapsed_s)
    if isinstance(record, TipEventRecord):
        header = types["std_msgs/msg/Header"](stamp=_time(record.stamp_s), frame_id=record.frame_id)
        return TIP_EVENT_TYPE, types[TIP_EVENT_TYPE](
            header, record.robot, _time(record.tipped_at_s), record.duration_s, record.recovered,
            record.peak_tilt_deg, record.peak_angular_rate_radps, _quaternion(record.final_orientation))
    raise ValueError(f"no message type for {type(record).__name__}")


def _bag_messages(path):
    """``(type name, CDR bytes)`` of every message in a bag directory or a single ``.mcap`` file."""
    from rollability_ros.core.bags.reader import BagReader, open_mcap

    if os.path.isdir(path):
        for message in BagReader(path):
            yield message.type_name, message.data
        return
    with open(path, "rb") as stream:
        reader, _ = open_mcap(path, stream)
        for schema, _, message in reader.iter_messages(log_time_order=True):
            yield (schema.name if schema else ""), message.data


def read_records_from_bag(path):
    """Read the records of a bag: ``(launch_outcomes, candidates, generations, tip_events)``, each in bag order.

    Parameters
    ----------
    path : str or os.PathLike
        A bag directory (``metadata.yaml`` + storage files, MCAP or SQLite3) or one ``.mcap`` file.
    """
    path = os.fspath(path)
    store = typestore()
    lists = {type_name: [] for type_name in RECORD_TYPES}
    seen = set()
    for type_name, data in _bag_messages(path):
        type_name = full_type_name(type_name) if type_name.count("/") == 1 else type_name
        if type_name not in lists:
            continue
        record = record_from_message(type_name, store.deserialize_cdr(data, type_name))
        key = (type_name,) + unique_key(record)
        if key not in seen:
            seen.add(key)
            lists[type_name].append(record)
    return tuple(lists[type_name] for type_name in RECORD_TYPES)
