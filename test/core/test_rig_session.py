"""The rig's launch sequence without ROS: a real ValveController on the dry-run backend, a simulated speed gate,
a scripted operator and synthetic IMU streams."""
import math
import threading
import time

import pytest
from synthetic_imu import piecewise, stream

from rollability_ros.core.config import check_settings
from rollability_ros.core.records import NO_SEED, LaunchCondition
from rollability_ros.core.rig.launch_backend import (LaunchAborted, LaunchBackend, OperatorChannel, OperatorOutcome,
                                                     RigPorts, RigSettings, parse_outcome_answer)
from rollability_ros.core.rig.outcome_sources import ImuOutcome
from rollability_ros.core.rig.rig_session import (ANSWERED, ASK_OUTCOME, ASK_REGULATOR, PhysicalLaunch, check_goal,
                                                  launch_backend_class, make_launch_backend, simulated_outcome,
                                                  launch_seed)
from rollability_ros.core.rig.speed_gate import SimulatedSpeedGate, SpeedGateConfig
from rollability_ros.core.imu.upright import ImuOutcomeConfig
from rollability_ros.core.rig.valve import ValveController
from rollability_ros.core.rig.valve_contract import RegulatorConfig, ValveConfig
from rollability_ros.core.rig.valve_boards import DryRunBackend

CONDITION = LaunchCondition("B", 0.75, 0.8, -30.0, 1)


class ScriptedOperator:
    """Answers the rig from inside on_phase, like a terminal would; records every phase."""

    def __init__(self, channel, outcomes=(), on_armed=None):
        self.channel = channel
        self.outcomes = list(outcomes)
        self.on_armed = on_armed
        self.phases = []

    def __call__(self, phase, detail):
        self.phases.append((phase, detail))
        if detail.startswith(ANSWERED):
            return
        if phase == "waiting_for_operator":
            assert detail.startswith(ASK_REGULATOR)
            assert self.channel.confirm() == (True, "accepted")
        elif phase == "classifying" and detail.startswith(ASK_OUTCOME):
            assert self.channel.record_outcome(self.outcomes.pop(0))[0]
        elif phase == "armed" and self.on_armed:
            self.on_armed()


@pytest.fixture
def valve():
    backend = DryRunBackend()
    controller = ValveController(backend, max_pulse_ms=500, watchdog_ms=200)
    controller.backend = backend
    yield controller
    controller.shutdown()


class BenchGate(SimulatedSpeedGate):
    """Stands in for light gates that measure (the simulated gate's times are never stored on a physical record)."""

    measures = True
    source = "the light gates"


def make_rig(valve, outcome_source="operator", imu=None, noise=0.0, countdown_s=0.0, gate=BenchGate, **settings):
    settings = RigSettings(**{"backend": "physical", "outcome_source": outcome_source, "countdown_s": countdown_s,
                              "operator_timeout_s": 2.0, **settings})
    settings.validate()
    return PhysicalLaunch(settings, valve, gate(0.34, noise, seed=1), SpeedGateConfig(), 150,
                          RegulatorConfig(), OperatorChannel(), imu)


def test_operator_launch_confirms_regulator_once_per_speed_and_disarms(valve):
    rig = make_rig(valve)
    operator = ScriptedOperator(rig.operator, [OperatorOutcome(True), OperatorOutcome(False, note="on its side"),
                                               OperatorOutcome(True)])
    first = rig.launch("run", "t0", CONDITION, operator)
    assert [p for p, d in operator.phases if not d.startswith(ANSWERED)] == [
        "waiting_for_operator", "armed", "fired", "in_flight", "settling", "classifying"]
    assert "30 psi" in operator.phases[0][1]
    assert first.upright and first.backend == "physical" and first.classified_by == "operator"
    assert math.isclose(first.measured_speed_mps, 0.8) and math.isclose(first.travel_time_s, 0.425)
    assert not first.speed_out_of_tolerance
    assert valve.backend.commands == ["start", "close", "open", "close", "close"]  # closed, pulse, disarm
    assert not valve.status().armed and valve.status().pulses == 1
    operator.phases.clear()
    second = rig.launch("run", "t1", CONDITION, operator)        # same speed block: no confirmation
    assert operator.phases[0][0] == "armed" and not second.upright
    assert second.note == "travel time: the light gates; on its side"   # the speed's source, then the operator's note
    operator.phases.clear()
    rig.launch("run", "t2", LaunchCondition("B", 0.75, 1.5, -30.0, 0), operator)
    assert operator.phases[0][0] == "waiting_for_operator" and "60 psi" in operator.phases[0][1]


def test_out_of_tolerance_speed_is_flagged_and_typed_time_fills_a_missing_gate(valve):
    rig = make_rig(valve, noise=0.5)
    flagged = [rig.launch("run", f"t{i}", CONDITION, ScriptedOperator(rig.operator, [OperatorOutcome(True)]))
               for i in range(6)]
    assert any(o.speed_out_of_tolerance for o in flagged)
    for outcome in flagged:
        assert outcome.speed_out_of_tolerance == (abs(outcome.measured_speed_mps - 0.8) > 0.12)
        assert ("off the target" in outcome.note) == outcome.speed_out_of_tolerance
    rig.speed_gate.read_travel_time = lambda timeout_s: math.nan            # gate saw nothing
    typed = rig.launch("run", "typed", CONDITION, ScriptedOperator(rig.operator, [OperatorOutcome(True, 0.25)]))
    assert typed.travel_time_s == 0.25 and math.isclose(typed.measured_speed_mps, 1.36)
    assert typed.speed_out_of_tolerance and typed.note.startswith("travel time: typed by the operator")


def test_a_simulated_speed_gate_never_writes_a_physical_speed_and_the_orientation_is_unknown(valve):
    """Issue 45: the shipped simulated gate's made-up times were stored as a physical launch's measured speed, and
    an operator-classified launch stored the upright quaternion (0, 0, 0, 1) even when it tipped."""
    rig = make_rig(valve, gate=SimulatedSpeedGate)
    assert "not a measurement" in rig.describe()
    tipped = rig.launch("run", "t0", CONDITION, ScriptedOperator(rig.operator, [OperatorOutcome(False)]))
    assert math.isnan(tipped.travel_time_s) and math.isnan(tipped.measured_speed_mps)
    assert not tipped.speed_out_of_tolerance
    assert tipped.note.startswith("travel time: not measured (the simulated speed gate")
    assert not tipped.orientation_known and all(math.isnan(q) for q in tipped.final_orientation)
    tipped.validate()
    typed = rig.launch("run", "t1", CONDITION, ScriptedOperator(rig.operator, [OperatorOutcome(True, 0.4)]))
    assert typed.travel_time_s == 0.4 and typed.note.startswith("travel time: typed by the operator")


def test_estop_during_countdown_aborts_and_leaves_the_fault_latched(valve):
    rig = make_rig(valve, countdown_s=0.3)
    operator = ScriptedOperator(rig.operator, on_armed=lambda: threading.Timer(0.05, valve.estop).start())
    with pytest.raises(LaunchAborted, match="e-stop"):
        rig.launch("run", "t0", CONDITION, operator)
    status = valve.status()
    assert status.fault and not status.armed and not status.open and status.pulses == 0
    assert "open" not in valve.backend.commands
    with pytest.raises(LaunchAborted, match="refused to arm.*fault latched"):
        rig.launch("run", "t0", CONDITION, operator)
    valve.disarm()                                                      # the operator acknowledges
    operator.on_armed = None
    operator.outcomes.append(OperatorOutcome(True))
    assert rig.launch("run", "t0", CONDITION, operator).upright


def test_a_fault_on_the_state_topic_never_shortens_the_countdown():
    """The valve state the rig reads comes from a topic any participant can publish: a fake fault there must not
    make the rig fire before the countdown ran out (it used to break the countdown and fire at once)."""
    class SpoofedStateValve:
        def __init__(self):
            self.armed_at = self.fired_at = None

        def arm(self):
            self.armed_at = time.monotonic()
            return True, "armed"

        def status(self):
            from rollability_ros.core.rig.valve import ValveStatus
            return ValveStatus(True, False, True, "forged fault", "dry_run", 0, 0)   # what a stray publishes

        def fire(self, pulse_ms):
            self.fired_at = time.monotonic()
            return False, "refused by the valve"

        def disarm(self):
            return True, "disarmed"

    spoofed = SpoofedStateValve()
    rig = make_rig(spoofed, countdown_s=0.4)
    operator = ScriptedOperator(rig.operator)
    with pytest.raises(LaunchAborted, match="refused by the valve"):
        rig.launch("run", "t0", CONDITION, operator)
    assert spoofed.fired_at - spoofed.armed_at >= 0.4


def test_watchdog_trip_aborts_the_launch(valve):
    rig = make_rig(valve, countdown_s=0.5)                              # no heartbeat: trips after 200 ms
    operator = ScriptedOperator(rig.operator)

    def watch():
        while not valve.check_watchdog():
            time.sleep(0.01)

    operator.on_armed = lambda: threading.Thread(target=watch, daemon=True).start()
    with pytest.raises(LaunchAborted, match="watchdog"):
        rig.launch("run", "t0", CONDITION, operator)
    assert valve.status().fault and not valve.status().open and "open" not in valve.backend.commands


def test_operator_timeout_and_cancel_abort(valve):
    rig = make_rig(valve, operator_timeout_s=0.2)
    silent = []
    with pytest.raises(LaunchAborted, match="no operator answer"):
        rig.launch("run", "t0", CONDITION, lambda phase, detail: silent.append(phase))
    assert silent == ["waiting_for_operator"] and valve.status().pulses == 0
    cancel = threading.Event()
    with pytest.raises(LaunchAborted, match="cancelled"):
        rig.launch("run", "t0", CONDITION, lambda phase, detail: cancel.set(), cancelled=cancel.is_set)


def test_an_open_question_is_repeated_until_answered(valve):
    """A feedback published before a client's subscription matched is lost (DDS does not queue it for a reader
    that matches later): an operator who missed the first announcement answers the repeat."""
    rig = make_rig(valve, operator_timeout_s=5.0, question_repeat_s=0.1)
    operator = ScriptedOperator(rig.operator, [OperatorOutcome(True)])
    heard = []

    def late_operator(phase, detail):
        if detail.startswith(ANSWERED):
            return
        heard.append(phase)
        if heard.count(phase) > 2 or phase not in ("waiting_for_operator", "classifying"):
            operator(phase, detail)     # the first two announcements of each question are lost

    outcome = rig.launch("run", "t0", CONDITION, late_operator)
    assert outcome.upright and outcome.classified_by == "operator"
    assert heard == ["waiting_for_operator"] * 3 + ["armed", "fired", "in_flight", "settling"] + ["classifying"] * 3
    with pytest.raises(ValueError, match=r"^rig.question_repeat_s out of range: 0.0 is not in \[0.05, 3600.0\]$"):
        check_settings(RigSettings(question_repeat_s=0.0), "rig")


def test_goal_checks_refuse_with_reasons(valve):
    rig = make_rig(valve)
    assert check_goal("run", "t", CONDITION, ["B"]) == ""
    assert "unknown configuration 'Z'" in check_goal("run", "t", LaunchCondition("Z", 1, 1, 0), ["B"])
    assert "height_m" in check_goal("run", "t", LaunchCondition("B", -1.0, 0.8, 0), ["B"])
    assert "finite" in check_goal("run", "t", LaunchCondition("B", math.nan, 0.8, 0), ["B"])
    assert "non-empty" in check_goal("", "t", CONDITION, ["B"])
    assert "no regulator pressure" in rig.check("run", "t", LaunchCondition("B", 0.75, 1.1, 0))
    with pytest.raises(ValueError, match="no regulator pressure"):
        rig.launch("run", "t", LaunchCondition("B", 0.75, 1.1, 0))
    assert valve.backend.commands == ["start", "close"]


def test_operator_channel_refuses_stray_answers():
    channel = OperatorChannel()
    assert channel.confirm() == (False, "the rig is not waiting for a regulator confirmation")
    channel.open("outcome", "t3")
    assert not channel.confirm()[0]
    assert channel.record_outcome(OperatorOutcome(True), "t9") == (
        False, "the rig waits for the outcome of 't3', not 't9'")
    assert channel.record_outcome(OperatorOutcome(False), "t3") == (True, "accepted")
    assert channel.record_outcome(OperatorOutcome(True)) == (
        False, "already answered for t3: tipped; this answer (upright) differs and is refused (the first answer counts)")
    assert channel.wait(1.0) == OperatorOutcome(False)
    channel.close()
    assert channel.wait(0.5) is None


def test_one_answer_counts_from_either_place_and_a_late_one_is_compared_with_it():
    """Issue 45: after `rollability rig outcome` was accepted, the campaign terminal's own answer read as a failure
    ("the rig is not waiting for an outcome"), and a different one was dropped without notice."""
    channel = OperatorChannel()
    channel.open("confirm", "t1")
    assert channel.confirm("t1") == (True, "accepted")
    channel.close()
    assert channel.confirm() == (True, "already answered for t1: regulator confirmed (this answer agrees; nothing "
                                       "changed)")
    channel.open("outcome", "t1")
    assert channel.record_outcome(OperatorOutcome(True, 0.41, "clean"), "t1") == (True, "accepted")
    channel.close()
    assert channel.record_outcome(OperatorOutcome(True), "t1")[0]                    # the same verdict: no failure
    accepted, message = channel.record_outcome(OperatorOutcome(False, note="on its side"))
    assert not accepted and "upright, travel time 0.41 s, note: clean" in message and "(tipped, note: on its side)" \
        in message
    assert channel.record_outcome(OperatorOutcome(False), "t2") == (False, "the rig is not waiting for an outcome")
    channel.open("outcome", "t2")                                                      # a new question: answered anew
    assert channel.record_outcome(OperatorOutcome(False), "t2") == (True, "accepted")


def test_the_rig_announces_the_answer_that_counted(valve):
    rig = make_rig(valve)
    operator = ScriptedOperator(rig.operator, [OperatorOutcome(False, note="on its side")])
    rig.launch("run", "t0", CONDITION, operator)
    answered = [(phase, detail) for phase, detail in operator.phases if detail.startswith(ANSWERED)]
    assert answered == [("waiting_for_operator", "answered: regulator confirmed"),
                        ("classifying", "answered: tipped, note: on its side")]


def test_regulator_confirmation_expires_and_is_forgotten_after_an_abort(valve, monkeypatch):
    rig = make_rig(valve, confirmation_valid_s=60.0, operator_timeout_s=0.2)
    operator = ScriptedOperator(rig.operator, [OperatorOutcome(True)] * 6)
    now, real_monotonic = [0.0], time.monotonic
    monkeypatch.setattr(time, "monotonic", lambda: real_monotonic() + now[0])   # time jumps forward on demand

    def asked(trial_id):
        operator.phases.clear()
        rig.launch("run", trial_id, CONDITION, operator)
        return operator.phases[0][0] == "waiting_for_operator"

    assert asked("t0")
    now[0] += 59.0
    assert not asked("t1"), "within confirmation_valid_s at the same speed: no question"
    now[0] += 61.0
    assert asked("t2"), "a confirmation is not remembered for ever"
    # an aborted launch (no outcome from the operator) forgets it too
    with pytest.raises(LaunchAborted, match="no operator answer"):
        rig.launch("run", "t3", CONDITION, lambda phase, detail: None)
    assert asked("t4")
    every = make_rig(valve, confirmation_valid_s=0.0)
    operator.channel = every.operator
    for trial_id in ("t5", "t6"):
        operator.phases.clear()
        every.launch("run", trial_id, CONDITION, operator)
        assert operator.phases[0][0] == "waiting_for_operator", "0 s: asked before every launch"


def test_a_confirmation_for_another_launch_is_refused():
    channel = OperatorChannel()
    channel.open("confirm", "t3")
    assert channel.confirm("t2") == (False, "the rig waits for a regulator confirmation of 't3', not 't2'")
    assert channel.confirm("t3") == (True, "accepted")


def test_parse_outcome_answer():
    assert parse_outcome_answer("y") == OperatorOutcome(True)
    assert parse_outcome_answer("n 0.43 landed on the lid") == OperatorOutcome(False, 0.43, "landed on the lid")
    assert parse_outcome_answer("upright wheels down").note == "wheels down"
    assert parse_outcome_answer("n 0.43 rolled=0.35 on its lid") == OperatorOutcome(False, 0.43, "on its lid", 0.35)
    assert parse_outcome_answer("y rolled=0").rest_distance_m == 0.0
    assert math.isnan(parse_outcome_answer("y 0.4").rest_distance_m)     # not typed: not measured
    for bad in ("", "maybe", "y -1", "y rolled=-0.2", "y rolled=far", "y rolled=nan", "y rolled=1 rolled=2"):
        with pytest.raises(ValueError):
            parse_outcome_answer(bad)


def _feed_launch(imu, final_tilt_deg, delay_s=0.05):
    """Feed a tumble that settles at ``final_tilt_deg`` (synthetic IMU, 200 Hz) after ``delay_s``."""
    samples = stream(piecewise([(0.0, 0.0), (0.4, 120.0), (0.8, final_tilt_deg)]), 2.0, rate_hz=200.0, seed=3)

    def feed():
        time.sleep(delay_s)
        for sample in samples:
            imu.feed(sample)
    threading.Thread(target=feed, daemon=True).start()


@pytest.mark.parametrize("final_tilt_deg, upright", [(3.0, True), (178.0, False)])
def test_imu_outcome_classifies_after_settling(valve, final_tilt_deg, upright):
    imu = ImuOutcome(ImuOutcomeConfig(settle_time_s=0.5, settle_timeout_s=3.0))
    rig = make_rig(valve, "imu", imu, imu_override_s=0.1)
    phases = []

    def on_phase(phase, detail):
        phases.append((phase, detail))
        if phase == "waiting_for_operator":
            rig.operator.confirm()
        if phase == "fired":
            _feed_launch(imu, final_tilt_deg)
    outcome = rig.launch("run", "t0", CONDITION, on_phase)
    assert outcome.classified_by == "imu" and outcome.upright is upright
    assert phases[-1][0] == "classifying" and "IMU" in phases[-1][1]
    tilt = math.degrees(2 * math.acos(min(1.0, abs(outcome.final_orientation[3]))))
    assert abs(tilt - final_tilt_deg) < 10
    # the continuous outcomes: the settled tilt; no impact in this tumble, so no landing: nothing counted from it
    assert abs(outcome.final_tilt_deg - final_tilt_deg) < 2
    assert math.isnan(outcome.time_to_rest_s) and math.isnan(outcome.peak_deceleration_mps2)
    assert math.isnan(outcome.rest_distance_m)


def test_operator_overrides_the_imu_and_answers_when_it_never_settles(valve):
    imu = ImuOutcome(ImuOutcomeConfig(settle_time_s=0.5, settle_timeout_s=1.5))
    rig = make_rig(valve, "imu", imu, imu_override_s=1.0)

    def override(phase, detail):
        if phase == "waiting_for_operator":
            rig.operator.confirm()
        if phase == "fired":
            _feed_launch(imu, 178.0)
        if phase == "classifying":
            assert rig.operator.record_outcome(OperatorOutcome(True, note="IMU cable caught", rest_distance_m=0.4))[0]
    overridden = rig.launch("run", "t0", CONDITION, override)
    assert overridden.upright and overridden.classified_by == "operator"
    # the verdict is overridden, not what the IMU measured; the typed distance is stored beside it
    assert abs(overridden.final_tilt_deg - 178.0) < 2 and overridden.rest_distance_m == 0.4
    assert "overrode the IMU (not upright" in overridden.note and "IMU cable caught" in overridden.note

    asked = []

    def no_imu(phase, detail):
        asked.append(detail)
        if phase == "classifying" and not detail.startswith(ANSWERED):
            assert detail.startswith(ASK_OUTCOME) and "did not see the chassis settle" in detail
            rig.operator.record_outcome(OperatorOutcome(False))
    silent = rig.launch("run", "t1", CONDITION, no_imu)
    assert not silent.upright and silent.classified_by == "operator"
    assert all(math.isnan(v) for v in silent.continuous().values())   # the IMU saw nothing of it: nothing stored


def test_simulated_outcome_and_launch_seed():
    class Result:
        upright = True
        final_orientation_xyzw = (0.0, 0.0, 0.0, 1.0)
        travel_time_s = 0.3
    outcome = simulated_outcome("run", "t", CONDITION, Result(), SpeedGateConfig())
    assert outcome.backend == "sim" and outcome.classified_by == "sim" and outcome.speed_out_of_tolerance
    assert "off the target" in outcome.note
    outcome.validate()
    assert launch_seed(0, "a/b") == launch_seed(0, "a/b") != launch_seed(1, "a/b")
    assert outcome.seed == NO_SEED                      # a result that names no seed
    Result.seed = 42
    assert simulated_outcome("run", "t", CONDITION, Result(), SpeedGateConfig()).seed == 42
    assert all(math.isnan(v) for v in outcome.continuous().values())   # a result that names none: not measured


def test_a_simulated_outcome_carries_the_twins_continuous_outcomes_and_invents_none():
    class Landed:
        upright, travel_time_s, seed = False, 0.4, 3
        final_orientation_xyzw = (1.0, 0.0, 0.0, 0.0)
        tilt_deg, rest_distance_m, time_to_rest_s, peak_deceleration_mps2 = 179.5, 0.42, 1.75, 96.0
        landing_position_m = (0.3, 0.0, 0.05)
    outcome = simulated_outcome("run", "t", CONDITION, Landed(), SpeedGateConfig())
    assert outcome.continuous() == {"final_tilt_deg": 179.5, "rest_distance_m": 0.42, "time_to_rest_s": 1.75,
                                    "peak_deceleration_mps2": 96.0}

    class NeverLanded(Landed):   # the twin's defaults for a launch that never reached the foam
        landing_position_m = (math.nan,) * 3
        time_to_rest_s, peak_deceleration_mps2, rest_distance_m = math.nan, 0.0, math.nan
    stalled = simulated_outcome("run", "t", CONDITION, NeverLanded(), SpeedGateConfig())
    assert math.isnan(stalled.peak_deceleration_mps2) and math.isnan(stalled.time_to_rest_s)
    assert stalled.final_tilt_deg == 179.5


class RecordingPorts(RigPorts):
    """RigPorts over a real dry-run ValveController and the simulated gate; records what the backend opened."""

    def __init__(self, valve, imu=True):
        self.valve, self.imu = valve, imu
        self.opened, self.closed = [], 0

    def open_valve(self, valve_config):
        self.opened.append("valve")
        return self.valve

    def open_speed_gate(self, speed_config):
        self.opened.append("speed_gate")
        return BenchGate(speed_config.run_length_m, 0.0, seed=1)

    def open_imu(self, imu_outcome):
        if not self.imu:
            raise ValueError("no IMU here")
        self.opened.append("imu")
        self.imu_outcome = imu_outcome

    def open_twin(self, twin_config):
        """The twin parsed here, as a node or a command parses it (not a hardware port: not in ``opened``)."""
        from rollability_ros.core.sim import load_launch_twin_settings

        self.twin_config = twin_config
        return load_launch_twin_settings(twin_config)

    def close(self):
        self.closed += 1


def test_factory_builds_the_physical_backend_on_the_callers_ports(valve):
    ports = RecordingPorts(valve)
    settings = RigSettings(backend="physical", countdown_s=0.0, configurations=["B"])
    backend = make_launch_backend(settings, SpeedGateConfig(), ValveConfig(), ImuOutcomeConfig(), ports)
    assert isinstance(backend, LaunchBackend) and backend.attended and backend.name == "physical"
    assert ports.opened == ["valve", "speed_gate"] and "outcome from operator" in backend.describe()
    # the contract's call, with the arguments every backend takes; the operator answers through backend.operator
    operator = ScriptedOperator(backend.operator, [OperatorOutcome(True)])
    outcome = backend.launch("run", "t0", CONDITION, operator, on_pose=lambda *pose: pytest.fail("no poses"),
                             cancelled=lambda: False)
    assert outcome.backend == "physical" and outcome.upright and valve.status().pulses == 1
    assert "no regulator pressure" in backend.check("run", "t1", LaunchCondition("B", 0.75, 1.1, 0))
    backend.close()
    assert ports.closed == 1

    imu_ports = RecordingPorts(valve)
    imu_backend = make_launch_backend(RigSettings(backend="physical", outcome_source="imu"), SpeedGateConfig(),
                                      ValveConfig(), ImuOutcomeConfig(), imu_ports)
    assert imu_ports.opened[0] == "imu" and imu_backend.imu is imu_ports.imu_outcome

    refusing = RecordingPorts(valve, imu=False)
    with pytest.raises(ValueError, match="no IMU here"):
        make_launch_backend(RigSettings(backend="physical", outcome_source="imu"), SpeedGateConfig(), ValveConfig(),
                            ImuOutcomeConfig(), refusing)
    assert refusing.opened == [] and refusing.closed == 1      # nothing opened, and what was started is stopped
    with pytest.raises(ValueError, match="backend must be one of"):
        make_launch_backend(RigSettings(backend="hybrid"), SpeedGateConfig(), ValveConfig(), ImuOutcomeConfig(),
                            refusing)
    assert launch_backend_class("sim").attended is False and launch_backend_class("physical").attended is True


def test_simulated_backend_opens_no_port_and_refuses_operator_answers(valve):
    pytest.importorskip("pybullet")
    ports = RecordingPorts(valve)
    backend = make_launch_backend(RigSettings(backend="sim", configurations=["baseline"]), SpeedGateConfig(),
                                  ValveConfig(), ImuOutcomeConfig(), ports)
    assert isinstance(backend, LaunchBackend) and not backend.attended and ports.opened == []
    assert ports.twin_config == RigSettings().twin_config   # the twin is read by the caller, from rig.twin_config
    assert backend.operator.record_outcome(OperatorOutcome(True))[0] is False
    assert "unknown configuration 'B'" in backend.check("run", "t0", CONDITION)
    with pytest.raises(ValueError, match="unknown configuration"):
        backend.launch("run", "t0", CONDITION)
    with pytest.raises(LaunchAborted, match="cancelled"):
        backend.launch("run", "t0", LaunchCondition("baseline", 0.75, 0.8, 0.0), cancelled=lambda: True)
    backend.close()
    assert valve.status().pulses == 0


def test_in_process_rig_refuses_an_imu_outcome_before_opening_the_valve():
    from rollability_ros.core.campaign.runner import LocalRig, local_rig_settings

    with pytest.raises(ValueError, match="operator only"):
        LocalRig(local_rig_settings("physical", {"rig.outcome_source": "imu"}))


def test_the_countdown_is_announced_each_second_and_cannot_outlast_the_arm_timeout(valve):
    """Issue 45: the countdown was one line ("firing in 1 s"); a countdown longer than valve.arm_timeout_s would
    have the valve disarm itself before the fire."""
    rig = make_rig(valve, countdown_s=1.1)
    operator = ScriptedOperator(rig.operator, [OperatorOutcome(True)])
    rig.launch("run", "t0", CONDITION, operator)
    armed = [detail for phase, detail in operator.phases if phase == "armed"]
    assert [detail.split(";")[1].split(",")[0] for detail in armed] == [" firing in 1.1 s", " firing in 1 s"]
    assert "rollability rig console" in armed[0]
    with pytest.raises(ValueError, match=r"rig.countdown_s \(20 s\) must be shorter than valve.arm_timeout_s \(15 s\)"):
        make_launch_backend(RigSettings(backend="physical", countdown_s=20.0), SpeedGateConfig(), ValveConfig(),
                            ImuOutcomeConfig(), RecordingPorts(valve))
