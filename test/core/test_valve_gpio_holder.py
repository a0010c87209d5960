"""The gpio backend's line holder: a child process that owns the line and drops it when the valve_controller dies.

The holder runs a stand-in ``gpiod`` (test/resources/fake_gpiod) that logs every line value with its time.
"""
import json
import os
import pathlib
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from rollability_ros.core.rig.valve import ValveController
from rollability_ros.core.rig.valve_boards import GpioHolderBackend

FAKE_GPIOD = pathlib.Path(__file__).resolve().parents[1] / "resources" / "fake_gpiod"


@pytest.fixture
def line_log(tmp_path, monkeypatch):
    log = tmp_path / "gpio.jsonl"
    monkeypatch.setenv("FAKE_GPIOD_LOG", str(log))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(FAKE_GPIOD), os.environ.get("PYTHONPATH")])))

    def entries():
        return [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []
    return entries


def values(entries):
    return [e["value"] for e in entries if e["event"] in ("request", "set")]


def test_holder_requests_inactive_pulses_and_releases(line_log):
    controller = ValveController(GpioHolderBackend("gpiochip3", 9, hardware_pulse_limiter=True), 500, 2000)
    assert not controller.status().fault, controller.status().fault_reason
    assert controller.arm()[0]
    ok, message = controller.fire(60)
    assert ok, message
    controller.shutdown()
    entries = line_log()
    assert entries[0]["event"] == "request" and entries[0]["value"] == "inactive" and entries[0]["offset"] == 9
    assert entries[0]["pid"] != os.getpid(), "the line belongs to the holder process"
    assert entries[-1]["event"] == "release" and values(entries)[-1] == "inactive"
    on = next(e for e in entries if e.get("value") == "active")
    off = next(e for e in entries if e.get("value") == "inactive" and e["monotonic_s"] > on["monotonic_s"])
    assert 0.05 <= off["monotonic_s"] - on["monotonic_s"] < 0.2


def test_without_a_declared_limiter_the_holder_never_drives_the_line(line_log):
    controller = ValveController(GpioHolderBackend("gpiochip3", 9), 500, 2000)
    assert controller.arm()[0]
    ok, message = controller.fire(60)
    assert not ok and "hardware_pulse_limiter" in message
    controller.shutdown()
    assert "active" not in values(line_log())


DYING_CONTROLLER = textwrap.dedent("""
    from rollability_ros.core.rig.valve import ValveController
    from rollability_ros.core.rig.valve_boards import GpioHolderBackend
    controller = ValveController(GpioHolderBackend("gpiochip3", 9, hardware_pulse_limiter=True, max_pulse_ms=5000),
                                 5000, 60000)
    controller.arm()
    controller.fire(3000)
""")


def test_sigkilled_valve_controller_mid_pulse_the_holder_drops_the_line(line_log):
    process = subprocess.Popen([sys.executable, "-c", DYING_CONTROLLER])
    try:
        deadline = time.monotonic() + 30
        while "active" not in values(line_log()):
            assert time.monotonic() < deadline and process.poll() is None, "never fired"
            time.sleep(0.01)
        killed_at = time.monotonic()
        process.send_signal(signal.SIGKILL)
        process.wait(10)
    finally:
        process.kill()
    deadline = time.monotonic() + 5
    while not line_log() or line_log()[-1]["event"] != "release":
        assert time.monotonic() < deadline, "the holder did not release the line"
        time.sleep(0.01)
    entries = line_log()
    on = next(e for e in entries if e.get("value") == "active")
    assert values(entries)[-1] == "inactive"
    held_s = entries[-1]["monotonic_s"] - on["monotonic_s"]
    print(f"gpio line holder: line active {held_s * 1000:.0f} ms from pulse start, inactive "
          f"{(entries[-1]['monotonic_s'] - killed_at) * 1000:.0f} ms after the controller's SIGKILL")
    assert held_s < 1.0, f"line held {held_s:.2f} s of a 3 s pulse after the controller's SIGKILL"
