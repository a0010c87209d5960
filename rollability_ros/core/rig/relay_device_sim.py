"""A simulated valve relay board on a pseudo-terminal, run as its own process, for testing the valve path.

Run ``python -m rollability_ros.core.rig.relay_device_sim [--port-file PORT] [--log LOG.jsonl]``: it opens a pty,
writes the slave's device path to ``PORT`` (atomically, once it is ready), prints it on a ready line
(``relay board simulator ready on /dev/pts/N ...``) and speaks the board protocol of
:mod:`rollability_ros.core.rig.relay_protocol` with the same state machine and timing as the firmware: the board,
not the computer, ends every pulse and drops the relay when the keep-alive stops. Every event goes to ``LOG`` as
one JSON object per line::

    {"event": "start"|"command"|"relay"|"cut"|"restore"|"estop"|"overslept"|"exit", "relay": "on"|"off",
     "line": ..., "answer": ..., "reason": ..., "time_s": <Unix time>,
     "monotonic_s": <CLOCK_MONOTONIC, comparable across processes on Linux>}

``relay`` entries are the relay's own transitions (``reason``: ``PULSE <ms>``, ``pulse end``, ``OFF``,
``DISARM``, ``keepalive``, ``estop``), so a test can measure from the board's side how long the relay was on;
``boot`` entries count bytes lost while the simulated bootloader runs (``--boot-delay-s``). An ``overslept`` entry
(``late_ms``) says this process woke that long after the deadline it had asked the kernel for: the host starved the
simulator, which a real board (a microcontroller of its own) never is, so a keep-alive fault that follows one may
be the simulator's and not the valve node's (the valve node logs its own late keep-alives).

Faults for tests, at run time: ``SIGUSR1`` cuts the serial line (bytes either way are lost, as with a pulled
cable), ``SIGUSR2`` restores it, ``SIGHUP`` presses and releases the e-stop button; ``--ack-delay-s`` answers late.
:class:`RelaySim` starts and reads such a process from a test.
"""
import argparse
import json
import os
import select
import signal
import subprocess
import sys
import time
import tty
import typing

import rollability_ros
from rollability_ros.core.rig.relay_protocol import (DEFAULT_KEEPALIVE_TIMEOUT_MS, DEFAULT_MAX_PULSE_MS,
                                                     RelayDevice, split_lines)


#: A wake-up this much later than the deadline the board's loop asked for is logged as ``overslept``, ms.
OVERSLEPT_MS = 50.0


class _Board:
    """A :class:`RelayDevice` on the monotonic clock, with the event log."""

    def __init__(self, log_path, max_pulse_ms, keepalive_timeout_ms):
        self.device = RelayDevice(max_pulse_ms, keepalive_timeout_ms)
        self._log = open(log_path, "a", encoding="utf-8", buffering=1)  # line-buffered: readable at once

    @staticmethod
    def now_ms() -> float:
        return time.monotonic() * 1000.0

    def log(self, event: str, **fields: typing.Any) -> None:
        entry = {"event": event, "relay": "on" if self.device.relay_on else "off",
                 "time_s": time.time(), "monotonic_s": time.monotonic(), **fields}
        self._log.write(json.dumps(entry) + "\n")

    def log_transitions(self, transitions: typing.Iterable[typing.Tuple[bool, str]]) -> None:
        for _on, reason in transitions:
            self.log("relay", reason=reason)

    def tick(self) -> None:
        self.log_transitions(self.device.tick(self.now_ms()))

    def answer(self, line: str) -> str:
        """Apply one command line; return the answer line (without line ending)."""
        answer, transitions = self.device.handle(line, self.now_ms())
        self.log_transitions(transitions)
        self.log("command", line=line, answer=answer)
        return answer

    def next_deadline_s(self) -> float:
        """Seconds until the board must act on its own (pulse end, keep-alive), capped at 50 ms."""
        return min(50.0, self.device.ms_until_next_deadline(self.now_ms())) / 1000.0

    def close(self) -> None:
        self.log("exit")
        self._log.close()


#: Start of the line the simulator prints once its board answers on the port (a script may wait for it).
READY = "relay board simulator ready on "


def ready_line(port: str, max_pulse_ms: int, keepalive_timeout_ms: int) -> str:
    """The line printed when the simulated board is ready: its port and the setting that uses it."""
    return (f"{READY}{port} (max pulse {max_pulse_ms} ms, keep-alive timeout {keepalive_timeout_ms} ms); use it with "
            f"valve.backend: serial_relay and valve.serial.port: {port}; Ctrl-C stops it")


def serve(port_file: str, log_path: str, max_pulse_ms: int = DEFAULT_MAX_PULSE_MS,
          keepalive_timeout_ms: int = DEFAULT_KEEPALIVE_TIMEOUT_MS, ack_delay_s: float = 0.0,
          boot_delay_s: float = 0.0) -> None:
    """Create the pty, publish its path in ``port_file`` (when given) and on stdout (:func:`ready_line`), and run
    the board until SIGTERM / SIGINT."""
    board = _Board(log_path, max_pulse_ms, keepalive_timeout_ms)
    master_fd, slave_fd = os.openpty()
    tty.setraw(slave_fd)  # no echo, no newline translation
    received: typing.List[int] = []  # signals, applied by the loop (a handler writing the log could interleave with it)
    cut = False

    for handled in (signal.SIGTERM, signal.SIGINT, signal.SIGUSR1, signal.SIGUSR2, signal.SIGHUP):
        signal.signal(handled, lambda signum, _frame: received.append(signum))
    board.log("start", port=os.ttyname(slave_fd), max_pulse_ms=max_pulse_ms,
              keepalive_timeout_ms=keepalive_timeout_ms)
    port = os.ttyname(slave_fd)
    if port_file:
        tmp = port_file + ".tmp"
        with open(tmp, "w", encoding="utf-8") as stream:
            stream.write(port + "\n")
        os.replace(tmp, port_file)
    print(ready_line(port, max_pulse_ms, keepalive_timeout_ms), flush=True)
    pending = b""
    booted_at = time.monotonic() + boot_delay_s  # before this, a bootloader runs: received bytes are lost
    try:
        while True:
            while received:
                signum = received.pop(0)
                if signum in (signal.SIGUSR1, signal.SIGUSR2):
                    cut = signum == signal.SIGUSR1
                    board.log("cut" if cut else "restore")
                elif signum == signal.SIGHUP:
                    board.log_transitions(board.device.set_estop(True, board.now_ms()))
                    board.log("estop")
                    board.device.set_estop(False, board.now_ms())
                else:
                    return
            board.tick()
            asked_s = board.next_deadline_s()
            asleep_at = time.monotonic()
            try:
                readable, _, _ = select.select([master_fd], [], [], asked_s)
            except InterruptedError:
                continue
            late_ms = (time.monotonic() - asleep_at - asked_s) * 1000.0
            if late_ms > OVERSLEPT_MS:
                board.log("overslept", late_ms=round(late_ms, 1))
            if not readable:
                continue
            data = os.read(master_fd, 4096)
            if cut:
                continue  # the wire is cut: the board never sees these bytes
            if time.monotonic() < booted_at:
                board.log("boot", dropped=len(data))
                continue
            lines, pending = split_lines(pending + data)
            for line in lines:
                if not line:
                    continue  # an empty line gets no answer (as in the firmware)
                reply = board.answer(line)
                if ack_delay_s > 0:
                    time.sleep(ack_delay_s)
                    board.tick()
                if not cut:
                    os.write(master_fd, (reply + "\n").encode("ascii"))
    finally:
        board.close()
        os.close(master_fd)
        os.close(slave_fd)


#: A relay on period from the board's log: ``(on entry, off entry or None while still on)``.
Interval = typing.Tuple[typing.Dict[str, typing.Any], typing.Optional[typing.Dict[str, typing.Any]]]


class RelaySim:
    """A relay board simulator process for tests: ``with RelaySim(tmp_path) as sim: ... sim.port ...``.

    Parameters
    ----------
    workdir : path
        Folder for the port file and the JSON-lines log.
    max_pulse_ms, keepalive_timeout_ms : int
        The board's limits (defaults: the firmware's).
    ack_delay_s : float
        Delay before each answer, s.
    boot_delay_s : float
        For this long after start the board drops what it receives (an Uno's bootloader after the port opened), s.
    """

    def __init__(self, workdir, max_pulse_ms=DEFAULT_MAX_PULSE_MS, keepalive_timeout_ms=DEFAULT_KEEPALIVE_TIMEOUT_MS,
                 ack_delay_s=0.0, boot_delay_s=0.0):
        self.port_file = os.path.join(os.fspath(workdir), "relay_port")
        self.log_path = os.path.join(os.fspath(workdir), "relay_log.jsonl")
        self.max_pulse_ms = max_pulse_ms
        self.keepalive_timeout_ms = keepalive_timeout_ms
        self._argv = [sys.executable, "-m", "rollability_ros.core.rig.relay_device_sim", "--port-file",
                      self.port_file, "--log", self.log_path, "--max-pulse-ms", str(max_pulse_ms),
                      "--keepalive-timeout-ms", str(keepalive_timeout_ms), "--ack-delay-s", str(ack_delay_s),
                      "--boot-delay-s", str(boot_delay_s)]
        self.process: typing.Optional[subprocess.Popen] = None
        self.port = None

    def start(self, timeout_s: float = 10.0) -> "RelaySim":
        """Start the process and wait until its port file appears; returns self."""
        package_root = os.path.dirname(os.path.dirname(os.path.abspath(rollability_ros.__file__)))
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [package_root, os.environ.get("PYTHONPATH")])))
        self.process = subprocess.Popen(self._argv, env=env, stdout=subprocess.DEVNULL)
        deadline = time.monotonic() + timeout_s
        while not os.path.exists(self.port_file):
            if self.process.poll() is not None:
                raise RuntimeError(f"relay simulator exited with code {self.process.returncode} before starting")
            if time.monotonic() > deadline:
                self.stop()
                raise TimeoutError(f"relay simulator did not publish its port within {timeout_s} s")
            time.sleep(0.01)
        with open(self.port_file, encoding="utf-8") as stream:
            self.port = stream.read().strip()
        return self

    def entries(self) -> typing.List[typing.Dict[str, typing.Any]]:
        """All log entries so far, oldest first."""
        if not os.path.exists(self.log_path):
            return []
        with open(self.log_path, encoding="utf-8") as stream:
            return [json.loads(line) for line in stream if line.endswith("\n")]

    def relay_on(self) -> bool:
        """The relay state after the last logged event."""
        entries = self.entries()
        return bool(entries) and entries[-1]["relay"] == "on"

    def _signal_and_wait(self, signum, event, timeout_s):
        seen = sum(e["event"] == event for e in self.entries())
        assert self.process is not None, "the simulated board is not running"
        self.process.send_signal(signum)
        deadline = time.monotonic() + timeout_s
        while sum(e["event"] == event for e in self.entries()) == seen:
            if time.monotonic() > deadline:
                raise TimeoutError(f"relay simulator did not log '{event}' within {timeout_s} s")
            time.sleep(0.005)

    def cut(self, timeout_s: float = 5.0) -> None:
        """Cut the serial line (nothing gets through either way); returns once the simulator has logged it."""
        self._signal_and_wait(signal.SIGUSR1, "cut", timeout_s)

    def restore(self, timeout_s: float = 5.0) -> None:
        """Reconnect the serial line; returns once the simulator has logged it."""
        self._signal_and_wait(signal.SIGUSR2, "restore", timeout_s)

    def press_estop(self, timeout_s: float = 5.0) -> None:
        """Press and release the board's e-stop button (the fault latches); returns once logged."""
        self._signal_and_wait(signal.SIGHUP, "estop", timeout_s)

    def longest_oversleep_ms(self) -> float:
        """The longest ``overslept`` delay in the log so far (0 when none): how long the host starved the board."""
        return max((e["late_ms"] for e in self.entries() if e["event"] == "overslept"), default=0.0)

    def relay_intervals(self) -> typing.List[Interval]:
        """The relay's on periods from the board's own log: ``[(on entry, off entry or None), ...]``."""
        intervals: typing.List[Interval] = []
        current: typing.Optional[typing.Dict[str, typing.Any]] = None
        for entry in self.entries():
            if entry["event"] != "relay":
                continue
            if entry["relay"] == "on" and current is None:
                current = entry
            elif entry["relay"] == "off" and current is not None:
                intervals.append((current, entry))
                current = None
        if current is not None:
            intervals.append((current, None))
        return intervals

    def stop(self, timeout_s: float = 5.0) -> None:
        """Terminate the process (killed if it does not exit within ``timeout_s``)."""
        if self.process is None or self.process.poll() is not None:
            return
        self.process.terminate()
        try:
            self.process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc_info):
        self.stop()


def main(argv: typing.Optional[typing.Sequence[str]] = None) -> int:
    """Command-line entry point (``python -m rollability_ros.core.rig.relay_device_sim``)."""
    parser = argparse.ArgumentParser(prog="relay_device_sim", description=__doc__.split("\n\n")[0])
    parser.add_argument("--port-file", default="",
                        help="file to write the pty device path into (it is printed on the ready line too)")
    parser.add_argument("--log", default=os.devnull, help="JSON-lines log of relay events (default: none)")
    parser.add_argument("--max-pulse-ms", type=int, default=DEFAULT_MAX_PULSE_MS,
                        help=f"the board's pulse limit, ms (firmware: {DEFAULT_MAX_PULSE_MS})")
    parser.add_argument("--keepalive-timeout-ms", type=int, default=DEFAULT_KEEPALIVE_TIMEOUT_MS,
                        help=f"armed silence that drops the relay, ms (firmware: {DEFAULT_KEEPALIVE_TIMEOUT_MS})")
    parser.add_argument("--ack-delay-s", type=float, default=0.0, help="delay before each answer, s")
    parser.add_argument("--boot-delay-s", type=float, default=0.0,
                        help="drop received bytes this long after start (a bootloader), s")
    args = parser.parse_args(argv)
    if args.ack_delay_s < 0 or args.boot_delay_s < 0:
        parser.error("--ack-delay-s and --boot-delay-s must be >= 0")
    if args.max_pulse_ms <= 0 or args.keepalive_timeout_ms <= 0:
        parser.error("--max-pulse-ms and --keepalive-timeout-ms must be > 0")
    serve(args.port_file, args.log, args.max_pulse_ms, args.keepalive_timeout_ms, args.ack_delay_s, args.boot_delay_s)
    return 0


if __name__ == "__main__":
    sys.exit(main())
