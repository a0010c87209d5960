"""Conversions between the ROS messages of ``msg/`` and the core records of ``core/results/records.py``.

One place for every field mapping, so nodes, the player and tests agree. Times: message stamps
(``builtin_interfaces/Time``) <-> float seconds since the Unix epoch.
"""
import math

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion

from rollability_ros.core.results import records
from rollability_ros.msg import (CandidateResult, GenerationSummary, LaunchCondition, LaunchOutcome,
                                 TipEvent)


def stamp_to_s(stamp):
    """``builtin_interfaces/Time`` -> seconds (float)."""
    return stamp.sec + stamp.nanosec * 1e-9


def s_to_stamp(seconds):
    """Seconds (float, >= 0) -> ``builtin_interfaces/Time``."""
    if not math.isfinite(seconds) or seconds < 0:
        seconds = 0.0
    sec = int(seconds)
    return Time(sec=sec, nanosec=min(int(round((seconds - sec) * 1e9)), 999_999_999))


def quaternion_to_tuple(q):
    return (q.x, q.y, q.z, q.w)


def tuple_to_quaternion(xyzw):
    x, y, z, w = (float(v) for v in xyzw)
    return Quaternion(x=x, y=y, z=z, w=w)


def condition_to_msg(condition):
    return LaunchCondition(configuration=condition.configuration, height_m=float(condition.height_m),
                           speed_mps=float(condition.speed_mps), angle_deg=float(condition.angle_deg),
                           repetition=int(condition.repetition))


def condition_from_msg(msg):
    """Raises ``ValueError`` naming the bad field."""
    condition = records.LaunchCondition(configuration=msg.configuration, height_m=msg.height_m,
                                        speed_mps=msg.speed_mps, angle_deg=msg.angle_deg,
                                        repetition=msg.repetition)
    condition.validate()
    return condition


def outcome_to_msg(outcome):
    msg = LaunchOutcome()
    msg.header.stamp = s_to_stamp(outcome.stamp_s)
    msg.header.frame_id = "world"
    msg.run_id = outcome.run_id
    msg.trial_id = outcome.trial_id
    msg.condition = condition_to_msg(outcome.condition)
    msg.backend = outcome.backend
    msg.upright = bool(outcome.upright)
    msg.travel_time_s = float(outcome.travel_time_s)
    msg.measured_speed_mps = float(outcome.measured_speed_mps)
    msg.speed_out_of_tolerance = bool(outcome.speed_out_of_tolerance)
    msg.final_orientation = tuple_to_quaternion(outcome.final_orientation)
    msg.classified_by = outcome.classified_by
    msg.note = outcome.note
    return msg


def outcome_from_msg(msg):
    """Raises ``ValueError`` naming the bad field (malformed messages are refused, not guessed)."""
    outcome = records.LaunchOutcome(
        run_id=msg.run_id, trial_id=msg.trial_id, condition=condition_from_msg(msg.condition),
        backend=msg.backend, upright=bool(msg.upright), travel_time_s=msg.travel_time_s,
        measured_speed_mps=msg.measured_speed_mps, speed_out_of_tolerance=bool(msg.speed_out_of_tolerance),
        final_orientation=quaternion_to_tuple(msg.final_orientation), classified_by=msg.classified_by,
        note=msg.note, stamp_s=stamp_to_s(msg.header.stamp))
    outcome.validate()
    return outcome


def candidate_to_msg(candidate):
    msg = CandidateResult()
    msg.header.stamp = s_to_stamp(candidate.stamp_s)
    msg.run_id = candidate.run_id
    msg.generation = int(candidate.generation)
    msg.index = int(candidate.index)
    msg.heights = [float(h) for h in candidate.heights]
    msg.fitness = float(candidate.fitness)
    msg.successes = int(candidate.successes)
    msg.trials = int(candidate.trials)
    msg.seed = int(candidate.seed)
    msg.eval_time_s = float(candidate.eval_time_s)
    msg.evaluator = candidate.evaluator
    return msg


def candidate_from_msg(msg):
    """Raises ``ValueError`` for an inconsistent candidate (successes > trials, NaN heights, ...)."""
    if not msg.run_id:
        raise ValueError("run_id is empty")
    if msg.successes > msg.trials:
        raise ValueError(f"successes {msg.successes} > trials {msg.trials}")
    heights = tuple(float(h) for h in msg.heights)
    if not all(math.isfinite(h) for h in heights):
        raise ValueError("heights contain NaN or infinity")
    if not (math.isfinite(msg.fitness) and 0.0 <= msg.fitness <= 1.0):
        raise ValueError(f"fitness {msg.fitness} is not in [0, 1]")
    return records.CandidateRecord(
        run_id=msg.run_id, generation=msg.generation, index=msg.index, heights=heights, fitness=msg.fitness,
        successes=msg.successes, trials=msg.trials, seed=msg.seed, eval_time_s=msg.eval_time_s,
        evaluator=msg.evaluator, stamp_s=stamp_to_s(msg.header.stamp))


def generation_to_msg(generation):
    msg = GenerationSummary()
    msg.header.stamp = s_to_stamp(generation.stamp_s)
    msg.run_id = generation.run_id
    msg.generation = int(generation.generation)
    msg.best_fitness = float(generation.best_fitness)
    msg.mean_fitness = float(generation.mean_fitness)
    msg.best_so_far = float(generation.best_so_far)
    msg.sigma = float(generation.sigma)
    msg.best_heights = [float(h) for h in generation.best_heights]
    msg.evaluations = int(generation.evaluations)
    msg.elapsed_s = float(generation.elapsed_s)
    return msg


def generation_from_msg(msg):
    return records.GenerationRecord(
        run_id=msg.run_id, generation=msg.generation, best_fitness=msg.best_fitness, mean_fitness=msg.mean_fitness,
        best_so_far=msg.best_so_far, sigma=msg.sigma, best_heights=tuple(msg.best_heights),
        evaluations=msg.evaluations, elapsed_s=msg.elapsed_s, stamp_s=stamp_to_s(msg.header.stamp))


def tip_event_to_msg(event):
    msg = TipEvent()
    msg.header.stamp = s_to_stamp(event.stamp_s)
    msg.header.frame_id = event.frame_id
    msg.robot = event.robot
    msg.tipped_at = s_to_stamp(event.tipped_at_s)
    msg.duration_s = float(event.duration_s)
    msg.recovered = bool(event.recovered)
    msg.peak_tilt_deg = float(event.peak_tilt_deg)
    msg.peak_angular_rate_radps = float(event.peak_angular_rate_radps)
    msg.final_orientation = tuple_to_quaternion(event.final_orientation)
    return msg


def tip_event_from_msg(msg):
    return records.TipEventRecord(
        robot=msg.robot, tipped_at_s=stamp_to_s(msg.tipped_at), duration_s=msg.duration_s,
        recovered=bool(msg.recovered), peak_tilt_deg=msg.peak_tilt_deg,
        peak_angular_rate_radps=msg.peak_angular_rate_radps,
        final_orientation=quaternion_to_tuple(msg.final_orientation), frame_id=msg.header.frame_id,
        stamp_s=stamp_to_s(msg.header.stamp))
