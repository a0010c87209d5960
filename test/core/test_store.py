"""Durable store: round trips, duplicates, corrupt files, migration of older schemas, and acknowledged outcomes
surviving kill -9."""
import dataclasses
import math
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import threading

import pytest

from rollability_ros.core.records import (
    NO_SEED,
    CandidateRecord,
    GenerationRecord,
    LaunchCondition,
    LaunchOutcome,
    TipEventRecord,
)
from rollability_ros.core.store import APPLICATION_ID, SCHEMA_VERSION, STORE_FILENAME, Store, unique_key

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _outcome(trial_id, run_id="run1", upright=True, **fields):
    condition = LaunchCondition("A", 0.75, 0.8, -30.0, 2)
    return LaunchOutcome(run_id=run_id, trial_id=trial_id, condition=condition, backend="sim", upright=upright,
                         **fields)


def test_launch_outcome_round_trip_keeps_every_field_and_order(tmp_path):
    measured = _outcome("t2", travel_time_s=0.41, measured_speed_mps=0.83, speed_out_of_tolerance=True,
                        final_orientation=(0.0, 0.70710678, 0.0, 0.70710678), classified_by="imu",
                        note="gate 2 late", stamp_s=1700000000.5, upright=False)
    unmeasured = _outcome("t1")
    with Store(tmp_path / "s.sqlite") as store:
        assert store.add_launch_outcome(measured)
        assert store.add_launch_outcome(unmeasured)
        assert store.add_launch_outcome(_outcome("t1", run_id="run2"))
        got = store.launch_outcomes("run1")
    assert got[0] == measured
    assert [o.trial_id for o in got] == ["t2", "t1"]  # insertion order, not sorted
    # NaN (not measured) survives the round trip as NaN
    assert math.isnan(got[1].travel_time_s) and math.isnan(got[1].measured_speed_mps)
    assert got[1].condition == unmeasured.condition and got[1].final_orientation == (0.0, 0.0, 0.0, 1.0)


def test_duplicate_trial_id_is_stored_once(tmp_path):
    with Store(tmp_path / "s.sqlite") as store:
        assert store.add_launch_outcome(_outcome("t1", upright=True))
        assert not store.add_launch_outcome(_outcome("t1", upright=False))
        outcomes = store.launch_outcomes()
        assert len(outcomes) == 1 and outcomes[0].upright
        assert store.trial_ids("run1") == {"t1"}
    assert unique_key(_outcome("t1")) == ("run1", "t1")
    with pytest.raises(ValueError, match="no LaunchCondition"):
        unique_key(LaunchCondition("A", 0.75, 0.8, 0.0))


def test_invalid_outcome_is_refused_and_not_stored(tmp_path):
    with Store(tmp_path / "s.sqlite") as store:
        with pytest.raises(ValueError, match="backend"):
            store.add_launch_outcome(LaunchOutcome("r", "t", LaunchCondition("A", 0.75, 0.8, 0.0), "mars", True))
        assert store.launch_outcomes() == []


def test_candidates_generations_tip_events_and_run_info(tmp_path):
    path = tmp_path / "s.sqlite"
    candidate = CandidateRecord("opt", 3, 1, (0.1, 0.25, 0.45), 0.75, 15, 20, 42, 2.5, "/sim_evaluator", 12.0)
    generation = GenerationRecord("opt", 3, 0.75, 0.5, 0.8, 0.05, (0.1, 0.2), 32, 120.0)
    tip = TipEventRecord("rover1", 1700000000.25, 1.5, True, 120.0, 4.2, (0.0, 0.0, 0.0, 1.0), "imu_link")
    with Store(path) as store:
        assert store.add_candidate(candidate) and not store.add_candidate(candidate)
        assert store.add_candidate(CandidateRecord("opt", 3, 2, (0.2,), 0.5, 10, 20, 43, 2.0))
        assert store.add_generation(generation) and not store.add_generation(generation)
        assert store.add_tip_event(tip) and not store.add_tip_event(tip)
        store.set_run_info("camp", "campaign", {"backend": "sim", "repetitions": 5})
        store.set_run_info("camp", "campaign", {"backend": "physical"})
    with Store(path) as store:  # reopened: the schema is recognised, data is there
        assert store.candidates("opt", generation=3)[0] == candidate
        assert [c.index for c in store.candidates(generation=3)] == [1, 2]
        assert store.candidates(generation=4) == []
        assert store.generations("opt") == [generation]
        assert store.tip_events("rover1") == [tip] and store.tip_events("rover2") == []
        assert store.run_info("camp") == {"kind": "campaign", "info": {"backend": "physical"}}
        assert store.run_info("nope") is None
        assert store.run_ids() == ["camp", "opt"]


def test_run_directory_holds_the_store_file(tmp_path):
    with Store(tmp_path) as store:
        store.add_launch_outcome(_outcome("t1"))
    assert (tmp_path / STORE_FILENAME).is_file()
    with sqlite3.connect(tmp_path / STORE_FILENAME) as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"


def test_corrupt_and_foreign_files_are_refused(tmp_path):
    garbage = tmp_path / "garbage.sqlite"
    garbage.write_bytes(b"this is not a database at all" * 200)
    with pytest.raises(ValueError, match="not a usable rollability store"):
        Store(garbage)
    foreign = tmp_path / "foreign.sqlite"
    with sqlite3.connect(foreign) as conn:
        conn.execute("CREATE TABLE things (x)")
    with pytest.raises(ValueError, match="another application"):
        Store(foreign)
    closed = Store(tmp_path / "ok.sqlite")
    closed.close()
    with pytest.raises(ValueError, match="closed"):
        closed.launch_outcomes()


def test_a_store_opened_while_another_process_creates_it_is_not_called_foreign(tmp_path, monkeypatch):
    """The creator commits the schema between the opener's reads of application_id and of the tables (the moment a
    fresh-clone run hit: a test reading the optimizer's store as it was made): the opener must see one moment,
    either before the commit (nothing there yet: it creates the same schema) or after it, never a mix."""
    from rollability_ros.core import store as store_module

    path = str(tmp_path / STORE_FILENAME)
    with sqlite3.connect(path) as creator:               # a creator that has just switched the new file to WAL
        assert creator.execute("PRAGMA journal_mode = WAL").fetchone()[0] == "wal"
    real_connect = sqlite3.connect
    created = []

    class Opener:
        """The opener's connection: the other process commits the whole schema just before the tables are read."""

        def __init__(self, *args, **kwargs):
            self._conn = real_connect(*args, **kwargs)

        def execute(self, sql, *params):
            if sql.startswith("SELECT count(*) FROM sqlite_master") and not created:
                with monkeypatch.context() as inner:
                    inner.setattr(store_module.sqlite3, "connect", real_connect)
                    Store(path).close()                   # the other process creates the store and commits
                created.append(True)
            return self._conn.execute(sql, *params)

        def __getattr__(self, name):
            return getattr(self._conn, name)

    monkeypatch.setattr(store_module.sqlite3, "connect", Opener)
    with Store(path) as opened:
        assert created and not opened.trial_ids("run1")
    monkeypatch.undo()
    with Store(path) as again:
        assert not again.trial_ids("run1")


def test_concurrent_writers_in_threads_store_everything_once(tmp_path):
    store = Store(tmp_path / "s.sqlite")
    accepted = []

    def write(offset):
        for i in range(40):
            # every id written by two threads: exactly one of them must win
            accepted.append(store.add_launch_outcome(_outcome(f"t{(i + offset) % 40}")))

    threads = [threading.Thread(target=write, args=(k * 20,)) for k in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert sum(accepted) == 40 and len(store.launch_outcomes()) == 40
    store.close()


WRITER = textwrap.dedent("""
    import sys
    from rollability_ros.core.records import LaunchCondition, LaunchOutcome
    from rollability_ros.core.store import Store
    store = Store(sys.argv[1])
    i = 0
    while True:
        outcome = LaunchOutcome("run", f"trial-{i:06d}", LaunchCondition("B", 1.3, 1.5, 60.0, i % 5), "sim",
                                i % 3 == 0, note="x" * 200)
        if store.add_launch_outcome(outcome):
            print(outcome.trial_id, flush=True)
        i += 1
""")


def test_acknowledged_outcomes_survive_sigkill_of_the_writer(tmp_path):
    path = tmp_path / "s.sqlite"
    env = dict(os.environ, PYTHONPATH=REPO_ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    writer = subprocess.Popen([sys.executable, "-c", WRITER, str(path)], stdout=subprocess.PIPE, text=True, env=env)
    acknowledged = []
    try:
        while len(acknowledged) < 150:
            line = writer.stdout.readline()
            assert line, "writer exited early"
            acknowledged.append(line.strip())
        os.kill(writer.pid, signal.SIGKILL)  # mid-stream: the writer is inside its loop
        acknowledged += [line.strip() for line in writer.stdout]  # printed before it died: acknowledged too
    finally:
        writer.kill()
        writer.wait()
    assert writer.returncode == -signal.SIGKILL
    with sqlite3.connect(path) as conn:
        assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    with Store(path) as store:
        stored = [o.trial_id for o in store.launch_outcomes("run")]
        assert set(acknowledged) <= set(stored)
        assert len(stored) == len(set(stored))
        # at most the one in flight when killed was stored but not yet acknowledged
        assert len(stored) - len(acknowledged) <= 1
        assert store.add_launch_outcome(_outcome("after-restart", run_id="run"))


def test_records_without_an_owner_or_of_the_wrong_type_are_refused(tmp_path):
    with Store(tmp_path / "s.sqlite") as store:
        with pytest.raises(ValueError, match="CandidateRecord.run_id must be non-empty"):
            store.add_candidate(CandidateRecord("", 0, 0, (), 0.5, 1, 2, 0, 1.0))
        with pytest.raises(ValueError, match="TipEventRecord.robot must be non-empty"):
            store.add_tip_event(TipEventRecord("", 1.0, 1.0, True, 90.0, 1.0))
        with pytest.raises(ValueError, match="expected a GenerationRecord"):
            store.add_generation(CandidateRecord("r", 0, 0, (), 0.5, 1, 2, 0, 1.0))
        assert store.candidates() == [] and store.tip_events() == [] and store.generations() == []


#: ``launch_outcomes`` as schema version 1 created it, before outcomes carried their seed.
_VERSION_1_OUTCOMES = (
    'CREATE TABLE launch_outcomes (seq INTEGER PRIMARY KEY AUTOINCREMENT, "run_id" TEXT NOT NULL, '
    '"trial_id" TEXT NOT NULL, "backend" TEXT NOT NULL, "upright" INTEGER NOT NULL, "travel_time_s" REAL, '
    '"measured_speed_mps" REAL, "speed_out_of_tolerance" INTEGER NOT NULL, "final_orientation" TEXT NOT NULL, '
    '"classified_by" TEXT NOT NULL, "note" TEXT NOT NULL, "stamp_s" REAL, "configuration" TEXT NOT NULL, '
    '"height_m" REAL, "speed_mps" REAL, "angle_deg" REAL, "repetition" INTEGER NOT NULL, UNIQUE ("run_id", '
    '"trial_id"))')


def _old_store(path, create_sql, row_sql, version):
    """A store file as schema ``version`` wrote it: ``launch_outcomes`` made by ``create_sql``, one row."""
    conn = sqlite3.connect(path)
    conn.execute(create_sql)
    conn.execute("INSERT INTO launch_outcomes (run_id, trial_id, backend, upright, travel_time_s, measured_speed_mps,"
                 " speed_out_of_tolerance, final_orientation, classified_by, note, stamp_s, configuration, height_m,"
                 f" speed_mps, angle_deg, repetition{row_sql}")
    conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
    conn.execute(f"PRAGMA user_version = {version}")
    conn.commit()
    conn.close()


def test_a_version_1_store_is_migrated_and_its_outcomes_read_without_a_seed(tmp_path):
    path = tmp_path / "old.sqlite"
    _old_store(path, _VERSION_1_OUTCOMES, ") VALUES ('old', 't1', 'sim', 1, 0.42, NULL, 0, '[0.0, 0.0, 0.6, 0.8]', "
                                          "'sim', 'kept', 1700000000.5, 'A', 0.75, 0.8, -30.0, 2)", 1)
    expected_old = _outcome("t1", run_id="old", travel_time_s=0.42, final_orientation=(0.0, 0.0, 0.6, 0.8),
                            note="kept", stamp_s=1700000000.5)
    seeded = _outcome("t2", run_id="old", travel_time_s=0.4, measured_speed_mps=0.85, seed=123456)
    with Store(path) as store:                     # migrated on open: the old row reads with no seed
        (old,) = store.launch_outcomes()
        assert dataclasses.replace(old, measured_speed_mps=0.0) == dataclasses.replace(
            expected_old, measured_speed_mps=0.0) and old.seed == NO_SEED
        assert store.add_launch_outcome(seeded) and not store.add_launch_outcome(_outcome("t1", run_id="old"))
    with Store(path) as store:                     # a second open finds it migrated and keeps both rows
        assert [o.seed for o in store.launch_outcomes()] == [NO_SEED, 123456]
        assert store.launch_outcomes()[1] == seeded
    conn = sqlite3.connect(path)
    assert conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION == 4
    conn.close()


#: ``launch_outcomes`` as schema version 3 created it: version 1 plus the seed, no continuous outcomes.
_VERSION_3_OUTCOMES = _VERSION_1_OUTCOMES.replace(', UNIQUE (', ', "seed" INTEGER NOT NULL DEFAULT -1, UNIQUE (')


def test_a_version_3_store_is_migrated_and_its_outcomes_read_with_unmeasured_continuous_outcomes(tmp_path):
    path = tmp_path / "v3.sqlite"
    _old_store(path, _VERSION_3_OUTCOMES, ", seed) VALUES ('old', 't1', 'sim', 0, 0.42, 0.81, 0, "
                                          "'[0.0, 1.0, 0.0, 0.0]', 'sim', 'kept', 1700000000.5, 'A', 0.75, 0.8, -30.0,"
                                          " 2, 99)", 3)
    expected_old = _outcome("t1", run_id="old", upright=False, travel_time_s=0.42, measured_speed_mps=0.81,
                            final_orientation=(0.0, 1.0, 0.0, 0.0), note="kept", stamp_s=1700000000.5, seed=99)
    measured = _outcome("t2", run_id="old", final_tilt_deg=172.5, rest_distance_m=0.31, time_to_rest_s=1.25,
                        peak_deceleration_mps2=143.0)
    with Store(path) as store:                     # migrated on open: nothing of the old row lost, nothing invented
        (old,) = store.launch_outcomes()
        assert old == expected_old and all(math.isnan(v) for v in old.continuous().values())
        assert store.add_launch_outcome(measured)
    with Store(path) as store:
        assert store.launch_outcomes() == [expected_old, measured]
    conn = sqlite3.connect(path)
    assert conn.execute("PRAGMA user_version").fetchone()[0] == 4
    conn.close()


@pytest.mark.parametrize("field, value", [("time_to_rest_s", -0.5), ("rest_distance_m", math.inf),
                                          ("final_tilt_deg", 181.0), ("peak_deceleration_mps2", -1.0)])
def test_a_bad_continuous_outcome_is_refused_naming_it(tmp_path, field, value):
    with Store(tmp_path / "s.sqlite") as store:
        with pytest.raises(ValueError, match=field):
            store.add_launch_outcome(_outcome("t1", **{field: value}))
        assert store.launch_outcomes() == []


def test_a_version_2_store_is_migrated_and_its_candidates_read_without_a_session(tmp_path):
    path = tmp_path / "v2.sqlite"
    old_candidate = CandidateRecord("optimization", 0, 0, (0.1,), 0.5, 1, 2, 7, 0.5)
    old_generation = GenerationRecord("optimization", 0, 0.5, 0.5, 0.5, 0.1, (0.1,), 1, 1.0)
    with Store(path) as store:
        assert store.add_candidate(old_candidate) and store.add_generation(old_generation)
    conn = sqlite3.connect(path)                  # as schema version 2 wrote it: no session columns
    conn.execute("ALTER TABLE candidates DROP COLUMN session")
    conn.execute("ALTER TABLE generations DROP COLUMN session")
    conn.execute("PRAGMA user_version = 2")
    conn.commit()
    conn.close()
    mine = dataclasses.replace(old_candidate, index=1, session="study-1.abcd")
    with Store(path) as store:
        assert store.candidates() == [old_candidate] and store.generations() == [old_generation]
        assert store.add_candidate(mine)
    with Store(path) as store:
        assert [c.session for c in store.candidates()] == ["", "study-1.abcd"]


def test_seed_round_trips_and_a_bad_seed_is_refused(tmp_path):
    with Store(tmp_path / "s.sqlite") as store:
        assert store.add_launch_outcome(_outcome("t1", seed=2**31 - 1))
        assert store.launch_outcomes()[0].seed == 2**31 - 1
        with pytest.raises(ValueError, match="seed must be a twin seed"):
            store.add_launch_outcome(_outcome("t2", seed=-2))


def test_a_store_damaged_past_its_header_is_refused_naming_it(tmp_path):
    """Was: the store opened (page 1 intact) and the first read raised sqlite3.DatabaseError, a traceback in
    `rollability report` and every other reader; now a ValueError naming the file."""
    from doubles import damaged_store
    from rollability_ros.core.store import StoreDamaged

    path = damaged_store(tmp_path / "damaged.sqlite")
    store = Store(path)
    try:
        with pytest.raises(StoreDamaged, match=r"damaged\.sqlite is damaged \(database disk image is malformed\)"):
            store.launch_outcomes()
        assert issubclass(StoreDamaged, ValueError)   # the CLI's one-line error
    finally:
        store.close()


def test_run_info_that_is_not_json_is_damage_and_the_logger_does_not_acknowledge_past_it(tmp_path):
    """A bit flip in the runs table's JSON was a bare JSONDecodeError; the outcome logger took it for a malformed
    outcome. Now StoreDamaged, and the logger's StoreFailure (not stored as described, not acknowledged)."""
    from rollability_ros.core.results.outcome_log import OutcomeLog, StoreFailure
    from rollability_ros.core.store import StoreDamaged

    path = tmp_path / "store.sqlite"
    with Store(path) as store:
        store.set_run_info("run1", "campaign", {"backend": "sim"})
    with sqlite3.connect(path) as conn:
        conn.execute("UPDATE runs SET info = ? WHERE run_id = 'run1'", ('{"backend": "si\x00',))
    with Store(path) as store:
        with pytest.raises(StoreDamaged, match="run info of run1 is not JSON"):
            store.run_info("run1")
    log = OutcomeLog.open(str(path))
    try:
        with pytest.raises(StoreFailure, match="run info of run1"):
            log.add(_outcome("t1"))
    finally:
        log.close()
