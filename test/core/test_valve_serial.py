"""The serial_relay backend against the simulated relay board, a separate process on a pseudo-terminal.

The board's own log (``relay`` events) is the evidence: it shows when the relay really switched, whatever the
computer side believed.
"""
import signal
import subprocess
import sys
import textwrap
import threading
import time

import pytest

from rollability_ros.core.rig.relay_device_sim import RelaySim
from rollability_ros.core.rig.valve import ValveController
from rollability_ros.core.rig.valve_boards import SerialRelayBackend

ANSWER_TIMEOUT_S = 0.15


def controller_for(sim, watchdog_ms=2000, max_pulse_ms=5000, **backend_options):
    options = dict(baud=115200, timeout_s=ANSWER_TIMEOUT_S, keepalive_period_ms=40)
    options.update(backend_options)
    states = []
    controller = ValveController(SerialRelayBackend(sim.port, **options), max_pulse_ms=max_pulse_ms,
                                 watchdog_ms=watchdog_ms, on_state=states.append)
    return controller, states


def lines(sim):
    return [e["line"] for e in sim.entries() if e["event"] == "command" and e["line"] != "KA"]


def on_ms(interval):
    on, off = interval
    assert off is not None, "relay still on"
    return (off["monotonic_s"] - on["monotonic_s"]) * 1000.0


def wait_until(predicate, timeout_s=5.0):
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.005)
    return True


@pytest.fixture
def sim(tmp_path):
    with RelaySim(tmp_path, max_pulse_ms=3000, keepalive_timeout_ms=250) as running:
        yield running


def test_closed_at_start_board_timed_pulse_and_shutdown(sim):
    controller, states = controller_for(sim)
    assert lines(sim) == ["HELLO", "STATUS", "OFF", "DISARM"], "driven closed and disarmed at start"
    assert controller.arm()[0] and lines(sim)[-1] == "ARM"
    ok, message = controller.fire(60)
    assert ok, message
    assert "PULSE 60" in lines(sim)
    (interval,) = sim.relay_intervals()
    assert interval[0]["reason"] == "PULSE 60"
    assert 55.0 <= on_ms(interval) < 90.0, f"relay held on {on_ms(interval):.1f} ms for a 60 ms pulse"
    controller.shutdown()
    assert lines(sim)[-2:] == ["OFF", "DISARM"] and not sim.relay_on()
    assert not states[-1].open and not states[-1].armed


def test_board_caps_the_pulse_at_its_own_limit(tmp_path):
    with RelaySim(tmp_path, max_pulse_ms=100) as small:
        controller, _ = controller_for(small, max_pulse_ms=1000)   # the computer side would allow 1 s
        assert controller.arm()[0]
        controller.fire(800)
        (interval,) = small.relay_intervals()
        assert interval[0]["reason"] == "PULSE 100" and interval[1]["reason"] == "pulse end"
        assert on_ms(interval) < 130.0
        controller.shutdown()


DYING_CONTROLLER = textwrap.dedent("""
    import sys, time
    from rollability_ros.core.rig.valve import ValveController
    from rollability_ros.core.rig.valve_boards import SerialRelayBackend
    controller = ValveController(SerialRelayBackend(sys.argv[1], timeout_s=0.5, keepalive_period_ms=40),
                                 max_pulse_ms=5000, watchdog_ms=60000)
    controller.arm()
    controller.fire(2500)
""")


def test_sigkilled_controller_mid_pulse_the_board_drops_the_relay_on_its_own(sim):
    process = subprocess.Popen([sys.executable, "-c", DYING_CONTROLLER, sim.port])
    try:
        assert wait_until(sim.relay_on, 30), "the controller process never fired"
        process.send_signal(signal.SIGKILL)
        process.wait(10)
    finally:
        process.kill()
    assert wait_until(lambda: not sim.relay_on(), 2)
    (interval,) = sim.relay_intervals()
    assert interval[1]["reason"] == "keepalive"
    # the pulse asked 2500 ms: the keep-alive timeout (250 ms after the last KA) ended it
    assert on_ms(interval) < 250.0 + 150.0


def test_cut_line_drops_the_relay_and_faults_the_controller(sim):
    controller, states = controller_for(sim)
    assert controller.arm()[0]
    result = {}
    firing = threading.Thread(target=lambda: result.update(out=controller.fire(2000)))
    firing.start()
    assert wait_until(sim.relay_on)
    sim.cut()
    firing.join(5)
    assert not firing.is_alive()
    (interval,) = sim.relay_intervals()
    assert interval[1]["reason"] == "keepalive" and on_ms(interval) < 2000
    assert wait_until(lambda: controller.status().fault)
    assert "link lost" in controller.status().fault_reason and not controller.status().armed
    sim.restore()
    assert controller.disarm()[0] and controller.arm()[0] and controller.fire(30)[0]
    controller.shutdown()
    assert not sim.relay_on()


def test_board_estop_button_latches_until_released_and_acknowledged(sim):
    controller, states = controller_for(sim)
    assert controller.arm()[0]
    sim.press_estop()
    assert wait_until(lambda: controller.status().fault)
    assert "board fault estop" in controller.status().fault_reason
    assert not controller.fire(30)[0] and not sim.relay_intervals()
    assert controller.disarm()[0], "button released: the acknowledgement clears the board too"
    assert "CLEAR" in lines(sim)
    assert controller.arm()[0] and controller.fire(30)[0]
    controller.shutdown()


def test_late_answers_fault_at_start_and_never_arm(tmp_path):
    with RelaySim(tmp_path, ack_delay_s=2 * ANSWER_TIMEOUT_S) as slow:
        controller, _ = controller_for(slow, boot_wait_s=0.0)
        status = controller.status()
        assert status.fault and "did not answer 'HELLO'" in status.fault_reason
        assert not controller.arm()[0], "cannot arm a board that does not answer"
        assert not slow.relay_on()
        controller.shutdown()


def test_hello_is_repeated_while_the_board_boots(tmp_path):
    # an Uno resets when its port opens; its bootloader eats whatever arrives for a moment
    (tmp_path / "one").mkdir()
    (tmp_path / "two").mkdir()
    with RelaySim(tmp_path / "one", boot_delay_s=0.6) as booting:
        controller, _ = controller_for(booting, boot_wait_s=0.0)
        assert controller.status().fault, "a single HELLO is lost in the boot"
        controller.shutdown()
    with RelaySim(tmp_path / "two", boot_delay_s=0.6) as booting:
        controller, _ = controller_for(booting, boot_wait_s=3.0)
        assert not controller.status().fault, controller.status().fault_reason
        assert controller.arm()[0] and controller.fire(30)[0]
        controller.shutdown()


def test_keepalive_period_must_fit_the_board_timeout(sim):
    controller, _ = controller_for(sim, keepalive_period_ms=100)     # 3 x 100 > 250
    assert controller.status().fault and "more than a third" in controller.status().fault_reason
    controller.shutdown()


def test_estop_during_pulse_switches_relay_off(sim):
    controller, _ = controller_for(sim)
    controller.arm()
    firing = threading.Thread(target=controller.fire, args=(800,))
    firing.start()
    assert wait_until(sim.relay_on)
    estop_at = time.monotonic()
    controller.estop("e-stop button")
    (interval,) = sim.relay_intervals()
    assert interval[1]["reason"] == "OFF"
    assert interval[1]["monotonic_s"] - estop_at < 0.05, "relay switched off within 50 ms of the e-stop"
    firing.join(2.0)
    assert not firing.is_alive() and not sim.relay_on()
    controller.shutdown()


def test_watchdog_trip_switches_relay_off(sim):
    controller, states = controller_for(sim, watchdog_ms=80)
    controller.start_watchdog(0.01)
    armed_at = time.monotonic()   # the simulator's log uses the same system-wide monotonic clock
    controller.arm()
    result = {}
    firing = threading.Thread(target=lambda: result.update(out=controller.fire(900)))
    firing.start()
    firing.join(2.0)
    ok, message = result["out"]
    assert not ok and "watchdog" in message
    (interval,) = sim.relay_intervals()
    # the heartbeat window starts at arming, so the cut comes 80 ms after arming (the ON may have come later)
    assert interval[1]["monotonic_s"] - armed_at >= 0.08 and on_ms(interval) < 500, \
        "cut by the 80 ms watchdog, not the 900 ms pulse"
    assert not sim.relay_on()
    controller.shutdown()


class _LatePort:
    """A pyserial-like port whose reader only runs again after the answer deadline (a thread that waited for the
    GIL on a busy machine), although the whole answer had arrived in time."""

    def __init__(self, answer, late_s):
        self.pending, self.late_s = answer, late_s

    @property
    def in_waiting(self):
        return len(self.pending) if self.pending and not self.late_s else 0

    def read(self, size):
        if self.late_s:
            time.sleep(self.late_s)
            self.late_s = 0
        data, self.pending = self.pending[:size], self.pending[size:]
        return data


def test_an_answer_that_arrived_in_time_is_not_a_timeout_when_the_reader_runs_late():
    from rollability_ros.core.rig.valve_boards import _SerialPort

    answer = b"OK KA armed=1 relay=0 fault=none\n"
    port = _SerialPort(_LatePort(answer, late_s=3 * ANSWER_TIMEOUT_S), ANSWER_TIMEOUT_S)
    assert port.read_until(b"\n") == answer   # byte by byte it would stop after the first byte: "partial answer"
    silent = _SerialPort(_LatePort(b"", late_s=0), ANSWER_TIMEOUT_S)
    started = time.monotonic()
    assert silent.read_until(b"\n") == b"" and time.monotonic() - started < 1.0   # silence still times out


def test_a_starved_simulator_says_so_in_its_log(sim):
    """A board simulator the host did not run (here SIGSTOP for 0.4 s) logs how late it woke: a keep-alive fault
    after such an entry may be the simulator's, not the valve node's (a real board is never starved)."""
    assert wait_until(lambda: any(e["event"] == "start" for e in sim.entries()))
    sim.process.send_signal(signal.SIGSTOP)
    time.sleep(0.4)
    sim.process.send_signal(signal.SIGCONT)
    assert wait_until(lambda: sim.longest_oversleep_ms() >= 250.0), sim.entries()[-3:]


def test_a_late_keepalive_while_armed_is_logged_by_the_valve(sim, caplog):
    """The valve side warns when, armed, two answered commands lie more than half the board's keep-alive timeout
    apart (here the port is held for 180 ms against a 250 ms timeout): how close the computer came to a board fault."""
    controller, _states = controller_for(sim)
    backend = controller._backend
    try:
        with caplog.at_level("WARNING", logger=backend_logger_name()):
            time.sleep(0.3)
            assert "starving the valve node" not in caplog.text     # disarmed, and on time
            assert controller.arm()[0]
            with backend._io_lock:
                time.sleep(0.18)
            assert wait_until(lambda: "starving the valve node" in caplog.text, 2), caplog.text
            assert "the valve node wrote 'KA'" in caplog.text and "answered late" not in caplog.text
    finally:
        controller.shutdown()


def test_a_board_that_answers_late_is_told_apart_from_a_starved_valve_node(tmp_path, caplog):
    """The same warning when the board is the slow side (here it answers each line 140 ms late against a 250 ms
    timeout): the valve node wrote on time and the board answered late, so it does not blame this computer."""
    with RelaySim(tmp_path, max_pulse_ms=3000, keepalive_timeout_ms=250, ack_delay_s=0.14) as slow:
        controller, _states = controller_for(slow, timeout_s=0.5)
        try:
            with caplog.at_level("WARNING", logger=backend_logger_name()):
                assert controller.arm()[0]
                assert wait_until(lambda: "answered late" in caplog.text, 3), caplog.text
                assert "starving the valve node" not in caplog.text, caplog.text
        finally:
            controller.shutdown()


def backend_logger_name():
    from rollability_ros.core.rig import valve_boards

    return valve_boards._LOG.name
