"""A simulated serial relay board on a pseudo-terminal, run as its own process, for testing the valve path.

Run ``python -m rollability_ros.core.rig.relay_device_sim --port-file PORT --log LOG.jsonl``: it opens a pty, writes
the slave's device path to ``PORT`` (atomically, once it is ready) and answers the line protocol of
:class:`~rollability_ros.core.rig.valve_backends.SerialRelayBackend`. Every event goes to ``LOG`` as one JSON object
per line: ``{"event": "start"|"command"|"mute"|"unmute"|"exit", "relay": "on"|"off", "line": ..., "acked": ...,
"time_s": <Unix time>, "monotonic_s": <CLOCK_MONOTONIC, comparable across processes on Linux>}``, so a test
can prove the relay really was switched off at each fault.

Misbehaviour for fault tests: ``--no-ack`` (switches the relay but never answers), ``--ack-delay-s`` (answers
late), and at run time ``SIGUSR1`` mutes / ``SIGUSR2`` unmutes the acknowledgements.
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

import rollability_ros


class _Board:
    """The relay state, the protocol and the event log of one simulated board."""

    def __init__(self, log_path, open_command, close_command, ack, ack_delay_s, muted):
        self.open_command = open_command
        self.close_command = close_command
        self.ack = ack
        self.ack_delay_s = ack_delay_s
        self.muted = muted
        self.relay_on = False
        self._log = open(log_path, "a", encoding="utf-8", buffering=1)  # line-buffered: readable at once

    def log(self, event, **fields):
        entry = {"event": event, "relay": "on" if self.relay_on else "off",
                 "time_s": time.time(), "monotonic_s": time.monotonic(), **fields}
        self._log.write(json.dumps(entry) + "\n")

    def answer(self, line):
        """Apply one command line; return the answer line (without line ending) or None to stay silent."""
        if line == self.open_command:
            self.relay_on = True
        elif line == self.close_command:
            self.relay_on = False
        else:
            self.log("command", line=line, acked=False, error="unknown command")
            return None if self.muted else "ERR unknown command"
        self.log("command", line=line, acked=not self.muted)
        return None if self.muted else self.ack

    def close(self):
        self.log("exit")
        self._log.close()


def serve(port_file, log_path, open_command, close_command, ack, ack_delay_s=0.0, muted=False):
    """Create the pty, publish its path in ``port_file`` and answer commands until SIGTERM / SIGINT."""
    board = _Board(log_path, open_command, close_command, ack, ack_delay_s, muted)
    master_fd, slave_fd = os.openpty()
    tty.setraw(slave_fd)  # no echo, no newline translation
    received = []  # signals, applied by the loop (a handler writing the log could interleave with it)

    for signum in (signal.SIGTERM, signal.SIGINT, signal.SIGUSR1, signal.SIGUSR2):
        signal.signal(signum, lambda signum, _frame: received.append(signum))
    board.log("start", port=os.ttyname(slave_fd))
    tmp = port_file + ".tmp"
    with open(tmp, "w", encoding="utf-8") as stream:
        stream.write(os.ttyname(slave_fd) + "\n")
    os.replace(tmp, port_file)
    pending = b""
    try:
        while True:
            while received:
                signum = received.pop(0)
                if signum in (signal.SIGUSR1, signal.SIGUSR2):
                    board.muted = signum == signal.SIGUSR1
                    board.log("mute" if board.muted else "unmute")
                else:
                    return
            try:
                readable, _, _ = select.select([master_fd], [], [], 0.05)
            except InterruptedError:
                continue
            if not readable:
                continue
            pending += os.read(master_fd, 4096)
            *lines, pending = pending.replace(b"\r\n", b"\n").replace(b"\r", b"\n").split(b"\n")
            for raw in lines:
                line = raw.decode("ascii", errors="replace").strip()
                if not line:
                    continue
                reply = board.answer(line)
                if reply is not None:
                    if board.ack_delay_s > 0:
                        time.sleep(board.ack_delay_s)
                    os.write(master_fd, (reply + "\n").encode("ascii"))
    finally:
        board.close()
        os.close(master_fd)
        os.close(slave_fd)


class RelaySim:
    """A relay board simulator process for tests: ``with RelaySim(tmp_path) as sim: ... sim.port ...``.

    Parameters
    ----------
    workdir : path
        Folder for the port file and the JSON-lines log.
    open_command, close_command, ack : str
        The protocol (defaults match ``config/rig.yaml``).
    ack_delay_s : float
        Delay before each acknowledgement, s.
    no_ack : bool
        Start muted (switch the relay, never answer).
    """

    def __init__(self, workdir, open_command="RELAY 1 ON", close_command="RELAY 1 OFF", ack="OK",
                 ack_delay_s=0.0, no_ack=False):
        self.port_file = os.path.join(os.fspath(workdir), "relay_port")
        self.log_path = os.path.join(os.fspath(workdir), "relay_log.jsonl")
        self._argv = [sys.executable, "-m", "rollability_ros.core.rig.relay_device_sim", "--port-file", self.port_file, "--log", self.log_path,
                      "--open-command", open_command, "--close-command", close_command, "--ack", ack,
                      "--ack-delay-s", str(ack_delay_s)] + (["--no-ack"] if no_ack else [])
        self.process = None
        self.port = None

    def start(self, timeout_s=10.0):
        """Start the process and wait until its port file appears; returns self."""
        package_root = os.path.dirname(os.path.dirname(os.path.abspath(rollability_ros.__file__)))
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [package_root, os.environ.get("PYTHONPATH")])))
        self.process = subprocess.Popen(self._argv, env=env)
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

    def entries(self):
        """All log entries so far, oldest first."""
        if not os.path.exists(self.log_path):
            return []
        with open(self.log_path, encoding="utf-8") as stream:
            return [json.loads(line) for line in stream if line.endswith("\n")]

    def relay_on(self):
        """The relay state after the last logged event."""
        entries = self.entries()
        return bool(entries) and entries[-1]["relay"] == "on"

    def _signal_and_wait(self, signum, event, timeout_s):
        seen = sum(e["event"] == event for e in self.entries())
        self.process.send_signal(signum)
        deadline = time.monotonic() + timeout_s
        while sum(e["event"] == event for e in self.entries()) == seen:
            if time.monotonic() > deadline:
                raise TimeoutError(f"relay simulator did not log '{event}' within {timeout_s} s")
            time.sleep(0.005)

    def mute(self, timeout_s=5.0):
        """Stop acknowledging (the relay still switches); returns once the simulator has logged it."""
        self._signal_and_wait(signal.SIGUSR1, "mute", timeout_s)

    def unmute(self, timeout_s=5.0):
        """Acknowledge again; returns once the simulator has logged it."""
        self._signal_and_wait(signal.SIGUSR2, "unmute", timeout_s)

    def stop(self, timeout_s=5.0):
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


def main(argv=None):
    """Command-line entry point (``python -m rollability_ros.core.rig.relay_device_sim``)."""
    parser = argparse.ArgumentParser(prog="relay_device_sim", description=__doc__.split("\n\n")[0])
    parser.add_argument("--port-file", required=True, help="file to write the pty device path into")
    parser.add_argument("--log", default=os.devnull, help="JSON-lines log of relay events (default: none)")
    parser.add_argument("--open-command", default="RELAY 1 ON", help="line that switches the relay on")
    parser.add_argument("--close-command", default="RELAY 1 OFF", help="line that switches the relay off")
    parser.add_argument("--ack", default="OK", help="acknowledgement line")
    parser.add_argument("--ack-delay-s", type=float, default=0.0, help="delay before each acknowledgement, s")
    parser.add_argument("--no-ack", action="store_true", help="switch the relay but never acknowledge")
    args = parser.parse_args(argv)
    if args.ack_delay_s < 0:
        parser.error("--ack-delay-s must be >= 0")
    serve(args.port_file, args.log, args.open_command, args.close_command, args.ack, args.ack_delay_s, args.no_ack)
    return 0


if __name__ == "__main__":
    sys.exit(main())
