"""The valve relay board's serial protocol (``RVR1``) and its device-side state machine, in one place.

The firmware (``firmware/arduino/valve_relay/valve_relay.ino``), the relay simulator
(:mod:`rollability_ros.core.rig.relay_device_sim`) and the ``serial_relay`` backend
(:mod:`rollability_ros.core.rig.valve_boards`) all follow this module; ``docs/firmware.md`` documents it for people.

Why the device, not the computer, is the safety device: a SIGKILLed or frozen controller process, a crashed
computer or an unplugged cable cannot send "relay off". So the board

- times every pulse itself: ``PULSE <ms>`` switches the relay on for ``min(ms, max_pulse_ms)`` and off again, with
  ``max_pulse_ms`` compiled into the board;
- is hold-to-run while armed: every accepted command restarts a ``keepalive_timeout_ms`` timer; when it runs out
  the board switches the relay off and disarms (fault ``keepalive``), whatever the computer is doing;
- latches a pressed e-stop button (relay off, disarmed) until ``CLEAR`` with the button released.

So the relay is off at the latest ``min(max_pulse_ms, keepalive_timeout_ms after the last command)`` after a pulse
starts, however the computer side dies.

Lines are ASCII, at most :data:`MAX_LINE` characters, ended by LF (a CR is ignored). Every command gets exactly
one answer line, ``OK ...`` or ``ERR <CODE>``; the board never speaks unasked.

=============  ==========================================  ===============================================
command        answer                                      effect
=============  ==========================================  ===============================================
``HELLO``      ``OK HELLO RVR1 max_pulse_ms=N              none (tells the computer the board's limits)
               keepalive_timeout_ms=M``
``ARM``        ``OK ARMED`` / ``ERR ESTOP``                armed; the keep-alive timer runs
``KA``         ``OK KA <state>``                           restarts the keep-alive timer
``STATUS``     ``OK STATUS <state>``                       none
``PULSE <ms>`` ``OK PULSE <granted ms>`` / ``ERR NOT_ARMED``  relay on for ``min(ms, max_pulse_ms)``
               / ``ERR BUSY`` / ``ERR BAD_ARG``
``OFF``        ``OK OFF``                                  relay off (stays armed)
``DISARM``     ``OK DISARMED``                             relay off, disarmed
``CLEAR``      ``OK CLEARED`` / ``ERR ESTOP_HELD``         clears a latched fault
=============  ==========================================  ===============================================

``<state>`` is ``armed=0|1 relay=0|1 fault=none|estop|keepalive``.
"""
import dataclasses

PROTOCOL = "RVR1"
#: Longest line the board accepts (longer lines are answered ``ERR BAD_ARG`` and ignored), characters.
MAX_LINE = 32
#: The firmware's compiled-in limits (``valve_relay.ino``); the simulator uses the same unless told otherwise.
DEFAULT_MAX_PULSE_MS = 500
DEFAULT_KEEPALIVE_TIMEOUT_MS = 250
FAULTS = ("none", "estop", "keepalive")


@dataclasses.dataclass(frozen=True)
class DeviceLimits:
    """What a board said in its ``HELLO`` answer."""

    protocol: str
    max_pulse_ms: int
    keepalive_timeout_ms: int


@dataclasses.dataclass(frozen=True)
class DeviceState:
    """A board's ``<state>`` (answer of ``KA`` and ``STATUS``)."""

    armed: bool
    relay_on: bool
    fault: str


def format_state(state: DeviceState) -> str:
    """``DeviceState`` -> ``"armed=1 relay=0 fault=none"``."""
    return f"armed={int(state.armed)} relay={int(state.relay_on)} fault={state.fault}"


def parse_state(text: str) -> DeviceState:
    """``"armed=1 relay=0 fault=none"`` -> :class:`DeviceState`; ``ValueError`` on anything else."""
    fields = dict(item.split("=", 1) for item in text.split() if "=" in item)
    if set(fields) != {"armed", "relay", "fault"} or fields["fault"] not in FAULTS \
            or fields["armed"] not in ("0", "1") or fields["relay"] not in ("0", "1"):
        raise ValueError(f"not a relay board state: {text!r}")
    return DeviceState(fields["armed"] == "1", fields["relay"] == "1", fields["fault"])


def parse_hello(answer: str) -> DeviceLimits:
    """The ``HELLO`` answer -> :class:`DeviceLimits`; ``ValueError`` naming what is wrong."""
    words = answer.split()
    if len(words) != 5 or words[:2] != ["OK", "HELLO"]:
        raise ValueError(f"not a relay board HELLO answer: {answer!r}")
    if words[2] != PROTOCOL:
        raise ValueError(f"relay board speaks protocol {words[2]!r}, this software speaks {PROTOCOL!r}")
    fields = dict(item.split("=", 1) for item in words[3:] if "=" in item)
    try:
        limits = DeviceLimits(words[2], int(fields["max_pulse_ms"]), int(fields["keepalive_timeout_ms"]))
    except (KeyError, ValueError) as exc:
        raise ValueError(f"relay board HELLO answer lacks its limits: {answer!r}") from exc
    if limits.max_pulse_ms <= 0 or limits.keepalive_timeout_ms <= 0:
        raise ValueError(f"relay board reports non-positive limits: {answer!r}")
    return limits


def split_lines(pending: bytes) -> tuple:
    """Received bytes -> ``(complete lines as str, unfinished rest)``; CRs dropped, an endless rest discarded."""
    *lines, rest = pending.replace(b"\r", b"").split(b"\n")
    if len(rest) > 4 * MAX_LINE:
        rest = b""  # garbage without line ends: drop it, as the firmware's bounded buffer does
    return [raw.decode("ascii", errors="replace") for raw in lines], rest


def pulse_command(pulse_ms: float) -> str:
    """The command line for a pulse of ``pulse_ms`` ms (a positive whole number; a fraction is refused)."""
    if isinstance(pulse_ms, bool) or int(pulse_ms) != pulse_ms or pulse_ms <= 0:
        raise ValueError(f"pulse length must be a positive whole number of ms, got {pulse_ms!r}")
    return f"PULSE {int(pulse_ms)}"


class RelayDevice:
    """The board's state machine on a millisecond clock the caller supplies (mirrors ``valve_relay.ino``).

    Call :meth:`handle` for every received line and :meth:`tick` often (the firmware's ``loop()``); both return the
    relay transitions they caused as ``[(relay_on, reason), ...]`` so a caller can log them.
    """

    def __init__(self, max_pulse_ms: int = DEFAULT_MAX_PULSE_MS,
                 keepalive_timeout_ms: int = DEFAULT_KEEPALIVE_TIMEOUT_MS):
        if max_pulse_ms <= 0 or keepalive_timeout_ms <= 0:
            raise ValueError("max_pulse_ms and keepalive_timeout_ms must be > 0")
        self.max_pulse_ms = int(max_pulse_ms)
        self.keepalive_timeout_ms = int(keepalive_timeout_ms)
        self.armed = False
        self.relay_on = False
        self.fault = "none"
        self.estop_held = False
        self._pulse_end_ms = 0.0
        self._last_command_ms = 0.0

    def state(self) -> DeviceState:
        """The current :class:`DeviceState`."""
        return DeviceState(self.armed, self.relay_on, self.fault)

    def ms_until_next_deadline(self, now_ms: float) -> float:
        """Milliseconds until the board must act on its own (pulse end, keep-alive); ``inf`` when idle."""
        deadlines = []
        if self.relay_on:
            deadlines.append(self._pulse_end_ms)
        if self.armed:
            deadlines.append(self._last_command_ms + self.keepalive_timeout_ms)
        return max(min(deadlines) - now_ms, 0.0) if deadlines else float("inf")

    def _relay(self, on, reason, transitions):
        if self.relay_on != on:
            self.relay_on = on
            transitions.append((on, reason))

    def _trip(self, fault, transitions):
        self.armed = False
        self.fault = fault
        self._relay(False, fault, transitions)

    def tick(self, now_ms: float) -> list:
        """Advance to ``now_ms``: end pulses, enforce the keep-alive and the e-stop input."""
        transitions: list = []
        if self.estop_held and (self.armed or self.relay_on or self.fault != "estop"):
            self._trip("estop", transitions)
        if self.relay_on and now_ms >= self._pulse_end_ms:
            self._relay(False, "pulse end", transitions)
        if self.armed and now_ms - self._last_command_ms >= self.keepalive_timeout_ms:
            self._trip("keepalive", transitions)
        return transitions

    def set_estop(self, pressed: bool, now_ms: float) -> list:
        """The e-stop input changed (a pressed button latches fault ``estop``)."""
        self.estop_held = bool(pressed)
        return self.tick(now_ms)

    def handle(self, line: str, now_ms: float) -> tuple:
        """Apply one received line at ``now_ms``; returns ``(answer line, transitions)``."""
        transitions = self.tick(now_ms)
        words = line.strip().split()
        if not words or len(line) > MAX_LINE:
            return "ERR BAD_ARG", transitions
        command, args = words[0], words[1:]
        known = {"HELLO", "ARM", "KA", "STATUS", "PULSE", "OFF", "DISARM", "CLEAR"}
        if command not in known or (args and command != "PULSE"):
            return "ERR UNKNOWN", transitions
        if command == "PULSE" and (len(args) != 1 or not args[0].isascii() or not args[0].isdigit()
                                   or len(args[0]) > 9 or int(args[0]) <= 0):
            return "ERR BAD_ARG", transitions
        self._last_command_ms = now_ms  # any well-formed command is a keep-alive
        if command == "HELLO":
            return (f"OK HELLO {PROTOCOL} max_pulse_ms={self.max_pulse_ms} "
                    f"keepalive_timeout_ms={self.keepalive_timeout_ms}"), transitions
        if command == "KA":
            return f"OK KA {format_state(self.state())}", transitions
        if command == "STATUS":
            return f"OK STATUS {format_state(self.state())}", transitions
        if command == "OFF":
            self._relay(False, "OFF", transitions)
            return "OK OFF", transitions
        if command == "DISARM":
            self.armed = False
            self._relay(False, "DISARM", transitions)
            return "OK DISARMED", transitions
        if command == "CLEAR":
            if self.estop_held:
                return "ERR ESTOP_HELD", transitions
            self.fault = "none"
            return "OK CLEARED", transitions
        if command == "ARM":
            if self.fault == "estop":
                return "ERR ESTOP", transitions
            self.armed = True
            self.fault = "none"
            return "OK ARMED", transitions
        # PULSE
        if not self.armed:
            return "ERR NOT_ARMED", transitions
        if self.relay_on:
            return "ERR BUSY", transitions
        granted_ms = min(int(args[0]), self.max_pulse_ms)
        self._pulse_end_ms = now_ms + granted_ms
        self._relay(True, f"PULSE {granted_ms}", transitions)
        return f"OK PULSE {granted_ms}", transitions
