"""Speed validation: travel time -> speed -> flag, and the three gate backends."""
import math
import statistics
import sys
import types

import pytest

from rollability_ros.core.config import ConfigError, from_mapping, load_parameters, section
from rollability_ros.core.rig.speed_gate import (GpioSpeedGate, OperatorSpeedGate, SimulatedSpeedGate, SpeedGateConfig,
                                             check_speed, expected_travel_time, make_speed_gate, measure,
                                             parse_travel_time, travel_speed)

RUN_M = 0.34


@pytest.mark.parametrize("target_mps, expected_s", [(0.8, 0.42), (1.5, 0.22)])
def test_paper_expected_travel_times(target_mps, expected_s):
    assert expected_travel_time(RUN_M, target_mps) == pytest.approx(expected_s, abs=0.01)
    assert travel_speed(RUN_M, expected_travel_time(RUN_M, target_mps)) == pytest.approx(target_mps)


def test_tolerance_boundaries():
    assert not check_speed(0.8, 0.8 * 1.149, 0.15)
    assert check_speed(0.8, 0.8 * 1.151, 0.15)
    assert check_speed(1.5, 1.5 * 0.84, 0.15)
    assert not check_speed(1.5, 1.5 * 0.86, 0.15)
    assert not check_speed(0.8, math.nan, 0.15), "not measured is not flagged"


def test_measure_fills_the_outcome_fields():
    slow = measure(0.8, 0.55, RUN_M, 0.15)       # 0.618 m/s: 23 % slow
    assert slow.measured_speed_mps == pytest.approx(0.618, abs=1e-3) and slow.speed_out_of_tolerance
    on_time = measure(1.5, 0.22, RUN_M, 0.15)
    assert not on_time.speed_out_of_tolerance
    missing = measure(0.8, math.nan, RUN_M, 0.15)
    assert math.isnan(missing.travel_time_s) and math.isnan(missing.measured_speed_mps)
    assert not missing.speed_out_of_tolerance


@pytest.mark.parametrize("call, match", [(lambda: travel_speed(0.34, 0.0), "travel_time_s"),
                                         (lambda: travel_speed(-1, 0.4), "run_length_m"),
                                         (lambda: check_speed(0.0, 0.8, 0.15), "target_mps"),
                                         (lambda: check_speed(0.8, 0.8, -0.1), "tolerance")])
def test_bad_input_is_refused(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_simulated_gate_spreads_around_the_target():
    gate = SimulatedSpeedGate(RUN_M, speed_noise_fraction=0.05, seed=3)
    speeds = []
    for _ in range(400):
        gate.arm(1.5)
        speeds.append(travel_speed(RUN_M, gate.read_travel_time(3.0)))
    assert statistics.mean(speeds) == pytest.approx(1.5, rel=0.01)
    assert statistics.stdev(speeds) == pytest.approx(0.075, rel=0.2)
    flagged = sum(check_speed(1.5, s, 0.15) for s in speeds)
    assert flagged <= 4, "3 sigma is the tolerance: almost nothing flagged"
    with pytest.raises(RuntimeError, match="arm"):
        gate.read_travel_time(3.0)


def test_simulated_gate_times_out_on_a_crawl():
    gate = SimulatedSpeedGate(RUN_M)
    gate.arm(0.05)                                # 6.8 s over the run
    assert math.isnan(gate.read_travel_time(3.0))


def test_operator_gate_reprompts_and_accepts_blank():
    answers = iter(["abc", "-1", " 0.43 ", ""])
    prompts = []

    def ask(prompt):
        prompts.append(prompt)
        return next(answers)

    gate = OperatorSpeedGate(ask, RUN_M)
    gate.arm(0.8)
    assert gate.read_travel_time() == 0.43
    assert "expected 0.42 s" in prompts[0]
    assert "must be a number" in prompts[1] and "positive" in prompts[2]
    assert math.isnan(gate.read_travel_time())
    assert math.isnan(parse_travel_time("   "))


class FakeEdgeRequest:
    """Edge events queued by the test, returned in batches like a kernel line request."""

    def __init__(self, batches):
        self.batches = list(batches)
        self.released = False

    def wait_edge_events(self, timeout):
        return bool(self.batches)

    def read_edge_events(self):
        return self.batches.pop(0)

    def release(self):
        self.released = True


def edge(offset, t_s):
    return types.SimpleNamespace(line_offset=offset, timestamp_ns=int(round(t_s * 1e9)))


@pytest.fixture
def fake_gpiod(monkeypatch):
    gpiod = pytest.importorskip("gpiod")
    state = {"batches": [], "requests": []}

    def request_lines(path, config, consumer=None, **_):
        ((offsets, settings),) = config.items()
        request = FakeEdgeRequest(state["batches"])
        state["requests"].append((path, offsets, settings, request))
        return request

    monkeypatch.setitem(sys.modules, "gpiod", types.SimpleNamespace(
        LineSettings=gpiod.LineSettings, line=gpiod.line, request_lines=request_lines))
    return state


def test_gpio_gate_uses_kernel_timestamps(fake_gpiod):
    gpiod = sys.modules["gpiod"]
    gate = GpioSpeedGate("gpiochip1", 22, 23, edge="falling", debounce_ms=2.0)
    gate.arm(0.8)
    path, offsets, settings, request = fake_gpiod["requests"][0]
    assert path == "/dev/gpiochip1" and offsets == (22, 23)
    assert settings.direction == gpiod.line.Direction.INPUT and settings.edge_detection == gpiod.line.Edge.FALLING
    assert settings.debounce_period.total_seconds() == pytest.approx(0.002)
    # an end edge before the start (hand in the far beam) is ignored, then start, a bounce, end
    request.batches[:] = [[edge(23, 9.0)], [edge(22, 10.0), edge(22, 10.001)], [edge(23, 10.4251)]]
    assert gate.read_travel_time(3.0) == pytest.approx(0.4251)
    request.batches[:] = [[edge(22, 20.0)]]
    assert math.isnan(gate.read_travel_time(0.05)), "no end edge: not measured"
    gate.release()
    assert request.released


def test_gpio_gate_arm_drops_stale_edges(fake_gpiod):
    gate = GpioSpeedGate("gpiochip0", 5, 6)
    gate.open()
    request = fake_gpiod["requests"][0][3]
    request.batches[:] = [[edge(5, 1.0)], [edge(6, 1.2)]]
    gate.arm(1.5)
    assert request.batches == []


def test_rig_config_speed_gate_section():
    config = from_mapping(SpeedGateConfig, section(load_parameters("rig"), "speed_gate"), "speed_gate")
    assert (config.run_length_m, config.tolerance_fraction) == (0.34, 0.15)
    assert isinstance(make_speed_gate(config), SimulatedSpeedGate)
    assert config.measure(0.8, 0.30).speed_out_of_tolerance
    for bad, match in [({"backend": "radar"}, "backend"), ({"tolerance_fraction": 1.5}, "tolerance_fraction"),
                       ({"gpio": {"start_line_offset": 3, "end_line_offset": 3}}, "two different offsets >= 0")]:
        with pytest.raises(ConfigError, match=match):
            from_mapping(SpeedGateConfig, bad, "speed_gate")
