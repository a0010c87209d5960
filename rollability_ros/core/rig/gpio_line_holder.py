"""The smallest process that owns the valve's GPIO line: the relay board protocol on stdin / stdout.

The ``gpio`` backend (:class:`~rollability_ros.core.rig.valve_boards.GpioHolderBackend`) starts
``python -m rollability_ros.core.rig.gpio_line_holder --chip C --line-offset N ...`` as a child and talks the
board's protocol (:mod:`.relay_protocol`, the same :class:`~.relay_protocol.RelayDevice` state machine) over its
pipes. This process does nothing else, so the line's owner is not the valve_controller with its DDS threads: when
the valve_controller dies (SIGKILL, crash, a Python exception), its end of the pipe closes and its keep-alives stop,
and this process drives the line inactive (end of input at once, keep-alive timeout at the latest) and exits.

It narrows the gap, it does not close it: if this process itself is killed, or the computer freezes, the line keeps
its level; only the hardware pulse limiter of docs/firmware.md bounds the pulse then.
"""
import argparse
import os
import select
import signal
import sys
import time
import typing

from rollability_ros.core.rig.relay_protocol import DEFAULT_KEEPALIVE_TIMEOUT_MS, RelayDevice, split_lines


class HeldLine(typing.Protocol):
    """The valve line this process drives (:class:`~rollability_ros.core.rig.valve_boards.GpioBackend`)."""

    def open_valve(self) -> None:
        """Drive the line active (the valve opens)."""

    def close_valve(self) -> None:
        """Drive the line inactive (the valve closes)."""

    def release(self) -> None:
        """Drive the line inactive and give it back."""


def serve(line: HeldLine, device: RelayDevice, in_fd: int = 0, out_fd: int = 1) -> None:
    """Run ``device`` on the lines of ``in_fd`` until end of input or SIGTERM (SIGINT is ignored), driving ``line``.

    ``line`` has ``open_valve()``, ``close_valve()`` and ``release()``
    (:class:`~rollability_ros.core.rig.valve_boards.GpioBackend`). The line is driven inactive and released at
    the end, whatever ends it.
    """
    stop = []
    signal.signal(signal.SIGTERM, lambda signum, _frame: stop.append(signum))
    # Ctrl-C reaches the whole process group: the valve_controller shuts down in order and closes the pipe
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    pending = b""

    def apply(transitions: typing.Iterable[typing.Tuple[bool, str]]) -> None:
        for relay_on, _reason in transitions:
            (line.open_valve if relay_on else line.close_valve)()

    try:
        while not stop:
            apply(device.tick(time.monotonic() * 1000.0))
            wait_s = min(50.0, device.ms_until_next_deadline(time.monotonic() * 1000.0)) / 1000.0
            try:
                readable, _, _ = select.select([in_fd], [], [], wait_s)
            except InterruptedError:
                continue
            if not readable:
                continue
            data = os.read(in_fd, 4096)
            if not data:
                return  # the valve_controller is gone
            lines, pending = split_lines(pending + data)
            for text in lines:
                if not text:
                    continue
                answer, transitions = device.handle(text, time.monotonic() * 1000.0)
                apply(transitions)
                os.write(out_fd, (answer + "\n").encode("ascii"))
    finally:
        line.release()  # drives the line inactive first


def main(argv: typing.Optional[typing.Sequence[str]] = None) -> int:
    """Command-line entry point (started by the gpio backend, not by people)."""
    from rollability_ros.core.rig.valve_boards import GpioBackend

    parser = argparse.ArgumentParser(prog="gpio_line_holder", description=__doc__.split("\n\n")[0])
    parser.add_argument("--chip", required=True, help="GPIO chip (/dev/gpiochipN or gpiochipN)")
    parser.add_argument("--line-offset", type=int, required=True, help="line offset on that chip")
    parser.add_argument("--active-low", action="store_true", help="a low level opens the valve")
    parser.add_argument("--max-pulse-ms", type=int, required=True, help="longest pulse, ms")
    parser.add_argument("--keepalive-timeout-ms", type=int, default=DEFAULT_KEEPALIVE_TIMEOUT_MS,
                        help="armed silence that drops the line, ms")
    args = parser.parse_args(argv)
    line = GpioBackend(args.chip, args.line_offset, active_high=not args.active_low, consumer="rollability-valve",
                       warn=False)  # the valve_controller that started this process has warned
    line.open()  # requested inactive from the first instant
    serve(line, RelayDevice(args.max_pulse_ms, args.keepalive_timeout_ms))
    return 0


if __name__ == "__main__":
    sys.exit(main())
