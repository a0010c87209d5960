"""The rig's declared seams (issue 29): valve backends, speed gates and launch backends are reached only through
their contracts and tables; a new board is one class plus one registration line, and it works through the same
factory, controller and refusals as the shipped ones."""
import math
import pathlib
import re
import threading

import pytest

from rollability_ros.core.registry import Registry
from rollability_ros.core.rig import valve_boards
from rollability_ros.core.rig.launch_backend import LaunchBackend
from rollability_ros.core.rig.launch_backend import LAUNCH_BACKENDS
from rollability_ros.core.rig.rig_session import PhysicalLaunch, SimulatedLaunch
from rollability_ros.core.rig.speed_gate import SPEED_GATES, SpeedGate, SpeedGateConfig, make_speed_gate
from rollability_ros.core.rig.valve import ValveController
from rollability_ros.core.rig.valve_contract import ValveConfig
from rollability_ros.core.rig import VALVE_BACKENDS, ValveBackend, register_valve_backend

RIG = pathlib.Path(__file__).resolve().parents[2] / "rollability_ros" / "core" / "rig"


class RecordingBoard(ValveBackend):
    """A board written for this test only: records every call, arms on the device, can report a fault itself."""

    name = "recording"

    def __init__(self, refuse=""):
        self.calls = []
        self.refuse = refuse
        self.listener = None

    @classmethod
    def from_config(cls, config):
        return cls()

    def open(self):
        self.calls.append("open")

    def open_valve(self, pulse_ms=None):
        self.calls.append(f"open_valve {pulse_ms}")

    def close_valve(self):
        self.calls.append("close_valve")

    def release(self):
        self.calls.append("release")

    def arm(self):
        self.calls.append("arm")

    def disarm(self):
        self.calls.append("disarm")

    def fire_refusal(self):
        return self.refuse

    def set_fault_listener(self, callback):
        self.listener = callback

    def link_state(self):
        return "recording: ok"


@pytest.fixture
def recording_board():
    register_valve_backend("recording", RecordingBoard)   # the one registration line
    try:
        yield
    finally:
        VALVE_BACKENDS.unregister("recording")


def test_valve_controller_never_probes_its_backend():
    source = (RIG / "valve.py").read_text()
    assert not re.findall(r"\b(hasattr|getattr)\(", source)
    assert "BACKENDS" not in source.replace("VALVE_BACKENDS", "")   # no second list of backend names


def test_backend_names_are_looked_at_only_by_the_tables():
    for module in ("valve.py", "valve_boards.py", "speed_gate.py", "launch_backend.py"):
        source = (RIG / module).read_text()
        assert not re.findall(r"backend (==|!=|in) ", source), module
    campaign = (RIG.parents[1] / "cli" / "campaign.py").read_text()
    assert not re.findall(r"backend (==|!=) ", campaign)


def test_a_board_registered_from_one_module_runs_through_the_factory(recording_board):
    config = ValveConfig(backend="recording")
    config.validate()
    states = []
    controller = valve_boards.make_controller(config, on_state=states.append)
    try:
        board = controller._backend
        assert isinstance(board, RecordingBoard)
        assert board.calls == ["open", "close_valve", "disarm"]
        assert controller.arm() == (True, "armed")
        assert controller.fire(30) == (True, "fired 30 ms")
        assert board.calls[3:] == ["arm", "open_valve 30", "close_valve"]
        assert controller.health()[2] == "recording: ok"
        assert states[-1].backend == "recording" and states[-1].pulses == 1
        board.listener("board e-stop")                 # the device reports a fault of its own
        status = controller.status()
        assert status.fault and "device: board e-stop" in status.fault_reason and not status.armed
        assert board.calls[-2:] == ["close_valve", "disarm"]
    finally:
        controller.shutdown()
    assert board.calls[-1] == "release"


def test_a_board_refusal_is_honoured_and_unknown_names_are_refused(recording_board):
    controller = ValveController(RecordingBoard(refuse="no limiter wired"), 100, 500)
    try:
        assert controller.arm()[0]
        assert controller.fire(10) == (False, "no limiter wired")
        assert "open_valve 10" not in controller._backend.calls
    finally:
        controller.shutdown()
    with pytest.raises(ValueError, match=r"^backend must be one of \('dry_run', 'gpio', 'serial_relay', "
                                         r"'recording'\), got 'nope'$"):
        ValveConfig(backend="nope").validate()
    with pytest.raises(ValueError, match="already registered"):
        register_valve_backend("recording", RecordingBoard)


def test_the_contract_is_declared_not_guessed():
    with pytest.raises(TypeError, match="must be a ValveBackend"):
        ValveController(object(), 100, 500)
    with pytest.raises(TypeError, match="non-empty class attribute name"):
        type("Nameless", (valve_boards.DryRunBackend,), {"name": ""})
    with pytest.raises(TypeError, match="abstract"):
        type("Half", (ValveBackend,), {"name": "half", "open": lambda self: None})()
    defaults = valve_boards.DryRunBackend()   # a board without the optional features gets the defaults
    assert (defaults.fire_refusal(), defaults.stalled(), defaults.startup_warning(), defaults.limits) == ("", "", "",
                                                                                                         None)
    assert defaults.link_state() == "dry_run: no device"
    table = Registry("backend", ValveBackend, {"bad": "rollability_ros.core.rig.speed_gate:SimulatedSpeedGate"})
    with pytest.raises(TypeError, match="not a ValveBackend"):
        table.get("bad")
    assert VALVE_BACKENDS.get("gpio") is valve_boards.GpioHolderBackend
    gpio = ValveConfig(backend="gpio")
    assert type(valve_boards.make_valve_backend(gpio)) is valve_boards.GpioHolderBackend
    gpio.gpio.line_holder = False
    assert type(VALVE_BACKENDS.get("gpio").from_config(gpio)) is valve_boards.GpioBackend
    assert "every fire is refused" in VALVE_BACKENDS.get("gpio").from_config(gpio).startup_warning()


class FixedGate(SpeedGate):
    """A gate written for this test only: every launch takes ``travel_s``."""

    def __init__(self, travel_s):
        self.travel_s = travel_s
        self.armed_at = None

    @classmethod
    def from_config(cls, config, ask):
        return cls(float(ask("travel time?")))

    def arm(self, target_mps):
        self.armed_at = target_mps

    def read_travel_time(self, timeout_s):
        return self.travel_s if self.travel_s <= timeout_s else math.nan


def test_a_speed_gate_registered_from_one_module_runs_through_the_factory():
    SPEED_GATES.register("fixed", FixedGate)
    try:
        config = SpeedGateConfig(backend="fixed")
        config.validate()
        gate = make_speed_gate(config, ask=lambda prompt: "0.5")
        gate.arm(0.8)
        assert (gate.armed_at, gate.read_travel_time(3.0)) == (0.8, 0.5)
        gate.release()                                   # the contract's default
    finally:
        SPEED_GATES.unregister("fixed")
    with pytest.raises(ValueError, match=r"^backend must be one of \('simulated', 'gpio', 'operator'\), got 'fixed'$"):
        SpeedGateConfig(backend="fixed").validate()
    shipped = make_speed_gate(SpeedGateConfig(backend="operator"), ask=lambda prompt: "0.4")
    shipped.arm(0.8)
    assert shipped.read_travel_time(3.0) == 0.4


def test_resimulating_is_a_declared_capability_of_the_launch_backend():
    assert SimulatedLaunch.resimulate_refusal() == ""
    refusal = PhysicalLaunch.resimulate_refusal()
    assert refusal == "a physical launch cannot be re-run: it has no twin seed"
    backend = PhysicalLaunch.__new__(PhysicalLaunch)      # the default method refuses without touching a port
    with pytest.raises(ValueError, match=re.escape(refusal)):
        backend.resimulate(None, 1)
    assert [name for name in LAUNCH_BACKENDS.names() if not LAUNCH_BACKENDS.get(name).resimulate_refusal()] == ["sim"]
    with pytest.raises(TypeError, match="does not implement from_ports"):
        type("Bare", (LaunchBackend,), {"name": "bare"}).from_ports(None, None, None, None, None)


def test_the_recording_board_is_bounded_like_any_other(recording_board):
    """A backend call that blocks is bounded by the contract's call_timeout_s default (2 s) unless declared."""
    class SlowBoard(RecordingBoard):
        call_timeout_s = 0.3

        def __init__(self):
            super().__init__()
            self.release_gate = threading.Event()

        def arm(self):
            self.release_gate.wait(5)

    controller = ValveController(SlowBoard(), 100, 500)
    try:
        ok, reason = controller.arm()
        assert not ok and "did not return within 0.3 s" in reason
    finally:
        controller._backend.release_gate.set()
        controller.shutdown()
