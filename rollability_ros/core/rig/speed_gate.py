"""Launch speed validation: travel time over the launch run -> measured speed -> flagged when off target.

The chassis crosses two light gates ``run_length_m`` apart (the 0.34 m run to the edge, paper 2.2); the travel
time between them gives the measured speed. Gates implement :class:`SpeedGate` (``arm(target_mps)`` before firing,
``read_travel_time(timeout_s) -> s``, NaN when not measured, and ``release()``): :class:`SimulatedSpeedGate`
(target speed plus noise), :class:`GpioSpeedGate` (two libgpiod lines, kernel edge timestamps) and
:class:`OperatorSpeedGate` (typed in), listed in :data:`SPEED_GATES`; :func:`make_speed_gate` is the only place
that looks at ``speed_gate.backend``. Adding a gate: one module with a ``SpeedGate`` subclass (and its
``from_config``) plus one ``"name": "package.module:Class"`` line in :data:`SPEED_GATES`.
"""
import abc
import dataclasses
import datetime
import logging
import math
import random
import time
import typing

from rollability_ros.core.optional import require
from rollability_ros.core.registry import Registry
from rollability_ros.core.records import NOT_MEASURED
from rollability_ros.core.rig.valve_backends import gpio_chip_path

_LOG = logging.getLogger(__name__)


def _positive(name, value):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")


def travel_speed(run_length_m: float, travel_time_s: float) -> float:
    """Return the mean speed (m/s) over ``run_length_m`` (m) covered in ``travel_time_s`` (s)."""
    _positive("run_length_m", run_length_m)
    _positive("travel_time_s", travel_time_s)
    return run_length_m / travel_time_s


def expected_travel_time(run_length_m: float, target_mps: float) -> float:
    """Return the travel time (s) over ``run_length_m`` (m) at ``target_mps`` (m/s): 0.34 m at 0.8 m/s -> 0.425 s."""
    _positive("run_length_m", run_length_m)
    _positive("target_mps", target_mps)
    return run_length_m / target_mps


def check_speed(target_mps: float, measured_mps: float, tolerance: float) -> bool:
    """Return True (flagged) when ``measured_mps`` is more than ``tolerance`` (fraction) off ``target_mps``.

    A NaN measurement (not measured) is not flagged: the outcome's NaN speed already says so.
    """
    _positive("target_mps", target_mps)
    if not 0 <= tolerance < math.inf:
        raise ValueError(f"tolerance must be a fraction >= 0, got {tolerance!r}")
    if math.isnan(measured_mps):
        return False
    return abs(measured_mps - target_mps) > tolerance * target_mps


@dataclasses.dataclass(frozen=True)
class SpeedMeasurement:
    """The speed fields of a launch outcome (``LaunchOutcome`` names)."""

    travel_time_s: float
    measured_speed_mps: float
    speed_out_of_tolerance: bool


def measure(target_mps: float, travel_time_s: float, run_length_m: float, tolerance: float) -> "SpeedMeasurement":
    """Turn a travel time (s, NaN if not measured) into a :class:`SpeedMeasurement` for a launch at ``target_mps``."""
    if math.isnan(travel_time_s):
        return SpeedMeasurement(NOT_MEASURED, NOT_MEASURED, False)
    speed_mps = travel_speed(run_length_m, travel_time_s)
    return SpeedMeasurement(travel_time_s, speed_mps, check_speed(target_mps, speed_mps, tolerance))


class SpeedGate(abc.ABC):
    """One source of launch travel times (the contract the physical launch calls).

    ``measures``: True when its travel times are measurements of the real run; a gate that makes them up
    (:class:`SimulatedSpeedGate`) says False, and a physical launch then stores its speed as not measured.
    """

    measures: bool = True
    #: How an outcome's note names this gate as the source of its travel time.
    source: str = "the light gates"

    @classmethod
    @abc.abstractmethod
    def from_config(cls, config: "SpeedGateConfig", ask: typing.Callable[[str], str]) -> "SpeedGate":
        """The gate for ``config`` (:class:`SpeedGateConfig`); ``ask(prompt) -> str`` reaches the operator."""

    @abc.abstractmethod
    def arm(self, target_mps: float) -> None:
        """Prepare for a launch at ``target_mps`` (m/s), before the valve fires."""

    @abc.abstractmethod
    def read_travel_time(self, timeout_s: float) -> float:
        """The travel time over the run of the armed launch, s; NaN when not measured within ``timeout_s`` (s)."""

    def release(self) -> None:
        """Free what the gate holds (default: nothing)."""


class SimulatedSpeedGate(SpeedGate):
    """Edge times of a chassis launched at the target speed times ``1 + N(0, speed_noise_fraction)``: made up, so
    ``measures`` is False (a physical record never stores them as its speed)."""

    measures = False
    source = "the simulated speed gate (speed_gate.backend simulated)"

    def __init__(self, run_length_m, speed_noise_fraction=0.0, seed=0, clock=time.monotonic):
        _positive("run_length_m", run_length_m)
        if not 0 <= speed_noise_fraction < 1:
            raise ValueError(f"speed_noise_fraction must be in [0, 1), got {speed_noise_fraction!r}")
        self.run_length_m = run_length_m
        self.speed_noise_fraction = speed_noise_fraction
        self._random = random.Random(seed)
        self._clock = clock
        self._target_mps = None

    @classmethod
    def from_config(cls, config: "SpeedGateConfig", ask: typing.Callable[[str], str]) -> "SpeedGate":
        """Noise and seed from ``speed_gate.simulated.*``."""
        return cls(config.run_length_m, config.simulated.speed_noise_fraction, config.simulated.seed)

    def arm(self, target_mps: float) -> None:
        """Prepare for a launch at ``target_mps`` (m/s)."""
        _positive("target_mps", target_mps)
        self._target_mps = target_mps

    def edge_times(self) -> typing.Tuple[float, float]:
        """Return ``(start_s, end_s)`` gate edges (steady clock, s) of the armed launch, starting now."""
        if self._target_mps is None:
            raise RuntimeError("arm(target_mps) the simulated speed gate before reading it")
        speed_mps = self._target_mps * max(0.05, 1.0 + self._random.gauss(0.0, self.speed_noise_fraction))
        start_s = self._clock()
        return start_s, start_s + self.run_length_m / speed_mps

    def read_travel_time(self, timeout_s: float) -> float:
        """Travel time (s) of the armed launch; NaN if it would exceed ``timeout_s``. Does not sleep."""
        start_s, end_s = self.edge_times()
        self._target_mps = None
        travel_time_s = end_s - start_s
        return travel_time_s if travel_time_s <= timeout_s else NOT_MEASURED


def _check_gate_lines(start_line_offset, end_line_offset, edge, debounce_ms):
    if start_line_offset == end_line_offset or min(start_line_offset, end_line_offset) < 0:
        raise ValueError(f"start_line_offset and end_line_offset must be two different offsets >= 0, got "
                         f"{start_line_offset} and {end_line_offset}")
    if edge not in ("falling", "rising"):
        raise ValueError(f"edge must be 'falling' or 'rising', got {edge!r}")
    if not 0 <= debounce_ms < math.inf:
        raise ValueError(f"debounce_ms must be >= 0, got {debounce_ms}")


class GpioSpeedGate(SpeedGate):
    """Two light gates on GPIO input lines; the travel time comes from the kernel's edge-event timestamps.

    Parameters
    ----------
    chip : str
        GPIO chip device, ``/dev/gpiochipN`` or ``gpiochipN``.
    start_line_offset, end_line_offset : int
        Lines of the gate at the start of the run and of the gate at the edge.
    edge : str
        ``"falling"`` or ``"rising"``: the edge a broken beam produces.
    debounce_ms : float
        Kernel debounce period of both lines, ms (0 disables).
    """

    def __init__(self, chip, start_line_offset, end_line_offset, edge="falling", debounce_ms=1.0,
                 consumer="rollability-speed-gate"):
        _check_gate_lines(start_line_offset, end_line_offset, edge, debounce_ms)
        self.chip_path = gpio_chip_path(chip)
        self.start_line_offset = start_line_offset
        self.end_line_offset = end_line_offset
        self.edge = edge
        self.debounce_ms = debounce_ms
        self.consumer = consumer
        self._request = None

    @classmethod
    def from_config(cls, config: "SpeedGateConfig", ask: typing.Callable[[str], str]) -> "SpeedGate":
        """The lines of ``speed_gate.gpio.*``."""
        g = config.gpio
        return cls(g.chip, g.start_line_offset, g.end_line_offset, g.edge, g.debounce_ms)

    def open(self) -> None:
        """Request both lines as inputs with edge detection and monotonic event timestamps."""
        gpiod = require("gpiod", feature="the gpio speed gate")
        settings = gpiod.LineSettings(
            direction=gpiod.line.Direction.INPUT,
            edge_detection=gpiod.line.Edge.FALLING if self.edge == "falling" else gpiod.line.Edge.RISING,
            debounce_period=datetime.timedelta(milliseconds=self.debounce_ms),
            event_clock=gpiod.line.Clock.MONOTONIC,
        )
        self._request = gpiod.request_lines(self.chip_path, consumer=self.consumer,
                                            config={(self.start_line_offset, self.end_line_offset): settings})

    def _drain(self):
        request = self._request
        assert request is not None   # drained only while open
        while request.wait_edge_events(0):
            request.read_edge_events()

    def arm(self, target_mps: float) -> None:
        """Open the lines if needed and drop stale edges (a hand through a beam before the launch)."""
        _positive("target_mps", target_mps)
        if self._request is None:
            self.open()
        self._drain()

    def read_travel_time(self, timeout_s: float, clock: typing.Callable[[], float] = time.monotonic) -> float:
        """Wait for a start-gate edge and then an end-gate edge; return the time between them (s), NaN on timeout."""
        if self._request is None:
            raise RuntimeError("arm() the gpio speed gate before reading it")
        deadline = clock() + timeout_s
        start_ns = None
        while True:
            remaining_s = deadline - clock()
            if remaining_s <= 0 or not self._request.wait_edge_events(remaining_s):
                _LOG.warning("speed gate: %s edge not seen within %.2f s", "start" if start_ns is None else "end",
                             timeout_s)
                return NOT_MEASURED
            for event in self._request.read_edge_events():
                if start_ns is None and event.line_offset == self.start_line_offset:
                    start_ns = event.timestamp_ns
                elif start_ns is not None and event.line_offset == self.end_line_offset:
                    return (event.timestamp_ns - start_ns) / 1e9

    def release(self) -> None:
        """Release both lines."""
        if self._request is not None:
            self._request.release()
            self._request = None


def parse_travel_time(text: str) -> float:
    """Parse an operator-typed travel time in seconds; blank means not measured (NaN). Raises ``ValueError``."""
    text = text.strip()
    if not text:
        return NOT_MEASURED
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"travel time must be a number of seconds, got {text!r}") from None
    _positive("travel time", value)
    return value


class OperatorSpeedGate(SpeedGate):
    """The operator times the run (stopwatch, video) and types the travel time in.

    ``ask(prompt) -> str`` is the terminal's ``input`` or a service-backed equivalent; invalid answers are
    asked again, a blank answer means not measured.
    """

    source = "the operator's typed travel time"

    def __init__(self, ask, run_length_m):
        self._ask = ask
        self.run_length_m = run_length_m
        self._target_mps = None

    @classmethod
    def from_config(cls, config: "SpeedGateConfig", ask: typing.Callable[[str], str]) -> "SpeedGate":
        """Asks through ``ask``."""
        return cls(ask, config.run_length_m)

    def arm(self, target_mps: float) -> None:
        """Remember the target to show the expected time in the prompt."""
        _positive("target_mps", target_mps)
        self._target_mps = target_mps

    def read_travel_time(self, timeout_s: typing.Optional[float] = None) -> float:
        """Ask until a valid time (s) or a blank (NaN) is typed; ``timeout_s`` is the operator's business."""
        expected = expected_travel_time(self.run_length_m, self._target_mps) if self._target_mps else None
        prompt = "travel time over the run, s" + (f" (expected {expected:.2f} s)" if expected else "") + \
            ", blank if not measured: "
        while True:
            try:
                return parse_travel_time(self._ask(prompt))
            except ValueError as exc:
                prompt = f"{exc}; try again: "


#: ``speed_gate.backend`` -> its :class:`SpeedGate` (a class, or ``"module:Class"`` imported when chosen).
SPEED_GATES: Registry[SpeedGate] = Registry("backend", SpeedGate, {
    "simulated": SimulatedSpeedGate,
    "gpio": GpioSpeedGate,
    "operator": OperatorSpeedGate,
})


@dataclasses.dataclass
class SimulatedGateConfig:
    """``speed_gate.simulated.*``."""

    speed_noise_fraction: float = dataclasses.field(default=0.03, metadata={
        "description": "standard deviation of the simulated speed as a fraction of the target",
        "range": (0.0, 1.0), "exclusive": "high"})
    seed: int = dataclasses.field(default=0, metadata={
        "description": "seed of the simulated gate's speed noise (integer >= 0)", "range": (0, 2147483647)})


@dataclasses.dataclass
class GpioGateConfig:
    """``speed_gate.gpio.*``."""

    chip: str = dataclasses.field(default="/dev/gpiochip0", metadata={
        "description": "GPIO chip device of the light gates (e.g. /dev/gpiochip0)"})
    start_line_offset: int = dataclasses.field(default=22, metadata={
        "description": "GPIO line of the light gate at the start of the launch run", "range": (0, 1023)})
    end_line_offset: int = dataclasses.field(default=23, metadata={
        "description": "GPIO line of the light gate at the ledge edge", "range": (0, 1023)})
    edge: str = dataclasses.field(default="falling", metadata={
        "description": "the edge a broken light beam produces on the gate lines: falling or rising"})
    debounce_ms: float = dataclasses.field(default=1.0, metadata={
        "description": "kernel debounce of both gate lines, ms (0 = off)", "range": (0.0, 1000.0)})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        _check_gate_lines(self.start_line_offset, self.end_line_offset, self.edge, self.debounce_ms)


@dataclasses.dataclass
class SpeedGateConfig:
    """``speed_gate.*`` of ``config/rig.yaml``."""

    backend: str = dataclasses.field(default="simulated", metadata={
        "description": "launch speed source: simulated (target speed plus noise), gpio (light-gate pair) or operator "
                       "(typed in)"})
    run_length_m: float = dataclasses.field(default=0.34, metadata={
        "description": "distance between the two light gates, m; speed = distance / travel time",
        "range": (0.0, 100.0), "exclusive": "low"})
    tolerance_fraction: float = dataclasses.field(default=0.15, metadata={
        "description": "a launch further than this fraction off its target speed is flagged",
        "range": (0.0, 1.0), "exclusive": "both"})
    timeout_s: float = dataclasses.field(default=3.0, metadata={
        "description": "longest wait for both gate edges after firing, s; then the speed is not measured",
        "range": (0.0, 600.0), "exclusive": "low"})
    simulated: SimulatedGateConfig = dataclasses.field(default_factory=SimulatedGateConfig)
    gpio: GpioGateConfig = dataclasses.field(default_factory=GpioGateConfig)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        SPEED_GATES.check(self.backend)

    def measure(self, target_mps: float, travel_time_s: float) -> "SpeedMeasurement":
        """:func:`measure` with this configuration's run length and tolerance."""
        return measure(target_mps, travel_time_s, self.run_length_m, self.tolerance_fraction)


def make_speed_gate(config: "SpeedGateConfig", ask: typing.Callable[[str], str] = input) -> SpeedGate:
    """Build the gate ``config.backend`` names (a :class:`SpeedGateConfig`); ``ask`` reaches the operator (the
    operator gate asks through it). The only place that looks at the name."""
    return SPEED_GATES.get(config.backend).from_config(config, ask)
