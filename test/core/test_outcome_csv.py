"""Outcome CSV: strict import (every bad row named, nothing imported) and export round trip."""
import dataclasses
import math
import re

import pytest

from rollability_ros.core.results import OutcomeCsvError, read_outcome_csv, write_outcome_csv
from rollability_ros.core.records import NO_SEED, LaunchCondition, LaunchOutcome


def _write(tmp_path, text, name="o.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_minimal_file_with_defaults(tmp_path):
    path = _write(tmp_path, "configuration,height_m,speed_mps,angle_deg,repetition,upright,note\n"
                            "A,0.75,0.8,-30,0,true,\n"
                            "\n"
                            'A,0.75,0.8,-30,1,No,"landed on the mesh,\nrolled back"\n'
                            "B,1.3,1.5,60,0,1,\n")
    first, second, third = read_outcome_csv(path, run_id="hand")
    assert math.isnan(first.travel_time_s) and math.isnan(first.measured_speed_mps)
    assert not first.orientation_known    # hand-recorded: no sensor saw the orientation, never "upright"
    assert dataclasses.replace(first, travel_time_s=0.0, measured_speed_mps=0.0,
                               final_orientation=(0.0, 0.0, 0.0, 1.0)) == LaunchOutcome(
        "hand", "A/h0.75m/v0.8mps/a-30deg/r0", LaunchCondition("A", 0.75, 0.8, -30.0, 0), "physical", True,
        travel_time_s=0.0, measured_speed_mps=0.0, classified_by="operator")
    assert not second.upright and second.note == "landed on the mesh,\nrolled back"
    assert third.upright and third.trial_id == "B/h1.3m/v1.5mps/a+60deg/r0"


def test_every_bad_row_is_reported_with_its_line_and_nothing_is_imported(tmp_path):
    path = _write(tmp_path, "run_id,trial_id,configuration,height_m,speed_mps,angle_deg,repetition,upright\n"
                            "r,t1,A,0.75,0.8,0,0,true\n"            # line 2: good
                            "r,t2,A,high,0.8,0,0,maybe\n"           # line 3: two reasons
                            "r,t3,A,0.75,-1,0,0,true\n"             # line 4: negative speed
                            "r,t1,A,0.75,0.8,0,1,false\n"           # line 5: duplicate trial id
                            "r,t5,A,0.75,0.8,0,0\n"                 # line 6: a field short
                            "r,,A,0.75,0.8,0,0,true\n"              # line 7: empty trial id
                            "r,t7,A,0.75,0.8,200,0.5,true\n")       # line 8: angle and repetition
    with pytest.raises(OutcomeCsvError) as caught:
        read_outcome_csv(path)
    problems = dict(caught.value.problems)
    assert sorted(problems) == [3, 4, 5, 6, 7, 8]
    assert "height_m must be a number" in problems[3] and "upright must be one of" in problems[3]
    assert "speed_mps must be > 0" in problems[4]
    assert "already on line 2" in problems[5]
    assert "expected 8 fields, got 7" in problems[6]
    assert "trial_id must not be empty" in problems[7]
    assert "repetition must be a whole number" in problems[8]
    typed = _write(tmp_path, "configuration,height_m,speed_mps,angle_deg,repetition,upright\n"
                             "A,0.7_5,0.8,0,0,true\n"                      # Python's float reads 0.75
                             "A,0.75,0.8,0,\u0663,true\n", "typed.csv")    # an Arabic-Indic 3: int reads 3
    with pytest.raises(OutcomeCsvError) as caught:
        read_outcome_csv(typed, run_id="r")
    assert dict(caught.value.problems) == {2: "height_m must be a number in plain digits, got '0.7_5'",
                                           3: "repetition must be a whole number in plain digits, got '\u0663'"}
    assert "line 3:" in str(caught.value) and "nothing imported" in str(caught.value)


@pytest.mark.parametrize("header, reason", [
    ("configuration,height_m,speed_mps,angle_deg,repetition", "missing required column(s) upright"),
    ("configuration,height_m,speed_mps,angle_deg,repetition,upright,uprigth", "unknown column 'uprigth'"),
    ("configuration,height_m,speed_mps,angle_deg,repetition,upright,upright", "appears more than once"),
    ("configuration,height_m,speed_mps,angle_deg,repetition,upright,final_qw", "all of final_qx"),
])
def test_bad_headers_are_refused(tmp_path, header, reason):
    with pytest.raises(OutcomeCsvError, match="line 1: .*" + re.escape(reason)):
        read_outcome_csv(_write(tmp_path, header + "\n"), run_id="r")


def test_a_run_id_is_needed_and_never_guessed(tmp_path):
    path = _write(tmp_path, "configuration,height_m,speed_mps,angle_deg,repetition,upright\nA,0.75,0.8,0,0,true\n")
    with pytest.raises(OutcomeCsvError, match="give the run id"):
        read_outcome_csv(path)
    with pytest.raises(OutcomeCsvError, match="empty file"):
        read_outcome_csv(_write(tmp_path, "", "empty.csv"))


def test_export_then_import_round_trip(tmp_path):
    outcomes = [
        LaunchOutcome("run", "t/1", LaunchCondition("baseline", 1.3, 1.5, -60.0, 4), "physical", False,
                      travel_time_s=0.2213, measured_speed_mps=0.34 / 0.2213, speed_out_of_tolerance=True,
                      final_orientation=(0.1, -0.2, 0.3, 0.9273618495495703), classified_by="imu",
                      note='said "ouch", then rolled', stamp_s=1712345678.123456),
        LaunchOutcome("run", "t2", LaunchCondition("A", 0.75, 0.8, 30.0, 0), "sim", True, seed=1_234_567_891),
    ]
    path = tmp_path / "out.csv"
    write_outcome_csv(path, outcomes)
    back = read_outcome_csv(path)
    assert back[0] == outcomes[0]
    assert back[1].condition == outcomes[1].condition and math.isnan(back[1].travel_time_s)
    assert back[1].classified_by == "sim" and back[1].final_orientation == (0.0, 0.0, 0.0, 1.0)
    assert (back[0].seed, back[1].seed) == (NO_SEED, 1_234_567_891)     # no seed: an empty cell


def test_an_unknown_orientation_round_trips_through_the_csv_and_the_store(tmp_path):
    """Issue 45: an operator-classified launch has no orientation; every path keeps it unknown (never upright)."""
    from rollability_ros.core.records import UNKNOWN_ORIENTATION
    from rollability_ros.core.store import Store

    outcome = LaunchOutcome("run", "t1", LaunchCondition("A", 0.75, 0.8, 30.0, 0), "physical", False,
                            final_orientation=UNKNOWN_ORIENTATION, classified_by="operator", stamp_s=1.0)
    outcome.validate()
    path = tmp_path / "out.csv"
    write_outcome_csv(path, [outcome])
    assert path.read_text(encoding="utf-8").splitlines()[1].endswith(",,,,")   # four empty cells, then no seed
    (back,) = read_outcome_csv(path)
    assert not back.orientation_known and all(math.isnan(q) for q in back.final_orientation)
    with Store(tmp_path / "s.sqlite") as store:
        store.add_launch_outcome(outcome)
        (stored,) = store.launch_outcomes()
    assert not stored.orientation_known
    with pytest.raises(ValueError, match="all 4 NaN"):   # half known is no orientation at all
        dataclasses.replace(outcome, final_orientation=(math.nan, 0.0, 0.0, 1.0)).validate()


def test_a_file_without_the_seed_column_reads_every_outcome_without_a_seed(tmp_path):
    """CSVs exported before outcomes carried their seed (every column of that time, no ``seed``)."""
    old_columns = ("run_id,trial_id,configuration,height_m,speed_mps,angle_deg,repetition,upright,backend,"
                   "travel_time_s,measured_speed_mps,speed_out_of_tolerance,classified_by,note,stamp_s,"
                   "final_qx,final_qy,final_qz,final_qw\n")
    path = _write(tmp_path, old_columns + "run,t1,A,0.75,0.8,30.0,0,true,sim,0.41,,false,sim,,0.0,0.0,0.0,0.0,1.0\n")
    (outcome,) = read_outcome_csv(path)
    assert outcome.seed == NO_SEED and outcome.upright and outcome.travel_time_s == 0.41
    seeded = _write(tmp_path, "configuration,height_m,speed_mps,angle_deg,repetition,upright,seed\n"
                              "A,0.75,0.8,30,0,true,77\nA,0.75,0.8,30,1,true,-1\nA,0.75,0.8,30,2,true,\n"
                              "A,0.75,0.8,30,3,true,-5\nA,0.75,0.8,30,4,true,x\n", name="seeded.csv")
    with pytest.raises(OutcomeCsvError) as refused:
        read_outcome_csv(seeded, run_id="hand")
    assert [line for line, _ in refused.value.problems] == [5, 6]
    lines = seeded.read_text().splitlines()
    seeded.write_text("\n".join(lines[:4]) + "\n")
    assert [o.seed for o in read_outcome_csv(seeded, run_id="hand")] == [77, NO_SEED, NO_SEED]


def test_unterminated_quote_is_refused_with_its_line_number(tmp_path):
    """Issue 17: an unterminated quote swallowed the following trials into one note (1 trial of 4 imported)."""
    path = _write(tmp_path, "configuration,height_m,speed_mps,angle_deg,repetition,upright,note\n"
                            "A,0.75,0.8,-30,0,true,fine\n"
                            'A,0.75,0.8,-30,1,false,"bounced\n'
                            "A,0.75,0.8,-30,2,true,\n"
                            "A,0.75,0.8,-30,3,true,\n")
    with pytest.raises(OutcomeCsvError) as caught:
        read_outcome_csv(path, run_id="hand")
    assert [line for line, _ in caught.value.problems] == [3]
    assert "unterminated quote" in str(caught.value) and "line 3" in str(caught.value)


def test_the_continuous_outcomes_round_trip_and_an_unmeasured_one_stays_empty(tmp_path):
    """Issue 44.2: final tilt, rest distance, time to rest and peak deceleration; NaN (not measured) is an empty
    cell both ways, never a number."""
    measured = LaunchOutcome("run", "t1", LaunchCondition("A", 0.75, 0.8, 30.0, 0), "sim", False, seed=7,
                             final_tilt_deg=171.25, rest_distance_m=0.4375, time_to_rest_s=1.625,
                             peak_deceleration_mps2=212.5)
    typed = LaunchOutcome("run", "t2", LaunchCondition("A", 0.75, 0.8, 30.0, 1), "physical", True,
                          final_orientation=(math.nan,) * 4, classified_by="operator", rest_distance_m=0.3)
    path = tmp_path / "out.csv"
    write_outcome_csv(path, [measured, typed])
    lines = path.read_text(encoding="utf-8").splitlines()
    assert lines[0].endswith(",seed,final_tilt_deg,rest_distance_m,time_to_rest_s,peak_deceleration_mps2")
    assert lines[2].endswith(",,,0.3,,")            # only the typed distance: the rest not measured
    assert read_outcome_csv(path) == [measured, typed]


@pytest.mark.parametrize("column, cell, reason", [
    ("time_to_rest_s", "-0.5", "time_to_rest_s must be >= 0"),
    ("rest_distance_m", "nan", "rest_distance_m must be finite"),
    ("final_tilt_deg", "190", r"final_tilt_deg must be in \[0, 180\]"),
    ("peak_deceleration_mps2", "fast", "peak_deceleration_mps2 must be a number"),
    ("rest_distance_m", "0.7_5", "rest_distance_m must be a number in plain digits"),   # float() reads 0.75
])
def test_a_bad_continuous_outcome_refuses_the_file_naming_line_and_column(tmp_path, column, cell, reason):
    path = _write(tmp_path, f"configuration,height_m,speed_mps,angle_deg,repetition,upright,{column}\n"
                            "A,0.75,0.8,0,0,true,\n"
                            f"A,0.75,0.8,0,1,true,{cell}\n")
    with pytest.raises(OutcomeCsvError, match="line 3: " + reason):
        read_outcome_csv(path, run_id="r")


def test_control_characters_are_refused_naming_the_line_and_column(tmp_path):
    """"A\x00" was imported as a configuration of its own beside "A", and "true\x1f" read as true (str.strip takes
    the unit separator for whitespace): a control character in any cell refuses the file; a note keeps its tabs and
    line breaks."""
    path = _write(tmp_path, "run_id,configuration,height_m,speed_mps,angle_deg,repetition,upright,backend,note\n"
                            "r,A,0.75,0.8,0,0,true,physical,\"two lines,\n\ta tab\"\n"   # line 2: good
                            "r,A\x00,0.75,0.8,0,1,true,physical,\n"                     # line 4: NUL in an id
                            "r,A,0.75,0.8,0,2,true\x1f,physical,\n"                     # line 5: in a boolean
                            "r,A,0.75,0.8,0,3,true,phys\tical,\n"                       # line 6: tab inside an id
                            "r,A,0.75,0.8,0,4,true,physical,bell\x07\n"                 # line 7: in a note
                            "r\x1b,A,0.75,0.8,0,5,true,physical,\n")                    # line 8: ESC in run_id
    with pytest.raises(OutcomeCsvError) as caught:
        read_outcome_csv(path)
    assert dict(caught.value.problems) == {
        4: "configuration must not hold control characters, got 'A\\x00'",
        5: "upright must not hold control characters, got 'true\\x1f'",
        6: "backend must not hold control characters, got 'phys\\tical'",
        7: "note must not hold control characters, got 'bell\\x07'",
        8: "run_id must not hold control characters, got 'r\\x1b'"}
    one = _write(tmp_path, "configuration,height_m,speed_mps,angle_deg,repetition,upright\nA\x00,0.75,0.8,0,0,true\n",
                 "one.csv")
    with pytest.raises(OutcomeCsvError) as caught:
        read_outcome_csv(one, run_id="r")
    assert str(caught.value) == (f"{one}: refused, nothing imported: line 2: configuration must not hold control "
                                 "characters, got 'A\\x00'")   # one problem: one line naming file, line and column
    (good,) = read_outcome_csv(_write(tmp_path, "configuration,height_m,speed_mps,angle_deg,repetition,upright,note\n"
                                                "\tA ,0.75,0.8,0,0,true,\"a\n\tb\"\n", "good.csv"), run_id="r")
    assert good.condition.configuration == "A" and good.note == "a\n\tb"   # layout around a cell is trimmed
