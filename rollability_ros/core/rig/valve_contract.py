"""The valve backend contract, its table and its settings (:class:`ValveConfig`, ``valve.*``): what
:class:`~rollability_ros.core.rig.valve.ValveController` calls and how a board is chosen and configured.

A backend is what physically opens and closes the launcher's solenoid valve. It implements :class:`ValveBackend`:
``open()`` (acquire the device, valve closed), ``open_valve(pulse_ms)``, ``close_valve()`` and ``release()``
(drive closed, then free the device) are required; the rest have defaults for a board without the feature
(device-side arming, faults reported by the device, a diagnostics line, a reason to refuse firing). The controller
calls every method unconditionally and never asks what kind of backend it holds.

Adding a board: one module with a ``ValveBackend`` subclass (``name``, the four required methods, the optional
ones it supports, ``from_config`` when it reads ``valve.*``) plus one line in :data:`VALVE_BACKENDS`
(``"my_board": "package.module:MyBoardBackend"``), or :func:`register_valve_backend` at run time.
"""
import abc
import dataclasses
import inspect
import math
import typing

from rollability_ros.core.registry import Registry
from rollability_ros.core.rig.relay_protocol import DeviceLimits

#: Longest one backend call may take when the backend declares no other ``call_timeout_s``, s.
DEFAULT_CALL_TIMEOUT_S = 2.0


class ValveBackend(abc.ABC):
    """One valve driver. Errors are raised (any exception); the controller turns them into latched faults.

    None may rely on a released line or a closed port to close the valve: ``release()`` commands it closed first.

    Attributes
    ----------
    name : str
        ``valve.backend`` value and the ``backend`` field of ``msg/ValveState.msg``; required (non-empty).
    call_timeout_s : float
        Longest one call may take, s; the controller bounds each call by it.
    boot_wait_s : float
        Extra time ``open()`` may take while the device boots, s.
    limits : relay_protocol.DeviceLimits or None
        The device's own limits when it reports them.
    """

    name: str = ""
    call_timeout_s: float = DEFAULT_CALL_TIMEOUT_S
    boot_wait_s: float = 0.0
    limits: typing.Optional["DeviceLimits"] = None

    def __init_subclass__(cls, **kwargs: typing.Any) -> None:
        super().__init_subclass__(**kwargs)
        if not inspect.isabstract(cls) and not (isinstance(cls.name, str) and cls.name):
            raise TypeError(f"valve backend {cls.__name__} must set a non-empty class attribute name")

    @classmethod
    def from_config(cls, config: "ValveConfig") -> "ValveBackend":
        """The backend for ``config`` (a :class:`~rollability_ros.core.rig.valve_contract.ValveConfig`), not yet opened."""
        return cls()

    # ---------------------------------------------------------------- required
    @abc.abstractmethod
    def open(self) -> None:
        """Acquire the device with the valve closed from the first instant."""

    @abc.abstractmethod
    def open_valve(self, pulse_ms: typing.Optional[float] = None) -> None:
        """Open the valve; ``pulse_ms`` (ms) is the pulse the controller times (a board may time it too)."""

    @abc.abstractmethod
    def close_valve(self) -> None:
        """Close the valve now."""

    @abc.abstractmethod
    def release(self) -> None:
        """Drive the valve closed, then free the device."""

    # ------------------------------------------------- optional, with defaults
    def arm(self) -> None:
        """Arm the device itself (default: the device has no arming of its own)."""

    def disarm(self) -> None:
        """Disarm the device itself (default: nothing to disarm)."""

    def clear(self) -> None:
        """Acknowledge a fault the device latched itself (default: it latches none)."""

    def fire_refusal(self) -> str:
        """A reason this backend must not fire at all, or "" (default: none)."""
        return ""

    def set_fault_listener(self, callback: typing.Callable[[str], None]) -> None:
        """Remember ``callback(reason)`` for faults the device reports on its own (default: it reports none)."""

    def link_state(self) -> str:
        """One line for diagnostics (default: ``"<name>: no device"``)."""
        return f"{self.name}: no device"

    def stalled(self) -> str:
        """A reason when a call of this backend's own (a keep-alive) overran its bound, else "" (default: none)."""
        return ""

    def startup_warning(self) -> str:
        """A warning the node logs once at start-up, or "" (default: none)."""
        return ""


#: ``valve.backend`` -> its :class:`ValveBackend` (``"module:Class"`` entries are imported when chosen).
VALVE_BACKENDS: Registry[ValveBackend] = Registry("backend", ValveBackend, {
    "dry_run": "rollability_ros.core.rig.valve_boards:DryRunBackend",
    "gpio": "rollability_ros.core.rig.valve_boards:GpioHolderBackend",
    "serial_relay": "rollability_ros.core.rig.valve_boards:SerialRelayBackend",
})


def register_valve_backend(name: str, backend_class: typing.Union[str, type]) -> None:
    """Add a board to :data:`VALVE_BACKENDS` at run time (a class or ``"module:Class"``)."""
    VALVE_BACKENDS.register(name, backend_class)


def make_valve_backend(config: "ValveConfig") -> ValveBackend:
    """The backend ``config.backend`` names, built from ``config`` and not yet opened (the only place that looks at
    the name)."""
    return VALVE_BACKENDS.get(config.backend).from_config(config)


@dataclasses.dataclass
class GpioValveConfig:
    """``valve.gpio.*``: the GPIO line driving the valve's solenoid driver."""

    chip: str = dataclasses.field(default="/dev/gpiochip0", metadata={
        "description": "GPIO chip device driving the solenoid (e.g. /dev/gpiochip0)"})
    line_offset: int = dataclasses.field(default=17, metadata={
        "description": "line offset on that chip that drives the solenoid driver", "range": (0, 1023)})
    active_high: bool = dataclasses.field(default=True, metadata={
        "description": "true: a high level on the line opens the valve; false: an active-low driver"})
    hardware_pulse_limiter: bool = dataclasses.field(default=False, metadata={
        "description": "true declares the hardware pulse limiter of docs/firmware.md (monostable or watchdog relay) "
                       "is wired; without it the gpio backend refuses to fire, since a dead process cannot close "
                       "the line"})
    line_holder: bool = dataclasses.field(default=True, metadata={
        "description": "true: a small child process owns the GPIO line and drops it when the valve node dies"})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if not self.chip:
            raise ValueError("gpio.chip must name a GPIO chip (e.g. /dev/gpiochip0)")


@dataclasses.dataclass
class SerialRelayConfig:
    """``valve.serial.*``: the valve relay board (``firmware/``) on a serial port."""

    port: str = dataclasses.field(default="/dev/ttyACM0", metadata={
        "description": "serial device of the relay board running firmware/arduino/valve_relay (e.g. /dev/ttyACM0)"})
    baud: int = dataclasses.field(default=115200, metadata={
        "description": "serial baud rate of the relay board, bit/s (the firmware uses 115200)", "range": (1, 10000000)})
    timeout_s: float = dataclasses.field(default=0.2, metadata={
        "description": "longest wait for the board's answer, s; a missing or late one faults and closes",
        "range": (0.0, 60.0), "exclusive": "low"})
    keepalive_period_ms: int = dataclasses.field(default=50, metadata={
        "description": "how often this side sends KA while armed, ms; the board drops the relay after its own "
                       "keep-alive timeout (250 ms) without one", "range": (1, 10000)})
    boot_wait_s: float = dataclasses.field(default=3.0, metadata={
        "description": "how long HELLO is repeated while the board boots after its port opens (an Uno resets), s",
        "range": (0.0, 60.0)})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if not self.port:
            raise ValueError("serial.port must name a serial device")


@dataclasses.dataclass
class RegulatorConfig:
    """``valve.regulator.*``: the supply pressure that gives each target launch speed (paper 2.2)."""

    speeds_mps: list[float] = dataclasses.field(default_factory=lambda: [0.8, 1.5], metadata={
        "description": "target launch speeds that have a regulator pressure, m/s"})
    pressures_psi: list[float] = dataclasses.field(default_factory=lambda: [30.0, 60.0], metadata={
        "description": "regulator supply pressure for each target speed in valve.regulator.speeds_mps, psi"})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if len(self.speeds_mps) != len(self.pressures_psi) or not self.speeds_mps:
            raise ValueError("regulator.speeds_mps and regulator.pressures_psi must be non-empty and equally long")
        if not all(0 < value < math.inf for value in (*self.speeds_mps, *self.pressures_psi)):
            raise ValueError("regulator speeds and pressures must be finite and > 0")

    def pressure_psi(self, speed_mps: float) -> float:
        """Return the regulator pressure (psi) for a target speed (m/s); ``ValueError`` if none is configured."""
        for speed, pressure in zip(self.speeds_mps, self.pressures_psi):
            if math.isclose(speed, speed_mps, rel_tol=1e-6, abs_tol=1e-9):
                return pressure
        raise ValueError(f"no regulator pressure configured for {speed_mps} m/s (configured: {self.speeds_mps})")


@dataclasses.dataclass
class ValveConfig:
    """``valve.*`` of ``config/rig.yaml`` (build with ``config.from_mapping(ValveConfig, section(p, "valve"), ...)``)."""

    backend: str = dataclasses.field(default="dry_run", metadata={
        "description": "valve driver: dry_run (logs only), gpio (a libgpiod line) or serial_relay (a relay board)"})
    max_pulse_ms: int = dataclasses.field(default=500, metadata={
        "description": "longest valve opening ever fired, ms; longer fire requests are refused", "range": (1, 600000)})
    launch_pulse_ms: int = dataclasses.field(default=150, metadata={
        "description": "valve opening the rig commands for one launch, ms (at most max_pulse_ms)",
        "range": (1, 600000)})
    watchdog_ms: int = dataclasses.field(default=500, metadata={
        "description": "an armed valve closes and faults when the rig's keep-alive is silent this long, ms",
        "range": (1, 600000)})
    watchdog_check_ms: int = dataclasses.field(default=20, metadata={
        "description": "how often the watchdog looks at the heartbeat (steady clock), ms (at most half the watchdog)",
        "range": (1, 600000)})
    heartbeat_period_ms: int = dataclasses.field(default=100, metadata={
        "description": "how often the rig sends its keep-alive to the valve, ms (at most half the watchdog)",
        "range": (1, 600000)})
    arm_timeout_s: float = dataclasses.field(default=15.0, metadata={
        "description": "an armed valve that fires nothing this long (since arming or its last pulse) is disarmed, s: "
                       "an arming outside a launch sequence does not stay armed; longer than rig.countdown_s",
        "range": (0.1, 3600.0)})
    session_key_file: str = dataclasses.field(default="", metadata={
        "description": "file of the per-session arming key the valve node writes (mode 0600) and the rig reads; "
                       "empty: a per-user runtime file named by ROS domain and namespace"})
    gpio: GpioValveConfig = dataclasses.field(default_factory=GpioValveConfig)
    serial: SerialRelayConfig = dataclasses.field(default_factory=SerialRelayConfig)
    regulator: RegulatorConfig = dataclasses.field(default_factory=RegulatorConfig)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        VALVE_BACKENDS.check(self.backend)
        if not self.launch_pulse_ms <= self.max_pulse_ms:
            raise ValueError(f"launch_pulse_ms must be at most max_pulse_ms={self.max_pulse_ms}, got "
                             f"{self.launch_pulse_ms}")
        if self.watchdog_check_ms > self.watchdog_ms / 2:
            raise ValueError(f"watchdog_check_ms ({self.watchdog_check_ms}) must be at most half of watchdog_ms "
                             f"({self.watchdog_ms})")
        if not self.heartbeat_period_ms <= self.watchdog_ms / 2:
            raise ValueError(f"heartbeat_period_ms ({self.heartbeat_period_ms}) must be at most watchdog_ms / 2: "
                             "one lost heartbeat must not trip the watchdog")
