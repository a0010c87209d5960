"""The rig's requests and physical records signed with the valve's session key: what passes and what is refused.

Every refusal here is one a stray participant on the DDS domain would meet (no key, forged MAC, a captured request
replayed or changed, another session); each assertion fails if the guard stops verifying.
"""
import dataclasses
import math

import pytest

from rollability_ros.core.records import LaunchCondition, LaunchOutcome
from rollability_ros.core.rig import rig_auth, valve_auth
from rollability_ros.core.rig.valve_auth import Signature

CONDITION = LaunchCondition("A", 0.75, 0.8, 30.0, 1)
WINDOW_NS = valve_auth.FRESH_WINDOW_NS


class FakeClock:
    def __init__(self, now_ns=10**12):
        self.now_ns = now_ns

    def __call__(self):
        return self.now_ns


@pytest.fixture
def key_path(tmp_path):
    path = str(tmp_path / "keys" / "valve.key")
    valve_auth.create_session_key(path)
    return path


def signer_at(key_path, clock):
    return valve_auth.RequestSigner(valve_auth.load_session_key(key_path), clock)


def guard_at(key_path, clock):
    clock.now_ns -= 1      # the guard starts just before the operator's tool signs
    guard = rig_auth.RequestGuard(key_path, clock)
    clock.now_ns += 1
    return guard


def outcome(**fields):
    values = dict(run_id="run", trial_id="t0", condition=CONDITION, backend="physical", upright=True,
                  travel_time_s=0.42, measured_speed_mps=0.34 / 0.42, speed_out_of_tolerance=False,
                  final_orientation=(0.0, 0.0, 0.0, 1.0), classified_by="operator", note="", stamp_s=1.7e9)
    values.update(fields)
    return LaunchOutcome(**values)


def test_a_signed_launch_passes_once_and_only_for_what_was_signed(key_path):
    clock = FakeClock()
    signer, guard = signer_at(key_path, clock), guard_at(key_path, clock)
    signature = signer.sign_text(rig_auth.launch_text("run", "t0", CONDITION))
    ticket, reason = guard.check_launch(signature, "run", "t0", CONDITION)
    assert ticket is not None and reason == "" and (ticket.run_id, ticket.trial_id) == ("run", "t0")
    # replayed as it was captured: refused
    assert guard.check_launch(signature, "run", "t0", CONDITION) == (None, "not authenticated: replayed request")
    # the same signature with any field changed: refused
    fresh = signer.sign_text(rig_auth.launch_text("run", "t1", CONDITION))
    for run_id, trial_id, condition in (("other", "t1", CONDITION), ("run", "t2", CONDITION),
                                        ("run", "t1", dataclasses.replace(CONDITION, speed_mps=1.5)),
                                        ("run", "t1", dataclasses.replace(CONDITION, height_m=1.3)),
                                        ("run", "t1", dataclasses.replace(CONDITION, configuration="B")),
                                        ("run", "t1", dataclasses.replace(CONDITION, angle_deg=-30.0)),
                                        ("run", "t1", dataclasses.replace(CONDITION, repetition=2))):
        ticket, reason = guard.check_launch(fresh, run_id, trial_id, condition)
        assert ticket is None and reason == "not authenticated: wrong MAC", (run_id, trial_id, condition)
    assert guard.check_launch(fresh, "run", "t1", CONDITION)[0] is not None
    assert guard.rejected == 8


def test_unsigned_forged_stale_early_and_other_session_launches_are_refused(key_path, tmp_path):
    clock = FakeClock()
    signer, guard = signer_at(key_path, clock), guard_at(key_path, clock)
    key = valve_auth.load_session_key(key_path)
    text = rig_auth.launch_text("run", "t0", CONDITION)
    refusals = {
        "no session key signature": rig_auth.UNSIGNED,
        "wrong MAC": Signature(key.session, clock.now_ns, "00" * 32),
        "signed for session": valve_auth.RequestSigner(valve_auth.create_session_key(str(tmp_path / "other")),
                                                       clock).sign_text(text),
    }
    for expected, signature in refusals.items():
        ticket, reason = guard.check_launch(signature, "run", "t0", CONDITION)
        assert ticket is None and expected in reason, (expected, reason)
    # made before the guard existed (captured from an earlier rig process), then replayed within the window
    early = valve_auth.RequestSigner(key, lambda: clock.now_ns - 10).sign_text(text)
    assert "signed before this verifier started" in guard.check_launch(early, "run", "t0", CONDITION)[1]
    # made now, arriving more than the freshness window later
    late = signer.sign_text(text)
    clock.now_ns += 2 * WINDOW_NS
    assert "stale request" in guard.check_launch(late, "run", "t0", CONDITION)[1]
    # a valve command's signature is no launch, and a launch's is no valve command
    arm = signer.sign("arm")
    assert "wrong MAC" in guard.check_launch(arm, "run", "t0", CONDITION)[1]
    launch = signer.sign_text(text)
    assert "wrong MAC" in valve_auth.RequestVerifier(key, clock).verify(launch, "arm")[1]


def test_confirmations_and_outcomes_are_bound_to_their_trial_and_content(key_path):
    clock = FakeClock()
    signer, guard = signer_at(key_path, clock), guard_at(key_path, clock)
    confirm = signer.sign_text(rig_auth.confirm_text("t0"))
    assert guard.check_confirm(confirm, "t1") == (False, "not authenticated: wrong MAC")   # another launch's
    assert guard.check_confirm(confirm, "") == (False, "not authenticated: wrong MAC")
    assert guard.check_confirm(confirm, "t0") == (True, "")
    assert guard.check_confirm(confirm, "t0") == (False, "not authenticated: replayed request")
    current = signer.sign_text(rig_auth.confirm_text(""))
    clock.now_ns += 2 * WINDOW_NS                                                        # expired
    assert "stale request" in guard.check_confirm(current, "")[1]

    answer = signer.sign_text(rig_auth.outcome_text("t0", True, math.nan, "fine"))
    assert not guard.check_confirm(answer, "t0")[0], "an outcome's signature is no confirmation"
    for changed in (("t1", True, math.nan, "fine"), ("t0", False, math.nan, "fine"), ("t0", True, 0.5, "fine"),
                    ("t0", True, math.nan, "forged")):
        assert guard.check_outcome(answer, *changed) == (False, "not authenticated: wrong MAC"), changed
    assert guard.check_outcome(answer, "t0", True, math.nan, "fine") == (True, "")
    assert guard.check_outcome(rig_auth.UNSIGNED, "t0", True, math.nan, "fine")[0] is False


def test_only_a_ticket_signs_a_record_and_the_logger_stores_only_signed_physical_ones(key_path, tmp_path):
    clock = FakeClock()
    signer, guard = signer_at(key_path, clock), guard_at(key_path, clock)
    ticket, _ = guard.check_launch(signer.sign_text(rig_auth.launch_text("run", "t0", CONDITION)), "run", "t0",
                                   CONDITION)
    record = outcome()
    signature = ticket.sign_record(record)
    records = rig_auth.RecordGuard(key_path)
    assert records.check(signature, record) == (True, "")
    assert records.check(signature, record) == (True, ""), "a record is not a request: a replay is a duplicate"
    for tampered in (outcome(upright=False), outcome(note="forged"), outcome(classified_by="imu"),
                     outcome(trial_id="t1"), outcome(stamp_s=1.7e9 + 1), outcome(travel_time_s=0.5),
                     outcome(condition=dataclasses.replace(CONDITION, height_m=1.3))):
        assert records.check(signature, tampered) == (False, "not authenticated: wrong MAC"), tampered
    assert "no record signature" in records.check(rig_auth.UNSIGNED, record)[1]
    # a request signature of the same session does not pass as a record signature
    assert "wrong MAC" in records.check(signer.sign_text(rig_auth.launch_text("run", "t0", CONDITION)), record)[1]
    with pytest.raises(valve_auth.AuthError, match="not the authenticated launch"):
        ticket.sign_record(outcome(trial_id="t9"))
    # sim outcomes need no key; a sim rig's ticket signs nothing, so its "physical" outcome is refused
    assert records.check(rig_auth.UNSIGNED, outcome(backend="sim", classified_by="sim")) == (True, "")
    open_ticket, _ = rig_auth.OpenGuard().check_launch(rig_auth.UNSIGNED, "run", "t0", CONDITION)
    assert open_ticket.sign_record(record) == rig_auth.UNSIGNED
    assert not records.check(open_ticket.sign_record(record), record)[0]
    # a logger that cannot read the key stores no physical outcome
    assert "cannot read the valve session key" in rig_auth.RecordGuard(str(tmp_path / "none.key")).check(
        signature, record)[1]
    assert records.rejected == 10


def test_a_restarted_valve_session_is_picked_up_and_the_old_one_refused(key_path):
    clock = FakeClock()
    old_signer, guard = signer_at(key_path, clock), guard_at(key_path, clock)
    records = rig_auth.RecordGuard(key_path)
    old_ticket, _ = guard.check_launch(old_signer.sign_text(rig_auth.launch_text("run", "t0", CONDITION)), "run",
                                       "t0", CONDITION)
    old_record = old_ticket.sign_record(outcome())
    assert records.check(old_record, outcome())[0]
    valve_auth.create_session_key(key_path)                     # the valve_controller restarted: a new session
    stale_session = old_signer.sign_text(rig_auth.launch_text("run", "t1", CONDITION))
    assert "signed for session" in guard.check_launch(stale_session, "run", "t1", CONDITION)[1]
    new_signer = signer_at(key_path, clock)
    assert guard.check_launch(new_signer.sign_text(rig_auth.launch_text("run", "t1", CONDITION)), "run", "t1",
                              CONDITION)[0] is not None
    assert records.check(old_record, outcome())[0], "a record of the previous session the logger saw still verifies"


def test_key_file_signer_follows_the_key_file_and_says_when_there_is_none(key_path, tmp_path):
    signer = rig_auth.KeyFileSigner(key_path)
    guard = rig_auth.RequestGuard(key_path)
    assert guard.check_confirm(signer.confirm("t0"), "t0") == (True, "")
    valve_auth.create_session_key(key_path)
    assert guard.check_outcome(signer.outcome("t0", False, 0.4, "x"), "t0", False, 0.4, "x") == (True, "")
    with pytest.raises(valve_auth.AuthError, match="cannot read the valve session key"):
        rig_auth.KeyFileSigner(str(tmp_path / "missing.key")).launch("run", "t0", CONDITION)


def test_the_sim_guard_passes_everything_and_the_physical_one_is_chosen_by_the_backend(key_path):
    assert isinstance(rig_auth.request_guard(True, key_path), rig_auth.RequestGuard)
    sim = rig_auth.request_guard(False, key_path)
    assert isinstance(sim, rig_auth.OpenGuard) and not sim.required
    assert sim.check_launch(rig_auth.UNSIGNED, "run", "t0", CONDITION)[0] is not None
    from rollability_ros.core.rig.rig_session import launch_backend_class
    assert launch_backend_class("physical").authenticated and not launch_backend_class("sim").authenticated


def test_texts_are_exact_and_unambiguous():
    # floats are signed exactly (hex), so 0.1 + 0.2 and 0.3 differ, and a NaN travel time has one text
    assert rig_auth.outcome_text("t", True, 0.1 + 0.2, "") != rig_auth.outcome_text("t", True, 0.3, "")
    assert rig_auth.outcome_text("t", True, math.nan, "") == rig_auth.outcome_text("t", True, float("nan"), "")
    # a field cannot bleed into the next, whatever characters an id or a note holds
    assert rig_auth.confirm_text("t0") != rig_auth.confirm_text("t0\n")
    nan_text = rig_auth.outcome_text("a", True, math.nan, "")
    bleeding = nan_text.split("\n", 1)[1]
    assert rig_auth.outcome_text("a", True, 0.0, "x") != rig_auth.outcome_text("a", True, 0.0, "x\n" + bleeding)
    assert rig_auth.outcome_text("a\n", False, 1.0, "") != rig_auth.outcome_text("a", False, 1.0, "\n")
    assert rig_auth.launch_text("r\nt", "", CONDITION) != rig_auth.launch_text("r", "\nt", CONDITION)
    kinds = {text.split("\n")[0] for text in (rig_auth.launch_text("r", "t", CONDITION), rig_auth.confirm_text("t"),
                                              rig_auth.outcome_text("t", True, 1.0, ""), rig_auth.record_text(outcome()))}
    assert kinds == {"rig-launch", "rig-confirm", "rig-outcome", "rig-record"}
    assert not kinds & set(valve_auth.COMMANDS)
