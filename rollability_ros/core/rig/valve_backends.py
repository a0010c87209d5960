"""Valve backends: what physically opens and closes the launcher's solenoid valve.

Every backend has ``name``, ``open()`` (acquire the device, valve closed), ``open_valve()``, ``close_valve()`` and
``release()`` (drive closed, then free the device). None relies on a released line or a closed port to close
the valve: ``release()`` commands it closed first. Errors are raised (``ValveBackendError`` or the library's
own); :class:`~rollability_ros.core.rig.valve.ValveController` turns them into latched faults.
"""
import logging
import time

from rollability_ros.core.optional import require
from rollability_ros.core.rig.valve import LINE_ENDINGS, ValveController

_LOG = logging.getLogger(__name__)


class ValveBackendError(RuntimeError):
    """The valve hardware did not do or confirm what it was told."""


class DryRunBackend:
    """Drives nothing; logs every command and keeps ``history`` as ``[(monotonic s, command), ...]``."""

    name = "dry_run"

    def __init__(self, clock=time.monotonic):
        self._clock = clock
        self.history = []

    def _record(self, command):
        self.history.append((self._clock(), command))
        _LOG.info("dry_run valve: %s", command)

    def open(self):
        """Start (nothing to acquire)."""
        self._record("start")

    def open_valve(self):
        """Log an open command."""
        self._record("open")

    def close_valve(self):
        """Log a close command."""
        self._record("close")

    def release(self):
        """Log a close command, then the release."""
        self.close_valve()
        self._record("release")

    @property
    def commands(self):
        """The commands of ``history`` without their times."""
        return [command for _, command in self.history]


def gpio_chip_path(chip):
    """Return a device path for ``chip``: ``"gpiochip0"`` -> ``"/dev/gpiochip0"``; paths are kept."""
    return chip if "/" in chip else f"/dev/{chip}"


class GpioBackend:
    """A GPIO line (libgpiod v2 ``gpiod`` bindings) driving the solenoid driver; active = valve open.

    Parameters
    ----------
    chip : str
        GPIO chip device, ``/dev/gpiochipN`` or ``gpiochipN``.
    line_offset : int
        Line offset on that chip.
    active_high : bool
        True when a high level opens the valve; False for active-low drivers (the kernel inverts the line).
    """

    name = "gpio"

    def __init__(self, chip, line_offset, active_high=True, consumer="rollability-valve"):
        self.chip_path = gpio_chip_path(chip)
        self.line_offset = line_offset
        self.active_high = active_high
        self.consumer = consumer
        self._gpiod = None
        self._request = None

    def open(self):
        """Request the line as an output whose initial value is inactive (valve closed) from the first instant."""
        gpiod = self._gpiod = require("gpiod", feature="the gpio valve backend")
        settings = gpiod.LineSettings(
            direction=gpiod.line.Direction.OUTPUT,
            active_low=not self.active_high,
            output_value=gpiod.line.Value.INACTIVE,
        )
        self._request = gpiod.request_lines(self.chip_path, consumer=self.consumer,
                                            config={self.line_offset: settings})

    def _set(self, active):
        if self._request is None:
            raise ValveBackendError(f"gpio line {self.chip_path}:{self.line_offset} is not requested")
        value = self._gpiod.line.Value.ACTIVE if active else self._gpiod.line.Value.INACTIVE
        self._request.set_value(self.line_offset, value)

    def open_valve(self):
        """Drive the line active."""
        self._set(True)

    def close_valve(self):
        """Drive the line inactive."""
        self._set(False)

    def release(self):
        """Drive the line inactive, then release the request."""
        if self._request is None:
            return
        try:
            self.close_valve()
        finally:
            self._request.release()
            self._request = None


class SerialRelayBackend:
    """A relay board on a serial port: one text line per command, answered by an acknowledgement line.

    Parameters
    ----------
    port : str
        Serial device (``/dev/ttyUSB0``, a pty path, ...).
    baud : int
        Baud rate.
    open_command, close_command : str
        Lines that switch the relay on (valve open) and off, without line ending.
    ack : str
        The line the board answers on success; anything else, or nothing within ``timeout_s``, raises.
    timeout_s : float
        Longest wait for the acknowledgement, s.
    line_ending : str
        ``"lf"``, ``"crlf"`` or ``"cr"``, appended to every command.
    """

    name = "serial_relay"

    def __init__(self, port, baud, open_command, close_command, ack, timeout_s, line_ending="lf"):
        if line_ending not in LINE_ENDINGS:
            raise ValueError(f"line_ending must be one of {sorted(LINE_ENDINGS)}, got {line_ending!r}")
        self.port = port
        self.baud = baud
        self.open_command = open_command
        self.close_command = close_command
        self.ack = ack
        self.timeout_s = timeout_s
        self._eol = LINE_ENDINGS[line_ending]
        self._serial = None

    def open(self):
        """Open the port (the valve is then commanded closed by the controller)."""
        serial = require("serial", feature="the serial_relay valve backend")
        self._serial = serial.Serial(self.port, self.baud, timeout=self.timeout_s, write_timeout=self.timeout_s)

    def _command(self, line):
        if self._serial is None:
            raise ValveBackendError(f"serial port {self.port} is not open")
        self._serial.reset_input_buffer()  # drop late acknowledgements of earlier commands
        self._serial.write((line + self._eol).encode("ascii"))
        self._serial.flush()
        answer = self._serial.read_until(b"\n")  # bounded by the port timeout
        text = answer.decode("ascii", errors="replace").strip()
        if not answer.endswith(b"\n"):
            raise ValveBackendError(f"relay did not acknowledge {line!r} within {self.timeout_s} s"
                                    + (f" (partial answer {text!r})" if text else ""))
        if text != self.ack:
            raise ValveBackendError(f"relay answered {text!r} to {line!r}, expected {self.ack!r}")

    def open_valve(self):
        """Send the open command and wait for its acknowledgement."""
        self._command(self.open_command)

    def close_valve(self):
        """Send the close command and wait for its acknowledgement."""
        self._command(self.close_command)

    def release(self):
        """Send the close command, then close the port."""
        if self._serial is None:
            return
        try:
            self.close_valve()
        finally:
            self._serial.close()
            self._serial = None


def make_backend(config):
    """Build the backend named by a :class:`~rollability_ros.core.rig.valve.ValveConfig` (not yet opened)."""
    if config.backend == "dry_run":
        return DryRunBackend()
    if config.backend == "gpio":
        return GpioBackend(config.gpio.chip, config.gpio.line_offset, config.gpio.active_high)
    if config.backend == "serial_relay":
        s = config.serial
        return SerialRelayBackend(s.port, s.baud, s.open_command, s.close_command, s.ack, s.timeout_s, s.line_ending)
    raise ValueError(f"unknown valve backend {config.backend!r}")


def make_controller(config, on_state=None):
    """Build the backend and a :class:`ValveController` for ``config`` and start its steady-clock watchdog.

    The controller drives the valve closed during construction; call ``shutdown()`` when done.
    """
    controller = ValveController(make_backend(config), config.max_pulse_ms, config.watchdog_ms, on_state=on_state)
    controller.start_watchdog(config.watchdog_check_ms / 1000.0)
    return controller
