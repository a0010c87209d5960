"""The serial_relay backend against the simulated relay board, a separate process on a pseudo-terminal."""
import threading
import time

import pytest

from rollability_ros.core.rig.relay_device_sim import RelaySim
from rollability_ros.core.rig.valve import ValveController
from rollability_ros.core.rig.valve_backends import SerialRelayBackend

ACK_TIMEOUT_S = 0.15


def controller_for(sim, watchdog_ms=2000, **backend_options):
    options = dict(baud=115200, open_command="RELAY 1 ON", close_command="RELAY 1 OFF", ack="OK",
                   timeout_s=ACK_TIMEOUT_S)
    options.update(backend_options)
    states = []
    controller = ValveController(SerialRelayBackend(sim.port, **options), max_pulse_ms=1000,
                                 watchdog_ms=watchdog_ms, on_state=states.append)
    return controller, states


def commands(sim):
    return [e for e in sim.entries() if e["event"] == "command"]


@pytest.fixture
def sim(tmp_path):
    with RelaySim(tmp_path) as running:
        yield running


def test_closed_at_start_fire_and_shutdown(sim):
    controller, states = controller_for(sim)
    assert [c["line"] for c in commands(sim)] == ["RELAY 1 OFF"], "driven closed explicitly at start"
    assert controller.arm()[0]
    ok, message = controller.fire(60)
    assert ok, message
    on, off = commands(sim)[-2:]
    assert (on["relay"], off["relay"]) == ("on", "off")
    held_ms = (off["monotonic_s"] - on["monotonic_s"]) * 1000.0
    assert 60.0 <= held_ms < 90.0, f"relay held on {held_ms:.1f} ms for a 60 ms pulse"
    controller.shutdown()
    assert commands(sim)[-1]["line"] == "RELAY 1 OFF" and not sim.relay_on()
    assert not states[-1].open and not states[-1].armed


def test_wrong_acknowledgement_faults(sim):
    controller, _ = controller_for(sim, ack="YES")
    status = controller.status()
    assert status.fault and "relay answered 'OK' to 'RELAY 1 OFF', expected 'YES'" in status.fault_reason
    assert not sim.relay_on()
    controller.shutdown()


def test_missing_ack_mid_run_faults_and_the_relay_ends_off(sim):
    controller, states = controller_for(sim)
    controller.arm()
    assert controller.fire(20)[0]
    sim.mute()
    ok, message = controller.fire(20)
    assert not ok and "did not acknowledge 'RELAY 1 ON'" in message
    assert states[-1].fault and not states[-1].armed
    last = commands(sim)[-1]
    assert last["line"] == "RELAY 1 OFF" and last["relay"] == "off", "close attempted after the failed open"
    assert controller.fire(20)[1].startswith("fault latched")
    sim.unmute()
    assert controller.disarm() == (True, "disarmed, valve closed")
    assert controller.arm()[0] and controller.fire(20)[0]
    assert not sim.relay_on()
    controller.shutdown()


def test_late_ack_faults_and_closes(tmp_path):
    with RelaySim(tmp_path, ack_delay_s=2 * ACK_TIMEOUT_S) as slow:
        controller, _ = controller_for(slow)
        status = controller.status()
        assert status.fault and "did not acknowledge 'RELAY 1 OFF'" in status.fault_reason
        assert not controller.arm()[0], "cannot arm with an unconfirmed close"
        assert not slow.relay_on()


def test_board_that_never_acks_is_still_commanded_off(tmp_path):
    with RelaySim(tmp_path, no_ack=True) as mute:
        controller, states = controller_for(mute)
        assert states[-1].fault
        controller.shutdown()
        assert all(c["line"] == "RELAY 1 OFF" for c in commands(mute)) and len(commands(mute)) >= 2
        assert not mute.relay_on()


def test_estop_during_pulse_switches_relay_off(sim):
    controller, _ = controller_for(sim)
    controller.arm()
    firing = threading.Thread(target=controller.fire, args=(800,))
    firing.start()
    time.sleep(0.1)
    estop_at = time.monotonic()
    controller.estop("e-stop button")
    off = commands(sim)[-1]
    assert off["line"] == "RELAY 1 OFF" and off["relay"] == "off"
    assert off["monotonic_s"] - estop_at < 0.05, "relay switched off within 50 ms of the e-stop"
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
    lines = [c["line"] for c in commands(sim)]
    on_index = lines.index("RELAY 1 ON")
    on, off = commands(sim)[on_index:on_index + 2]
    assert off["line"] == "RELAY 1 OFF" and off["relay"] == "off"
    # the heartbeat window starts at arming, so the cut comes 80 ms after arming (the ON may have come later)
    assert off["monotonic_s"] - armed_at >= 0.08 and off["monotonic_s"] - on["monotonic_s"] < 0.5, \
        "cut by the 80 ms watchdog, not the 900 ms pulse"
    assert not sim.relay_on()
    controller.shutdown()
