"""Outcome log: store-then-acknowledge results, malformed records, store failures, running summary."""
import dataclasses
import math
import sqlite3

import pytest

from rollability_ros.core.results.outcome_log import OutcomeLog, OutcomeLoggerSettings, StoreFailure
from rollability_ros.core.records import (CandidateRecord, GenerationRecord, LaunchCondition, LaunchOutcome,
                                          TipEventRecord)
from rollability_ros.core.stats import wilson_interval


def outcome(trial_id, configuration="A", upright=True, run_id="run1", angle_deg=0.0, stamp_s=100.0, **fields):
    condition = LaunchCondition(configuration, 0.75, 0.8, angle_deg, 0)
    return LaunchOutcome(run_id=run_id, trial_id=trial_id, condition=condition, backend="sim", upright=upright,
                         stamp_s=stamp_s, **fields)


def candidate(index, run_id="opt1"):
    return CandidateRecord(run_id=run_id, generation=0, index=index, heights=(0.1, 0.2), fitness=0.5,
                           successes=1, trials=2, seed=7, eval_time_s=0.3)


def test_summary_counts_per_configuration_with_wilson_interval(tmp_path):
    log = OutcomeLog.open(tmp_path / "nested" / "dir" / "outcomes.sqlite")   # parent directories created
    for i, upright in enumerate([True, True, False]):
        assert log.add(outcome(f"a{i}", "A", upright, angle_deg=10.0 * i, stamp_s=100.0 + i))
    assert log.add(outcome("b0", "B", False))
    assert log.add(outcome("x0", "A", True, run_id="run2", stamp_s=500.0))
    assert log.add(candidate(0)) and log.add(candidate(1))
    everything = log.summary()
    assert (everything.trials, everything.candidates, everything.latest_stamp_s) == (5, 2, 500.0)
    a, b = everything.configurations
    assert (a.configuration, a.trials, a.successes) == ("A", 4, 3)
    assert a.success_rate == 0.75 and (a.ci_low, a.ci_high) == wilson_interval(3, 4)
    assert (b.configuration, b.trials, b.successes, b.success_rate) == ("B", 1, 0, 0.0)
    run1 = log.summary("run1")
    assert (run1.trials, run1.candidates, run1.latest_stamp_s) == (4, 0, 102.0)
    assert [(c.configuration, c.trials, c.successes) for c in run1.configurations] == [("A", 3, 2), ("B", 1, 0)]
    unknown = log.summary("no-such-run")
    assert (unknown.trials, unknown.candidates, unknown.configurations) == (0, 0, ())
    log.close()


def test_every_campaign_the_logger_stores_is_in_the_runs_table(tmp_path):
    """Issue 45: a campaign run through the graph never opens the store, so its runs table stayed empty."""
    log = OutcomeLog.open(tmp_path / "outcomes.sqlite")
    log.store.set_run_info("run2", "campaign", {"designs": {"designs_file": "d.yaml"}})   # described by its campaign
    assert log.add(outcome("t1")) and log.add(outcome("t2")) and log.add(outcome("t1", run_id="run2"))
    assert log.add(dataclasses.replace(outcome("p1", run_id="run3"), backend="physical", classified_by="operator"))
    assert log.add(outcome("s1", run_id="run3"))
    assert log.store.run_info("run1") == {"kind": "campaign", "info": {"backend": "sim"}}
    assert log.store.run_info("run2") == {"kind": "campaign", "info": {"backend": "sim",
                                                                       "designs": {"designs_file": "d.yaml"}}}
    assert log.store.run_info("run3")["info"]["backend"] == "mixed"
    log.close()


def test_the_logger_files_the_twin_its_rig_launched_in_relative_to_the_store_folder(tmp_path):
    """Through the graph the logger owns the store and the rig sends its twin with each outcome: the logger files
    it in the run's info (a file inside the store's folder relative to it) without reading the rig's files, so
    ``campaign --resimulate`` finds it; a later outcome of another twin marks the run, a physical outcome records
    that its rig had no twin whatever its message claims, and a malformed claim is refused in one line."""
    from rollability_ros.core.campaign import recorded_twin
    from rollability_ros.core.rig import launched_twin, twin_from_text, twin_to_text

    folder = tmp_path / "study"
    folder.mkdir()
    twin_yaml = folder / "twin.yaml"
    twin_yaml.write_text("/**:\n  ros__parameters:\n    launch_twin: {}\n", encoding="utf-8")
    sent = twin_from_text(twin_to_text(launched_twin("sim", ["sim", str(twin_yaml)], {})))   # as the rig sends it
    assert sent["files"][1] == {"given": str(twin_yaml), "path": str(twin_yaml), "sha256": sent["files"][1]["sha256"]}
    log = OutcomeLog.open(folder / "outcomes.sqlite")
    assert log.add(outcome("t1"), sent) and log.add(outcome("t2"), sent)
    info = log.store.run_info("run1")["info"]
    assert info["backend"] == "sim" and info["twin"]["files"][1]["path"] == "twin.yaml"
    assert recorded_twin(info, str(folder), "run1").twin_config == [sent["files"][0]["path"], str(twin_yaml)]

    other = {**sent, "files": sent["files"][:1]}   # a rig restarted on other files, same run
    assert log.add(outcome("t3"), other)
    with pytest.raises(ValueError, match="^run run1 was launched on different twin files in different sessions"):
        recorded_twin(log.store.run_info("run1")["info"], str(folder), "run1")

    physical = dataclasses.replace(outcome("p1", run_id="run2"), backend="physical", classified_by="operator")
    assert log.add(physical, sent)
    assert log.store.run_info("run2")["info"]["twin"] == {"no_twin": "physical"}
    with pytest.raises(ValueError, match="^run run2 was launched on the physical rig, not on a twin: no twin files"):
        recorded_twin(log.store.run_info("run2")["info"], str(folder), "run2")
    log.close()
    for text, reason in (("{", "twin: not JSON"), ('{"files": []}', "twin: files must list"),
                         ('{"no_twin": "physical", "files": []}', "twin: no_twin names a backend and nothing else")):
        with pytest.raises(ValueError, match=f"^{reason}"):
            twin_from_text(text)


def test_duplicates_are_stored_once_and_summary_is_rebuilt_on_reopen(tmp_path):
    path = tmp_path / "outcomes.sqlite"
    log = OutcomeLog.open(path)
    assert log.add(outcome("t1", upright=True))
    assert not log.add(outcome("t1", upright=False))         # same run and trial id: the first one stays
    assert log.add(outcome("t1", upright=False, run_id="run2"))  # same trial id in another run is another trial
    assert log.add(candidate(0)) and not log.add(candidate(0))
    log.close()
    reopened = OutcomeLog.open(path)
    summary = reopened.summary()
    assert summary.trials == 2 and summary.candidates == 1
    assert [(c.trials, c.successes) for c in summary.configurations] == [(2, 1)]
    assert [o.upright for o in reopened.store.launch_outcomes("run1")] == [True]
    reopened.close()


MALFORMED = [
    (dataclasses.replace(outcome("t1"), backend="catapult"), "backend"),
    (dataclasses.replace(outcome("t1"), run_id=""), "run_id"),
    (dataclasses.replace(outcome("t1"), condition=LaunchCondition("A", math.nan, 0.8, 0.0)), "height_m"),
    (dataclasses.replace(candidate(0), run_id=""), "run_id"),
    (GenerationRecord("", 0, 0.5, 0.4, 0.5, 0.1, (0.1,), 8, 1.0), "run_id"),
    (TipEventRecord("", 1.0, 2.0, True, 90.0, 3.0), "robot"),
    (TipEventRecord("bot", math.nan, 2.0, True, 90.0, 3.0), "tipped_at"),
    (LaunchCondition("A", 0.75, 0.8, 0.0), "no LaunchCondition"),
]


@pytest.mark.parametrize("record, reason", MALFORMED)
def test_malformed_records_are_refused_with_a_reason_and_not_stored(tmp_path, record, reason):
    log = OutcomeLog.open(tmp_path / "outcomes.sqlite")
    with pytest.raises(ValueError, match=reason):
        log.add(record)
    assert log.summary().trials == 0 and log.store.launch_outcomes() == [] and log.store.candidates() == []
    log.close()


def test_generation_and_tip_event_are_stored_once(tmp_path):
    log = OutcomeLog.open(tmp_path / "outcomes.sqlite")
    generation = GenerationRecord("opt1", 3, 0.5, 0.4, 0.6, 0.1, (0.1, 0.2), 32, 12.5)
    event = TipEventRecord("bot", 1700000000.0, 2.0, True, 95.0, 3.1)
    assert log.add(generation) and not log.add(generation)
    assert log.add(event) and not log.add(event)
    assert log.store.generations() == [generation] and log.store.tip_events() == [event]
    log.close()


def test_store_failure_is_not_acknowledged_and_not_counted(tmp_path):
    log = OutcomeLog.open(tmp_path / "outcomes.sqlite")
    assert log.add(outcome("t1"))
    # another process holds the write lock (or the disk is full): the write fails after the busy timeout
    blocker = sqlite3.connect(log.store.path, isolation_level=None)
    blocker.execute("BEGIN EXCLUSIVE")
    log.store._conn.execute("PRAGMA busy_timeout = 50")
    try:
        with pytest.raises(StoreFailure, match="locked"):
            log.add(outcome("t2"))
    finally:
        blocker.execute("ROLLBACK")
        blocker.close()
    assert log.summary().trials == 1
    assert log.add(outcome("t2"))            # the sender can retry once the store works again
    assert log.summary().trials == 2
    log.close()


def test_settings_validation(tmp_path):
    OutcomeLoggerSettings().validate()
    OutcomeLoggerSettings(str(tmp_path)).validate()   # a run directory holds store.sqlite
    for bad in ("", "   ", "a\0b"):
        with pytest.raises(ValueError, match="store_path"):
            OutcomeLoggerSettings(bad).validate()
    with pytest.raises(ValueError, match="not a usable rollability store"):
        (tmp_path / "junk.sqlite").write_bytes(b"this is not a database file at all, not even close" * 4)
        OutcomeLog.open(tmp_path / "junk.sqlite")
