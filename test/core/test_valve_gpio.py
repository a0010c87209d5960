"""The gpio backend against a fake ``gpiod`` module (no /dev/gpiochip and no gpio-sim kernel module here).

The fake replaces only ``gpiod.request_lines``; line settings and values are the real libgpiod v2 Python types,
so a wrong keyword or enum in the backend fails here as it would on a robot.
"""
import sys
import types

import pytest

from rollability_ros.core.optional import MissingDependency
from rollability_ros.core.rig.valve import ValveController
from rollability_ros.core.rig.valve_boards import GpioBackend

gpiod = pytest.importorskip("gpiod")
ACTIVE, INACTIVE = gpiod.line.Value.ACTIVE, gpiod.line.Value.INACTIVE


class FakeRequest:
    """A line request that records the values driven onto each line, starting with the requested output value."""

    def __init__(self, path, config, consumer):
        self.path, self.consumer = path, consumer
        self.settings = {}
        self.values = {}
        for offset, settings in config.items():
            assert isinstance(settings, gpiod.LineSettings)
            self.settings[offset] = settings
            self.values[offset] = [settings.output_value]
        self.released = False

    def set_value(self, offset, value):
        assert not self.released, "set_value after release"
        assert isinstance(value, gpiod.line.Value)
        self.values[offset].append(value)

    def release(self):
        self.released = True


@pytest.fixture
def fake_gpiod(monkeypatch):
    requests = []

    def request_lines(path, config, consumer=None, event_buffer_size=None, output_values=None):
        requests.append(FakeRequest(path, config, consumer))
        return requests[-1]

    module = types.SimpleNamespace(LineSettings=gpiod.LineSettings, line=gpiod.line, request_lines=request_lines)
    monkeypatch.setitem(sys.modules, "gpiod", module)
    return requests


@pytest.mark.parametrize("active_high", [True, False])
def test_line_requested_closed_and_driven_closed(fake_gpiod, active_high):
    controller = ValveController(GpioBackend("gpiochip2", 5, active_high=active_high, hardware_pulse_limiter=True),
                                 200, 500)
    (request,) = fake_gpiod
    assert request.path == "/dev/gpiochip2"
    settings = request.settings[5]
    assert settings.direction == gpiod.line.Direction.OUTPUT
    assert settings.active_low is (not active_high)
    assert request.values[5] == [INACTIVE, INACTIVE], "inactive from the request on, then closed explicitly"
    controller.arm()
    assert controller.fire(10)[0]
    assert request.values[5][-2:] == [ACTIVE, INACTIVE]
    controller.estop()
    controller.shutdown()
    assert request.values[5][-1] == INACTIVE and request.released
    assert request.values[5][-2:] == [INACTIVE, INACTIVE], "driven closed before the release"


def test_gpio_error_faults_the_controller(fake_gpiod):
    controller = ValveController(GpioBackend("/dev/gpiochip0", 3, hardware_pulse_limiter=True), 200, 500)
    (request,) = fake_gpiod

    def broken(offset, value):
        raise OSError("line lost")

    controller.arm()
    request.set_value = broken
    ok, message = controller.fire(10)
    assert not ok and "backend error on open: line lost" in message
    assert controller.status().fault


def test_without_a_declared_hardware_limiter_it_warns_at_start_and_never_fires(fake_gpiod, caplog):
    controller = ValveController(GpioBackend("gpiochip0", 4), 200, 500)
    (request,) = fake_gpiod
    assert "nothing in software can close the valve" in caplog.text and "every fire is refused" in caplog.text
    assert controller.arm()[0]
    ok, message = controller.fire(10)
    assert not ok and "hardware_pulse_limiter" in message
    assert ACTIVE not in request.values[4], "the line was never driven active"
    assert not controller.status().fault, "a refusal, not a fault"
    controller.shutdown()


def test_missing_chip_with_the_real_library_faults_at_start():
    controller = ValveController(GpioBackend("/dev/gpiochip-does-not-exist", 0), 200, 500)
    status = controller.status()
    assert status.fault and "backend error on close" in status.fault_reason and not status.open
    assert not controller.arm()[0]


def test_missing_gpiod_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "gpiod", None)
    with pytest.raises(MissingDependency, match=r"rollability_ros\[hardware\]"):
        GpioBackend("gpiochip0", 1).open()
