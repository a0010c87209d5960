"""The one record <-> message mapping (core/results/record_messages.py) through the rosbags binding: round trips,
stamps, and the validation the nodes and the bag reader share."""
import math

import pytest

from rollability_ros.core.bags.messages import make_message, message_from_record, read_records_from_bag, typestore
from rollability_ros.core.bags.writer import BagWriter
from rollability_ros.core import record_messages
from rollability_ros.core.records import (CandidateRecord, GenerationRecord, LaunchCondition, LaunchOutcome,
                                                  TipEventRecord)

RECORDS = [
    LaunchOutcome("camp", "A/t1", LaunchCondition("A", 0.75, 0.8, -30.0, 2), "physical", True, 0.41, 0.83, False,
                  (0.0, 0.0, 0.6, 0.8), "operator", "lid", 1_700_000_000.25, final_tilt_deg=73.7,
                  rest_distance_m=0.31, time_to_rest_s=1.5, peak_deceleration_mps2=88.0),
    CandidateRecord("opt", 3, 1, (0.1, 0.2, 0.3), 0.5, 5, 10, 77, 1.5, "eval_0", 1_700_000_001.5),
    GenerationRecord("opt", 3, 0.6, 0.4, 0.7, 0.05, (0.1, 0.2, 0.3), 48, 12.5, 1_700_000_002.0),
    TipEventRecord("husky", 1_700_000_003.125, 2.5, True, 120.0, 3.0, (0.0, 0.0, 0.0, 1.0), "imu_link",
                   1_700_000_004.0),
]


@pytest.mark.parametrize("record", RECORDS, ids=lambda r: type(r).__name__)
def test_every_record_round_trips_through_cdr(record):
    type_name, message = message_from_record(record)
    decoded = typestore().deserialize_cdr(bytes(typestore().serialize_cdr(message, type_name)), type_name)
    again = record_messages.record_from_message(type_name, decoded)
    assert type(again) is type(record)
    for field, value in vars(record).items():
        expected = getattr(again, field)
        if isinstance(value, float):
            assert expected == pytest.approx(value, abs=1e-9), field
        else:
            assert expected == value, field


def test_an_unknown_orientation_stays_unknown_in_a_bag_message():
    """Issue 45: an operator-classified launch has no orientation: NaN through CDR, never the upright quaternion."""
    from rollability_ros.core.records import UNKNOWN_ORIENTATION

    record = LaunchOutcome("camp", "A/t2", LaunchCondition("A", 0.75, 0.8, 0.0, 0), "physical", False,
                           final_orientation=UNKNOWN_ORIENTATION, classified_by="operator", stamp_s=1_700_000_000.0)
    type_name, message = message_from_record(record)
    decoded = typestore().deserialize_cdr(bytes(typestore().serialize_cdr(message, type_name)), type_name)
    again = record_messages.record_from_message(type_name, decoded)
    assert not again.orientation_known and all(math.isnan(q) for q in again.final_orientation)


def test_stamps_clamp_nanoseconds_and_refuse_impossible_times():
    assert record_messages.split_stamp(1.9999999999) == (1, 999_999_999)   # rounds to 1e9 ns: clamped
    assert record_messages.split_stamp(12.5) == (12, 500_000_000)
    for impossible in (math.nan, math.inf, -3.0):
        assert record_messages.split_stamp(impossible) == (0, 0)
    stamp = record_messages.make_stamp(make_message, 1.9999999999)
    assert (stamp.sec, stamp.nanosec) == (1, 999_999_999)


def _malformed():
    """Messages the outcome_logger refuses: successes > trials, an unknown backend, an empty robot."""
    _, candidate = message_from_record(RECORDS[1])
    candidate.successes = 11
    _, outcome = message_from_record(RECORDS[0])
    outcome.backend = "hybrid"
    _, tip = message_from_record(RECORDS[3])
    tip.robot = ""
    return [(record_messages.CANDIDATE_TYPE, candidate, "successes 11 > trials 10"),
            (record_messages.OUTCOME_TYPE, outcome, "backend must be one of"),
            (record_messages.TIP_EVENT_TYPE, tip, "robot must be non-empty")]


def test_malformed_messages_are_refused_and_the_bag_reader_skips_them(tmp_path, caplog):
    for type_name, message, reason in _malformed():
        with pytest.raises(ValueError, match=reason):
            record_messages.record_from_message(type_name, message)
    bag_dir = tmp_path / "bag"
    with BagWriter(bag_dir) as bag:
        topics = {}
        for type_name in record_messages.RECORD_TYPES:
            topics[type_name] = f"/{type_name.rsplit('/', 1)[-1].lower()}"
            bag.add_topic(topics[type_name], type_name)
        stamp_ns = 10**18
        for type_name, message in [message_from_record(r) for r in RECORDS] + [m[:2] for m in _malformed()]:
            stamp_ns += 1
            bag.write(topics[type_name], bytes(typestore().serialize_cdr(message, type_name)), stamp_ns)
    outcomes, candidates, generations, tip_events = read_records_from_bag(bag_dir)
    assert (len(outcomes), len(candidates), len(generations), len(tip_events)) == (1, 1, 1, 1)
    assert sum("skipped malformed" in r.message for r in caplog.records) == 3


def test_the_continuous_outcomes_cross_cdr_and_a_not_measured_one_stays_nan():
    measured = LaunchOutcome("camp", "A/t3", LaunchCondition("A", 0.75, 0.8, -30.0, 0), "sim", False, 0.42, 0.81,
                             final_tilt_deg=171.5, rest_distance_m=0.375, peak_deceleration_mps2=120.25, seed=5)
    type_name, message = message_from_record(measured)
    decoded = typestore().deserialize_cdr(bytes(typestore().serialize_cdr(message, type_name)), type_name)
    back = record_messages.record_from_message(type_name, decoded)
    assert back == measured and math.isnan(back.time_to_rest_s)
    negative = typestore().deserialize_cdr(bytes(typestore().serialize_cdr(message, type_name)), type_name)
    negative.time_to_rest_s = -1.0                       # a malformed record: refused naming the field
    with pytest.raises(ValueError, match="time_to_rest_s must be >= 0"):
        record_messages.record_from_message(type_name, negative)


def test_a_seeded_outcome_round_trips_and_the_old_sample_bag_decodes_without_seeds():
    """The seed crosses CDR; the committed sample bag, recorded before LaunchOutcome had a seed, decodes from its
    stored definition (every outcome without a seed) and is re-encoded in today's definition for the player."""
    import os

    from rollability_ros.core.bags.messages import CurrentDefinitions, decoding_typestore
    from rollability_ros.core.bags.msg_definitions import definition_for
    from rollability_ros.core.bags.reader import BagReader
    from rollability_ros.core.records import NO_SEED

    seeded = LaunchOutcome("camp", "A/t2", LaunchCondition("A", 0.75, 0.8, -30.0, 0), "sim", True, 0.42, 0.81,
                           seed=2**31 - 1)
    type_name, message = message_from_record(seeded)
    decoded = typestore().deserialize_cdr(bytes(typestore().serialize_cdr(message, type_name)), type_name)
    assert decoded.seed == 2**31 - 1 and record_messages.record_from_message(type_name, decoded) == seeded

    sample = os.path.join(os.path.dirname(__file__), "..", "..", "bags", "sample")
    recorded = [(m, definition) for m, definition in BagReader(sample).with_definitions()
                if m.type_name == record_messages.OUTCOME_TYPE]
    assert len(recorded) == 36 and "seed" not in recorded[0][1]             # the old definition, stored
    assert recorded[0][1] != definition_for(record_messages.OUTCOME_TYPE)
    with pytest.raises(Exception):                 # today's definition cannot read the old bytes
        record_messages.record_from_message(type_name, typestore().deserialize_cdr(recorded[0][0].data, type_name))
    old = [record_messages.record_from_message(type_name, decoding_typestore(type_name, definition)
                                               .deserialize_cdr(m.data, type_name)) for m, definition in recorded]
    assert read_records_from_bag(sample)[0] == old and {o.seed for o in old} == {NO_SEED}
    # nor the continuous outcomes: each not measured, never a number made up
    assert all(math.isnan(v) for o in old for v in o.continuous().values())
    upgraded = [m for m in CurrentDefinitions(BagReader(sample)) if m.type_name == record_messages.OUTCOME_TYPE]
    assert [record_messages.record_from_message(type_name, typestore().deserialize_cdr(m.data, type_name))
            for m in upgraded] == old
