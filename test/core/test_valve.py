"""ValveController: fail-closed paths, refusals and pulse timing against the dry-run backend."""
import threading
import time

import pytest

from rollability_ros.core.config import ConfigError, check_settings, from_mapping, load_parameters, section
from rollability_ros.core.rig.valve import RegulatorCheck, ValveConfig, ValveController
from rollability_ros.core.rig.valve_backends import DryRunBackend, make_controller


class FakeClock:
    """A steady clock the test advances by hand."""

    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now

    def advance(self, seconds):
        self.now += seconds


class FailingBackend(DryRunBackend):
    """Dry-run backend that raises on the commands named in ``fail``."""

    def __init__(self, fail=()):
        super().__init__()
        self.fail = set(fail)

    def _record(self, command):
        super()._record(command)
        if command in self.fail:
            raise OSError(f"{command} broke")


def make(backend=None, max_pulse_ms=200, watchdog_ms=500, clock=None, arm_timeout_s=None):
    backend = backend or DryRunBackend()
    states = []
    controller = ValveController(backend, max_pulse_ms, watchdog_ms, clock=clock or time.monotonic,
                                 on_state=states.append, arm_timeout_s=arm_timeout_s)
    return controller, backend, states


def test_closed_at_start_and_state_published():
    controller, backend, states = make()
    assert backend.commands == ["start", "close"]
    assert len(states) == 1
    assert states[0] == controller.status()
    assert (states[0].armed, states[0].open, states[0].fault, states[0].backend) == (False, False, False, "dry_run")


@pytest.mark.parametrize("pulse_ms, reason", [(0, "> 0"), (-5, "> 0"), (201, "exceeds max_pulse_ms 200"),
                                              (float("nan"), "must be a number"), ("50", "must be a number"),
                                              (True, "must be a number")])
def test_bad_pulse_lengths_are_refused(pulse_ms, reason):
    controller, backend, _ = make()
    controller.arm()
    ok, message = controller.fire(pulse_ms)
    assert not ok and reason in message
    assert "open" not in backend.commands


def test_fire_refused_while_disarmed():
    controller, backend, _ = make()
    ok, message = controller.fire(50)
    assert (ok, message) == (False, "valve is disarmed")
    assert "open" not in backend.commands


def test_pulse_is_cut_at_its_commanded_length():
    controller, backend, states = make()
    assert controller.arm() == (True, "armed")
    ok, message = controller.fire(40)
    assert ok, message
    assert backend.commands[-2:] == ["open", "close"]
    (t_open, _), (t_close, _) = backend.history[-2:]
    held_ms = (t_close - t_open) * 1000.0
    assert 40.0 <= held_ms < 55.0, f"valve held open {held_ms:.2f} ms for a 40 ms pulse"
    status = controller.status()
    assert (status.open, status.pulses, status.last_pulse_ms, status.armed) == (False, 1, 40, True)
    assert [s.open for s in states[-2:]] == [True, False]


def test_max_pulse_is_allowed_and_bounded():
    controller, backend, _ = make(max_pulse_ms=60)
    controller.arm()
    started = time.monotonic()
    assert controller.fire(60)[0]
    assert time.monotonic() - started < 0.09
    assert not controller.fire(61)[0]


def test_disarm_closes_and_refuses_later_fires():
    controller, backend, _ = make()
    controller.arm()
    assert controller.disarm() == (True, "disarmed, valve closed")
    assert backend.commands[-1] == "close"
    assert controller.fire(10) == (False, "valve is disarmed")


def test_estop_latches_until_disarm_then_arm():
    controller, backend, states = make()
    controller.arm()
    controller.estop("operator e-stop")
    assert backend.commands[-1] == "close"
    status = controller.status()
    assert status.fault and status.fault_reason == "operator e-stop" and not status.armed and not status.open
    assert states[-1] == status
    assert controller.fire(10) == (False, "fault latched: operator e-stop")
    ok, message = controller.arm()
    assert not ok and "acknowledge it with a disarm" in message
    assert controller.disarm()[0]
    assert controller.arm() == (True, "armed")
    assert controller.fire(5)[0]


def test_estop_cuts_a_running_pulse():
    controller, backend, _ = make(max_pulse_ms=2000)
    controller.arm()
    result = {}
    firing = threading.Thread(target=lambda: result.update(out=controller.fire(1500)))
    started = time.monotonic()
    firing.start()
    time.sleep(0.05)
    controller.estop()
    firing.join(2.0)
    elapsed = time.monotonic() - started
    ok, message = result["out"]
    assert not ok and "pulse cut after" in message and "e-stop" in message
    assert elapsed < 0.5
    assert backend.commands[-1] == "close" and not controller.status().open
    assert controller.status().last_pulse_ms < 500


def test_second_fire_during_a_pulse_is_refused():
    controller, _, _ = make()
    controller.arm()
    firing = threading.Thread(target=controller.fire, args=(150,))
    firing.start()
    time.sleep(0.03)
    assert controller.fire(10) == (False, "a pulse is already in progress")
    firing.join()


def test_watchdog_trips_on_fake_steady_clock():
    clock = FakeClock()
    controller, backend, states = make(clock=clock, watchdog_ms=500)
    clock.advance(60.0)
    assert not controller.check_watchdog(), "a disarmed valve needs no heartbeat"
    controller.arm()
    clock.advance(0.4)
    assert not controller.check_watchdog()
    controller.heartbeat()
    clock.advance(0.5)
    assert not controller.check_watchdog(), "exactly watchdog_ms of silence is still allowed"
    clock.advance(0.001)
    assert controller.check_watchdog()
    status = controller.status()
    assert status.fault and status.fault_reason.startswith("watchdog: no rig heartbeat for 501 ms")
    assert backend.commands[-1] == "close" and states[-1] == status
    assert not controller.check_watchdog(), "a latched fault trips once"
    assert controller.fire(10)[1].startswith("fault latched: watchdog")


def test_an_arming_that_fires_nothing_times_out_to_disarmed():
    """Issue 45: a manual `rollability rig arm` left the valve armed and idle for 34 s, kept alive by the rig's
    heartbeats; now an armed valve that fires nothing for valve.arm_timeout_s is disarmed (no fault to clear)."""
    clock = FakeClock()
    controller, backend, states = make(clock=clock, watchdog_ms=500, arm_timeout_s=15.0)
    controller.arm()
    for _ in range(149):                      # 14.9 s of heartbeats: still armed
        clock.advance(0.1)
        controller.heartbeat()
        controller.check_watchdog()
    assert controller.status().armed
    assert controller.fire(10)[0]             # a pulse restarts the idle window
    clock.advance(14.0)
    controller.heartbeat()
    controller.check_watchdog()
    assert controller.status().armed
    clock.advance(1.1)
    controller.heartbeat()
    assert not controller.check_watchdog()    # not a trip: a timeout to disarmed
    status = controller.status()
    assert not status.armed and not status.fault and not status.open and backend.commands[-1] == "close"
    assert controller.fire(10) == (False, "valve is disarmed")
    assert controller.arm() == (True, "armed")   # arming again needs no acknowledgement
    with pytest.raises(ValueError, match="arm_timeout_s"):
        make(arm_timeout_s=0.0)
    config = ValveConfig(arm_timeout_s=float("nan"))
    with pytest.raises(ValueError, match=r"^valve.arm_timeout_s out of range: nan is not in \[0.1, 3600.0\]$"):
        check_settings(config, "valve")
    built = make_controller(ValveConfig(arm_timeout_s=2.5))
    assert built.arm_timeout_s == 2.5
    built.shutdown()


def test_watchdog_thread_trips_on_the_real_clock():
    controller, backend, states = make(watchdog_ms=60, max_pulse_ms=2000)
    controller.start_watchdog(0.005)
    controller.arm()
    for _ in range(10):  # 200 ms of regular heartbeats: no trip
        controller.heartbeat()
        time.sleep(0.02)
    assert not controller.status().fault
    result = {}
    firing = threading.Thread(target=lambda: result.update(out=controller.fire(1000)))
    controller.heartbeat()
    last_heartbeat = time.monotonic()
    firing.start()
    firing.join(2.0)
    trip_latency = time.monotonic() - last_heartbeat
    ok, message = result["out"]
    assert not ok and "watchdog" in message
    assert 0.06 <= trip_latency < 0.3, f"watchdog closed the valve {trip_latency * 1000:.0f} ms after the last beat"
    assert backend.commands[-1] == "close" and controller.status().fault
    controller.shutdown()


def test_shutdown_closes_releases_and_refuses():
    controller, backend, states = make()
    controller.arm()
    controller.shutdown()
    assert backend.commands[-3:] == ["close", "close", "release"]
    assert not states[-1].armed and not states[-1].open
    assert controller.fire(10) == (False, "valve controller is shut down")
    assert controller.arm()[0] is False
    controller.shutdown()
    assert backend.commands[-1] == "release", "shutdown is idempotent"


def test_backend_error_on_open_faults_and_closes():
    backend = FailingBackend(fail={"open"})
    controller, _, _ = make(backend=backend)
    controller.arm()
    ok, message = controller.fire(20)
    assert not ok and message == "backend error on open: open broke"
    assert backend.commands[-2:] == ["open", "close"]
    status = controller.status()
    assert status.fault and not status.open and not status.armed


def test_backend_error_on_close_leaves_the_valve_reported_open():
    backend = FailingBackend()
    controller, _, _ = make(backend=backend)
    controller.arm()
    backend.fail = {"close"}
    ok, message = controller.fire(10)
    assert not ok and "backend error on close: close broke" in message
    status = controller.status()
    assert status.open and status.fault, "a valve whose close failed is not known to be closed"
    ok, message = controller.disarm()
    assert not ok and "close command failed" in message and controller.status().fault
    backend.fail = set()
    assert controller.disarm() == (True, "disarmed, valve closed")
    assert not controller.status().open and not controller.status().fault


def test_backend_that_cannot_start_faults_until_it_can():
    backend = FailingBackend(fail={"start"})
    controller, _, states = make(backend=backend)
    assert states[-1].fault and "start broke" in states[-1].fault_reason
    assert not controller.arm()[0]
    backend.fail = set()
    assert controller.disarm()[0]
    assert backend.commands[-2:] == ["start", "close"]
    assert controller.arm()[0]


def test_exception_during_pulse_still_closes():
    controller, backend, _ = make()
    controller.arm()

    def interrupted(_timeout):
        raise KeyboardInterrupt

    controller._cut.wait = interrupted
    with pytest.raises(KeyboardInterrupt):
        controller.fire(50)
    assert backend.commands[-2:] == ["open", "close"] and not controller.status().open


def test_broken_state_callback_does_not_keep_the_valve_open():
    backend = DryRunBackend()

    def broken(_status):
        raise RuntimeError("publisher gone")

    controller = ValveController(backend, 100, 500, on_state=broken)
    controller.arm()
    assert controller.fire(5)[0]
    controller.estop()
    assert backend.commands[-1] == "close"


def test_state_changes_are_logged(caplog):
    caplog.set_level("INFO", logger="rollability_ros.core.rig.valve")
    controller, _, _ = make()
    controller.arm()
    controller.estop("test stop")
    messages = [r.getMessage() for r in caplog.records]
    assert any("valve armed" in m for m in messages)
    assert any("valve e-stop" in m and "test stop" in m for m in messages)


def test_rig_config_valve_section_loads_and_validates():
    params = load_parameters("rig")
    config = from_mapping(ValveConfig, section(params, "valve"), "valve")
    assert config.backend == "dry_run" and 0 < config.launch_pulse_ms <= config.max_pulse_ms
    assert config.regulator.pressure_psi(0.8) == 30.0 and config.regulator.pressure_psi(1.5) == 60.0
    with pytest.raises(ValueError, match="no regulator pressure configured for 1.1 m/s"):
        config.regulator.pressure_psi(1.1)
    for bad, match in [({"backend": "laser"}, "backend must be one of"),
                       ({"launch_pulse_ms": 900, "max_pulse_ms": 500}, "launch_pulse_ms must be at most max_pulse_ms"),
                       ({"heartbeat_period_ms": 400, "watchdog_ms": 500}, "heartbeat_period_ms"),
                       ({"serial": {"line_ending": "\n"}}, "line_ending"),
                       ({"regulator": {"speeds_mps": [0.8], "pressures_psi": [30.0, 60.0]}}, "equally long"),
                       ({"max_pulse_ms": "lots"}, "expected an integer")]:
        with pytest.raises(ConfigError, match=match):
            from_mapping(ValveConfig, bad, "valve")


def test_regulator_check_asks_once_per_speed_block():
    check = RegulatorCheck(ValveConfig().regulator)
    assert check.pending_psi(0.8) == 30.0
    check.confirm(0.8)
    assert check.pending_psi(0.8) is None
    assert check.pending_psi(1.5) == 60.0
    check.confirm(1.5)
    assert check.pending_psi(0.8) == 30.0


def test_make_controller_runs_the_watchdog():
    config = ValveConfig(watchdog_ms=40, watchdog_check_ms=5, heartbeat_period_ms=10)
    controller = make_controller(config)
    try:
        controller.arm()
        time.sleep(0.15)
        assert controller.status().fault_reason.startswith("watchdog")
    finally:
        controller.shutdown()


def test_rig_side_core_imports_without_heavy_or_hardware_packages():
    """The robot computer may lack pybullet, trimesh, matplotlib, ray, scipy, and even pyserial / gpiod."""
    import os
    import subprocess
    import sys

    blocked = ["pybullet", "trimesh", "matplotlib", "ray", "scipy", "cma", "serial", "gpiod", "rclpy"]
    script = (
        "import sys\n"
        f"for name in {blocked!r}: sys.modules[name] = None\n"
        "import rollability_ros.core.rig.valve, rollability_ros.core.rig.valve_backends, rollability_ros.core.rig.speed_gate\n"
        "import rollability_ros.core.imu.upright, rollability_ros.core.imu.tip_tracker, rollability_ros.core.rig.relay_device_sim\n"
        "from rollability_ros.core.rig.valve import ValveConfig\n"
        "from rollability_ros.core.rig.valve_backends import make_controller\n"
        "c = make_controller(ValveConfig()); c.arm(); assert c.fire(5)[0]; c.shutdown()\n"
    )
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")])))
    result = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr


class StuckBackend(DryRunBackend):
    """Dry-run backend whose ``close_valve`` blocks while ``jam`` is set (a write into a board that takes no bytes)."""

    call_timeout_s = 0.6

    def __init__(self):
        super().__init__()
        self.jam = threading.Event()
        self.unjam = threading.Event()

    def close_valve(self):
        if self.jam.is_set():
            self.unjam.wait(30)
        super().close_valve()


def test_a_stuck_backend_call_latches_a_fault_in_bounded_time_and_never_blocks_health():
    controller, backend, states = make(StuckBackend())
    assert controller.arm()[0]
    backend.jam.set()
    answer = []
    started = time.monotonic()
    disarm = threading.Thread(target=lambda: answer.append(controller.disarm()))
    disarm.start()
    time.sleep(0.2)                     # the disarm holds the lock, waiting for the stuck close
    t0 = time.monotonic()
    status, _margin, link = controller.health()
    controller.heartbeat()
    assert time.monotonic() - t0 < 0.3, "health() / heartbeat() waited for the stuck backend call"
    assert "backend call close_valve running for" in link and status.armed   # the last state, said to be stale
    disarm.join(5)
    took_s = time.monotonic() - started
    assert 0.55 < took_s < 1.5, took_s   # bounded by call_timeout_s
    ok, message = answer[0]
    assert not ok and "close_valve did not return within 0.6 s" in message
    assert states[-1].fault and not states[-1].armed
    # later calls are refused at once while the stuck one has not returned; arming is refused (fault latched)
    t0 = time.monotonic()
    controller.estop("e-stop")
    assert time.monotonic() - t0 < 0.3 and "still stuck in close_valve" in controller.status().fault_reason
    assert not controller.arm()[0] and not controller.fire(50)[0]
    closes = backend.commands.count("close")
    backend.unjam.set()                 # the call returns at last: the valve is driven closed once more
    deadline = time.monotonic() + 5
    while backend.commands.count("close") < closes + 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert backend.commands.count("close") >= closes + 2   # the stuck one, then the controller's own
    assert controller.status().fault and not controller.status().open
    backend.jam.clear()
    assert controller.disarm() == (True, "disarmed, valve closed") and not controller.status().fault
    controller.shutdown()
