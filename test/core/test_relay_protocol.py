"""The relay board's state machine (the simulator's and, line for line, the firmware's) on a given clock."""
import pytest

from rollability_ros.core.rig import relay_protocol
from rollability_ros.core.rig.relay_protocol import RelayDevice


def test_hello_reports_the_limits_and_parses():
    device = RelayDevice(max_pulse_ms=300, keepalive_timeout_ms=200)
    answer, _ = device.handle("HELLO", 0)
    assert relay_protocol.parse_hello(answer) == relay_protocol.DeviceLimits("RVR1", 300, 200)
    with pytest.raises(ValueError, match="protocol 'RVR0'"):
        relay_protocol.parse_hello("OK HELLO RVR0 max_pulse_ms=1 keepalive_timeout_ms=1")


def test_pulse_needs_arming_and_is_capped_and_timed_by_the_board():
    device = RelayDevice(max_pulse_ms=500, keepalive_timeout_ms=250)
    assert device.handle("PULSE 100", 0)[0] == "ERR NOT_ARMED" and not device.relay_on
    assert device.handle("ARM", 0)[0] == "OK ARMED"
    answer, transitions = device.handle("PULSE 9000", 10)
    assert answer == "OK PULSE 500" and transitions == [(True, "PULSE 500")]
    assert device.handle("PULSE 10", 100)[0] == "ERR BUSY"
    for now in range(120, 500, 50):                       # keep-alives through the pulse
        assert device.handle("KA", now)[0] == "OK KA armed=1 relay=1 fault=none"
    assert device.tick(509) == [] and device.relay_on
    assert device.tick(510) == [(False, "pulse end")] and device.armed


def test_silence_while_armed_drops_the_relay_and_disarms():
    device = RelayDevice(max_pulse_ms=500, keepalive_timeout_ms=250)
    device.handle("ARM", 0)
    device.handle("PULSE 500", 100)
    assert device.ms_until_next_deadline(100) == 250
    assert device.tick(349) == []
    assert device.tick(350) == [(False, "keepalive")]
    assert (device.armed, device.fault) == (False, "keepalive")
    assert device.handle("PULSE 10", 360)[0] == "ERR NOT_ARMED"
    assert device.handle("ARM", 370)[0] == "OK ARMED" and device.fault == "none"


def test_estop_button_latches_until_cleared_with_the_button_released():
    device = RelayDevice()
    device.handle("ARM", 0)
    device.handle("PULSE 300", 0)
    assert device.set_estop(True, 5) == [(False, "estop")]
    assert device.handle("ARM", 10)[0] == "ERR ESTOP"
    assert device.handle("CLEAR", 20)[0] == "ERR ESTOP_HELD"
    device.set_estop(False, 30)
    assert device.handle("ARM", 40)[0] == "ERR ESTOP", "still latched after the release"
    assert device.handle("CLEAR", 50)[0] == "OK CLEARED"
    assert device.handle("ARM", 60)[0] == "OK ARMED"


@pytest.mark.parametrize("line", ["", "PULSE", "PULSE -5", "PULSE 0", "PULSE 1e3", "ARM now", "X" * 40, "relay on"])
def test_malformed_lines_change_nothing_and_are_no_keepalive(line):
    device = RelayDevice(keepalive_timeout_ms=100)
    device.handle("ARM", 0)
    answer, _ = device.handle(line, 90)
    assert answer.startswith("ERR") and not device.relay_on
    assert device.tick(100) == [] and not device.armed and device.fault == "keepalive"


def test_state_round_trips():
    state = relay_protocol.DeviceState(True, False, "estop")
    assert relay_protocol.parse_state(relay_protocol.format_state(state)) == state
    with pytest.raises(ValueError):
        relay_protocol.parse_state("armed=2 relay=0 fault=none")


def test_the_simulator_prints_its_port_on_a_ready_line(tmp_path):
    """Issue 45: the simulator printed nothing, so a technician could not tell its port or that it was ready."""
    import os
    import subprocess
    import sys

    from rollability_ros.core.rig.relay_device_sim import READY

    process = subprocess.Popen([sys.executable, "-m", "rollability_ros.core.rig.relay_device_sim"],
                               stdout=subprocess.PIPE, text=True)
    try:
        line = process.stdout.readline()
        assert line.startswith(READY), line
        port = line[len(READY):].split()[0]
        assert os.path.exists(port) and f"valve.serial.port: {port}" in line
    finally:
        process.terminate()
        assert process.wait(10) == 0
