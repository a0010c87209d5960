"""Valve backends: what physically opens and closes the launcher's solenoid valve.

Each implements :class:`~rollability_ros.core.rig._valve_backend.ValveBackend` (``open()``, ``open_valve(pulse_ms)``,
``close_valve()``, ``release()``, and those of the optional ``arm()`` / ``disarm()`` / ``clear()``,
``fire_refusal()``, ``set_fault_listener(callback)``, ``link_state()``, ``stalled()`` its device supports) and is
listed in :data:`~rollability_ros.core.rig._valve_backend.VALVE_BACKENDS`. Errors are raised
(``ValveBackendError`` or the library's own); :class:`~rollability_ros.core.rig.valve.ValveController` turns them
into latched faults.

What each backend can promise when the controlling process dies (SIGKILL, crash, power loss): ``serial_relay``
talks to a board that times pulses and drops the relay without keep-alives (:mod:`.relay_protocol`), so the relay
is off within ``max_pulse_ms``; ``gpio`` keeps the line in a tiny holder process (:mod:`.gpio_line_holder`) that
drops it when the controller dies, but a GPIO line keeps its level when its own owner dies, so it fires only when the
configuration declares an external hardware pulse limiter; ``dry_run`` drives nothing.
"""
import logging
import os
import select
import subprocess
import sys
import threading
import time
import typing

from rollability_ros.core.optional import require
from rollability_ros.core.rig import relay_protocol
from rollability_ros.core.rig.valve import ValveConfig, ValveController
from rollability_ros.core.rig._valve_backend import ValveBackend, make_valve_backend

_LOG = logging.getLogger(__name__)


class ValveBackendError(RuntimeError):
    """The valve hardware did not do or confirm what it was told."""


class DryRunBackend(ValveBackend):
    """Drives nothing; logs every command and keeps ``history`` as ``[(monotonic s, command), ...]``."""

    name = "dry_run"

    def __init__(self, clock=time.monotonic):
        self._clock = clock
        self.history = []

    def _record(self, command):
        self.history.append((self._clock(), command))
        _LOG.info("dry_run valve: %s", command)

    def open(self) -> None:
        """Start (nothing to acquire)."""
        self._record("start")

    def open_valve(self, pulse_ms: typing.Optional[float] = None) -> None:
        """Log an open command (``pulse_ms`` is the controller's, the dry run has no device to time it)."""
        self._record("open")

    def close_valve(self) -> None:
        """Log a close command."""
        self._record("close")

    def release(self) -> None:
        """Log a close command, then the release."""
        self.close_valve()
        self._record("release")

    @property
    def commands(self) -> typing.List[str]:
        """The commands of ``history`` without their times."""
        return [command for _, command in self.history]


def gpio_chip_path(chip: str) -> str:
    """Return a device path for ``chip``: ``"gpiochip0"`` -> ``"/dev/gpiochip0"``; paths are kept."""
    return chip if "/" in chip else f"/dev/{chip}"


def _limiter_note(hardware_pulse_limiter):
    return "" if hardware_pulse_limiter else \
        " -- none is declared (valve.gpio.hardware_pulse_limiter: false), so every fire is refused"


class GpioBackend(ValveBackend):
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

    def __init__(self, chip, line_offset, active_high=True, consumer="rollability-valve",
                 hardware_pulse_limiter=False, warn=True):
        self.chip_path = gpio_chip_path(chip)
        self.line_offset = line_offset
        self.active_high = active_high
        self.hardware_pulse_limiter = hardware_pulse_limiter
        self.warn = warn  # False in the line holder, whose parent warns
        self.consumer = consumer
        self._gpiod = None
        self._request = None

    def open(self) -> None:
        """Request the line as an output whose initial value is inactive (valve closed) from the first instant."""
        gpiod = self._gpiod = require("gpiod", feature="the gpio valve backend")
        settings = gpiod.LineSettings(
            direction=gpiod.line.Direction.OUTPUT,
            active_low=not self.active_high,
            output_value=gpiod.line.Value.INACTIVE,
        )
        self._request = gpiod.request_lines(self.chip_path, consumer=self.consumer,
                                            config={self.line_offset: settings})
        if self.warn:
            _LOG.warning(
                "gpio valve backend: if this process dies (SIGKILL, crash, power loss of the computer only) the "
                "line %s:%d keeps its level and nothing in software can close the valve; %s", self.chip_path,
                self.line_offset,
                "the configuration declares a hardware pulse limiter (valve.gpio.hardware_pulse_limiter)"
                if self.hardware_pulse_limiter else "no hardware pulse limiter is declared, so every fire is refused")

    def fire_refusal(self) -> str:
        """Refuse every pulse unless the configuration declares the external hardware pulse limiter."""
        if self.hardware_pulse_limiter:
            return ""
        return ("gpio backend without a hardware pulse limiter: a killed process would leave the line (and the "
                "valve) on; wire the limiter of docs/firmware.md and set valve.gpio.hardware_pulse_limiter: true, "
                "or use the serial_relay board")

    def startup_warning(self) -> str:
        """What a dead process leaves behind on the GPIO line, and whether firing is refused for it."""
        return ("gpio backend (line held by this process, valve.gpio.line_holder: false): if this node dies the "
                "line stays where it was; only the hardware pulse limiter of docs/firmware.md closes the valve then"
                + _limiter_note(self.hardware_pulse_limiter))

    def link_state(self) -> str:
        """One line for diagnostics."""
        requested = "requested" if self._request is not None else "not requested"
        limiter = "hardware pulse limiter declared" if self.hardware_pulse_limiter else "NO hardware pulse limiter"
        return f"gpio line {self.chip_path}:{self.line_offset} {requested}; {limiter}"

    def _set(self, active):
        if self._request is None:
            raise ValveBackendError(f"gpio line {self.chip_path}:{self.line_offset} is not requested")
        assert self._gpiod is not None   # imported by the open that requested the line
        value = self._gpiod.line.Value.ACTIVE if active else self._gpiod.line.Value.INACTIVE
        self._request.set_value(self.line_offset, value)

    def open_valve(self, pulse_ms: typing.Optional[float] = None) -> None:
        """Drive the line active (the controller times the pulse; only a hardware limiter survives its death)."""
        self._set(True)

    def close_valve(self) -> None:
        """Drive the line inactive."""
        self._set(False)

    def release(self) -> None:
        """Drive the line inactive, then release the request."""
        if self._request is None:
            return
        try:
            self.close_valve()
        finally:
            self._request.release()
            self._request = None


class SerialRelayBackend(ValveBackend):
    """The valve relay board (:mod:`~rollability_ros.core.rig.relay_protocol`, firmware in ``firmware/``).

    The board times each pulse and drops the relay when its keep-alive stops; this backend sends ``KA`` from a
    thread every ``keepalive_period_ms`` while the port is open, so the relay stays usable exactly as long as this
    process runs and talks. A board that disarmed itself (keep-alive timeout, e-stop button) or a link that stops
    answering is reported to the fault listener.

    Parameters
    ----------
    port : str
        Serial device (``/dev/ttyACM0``, a pty path, ...).
    baud : int
        Baud rate, bit/s (the firmware uses 115200).
    timeout_s : float
        Longest wait for an answer line, s; a missing or wrong answer raises :class:`ValveBackendError`.
    keepalive_period_ms : int
        Period of the ``KA`` line, ms; must be at most a third of the board's ``keepalive_timeout_ms``.
    boot_wait_s : float
        How long ``HELLO`` is repeated until the board answers, s: opening the port resets an Uno / Nano, whose
        bootloader runs for 1-2 s before the sketch answers.
    """

    name = "serial_relay"

    @classmethod
    def from_config(cls, config: "ValveConfig") -> ValveBackend:
        """The board on ``valve.serial.*``."""
        s = config.serial
        return cls(s.port, s.baud, s.timeout_s, s.keepalive_period_ms, s.boot_wait_s)

    def __init__(self, port, baud=115200, timeout_s=0.2, keepalive_period_ms=50, boot_wait_s=3.0):
        self.port = port
        self.boot_wait_s = boot_wait_s
        self.baud = baud
        self.timeout_s = timeout_s
        self.keepalive_period_ms = keepalive_period_ms
        self.limits = None              # DeviceLimits, from HELLO
        self._serial = None
        self._io_lock = threading.Lock()  # one command and its answer at a time (the keep-alive thread too)
        self._armed = False               # what this side asked for
        self._fault_listener = None
        self._stop = threading.Event()
        self._thread = None
        self._link = "not open"
        self._last_answer_at = None
        self._last_device_state = None
        self._reported_fault = "none"
        self._busy = None                 # (line, monotonic start) of the command holding the port

    @property
    def call_timeout_s(self) -> float:  # type: ignore[override]  # a property over the contract's class attribute
        """Longest one command may take (write bound + answer bound + slack), s; the controller bounds each call by
        it and :meth:`stalled` reports a command that overran it."""
        return max(self.timeout_s, MIN_WRITE_TIMEOUT_S) + self.timeout_s + 0.5

    def stalled(self) -> str:
        """A reason when the command holding the port (the keep-alive's too) has overrun :attr:`call_timeout_s`,
        else "": a write into a board that stopped taking bytes must not go unnoticed while no one else calls."""
        busy = self._busy
        if busy is None:
            return ""
        age_s = time.monotonic() - busy[1]
        if age_s <= self.call_timeout_s:
            return ""
        return (f"serial link stuck: command {busy[0]!r} has not returned for {age_s * 1000:.0f} ms "
                f"(bound {self.call_timeout_s:.1f} s)")

    def set_fault_listener(self, callback: typing.Callable[[str], None]) -> None:
        """``callback(reason)`` is called (from the keep-alive thread) when the board faults on its own."""
        self._fault_listener = callback

    def _open_port(self):
        """The port object (``write``, ``read_until``, ``reset_input_buffer``, ``close``)."""
        serial = require("serial", feature="the serial_relay valve backend")
        # pyserial checks its write timeout after the write returns, so a thread that waited for the GIL longer
        # than the timeout would report a write that went through as failed: the write gets a wider bound (a
        # port that really blocks for a second is dead; the board has dropped the relay long before)
        port = serial.Serial(self.port, self.baud, timeout=READ_POLL_S,
                             write_timeout=max(self.timeout_s, MIN_WRITE_TIMEOUT_S))
        return _SerialPort(port, self.timeout_s)

    def open(self) -> None:
        """Open the port, check the board's protocol and limits, start the keep-alive thread."""
        self._serial = self._open_port()
        deadline = time.monotonic() + self.boot_wait_s
        attempts = 0
        while True:
            attempts += 1
            try:
                hello = self._command("HELLO")
                break
            except ValveBackendError:
                if time.monotonic() >= deadline:
                    raise
        if attempts > 1:
            # the board answers in order: the answer just read may be that of an earlier HELLO it got late, and the
            # answers to the later ones follow at once; let them arrive and drop them before the next command
            time.sleep(self.timeout_s)
            with self._io_lock:
                self._serial.reset_input_buffer()
        try:
            self.limits = relay_protocol.parse_hello(hello)
        except ValueError as exc:
            raise ValveBackendError(f"relay board on {self.port}: {exc}") from exc
        if 3 * self.keepalive_period_ms > self.limits.keepalive_timeout_ms:
            raise ValveBackendError(
                f"serial.keepalive_period_ms {self.keepalive_period_ms} is more than a third of the board's "
                f"keepalive_timeout_ms {self.limits.keepalive_timeout_ms}: one late keep-alive would drop the relay")
        try:
            state = relay_protocol.parse_state(self._command("STATUS", expect="OK STATUS ")[len("OK STATUS "):])
        except ValueError as exc:
            raise ValveBackendError(f"relay board on {self.port}: {exc}") from exc
        if state.fault == "keepalive":
            # the previous controller went silent (killed, unplugged) and the board dropped the relay: expected
            # after a crash, so not a fault of this session; an e-stop, though, is reported by the keep-alive loop
            _LOG.warning("relay board on %s had dropped the relay on its own after its previous controller went "
                         "silent (fault keepalive)", self.port)
            self._reported_fault = "keepalive"
        self._last_device_state = state
        self._link = "ok"
        self._stop.clear()
        self._thread = threading.Thread(target=self._keepalive_loop, name="relay-keepalive", daemon=True)
        self._thread.start()

    def _command(self, line, expect=None, then=None):
        """Send one line and return its answer (stripped); raise unless it starts with ``expect``.

        ``then(answer)`` runs before the port is free again, so what this side believes about arming changes in
        the same order as the board's answers (the keep-alive thread compares them).
        """
        with self._io_lock:
            if self._serial is None:
                raise ValveBackendError(f"serial port {self.port} is not open")
            self._busy = (line, time.monotonic())
            try:
                self._serial.reset_input_buffer()  # drop late answers of earlier commands
                # bounded by the write timeout; no flush(): pyserial's is tcdrain, which has no timeout and blocks
                # for as long as a board (or a USB-serial chip) takes no bytes; the answer shows the line arrived
                self._serial.write((line + "\n").encode("ascii"))
                sent_at = time.monotonic()
                answer = self._serial.read_until(b"\n")  # bounded by the port timeout
            finally:
                self._busy = None
            text = answer.decode("ascii", errors="replace").strip()
            if not answer.endswith(b"\n"):
                raise ValveBackendError(f"relay board did not answer {line!r} within {self.timeout_s} s"
                                        + (f" (partial answer {text!r})" if text else ""))
            self._note_answer(time.monotonic(), line, sent_at)
            if expect is not None and not text.startswith(expect):
                raise ValveBackendError(f"relay board answered {text!r} to {line!r}, expected {expect!r}")
            return then(text) if then is not None else text

    def _note_answer(self, now, line, sent_at):
        """Record the answer to ``line`` (written at ``sent_at``) at ``now`` (port lock held); warn when, armed, the
        command before it was answered more than half the board's keep-alive timeout earlier: the board restarts
        its timer on every command, so that gap, seen from this side, is how close this computer came to the board
        dropping the relay. The warning splits the gap: how long this side took to write the next line after the
        last answer (a valve node that did not run: starved, or a thread holding the GIL) and how long the board
        took to answer it (a slow board or link)."""
        previous, self._last_answer_at = self._last_answer_at, now
        if not self._armed or previous is None or self.limits is None:
            return
        gap_ms = (now - previous) * 1000.0
        if gap_ms <= self.limits.keepalive_timeout_ms / 2:
            return
        waited_ms, answer_ms = (sent_at - previous) * 1000.0, (now - sent_at) * 1000.0
        side = ("this computer is starving the valve node" if waited_ms >= answer_ms
                else "the board (or its link) answered late")
        _LOG.warning("relay board: %.0f ms between two answered commands while armed (keep-alive every %d ms; the "
                     "board drops the relay after %d ms without a command): the valve node wrote %r %.0f ms after the "
                     "last answer and the board answered it after %.0f ms: %s", gap_ms, self.keepalive_period_ms,
                     self.limits.keepalive_timeout_ms, line, waited_ms, answer_ms, side)

    def _notify(self, reason):
        _LOG.error("relay board: %s", reason)
        if self._fault_listener is not None:
            try:
                self._fault_listener(reason)
            except Exception:  # noqa: BLE001 - the keep-alive must go on whatever the listener does
                _LOG.exception("valve fault listener failed")

    def _keepalive_loop(self):
        while not self._stop.wait(self.keepalive_period_ms / 1000.0):
            try:
                state, expected_armed = self._command("KA", expect="OK KA ", then=self._keepalive_answer)
            except (ValveBackendError, ValueError, OSError) as exc:
                if self._link == "ok":
                    self._link = f"lost: {exc}"
                    self._notify(f"link lost: {exc}")
                continue
            except Exception as exc:  # noqa: BLE001 - e.g. the port closed under us at release
                if self._stop.is_set():
                    return
                self._link = f"lost: {exc}"
                continue
            self._link = "ok"
            self._last_device_state = state
            if state.fault != "none" and state.fault != self._reported_fault:
                self._reported_fault = state.fault
                self._notify(f"board fault {state.fault}: relay off and disarmed by the board")
            elif expected_armed and not state.armed:
                self._notify("board disarmed itself: relay off")
            if state.fault == "none":
                self._reported_fault = "none"

    def _keepalive_answer(self, answer):
        """``(board state, armed as this side expected it)`` for one KA answer (port lock held)."""
        state = relay_protocol.parse_state(answer[len("OK KA "):])
        expected_armed = self._armed
        if not state.armed:
            self._armed = False
        return state, expected_armed

    def link_state(self) -> str:
        """One line for diagnostics: link, board limits, last answer age, board state."""
        if self.limits is None:
            return f"{self.port}: {self._link}"
        age = "never" if self._last_answer_at is None else f"{(time.monotonic() - self._last_answer_at) * 1e3:.0f} ms ago"
        state = relay_protocol.format_state(self._last_device_state) if self._last_device_state else "unknown"
        return (f"{self.port}: {self._link}; {self.limits.protocol} max_pulse_ms={self.limits.max_pulse_ms} "
                f"keepalive_timeout_ms={self.limits.keepalive_timeout_ms}; last answer {age}; board {state}")

    def arm(self) -> None:
        """Arm the board (its keep-alive timer starts)."""
        self._command("ARM", expect="OK ARMED", then=lambda _answer: setattr(self, "_armed", True))

    def disarm(self) -> None:
        """Disarm the board (relay off)."""
        self._command("DISARM", expect="OK DISARMED", then=lambda _answer: setattr(self, "_armed", False))

    def clear(self) -> None:
        """Acknowledge a latched board fault (refused while the e-stop button is held)."""
        self._command("CLEAR", expect="OK CLEARED")
        self._reported_fault = "none"

    def open_valve(self, pulse_ms: typing.Optional[float] = None) -> None:
        """Ask the board for a pulse of ``pulse_ms`` ms; the board ends it at ``min(pulse_ms, its max_pulse_ms)``."""
        if pulse_ms is None:
            raise ValveBackendError("the relay board needs the pulse length")
        answer = self._command(relay_protocol.pulse_command(pulse_ms), expect="OK PULSE ")
        self.granted_ms = int(answer.split()[-1])

    def close_valve(self) -> None:
        """Switch the relay off now (the board also ends the pulse on its own)."""
        self._command("OFF", expect="OK OFF")

    def release(self) -> None:
        """Stop the keep-alive, switch the relay off and disarm, then close the port."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2 * self.timeout_s + self.keepalive_period_ms / 1000.0)
        if self._serial is None:
            return
        try:
            self.close_valve()
            self.disarm()
        finally:
            with self._io_lock:
                self._serial.close()
                self._serial = None
            self._link = "released"


#: How long one read of the serial port waits for a first byte, s (answers are read in chunks of what arrived).
READ_POLL_S = 0.01

#: Least write timeout of the serial port, s.
MIN_WRITE_TIMEOUT_S = 1.0


class _LinePort:
    """Reads answer lines in chunks of whatever has arrived, bounded by ``timeout_s``.

    Bytes that arrived before the deadline count even when this thread only runs again after it: on a busy
    machine the keep-alive thread may wait tens of ms for the GIL, and reading an answer byte by byte (pyserial's
    ``read_until``) would pay that wait per byte and report a board that answered at once as silent.
    """

    def __init__(self, timeout_s):
        self.timeout_s = timeout_s
        self._buffer = b""

    def _read_available(self, wait_s):
        """Append what has arrived (waiting up to about ``wait_s`` for a first byte); True when anything came."""
        raise NotImplementedError

    def read_until(self, terminator: bytes = b"\n") -> bytes:
        """Bytes up to and including ``terminator``, or what arrived within ``timeout_s``."""
        deadline = time.monotonic() + self.timeout_s
        while terminator not in self._buffer:
            remaining = deadline - time.monotonic()
            if not self._read_available(max(0.0, remaining)) and remaining <= 0:
                break
        if terminator in self._buffer:
            line, self._buffer = self._buffer.split(terminator, 1)
            return line + terminator
        partial, self._buffer = self._buffer, b""
        return partial


class _SerialPort(_LinePort):
    """A pyserial port (opened with a short read timeout, :data:`READ_POLL_S`) with chunked line reads."""

    def __init__(self, port, timeout_s):
        super().__init__(timeout_s)
        self.port = port

    def _read_available(self, wait_s):
        waiting = self.port.in_waiting
        if waiting:
            data = self.port.read(waiting)
        elif wait_s > 0:
            data = self.port.read(1)      # returns within READ_POLL_S when nothing comes
        else:
            data = b""
        self._buffer += data
        return bool(data)

    def reset_input_buffer(self) -> None:
        """Drop everything received so far."""
        self.port.reset_input_buffer()
        self._buffer = b""

    def write(self, data: bytes) -> None:
        """Send bytes to the board."""
        self.port.write(data)

    def close(self) -> None:
        """Close the port."""
        self.port.close()


class _PipePort(_LinePort):
    """A child process's stdin / stdout as a serial-like port (the subset :class:`SerialRelayBackend` uses)."""

    def __init__(self, process, timeout_s):
        super().__init__(timeout_s)
        self.process = process

    def _read_available(self, wait_s):
        fd = self.process.stdout.fileno()
        readable, _, _ = select.select([fd], [], [], wait_s)
        if not readable:
            return False
        data = os.read(fd, 4096)
        if not data:
            raise ValveBackendError(f"gpio line holder exited (code {self.process.poll()})")
        self._buffer += data
        return True

    def reset_input_buffer(self) -> None:
        """Drop everything received so far."""
        while self.process.poll() is None and self._read_available(0):
            pass
        self._buffer = b""

    def write(self, data: bytes) -> None:
        """Send bytes to the holder."""
        try:
            os.write(self.process.stdin.fileno(), data)
        except OSError as exc:
            raise ValveBackendError(f"gpio line holder gone: {exc}") from exc

    def close(self) -> None:
        """Close the holder's input (it drives the line inactive and exits); kill it if it does not."""
        self.process.stdin.close()
        try:
            self.process.wait(5.0)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self.process.stdout.close()


class GpioHolderBackend(SerialRelayBackend):
    """The gpio backend: the line is owned by :mod:`~rollability_ros.core.rig.gpio_line_holder`, a child process
    that speaks the relay board's protocol on its pipes, so the valve_controller's death drops the line.

    The holder can still die itself (or the computer freeze) with the line active: every fire is refused unless
    ``hardware_pulse_limiter`` declares the external limiter of docs/firmware.md.
    """

    name = "gpio"

    def __init__(self, chip, line_offset, active_high=True, hardware_pulse_limiter=False, max_pulse_ms=500,
                 keepalive_timeout_ms=relay_protocol.DEFAULT_KEEPALIVE_TIMEOUT_MS, timeout_s=0.5,
                 keepalive_period_ms=50, boot_wait_s=10.0):
        super().__init__(f"gpio line holder for {gpio_chip_path(chip)}:{line_offset}", timeout_s=timeout_s,
                         keepalive_period_ms=keepalive_period_ms, boot_wait_s=boot_wait_s)
        self._argv = [sys.executable, "-m", "rollability_ros.core.rig.gpio_line_holder", "--chip", chip,
                      "--line-offset", str(line_offset), "--max-pulse-ms", str(max_pulse_ms),
                      "--keepalive-timeout-ms", str(keepalive_timeout_ms)] + ([] if active_high else ["--active-low"])
        self.hardware_pulse_limiter = hardware_pulse_limiter
        self.process = None

    def _open_port(self):
        # its own session: a SIGKILL of the valve_controller's process group (a supervisor's last resort) leaves the
        # holder alive to see the closed pipe and drop the line
        self.process = subprocess.Popen(self._argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, bufsize=0,
                                        start_new_session=True)
        _LOG.warning("gpio valve backend: line held by process %d; if it dies too (or the computer freezes) the "
                     "line keeps its level, %s", self.process.pid, "the declared hardware pulse limiter ends the "
                     "pulse" if self.hardware_pulse_limiter else "and no hardware pulse limiter is declared, so "
                     "every fire is refused")
        return _PipePort(self.process, self.timeout_s)

    @classmethod
    def from_config(cls, config: "ValveConfig") -> ValveBackend:
        """The line on ``valve.gpio.*``: held by the child process, or (``line_holder: false``) by this process."""
        g = config.gpio
        if g.line_holder:
            return cls(g.chip, g.line_offset, g.active_high, g.hardware_pulse_limiter, max_pulse_ms=config.max_pulse_ms)
        return GpioBackend(g.chip, g.line_offset, g.active_high, hardware_pulse_limiter=g.hardware_pulse_limiter)

    fire_refusal = GpioBackend.fire_refusal

    def startup_warning(self) -> str:
        """What a dead holder leaves behind on the GPIO line, and whether firing is refused for it."""
        return ("gpio backend: the line holder process drops the line when this node dies, but if the holder dies "
                "too (or the computer freezes) the line stays where it was; only the hardware pulse limiter of "
                "docs/firmware.md closes the valve then" + _limiter_note(self.hardware_pulse_limiter))

    def link_state(self) -> str:
        """One line for diagnostics: the holder link and whether a hardware limiter is declared."""
        limiter = "hardware pulse limiter declared" if self.hardware_pulse_limiter else "NO hardware pulse limiter"
        return f"{super().link_state()}; {limiter}"


def make_controller(config: "ValveConfig",
                    on_state: typing.Optional[typing.Callable[..., None]] = None) -> ValveController:
    """Build the backend ``config.backend`` names and a :class:`ValveController` for ``config``, and start its
    steady-clock watchdog.

    The controller drives the valve closed during construction; call ``shutdown()`` when done.
    """
    controller = ValveController(make_valve_backend(config), config.max_pulse_ms, config.watchdog_ms, on_state=on_state,
                                 arm_timeout_s=config.arm_timeout_s)
    controller.start_watchdog(config.watchdog_check_ms / 1000.0)
    return controller
