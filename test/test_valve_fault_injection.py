"""Fault injection on the valve path: the valve_controller node (own process, real DDS) on the relay board
simulator (own process, the firmware's protocol and timing), with the test playing the rig's operator side.

Each case fires a 450 ms pulse (max_pulse_ms 500 on both sides; the board's keep-alive timeout 250 ms) and injects
one fault while the relay is on. The evidence is the board's own event log: the relay must be off within
``max_pulse_ms + keepalive_timeout_ms`` of the pulse start, however the computer side failed. A stray participant
on the same domain, without the session key, must never get the relay on: neither at the valve's services nor
through the rig's (launch goals, rig/confirm, record_outcome) or the outcome_logger's input (physical outcomes),
with the dry-run valve and with the relay board simulator.

Run with ``-s`` to see the table of measured times (the closing note of issue 16 quotes it).
"""
import statistics
import signal
import subprocess
import sys
import textwrap
import time

import pytest
import valve_client
from valve_client import ValveClient, retried_on_stall

from rollability_ros.core.rig.relay_device_sim import RelaySim

MAX_PULSE_MS = 500
KEEPALIVE_TIMEOUT_MS = 250
PULSE_MS = 450
BOUND_MS = MAX_PULSE_MS + KEEPALIVE_TIMEOUT_MS
WATCHDOG_MS = 1000
VALVE_PARAMS = {"valve.backend": "serial_relay", "valve.max_pulse_ms": MAX_PULSE_MS, "valve.launch_pulse_ms": 150,
                "valve.watchdog_ms": WATCHDOG_MS, "valve.heartbeat_period_ms": 50}

MEASURED = []


@pytest.fixture(scope="module", autouse=True)
def print_table():
    yield
    if MEASURED:
        print("\n| fault (450 ms pulse, max_pulse_ms 500, keep-alive timeout 250 ms) | relay on, ms | switched off by |")
        print("|---|---|---|")
        for fault, on_ms, reason in MEASURED:
            print(f"| {fault} | {on_ms} | {reason} |")


@pytest.fixture
def relay(tmp_path):
    with RelaySim(tmp_path, max_pulse_ms=MAX_PULSE_MS, keepalive_timeout_ms=KEEPALIVE_TIMEOUT_MS) as sim:
        yield sim


def check_pulse(relay, fault, timeout_s=5.0):
    """The last pulse on the board's log ended within the bound; record it for the table. Returns its length, ms."""
    deadline = time.monotonic() + timeout_s
    while relay.relay_on() and time.monotonic() < deadline:
        time.sleep(0.01)
    intervals = relay.relay_intervals()
    assert intervals, f"{fault}: the relay never switched on"
    on, off = intervals[-1]
    assert off is not None, f"{fault}: relay still on {timeout_s} s after the check began"
    on_ms = (off["monotonic_s"] - on["monotonic_s"]) * 1000.0
    MEASURED.append((fault, f"{on_ms:.0f}", off["reason"]))
    assert on_ms <= BOUND_MS, f"{fault}: relay on {on_ms:.0f} ms > {BOUND_MS} ms"
    return on_ms


def fire_and_wait_on(valve, spun, relay):
    """Ask for the pulse without waiting for the answer; return once the board switched the relay on."""
    return valve_client.fire_and_wait_on(valve, spun, relay, PULSE_MS, WATCHDOG_MS)


def armed_valve(start_node, spun, relay, **params):
    process = start_node("valve_controller", params={**VALVE_PARAMS, "valve.serial.port": relay.port, **params})
    valve = ValveClient(spun)
    valve.ready(process.log)
    return process, valve


@pytest.mark.parametrize("fault", ["e-stop", "disarm", "watchdog"])
@retried_on_stall(WATCHDOG_MS)
def test_operator_and_watchdog_faults_mid_pulse(ros_node, start_node, relay, fault):
    process, valve = armed_valve(start_node, ros_node, relay)
    with valve.heartbeats():
        assert valve.arm()[0], process.log()
        future = fire_and_wait_on(valve, ros_node, relay)
        if fault == "e-stop":
            valve.estop()
        elif fault == "disarm":
            valve.arm_client.call_async(valve._arm.Request(arm=False, auth=valve.auth("disarm")))
    if fault == "watchdog":   # the heartbeats stopped when the block ended, at the pulse start
        assert ros_node.wait_for(lambda: valve.last().fault, 3 * WATCHDOG_MS / 1000), process.log()
        assert "watchdog" in valve.last().fault_reason
    on_ms = check_pulse(relay, fault)
    assert ros_node.wait_for(future.done, 10)
    if fault != "watchdog":
        assert relay.relay_intervals()[-1][1]["reason"] == "OFF", f"{fault} did not cut the pulse ({on_ms:.0f} ms)"
    assert ros_node.wait_for(lambda: not valve.last().armed, 10)
    assert process.stop() == 0


@retried_on_stall(WATCHDOG_MS)
def test_sigkill_of_the_valve_node_mid_pulse_without_restart(ros_node, start_node, relay):
    process, valve = armed_valve(start_node, ros_node, relay)
    with valve.heartbeats():
        assert valve.arm()[0]
        fire_and_wait_on(valve, ros_node, relay)
        process.signal(signal.SIGKILL)
        check_pulse(relay, "SIGKILL of the valve node, no restart")
    entries = relay.entries()
    assert not relay.relay_on() and entries[-1]["event"] != "exit", "the board is still running, relay off"
    time.sleep(0.5)
    assert not relay.relay_on()


@retried_on_stall(WATCHDOG_MS)
def test_frozen_valve_node_mid_pulse(ros_node, start_node, relay):
    process, valve = armed_valve(start_node, ros_node, relay)
    with valve.heartbeats():
        assert valve.arm()[0]
        fire_and_wait_on(valve, ros_node, relay)
        process.signal(signal.SIGSTOP)     # every thread stops, the keep-alive thread too
        try:
            check_pulse(relay, "valve node frozen (SIGSTOP)")
        finally:
            process.signal(signal.SIGCONT)
        # thawed, the valve learns from the board that it was disarmed and latches a fault
        assert ros_node.wait_for(lambda: valve.last().fault, 15), process.log()
    assert "board" in valve.last().fault_reason and not valve.last().armed
    assert process.stop() == 0 and not relay.relay_on()


@retried_on_stall(WATCHDOG_MS)
def test_serial_line_cut_mid_pulse(ros_node, start_node, relay):
    process, valve = armed_valve(start_node, ros_node, relay)
    with valve.heartbeats():
        assert valve.arm()[0]
        fire_and_wait_on(valve, ros_node, relay)
        relay.cut()
        check_pulse(relay, "serial line cut")
        assert ros_node.wait_for(lambda: valve.last().fault, 10), process.log()
        # the keep-alive or the pulse's own OFF finds the dead line first, whichever runs first after the cut
        reason = valve.last().fault_reason
        assert "link lost" in reason or "did not answer" in reason or "did not return" in reason, reason
        relay.restore()
        assert not valve.fire(100).success, "no pulse on a latched fault"
    assert process.stop() == 0


SUPERVISOR = textwrap.dedent("""
    # A rig computer's supervisor (as `rollability bringup`) running only the valve_controller.
    import json, signal, sys, time
    from rollability_ros.core.graph.bringup import NodeLaunch, parameter_files
    from rollability_ros.core.graph.supervisor import Supervisor
    node = NodeLaunch("valve_controller", params=json.loads(sys.argv[1]))
    supervisor = Supervisor([node.process_spec(parameter_files(), sys.argv[2])], sys.argv[2],
                            on_event=lambda event: print(event.text(), flush=True))
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append("SIGTERM"))
    supervisor.start()
    try:
        while not stop and supervisor.poll():
            time.sleep(0.1)
    finally:
        supervisor.stop()
""")


class SupervisedValve:
    """The supervisor script in its own process; the valve_controller is its child."""

    def __init__(self, tmp_path, relay):
        import json

        params = {**VALVE_PARAMS, "valve.serial.port": relay.port}
        self.log_path = tmp_path / "supervisor.log"
        self.process = subprocess.Popen([sys.executable, "-c", SUPERVISOR, json.dumps(params),
                                         str(tmp_path / "logs")], stdout=open(self.log_path, "w"),
                                        stderr=subprocess.STDOUT)

    def log(self):
        return self.log_path.read_text()

    def valve_pid(self):
        import re

        return int(re.search(r"\[valve_controller\] started: pid (\d+)", self.log()).group(1))

    def restarted(self):
        return "[valve_controller] restarted" in self.log()

    def stop(self):
        """Kill the supervisor and wait until every valve_controller it started is gone (they get SIGTERM when
        it dies), so the next valve on this domain is the only one."""
        import os
        import re

        if self.process.poll() is None:
            self.process.kill()
        self.process.wait(15)
        deadline = time.monotonic() + 15
        for pid in map(int, re.findall(r"\[valve_controller\] (?:started|restarted): [^\n]*?pid (\d+)", self.log())):
            while time.monotonic() < deadline:
                try:
                    os.kill(pid, 0)
                except ProcessLookupError:
                    break
                time.sleep(0.05)


@pytest.mark.parametrize("fault", ["SIGTERM of the supervisor", "SIGKILL of the supervisor",
                                   "SIGKILL of the valve node, supervisor restarts it"])
@retried_on_stall(WATCHDOG_MS)
def test_supervisor_faults_mid_pulse(ros_node, relay, tmp_path, fault):
    import os

    from rollability_ros.core.rig import valve_auth
    from rollability_ros.msg import ValveAuth

    supervised = SupervisedValve(tmp_path, relay)
    try:
        valve = ValveClient(ros_node)
        valve.ready(supervised.log)
        with valve.heartbeats():
            armed, message = valve.arm()
            assert armed, message + "\n" + supervised.log()
            old_key = valve_auth.load_session_key(valve_auth.default_key_path(""))
            fire_and_wait_on(valve, ros_node, relay)
            if fault == "SIGTERM of the supervisor":
                supervised.process.send_signal(signal.SIGTERM)
            elif fault == "SIGKILL of the supervisor":
                supervised.process.send_signal(signal.SIGKILL)
            else:
                os.kill(supervised.valve_pid(), signal.SIGKILL)
            check_pulse(relay, fault)
        if fault.startswith("SIGKILL of the valve node"):
            # the restarted valve_controller comes up closed and disarmed, in a new session
            assert ros_node.wait_for(supervised.restarted, 30), supervised.log()
            assert ros_node.wait_for(lambda: valve_auth.load_session_key(
                valve_auth.default_key_path("")).session != old_key.session, 30)
            assert ros_node.wait_for(lambda: not valve.last().armed and not valve.last().fault
                                     and valve.last().pulses == 0, 30)
            assert not relay.relay_on()
            # requests signed in the killed valve's session do not count in the new one
            old_signer = valve_auth.RequestSigner(old_key)

            def stale_request():
                old = old_signer.sign("arm")
                return valve._arm.Request(arm=True, auth=ValveAuth(session=old.session, counter=old.counter,
                                                                   mac=old.mac))
            stale = valve.answered(valve.arm_client, stale_request, "an arm signed in the killed session")
            assert not stale.success and "signed for session" in stale.message
        else:
            supervised.process.wait(30)
            assert ros_node.wait_for(lambda: not relay.relay_on(), 5)
    finally:
        supervised.stop()


STRAY = textwrap.dedent("""
    # A stray participant on the same ROS domain: no session key, but it sees every topic.
    import secrets, sys, time
    import rclpy
    from rclpy.node import Node
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from rollability_ros.msg import ValveAuth, ValveHeartbeat
    from rollability_ros.srv import ArmValve, FireValve
    rclpy.init()
    node = Node("stray_participant")
    captured, sessions = [], []
    node.create_subscription(ValveHeartbeat, "rig/heartbeat", captured.append, 100)
    node.create_subscription(DiagnosticArray, "/diagnostics", lambda a: sessions.extend(
        kv.value for s in a.status for kv in s.values if kv.key == "session"), 10)
    beat = node.create_publisher(ValveHeartbeat, "rig/heartbeat", 10)
    arm, fire = node.create_client(ArmValve, "valve/arm"), node.create_client(FireValve, "valve/fire")
    arm.wait_for_service(timeout_sec=30)
    fire.wait_for_service(timeout_sec=30)
    successes = calls = 0
    deadline = time.monotonic() + float(sys.argv[1])
    while time.monotonic() < deadline:
        # a steady stream of stray requests, not a CPU flood: on a 2-core test machine a flood starves the relay
        # simulator's process past the 0.2 s answer timeout (a denial of service that latches a link fault, never
        # a pulse; see docs/valve-safety.md)
        time.sleep(0.05)
        rclpy.spin_once(node, timeout_sec=0.01)
        session = sessions[-1] if sessions else ""
        forged = ValveAuth(session=session, counter=time.monotonic_ns(), mac=secrets.token_hex(32))
        for auth in (ValveAuth(), forged, *(c.auth for c in captured[-2:])):
            beat.publish(ValveHeartbeat(auth=auth))               # unsigned, forged, replayed heartbeats
            for client, request in ((arm, ArmValve.Request(arm=True, auth=auth)),
                                    (fire, FireValve.Request(pulse_ms=400, auth=auth)),
                                    (arm, ArmValve.Request(arm=False, auth=auth))):
                future = client.call_async(request)
                rclpy.spin_until_future_complete(node, future, timeout_sec=5)
                calls += 1
                successes += bool(future.done() and future.result().success)
    print(f"stray: {calls} calls, {successes} succeeded, {len(captured)} heartbeats captured, "
          f"session {'known' if sessions else 'unknown'}", flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
""")


@pytest.mark.slow   # about 16 s; the stray participant against the rig (dry_run) stays in the README's command
def test_stray_participant_never_gets_the_relay_on(ros_node, start_node, relay):
    process, valve = armed_valve(start_node, ros_node, relay)
    with valve.heartbeats():
        # phase 1: the valve is disarmed; phase 2: the operator side armed it and keeps it alive
        for phase in ("disarmed", "armed by the operator"):
            if phase.startswith("armed"):
                armed, message = valve.arm()
                if not armed and any(reason in message for reason in ("link lost", "keepalive", "did not answer",
                                                                      "did not return", "serial link stuck")):
                    # the stray's load starved the board or this valve past a serial timeout in phase 1: a latched
                    # link fault (fail-safe, docs/valve-safety.md); the operator acknowledges it and arms
                    assert valve.arm(False)[0], process.log()
                    armed, message = valve.arm()
                assert armed, message + process.log()
            stray = subprocess.run([sys.executable, "-c", STRAY, "4"], capture_output=True, text=True, timeout=120)
            assert stray.returncode == 0, stray.stderr
            assert " 0 succeeded" in stray.stdout and "session known" in stray.stdout, stray.stdout
            calls = int(stray.stdout.split("stray: ")[1].split(" calls")[0])
            assert calls >= 9, stray.stdout
            assert not relay.relay_intervals(), f"the stray process got the relay on ({phase})"
            last = valve.last()
            if phase.startswith("armed") and not last.armed:
                # on a starved machine the board may miss the computer's keep-alive and disarm itself: fail-safe,
                # and not the stray's doing (every stray request was refused: " 0 succeeded" above)
                assert last.fault and "fault keepalive" in last.fault_reason, ("the stray disarmed the valve", last)
            else:
                assert last.armed == phase.startswith("armed"), ("the stray could arm or disarm", last)
        MEASURED.append(("stray participant: unsigned / forged / replayed heartbeats, arm, fire, disarm "
                         f"({calls} calls per phase)", "never on", "-"))
        # an e-stop latched by the operator cannot be cleared by the stray's disarm
        valve.estop()
        assert ros_node.wait_for(lambda: valve.last().fault, 10)
        stray = subprocess.run([sys.executable, "-c", STRAY, "2"], capture_output=True, text=True, timeout=120)
        assert " 0 succeeded" in stray.stdout and valve.last().fault, stray.stdout
        # the operator side still works. On a loaded 2-core machine the stray's traffic can starve the valve node
        # or the board simulator past a serial answer or keep-alive timeout: a fail-safe (latched fault, board
        # disarmed), never a pulse; only such a fault allows another attempt
        fail_safe = ("did not answer", "link lost", "keepalive", "NOT_ARMED", "did not return", "serial link stuck")
        for _ in range(3):
            ok, message = valve.arm(False)
            if ok:
                ok, message = valve.arm()
            if ok:
                fired = valve.fire(100)
                ok, message = fired.success, fired.message
            if ok:
                break
            assert any(reason in message for reason in fail_safe), message + process.log()
        assert ok, message
    assert len(relay.relay_intervals()) == 1
    assert process.stop() == 0


def test_gpio_backend_sigkill_of_the_valve_node_mid_pulse(ros_node, start_node, tmp_path):
    """The gpio backend's line holder (with a stand-in gpiod that logs the line) drops the line on the node's death."""
    import json
    import os
    import pathlib

    fake_gpiod = pathlib.Path(__file__).resolve().parent / "resources" / "fake_gpiod"
    log = tmp_path / "gpio.jsonl"
    env = dict(os.environ, FAKE_GPIOD_LOG=str(log),
               PYTHONPATH=os.pathsep.join(filter(None, [str(fake_gpiod), os.environ.get("PYTHONPATH")])))
    process = start_node("valve_controller", params={
        "valve.backend": "gpio", "valve.gpio.chip": "gpiochip3", "valve.gpio.line_offset": 9,
        "valve.gpio.hardware_pulse_limiter": True, "valve.max_pulse_ms": MAX_PULSE_MS,
        "valve.watchdog_ms": WATCHDOG_MS}, env=env)
    valve = ValveClient(ros_node)
    valve.ready(process.log)

    def line_events():
        return [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []

    with valve.heartbeats():
        assert valve.arm()[0], process.log()
        valve.fire_client.call_async(valve.fire_request(PULSE_MS))
        assert ros_node.wait_for(lambda: any(e.get("value") == "active" for e in line_events()), 15), process.log()
        process.signal(signal.SIGKILL)     # the node's whole process group
        assert ros_node.wait_for(lambda: line_events()[-1]["event"] == "release", 5), line_events()
    events = line_events()
    on = next(e for e in events if e.get("value") == "active")
    off = next(e for e in events if e.get("value") == "inactive" and e["monotonic_s"] > on["monotonic_s"])
    on_ms = (off["monotonic_s"] - on["monotonic_s"]) * 1000.0
    MEASURED.append(("gpio backend (line holder), SIGKILL of the valve node's process group", f"{on_ms:.0f}",
                     "line holder: pipe closed"))
    assert on_ms <= BOUND_MS and on["pid"] != process.process.pid


STUCK_S = 6.0
STUCK_WATCHDOG_MS = 4000


def test_a_stuck_serial_call_does_not_silence_the_valve(ros_node, tmp_path, relay):
    """Issue 30: the board stops taking bytes, so the valve's serial writes block for STUCK_S; an operator disarm
    arrives meanwhile. The valve's state must report the fault while the call is still stuck, /diagnostics must
    keep coming once a second, and the disarm must answer; afterwards a disarm clears the fault."""
    import pathlib

    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

    from ros_fixtures import NodeProcess

    jam = tmp_path / "jam"
    # the watchdog well beyond the stuck-call bound (1.7 s): this case is about the stuck call, and with a 1 s
    # watchdog a 1 s stall of this loaded machine latched a watchdog fault first (CI, fault "no rig heartbeat for
    # 1007 ms"), a correct trip of a different fault
    params = {**VALVE_PARAMS, "valve.serial.port": relay.port, "valve.watchdog_ms": STUCK_WATCHDOG_MS}
    argv = [sys.executable, str(pathlib.Path(__file__).with_name("stuck_serial_valve.py")), str(jam), "--ros-args"]
    for key, value in params.items():
        argv += ["-p", f"{key}:={value}"]
    process = NodeProcess(argv, tmp_path / "valve.log")
    try:
        # (stamp s, arrival monotonic s, level) of every /diagnostics message of this valve: the stamp is the valve
        # node's clock when it published, so the schedule is checked at the source; arrival gaps also hold the
        # delivery to this test process, which a stall of the test process lengthens (fresh-clone run 40: a gap of
        # 2.07 s by arrival, docs/testing.md)
        arrivals = []
        ros_node.node.create_subscription(
            DiagnosticArray, "/diagnostics",
            lambda msg: arrivals.extend((msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, time.monotonic(),
                                         s.level) for s in msg.status if s.name.endswith("valve_controller: valve")),
            10)
        valve = ValveClient(ros_node)
        valve.ready(process.log)
        assert ros_node.wait_for(lambda: arrivals, 10), process.log()
        with valve.heartbeats():
            assert valve.arm()[0], process.log()
            jam.touch()
            jammed_at, jammed_stamp = time.monotonic(), time.time()
            disarm = valve.arm_client.call_async(valve._arm.Request(arm=False, auth=valve.auth("disarm")))
            assert ros_node.wait_for(lambda: valve.last().fault, STUCK_S - 2), (
                f"no fault state {STUCK_S - 2:.0f} s into a stuck serial call\n{process.log()}")
            fault_after_s = time.monotonic() - jammed_at
            reason = valve.last().fault_reason
            assert "did not return" in reason or "stuck" in reason, reason
            assert ros_node.wait_for(disarm.done, jammed_at + STUCK_S - 1 - time.monotonic()), (
                f"disarm unanswered while the serial call is stuck\n{process.log()}")
            assert not disarm.result().success, disarm.result().message
            time.sleep(max(0.0, jammed_at + STUCK_S - time.monotonic()))
            jam.unlink()
            unjammed_at, unjammed_stamp = time.monotonic(), time.time()
        # one published after the jam ended has arrived, so every earlier one has (one reliable writer, in order)
        assert ros_node.wait_for(lambda: arrivals[-1][0] > unjammed_stamp, 10), process.log()
        during = [stamp for stamp, _, _ in arrivals if jammed_stamp <= stamp <= unjammed_stamp]
        gaps = [b - a for a, b in zip([jammed_stamp] + during, during + [unjammed_stamp])]
        received = [t for _, t, _ in arrivals if jammed_at <= t <= unjammed_at]
        received_gaps = [b - a for a, b in zip([jammed_at] + received, received + [unjammed_at])]
        print(f"\nstuck serial call {STUCK_S:.0f} s: fault state after {fault_after_s:.2f} s ({reason}); "
              f"{len(during)} /diagnostics, longest gap {max(gaps):.2f} s as published, "
              f"{max(received_gaps):.2f} s as received")
        # the period is 1 s; a timer that waited for the stuck call's 1.7 s bound would leave gaps of up to 2.7 s and
        # at most 3 messages in the 6 s, every gap at least 1.7 s; a silenced one none. Threads of an idle node
        # process on this VM were measured not running for 0.1-1.1 s with no thread holding the GIL and no CPU load
        # (docs/testing.md, fresh-clone run 40), and CI saw one gap of 2.54 s among gaps near 1 s: so the schedule is
        # judged by the median gap (one stall lengthens one gap, a timer that waits on the bound lengthens every
        # one) and a silence by the longest
        median_gap = statistics.median(gaps)
        assert median_gap < 1.5, (
            f"/diagnostics every {median_gap:.1f} s (median) during a stuck serial call, period 1 s\n{process.log()}")
        assert max(gaps) < 4.0, f"/diagnostics silent {max(gaps):.1f} s during a stuck serial call\n{process.log()}"
        assert len(during) >= 4, f"{len(during)} /diagnostics in {STUCK_S:.0f} s of a stuck serial call"
        assert any(level == DiagnosticStatus.ERROR for stamp, _, level in arrivals
                   if jammed_stamp <= stamp <= unjammed_stamp), "no ERROR diagnostics"
        # the line works again: the operator's disarm acknowledges the fault, the relay is off
        # (the keep-alive that was stuck may still report the board's own keep-alive fault: acknowledge that too)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and not (valve.arm(False)[0] and not ros_node.wait_for(
                lambda: valve.last().fault, 0.5)):
            pass
        assert not valve.last().fault, f"{valve.last()}\n{process.log()}"
        assert not relay.relay_on()
    finally:
        jam.unlink(missing_ok=True)
        assert process.stop() == 0, process.log()


# --- the rig as deputy (issue 26): a stray participant against the rig's interfaces ----------------------------------

STRAY_RIG = textwrap.dedent("""
    # A stray participant on the rig's domain without the session key: launch goals (unsigned, forged, fuzzed, and
    # the operator's captured signed goal replayed), its own answers on rig/confirm and record_outcome (unsigned,
    # forged, the operator's captured ones replayed), and physical LaunchOutcomes published on launch_outcomes
    # (forged, and the rig's signed ones replayed and tampered with).
    import json, math, random, secrets, sys, time
    import rclpy
    from action_msgs.msg import GoalStatus
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.action import ActionClient
    from rclpy.node import Node
    from rollability_ros.action import Launch
    from rollability_ros.msg import LaunchCondition, LaunchOutcome, ValveAuth
    from rollability_ros.nodes._support import RECORD_QOS
    from rollability_ros.srv import ConfirmRegulator, RecordOutcome
    rclpy.init()
    node = Node("stray_participant")
    seconds, captured = float(sys.argv[1]), json.loads(sys.argv[2])
    rng = random.Random(26)
    sessions, outcomes = [], []
    node.create_subscription(DiagnosticArray, "/diagnostics", lambda a: sessions.extend(
        kv.value for s in a.status for kv in s.values if kv.key == "session"), 10)
    node.create_subscription(LaunchOutcome, "launch_outcomes", outcomes.append, RECORD_QOS)
    publisher = node.create_publisher(LaunchOutcome, "launch_outcomes", RECORD_QOS)
    action = ActionClient(node, Launch, "launch")
    confirm = node.create_client(ConfirmRegulator, "rig/confirm")
    record = node.create_client(RecordOutcome, "record_outcome")
    assert action.wait_for_server(timeout_sec=30) and confirm.wait_for_service(timeout_sec=30)
    assert record.wait_for_service(timeout_sec=30)
    replayed = [ValveAuth(session=s, counter=c, mac=m) for s, c, m in captured["auth"]]

    def fuzz_auth():
        session = sessions[-1] if sessions else secrets.token_hex(8)
        return rng.choice([
            ValveAuth(),
            ValveAuth(session=session, counter=time.monotonic_ns(), mac=secrets.token_hex(32)),
            ValveAuth(session=session, counter=rng.randrange(2**64), mac=secrets.token_hex(32).upper()),
            ValveAuth(session=secrets.token_hex(8), counter=time.monotonic_ns(), mac=secrets.token_hex(32)),
            ValveAuth(session="\\u00e9" * rng.randrange(5), counter=0, mac="zz" * rng.randrange(40)),
            *replayed])   # the operator's own signatures, on whatever this request is

    def condition():
        return LaunchCondition(configuration=rng.choice(["A", "B", "baseline", "Z", "", "A" * 300]),
                               height_m=rng.choice([0.75, 1.3, math.nan, -1.0, math.inf, 1e300]),
                               speed_mps=rng.choice([0.8, 1.5, math.nan, 0.0, -0.8]),
                               angle_deg=rng.choice([0.0, 30.0, math.nan, 720.0]),
                               repetition=rng.randrange(2**32))

    def result(future, timeout_s=10.0):
        rclpy.spin_until_future_complete(node, future, timeout_sec=timeout_s)
        return future.result() if future.done() else None

    tried = {"goals": 0, "confirms": 0, "outcomes": 0, "published": 0}
    accepted = {"goals": 0, "confirms": 0, "outcomes": 0}
    past_the_guard = []   # refused for another reason than authentication: the request got past the guard
    deadline = time.monotonic() + seconds
    index = 0
    while time.monotonic() < deadline:
        index += 1
        trial = rng.choice([f"stray/{index}", captured["trial_id"], captured["waiting"], ""])
        goal = Launch.Goal(run_id=rng.choice(["stray-run", captured["run_id"]]), trial_id=trial or f"stray/{index}",
                           condition=condition(), auth=fuzz_auth())
        if index % 5 == 0:   # the operator's signed goal, resent exactly as captured
            goal = Launch.Goal(run_id=captured["run_id"], trial_id=captured["trial_id"],
                               condition=LaunchCondition(**captured["condition"]), auth=replayed[0])
        handle = result(action.send_goal_async(goal))
        tried["goals"] += 1
        if handle is not None and handle.accepted:
            done = result(handle.get_result_async())
            if done is not None and done.status == GoalStatus.STATUS_SUCCEEDED:
                accepted["goals"] += 1
            elif done is not None and "not authenticated" not in done.result.message:
                past_the_guard.append(done.result.message)
        for client, request, kind in (
                (confirm, ConfirmRegulator.Request(trial_id=trial, auth=fuzz_auth()), "confirms"),
                (record, RecordOutcome.Request(trial_id=trial, upright=True, note="forged", auth=fuzz_auth(),
                                               travel_time_s=rng.choice([math.nan, 0.4, -1.0, math.inf])),
                 "outcomes")):
            response = result(client.call_async(request), 5.0)
            tried[kind] += 1
            ok = response is not None and (response.success if kind == "confirms" else response.accepted)
            accepted[kind] += bool(ok)
            if response is not None and not ok and "not authenticated" not in response.message:
                past_the_guard.append(response.message)
        forged = LaunchOutcome(run_id="stray-run", trial_id=f"stray/{index}", backend="physical", upright=True,
                               classified_by="operator", note="forged", travel_time_s=0.4,
                               measured_speed_mps=0.85, auth=fuzz_auth())
        forged.condition = LaunchCondition(configuration="A", height_m=0.75, speed_mps=0.8)
        forged.final_orientation.w = 1.0
        publisher.publish(forged)
        tried["published"] += 1
        for outcome in [o for o in outcomes if o.backend == "physical"][-2:]:
            publisher.publish(outcome)                       # the rig's signed record, replayed as it was
            outcome.note, outcome.trial_id = "forged", outcome.trial_id + "/forged"
            publisher.publish(outcome)                       # and tampered with
            tried["published"] += 2
        time.sleep(0.1)   # a steady stream, not a flood (a flood is a denial of service: docs/valve-safety.md)
    print(json.dumps({"tried": tried, "accepted": accepted, "past_the_guard": past_the_guard,
                      "session_known": bool(sessions), "outcomes_seen": len(outcomes)}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
""")

RIG_PARAMS = {"rig.backend": "physical", "rig.countdown_s": 0.1, "rig.operator_timeout_s": 60.0,
              "valve.watchdog_ms": WATCHDOG_MS, "valve.heartbeat_period_ms": 50}
#: the valve's fail-safe faults a stray's load can cause on a shared 2-core machine (never a pulse)
FAIL_SAFE = ("did not answer", "link lost", "keepalive", "NOT_ARMED", "watchdog")


def wait_phase(spun, feedback, phase, process_logs, timeout_s=30):
    assert spun.wait_for(lambda: feedback and feedback[-1][0] == phase, timeout_s), f"{feedback}\n{process_logs()}"


def rig_cli(*args):
    return subprocess.run([sys.executable, "-m", "rollability_ros.cli", "rig", *args, "--namespace", "/"],
                          capture_output=True, text=True, timeout=60)


# The serial relay's case runs in the slow tier: the relay's own stray test above (the board never switches on)
# and this dry_run case keep both halves of the boundary in the README's command.
@pytest.mark.parametrize("backend", ["dry_run", pytest.param("serial_relay", marks=pytest.mark.slow)])
def test_stray_participant_never_launches_through_the_rig(ros_node, start_node, tmp_path, request, backend):
    import json

    from action_msgs.msg import GoalStatus
    from rig_client import RigClient

    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.store import Store
    from rollability_ros.core.rig import rig_auth, valve_auth
    from rollability_ros.nodes._convert import auth_msg
    from rollability_ros.srv import ConfirmRegulator

    relay = request.getfixturevalue("relay") if backend == "serial_relay" else None
    valve_params = {**VALVE_PARAMS, "valve.backend": backend, "valve.watchdog_ms": WATCHDOG_MS}
    if relay is not None:
        valve_params["valve.serial.port"] = relay.port
    valve_process = start_node("valve_controller", params=valve_params)
    valve = ValveClient(ros_node)
    assert ros_node.wait_for(lambda: valve.states, 30), valve_process.log()
    store_path = tmp_path / "store.sqlite"
    logger = start_node("outcome_logger", params={"store_path": str(store_path)})
    rig_process = start_node("rig", params=RIG_PARAMS)
    rig = RigClient(ros_node)

    def logs():
        return "\n".join(f"--- {p.log_path.name}\n{p.log()[-3000:]}" for p in (valve_process, rig_process, logger))

    def stored():
        if not store_path.exists():
            return []
        with Store(store_path) as store:
            return store.launch_outcomes()

    def pulses():
        return len(relay.relay_intervals()) if relay is not None else valve.last().pulses

    # --- the operator's launch op/0, through the test's signed client: what a stray could capture of it --------
    condition = LaunchCondition("A", 0.75, 0.8, 0.0, 0)
    assert rig.action.wait_for_server(timeout_sec=30), logs()   # sign once the rig is there, as the tools do
    key = valve_auth.load_session_key(valve_auth.default_key_path(""))
    unsigned = RigClient(ros_node, signed=False)
    for attempt in range(3):
        feedback = []
        goal = rig.goal("op/0", condition, run_id="op-run")
        future = rig.send("op/0", condition, feedback, goal=goal)
        wait_phase(ros_node, feedback, "waiting_for_operator", logs)
        if attempt == 0:
            expired = valve_auth.RequestSigner(key, lambda: time.monotonic_ns() - 6_000_000_000).sign_text(
                rig_auth.confirm_text("op/0"))
            refused = rig.confirm(request=ConfirmRegulator.Request(trial_id="op/0", auth=auth_msg(expired)))
            assert not refused.success and "stale request" in refused.message, refused.message
            other = rig.confirm("op/9")                    # signed, but for another launch than the one waiting
            assert not other.success and "waits for a regulator confirmation of 'op/0', not 'op/9'" in other.message
            assert "not authenticated" in unsigned.confirm("op/0").message
        confirmation = ConfirmRegulator.Request(trial_id="op/0", auth=rig.auth(lambda signer: signer.confirm("op/0")))
        assert rig.confirm(request=confirmation).success
        assert ros_node.wait_for(lambda: future.done() or feedback[-1][0] == "classifying", 30), (
            f"{feedback}\n{logs()}")
        if not future.done():
            break
        # a stall of this loaded machine held the valve node or the board simulator past a bound (slow tier beside
        # another suite: the launch never reached classifying): a fail-safe abort, never a pulse; the operator
        # acknowledges it and launches again
        done = rig.result(future)
        assert any(reason in done.result.message for reason in FAIL_SAFE), done.result.message + logs()
        assert pulses() == 0, logs()
        valve.arm(False)
    wait_phase(ros_node, feedback, "classifying", logs)   # the loop's last attempt reached it
    assert "not authenticated" in unsigned.record(True, "op/0", note="forged").message
    answer = rig.record(False, "op/0", note="operator")
    assert answer.accepted, answer.message
    done = rig.result(future)
    assert done.status == GoalStatus.STATUS_SUCCEEDED, done.result.message + logs()
    assert done.result.outcome.backend == "physical" and done.result.outcome.auth.session == key.session
    assert ros_node.wait_for(lambda: [o.trial_id for o in stored()] == ["op/0"], 15), logs()
    assert pulses() == 1
    # the captured signed goal and confirmation, resent at once: refused as replays, no second pulse
    replay = rig.result(rig.send("op/0", condition, [], goal=goal))
    assert replay.status == GoalStatus.STATUS_ABORTED and "replayed request" in replay.result.message
    assert "replayed request" in rig.confirm(request=confirmation).message
    assert pulses() == 1

    # --- the stray participant runs while the operator launches op/1 with `rollability rig` -----------------------
    captured = {"run_id": "op-run", "trial_id": "op/0", "waiting": "op/1",
                "condition": {"configuration": "A", "height_m": 0.75, "speed_mps": 0.8, "angle_deg": 0.0,
                              "repetition": 0},
                "auth": [[a.session, a.counter, a.mac] for a in (goal.auth, confirmation.auth)]}
    stray = subprocess.Popen([sys.executable, "-c", STRAY_RIG, "10", json.dumps(captured)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        time.sleep(2.0)                                   # the stray is sending by now
        for attempt in range(3):
            feedback = []
            fast = LaunchCondition("A", 0.75, 1.5, 0.0, 0)  # another speed: the rig asks for the regulator again
            future = rig.send("op/1", fast, feedback, goal=rig.goal("op/1", fast, run_id="op-run"))
            wait_phase(ros_node, feedback, "waiting_for_operator", logs)
            time.sleep(1.0)                               # the stray answers meanwhile: the question stays open
            assert feedback[-1][0] == "waiting_for_operator" and not future.done(), feedback
            confirmed = rig_cli("confirm", "--trial-id", "op/1")
            assert confirmed.returncode == 0 and "confirm: ok" in confirmed.stdout, confirmed.stdout + confirmed.stderr
            assert ros_node.wait_for(lambda: future.done() or feedback[-1][0] == "classifying", 30), logs()
            if not future.done():
                time.sleep(1.0)                           # the stray records its outcome meanwhile: still open
                assert feedback[-1][0] == "classifying" and not future.done(), feedback
                recorded = rig_cli("outcome", "upright", "--trial-id", "op/1", "--note", "operator")
                assert recorded.returncode == 0, recorded.stdout + recorded.stderr
            done = rig.result(future)
            if done.status == GoalStatus.STATUS_SUCCEEDED:
                break
            # the stray's load stalled the valve node or the board simulator: a fail-safe, never a pulse; the
            # operator acknowledges it and launches again
            assert any(reason in done.result.message for reason in FAIL_SAFE), done.result.message + logs()
            valve.arm(False)
        assert done.status == GoalStatus.STATUS_SUCCEEDED, done.result.message
        out, err = stray.communicate(timeout=120)
    finally:
        if stray.poll() is None:
            stray.kill()
    assert stray.returncode == 0, err
    counts = json.loads(out.strip().splitlines()[-1])
    tried, accepted = counts["tried"], counts["accepted"]
    assert counts["session_known"] and counts["outcomes_seen"] >= 1, counts
    assert tried["goals"] >= 10 and tried["confirms"] >= 10 and tried["outcomes"] >= 10, counts
    assert accepted == {"goals": 0, "confirms": 0, "outcomes": 0}, counts
    assert counts["past_the_guard"] == [], counts
    # the valve pulsed for the operator's two launches only; the store holds exactly the operator's outcomes
    assert pulses() == 2, logs()
    assert ros_node.wait_for(lambda: len(stored()) == 2, 15), logs()
    outcomes = {o.trial_id: o for o in stored()}
    assert sorted(outcomes) == ["op/0", "op/1"] and all(o.run_id == "op-run" for o in outcomes.values())
    # every physical note starts with where its travel time came from (issue 45), then the operator's own note
    assert not outcomes["op/0"].upright and outcomes["op/1"].upright
    for outcome in outcomes.values():
        assert outcome.note.startswith("travel time: ") and outcome.note.endswith("; operator"), outcome.note
    assert "refused physical launch outcome" in logger.log() and "not authenticated" in rig_process.log()
    total = sum(tried.values())
    MEASURED.append((f"stray participant against the rig ({backend} valve): {tried['goals']} launch goals, "
                     f"{tried['confirms']} confirmations, {tried['outcomes']} outcomes, {tried['published']} "
                     f"physical outcomes published ({total} in all; unsigned, forged, fuzzed, replayed), while the "
                     "operator launched", "2 pulses (the operator's)", "0 accepted, 0 stored"))
