"""E-stop latency from a keypress in `rollability rig console` to the relay off, on the relay board simulator.

Processes: the relay board simulator (``core/rig/relay_device_sim``, the firmware's protocol and timing, its own
event log with CLOCK_MONOTONIC times), the valve_controller node on ``serial_relay``, ``rollability rig console``
on a pseudo-terminal (the key is written into the pty, as a keyboard would), and this script as the rig: it arms
the valve (signed), keeps it alive with signed heartbeats, counts down, fires. For each countdown length:

- **in the countdown**: the key is pressed 0.2 s before the fire; the fire must be refused and the relay never on.
  Measured: keypress -> the valve's first command to the board after it (``OFF``: the board is told to stay off).
- **mid-pulse**: a 450 ms pulse (``max_pulse_ms`` 500), the key pressed 100 ms after the board switched the relay
  on. Measured: keypress -> the board's own ``relay off`` entry.

The target is at most 200 ms: an e-stop typed in the console lands before the fire whenever it is typed more than
that before the end of the countdown (the countdown length sets the window, not the latency). Prints each run,
then min / median / max per case and the ratio of the worst to the target.

    python bench/bench_estop_latency.py [--countdowns 1 2 3] [--runs 3] [--smoke]

Everything runs in a ROS domain of its own (``bench.smoke.isolated_ros``), with its session keys and ROS logs in a
temporary folder. ``--smoke``: one run of each case at a 1 s countdown (bench/smoke.py).
"""
import argparse
import json
import os
import pty
import select
import statistics
import subprocess
import sys
import tempfile
import threading
import time

BENCH_DIR = os.path.dirname(os.path.abspath(__file__))
REPO_ROOT = os.path.dirname(BENCH_DIR)
sys.path.insert(0, REPO_ROOT)

TARGET_MS = 200.0
PULSE_MS = 450


def read_until(fd, marker, timeout_s, seen=b""):
    """Bytes from ``fd`` until ``marker`` appears (RuntimeError with what came after ``timeout_s``)."""
    deadline = time.monotonic() + timeout_s
    while marker.encode() not in seen:
        if time.monotonic() > deadline:
            raise RuntimeError(f"no {marker!r} within {timeout_s:g} s; got: {seen.decode(errors='replace')}")
        readable, _, _ = select.select([fd], [], [], 0.1)
        if readable:
            try:
                seen += os.read(fd, 4096)
            except OSError:
                break
    return seen


class Rig:
    """This script's side: the valve's signed services and heartbeats, over rclpy."""

    def __init__(self):
        import rclpy
        from rclpy.executors import MultiThreadedExecutor
        from rclpy.node import Node

        from rollability_ros.msg import ValveHeartbeat, ValveState
        from rollability_ros.nodes._support import LATCHED_QOS
        from rollability_ros.srv import ArmValve, FireValve

        rclpy.init(args=[])
        self.node = Node("bench_estop_rig")
        self.arm_client = self.node.create_client(ArmValve, "valve/arm")
        self.fire_client = self.node.create_client(FireValve, "valve/fire")
        self.heartbeats = self.node.create_publisher(ValveHeartbeat, "rig/heartbeat", 10)
        self._state = None
        self._state_changed = threading.Condition()
        self.node.create_subscription(ValveState, "valve/state", self._on_state, LATCHED_QOS)
        self._types = ArmValve, FireValve, ValveHeartbeat
        self.executor = MultiThreadedExecutor(2)
        self.executor.add_node(self.node)
        threading.Thread(target=self.executor.spin, daemon=True).start()
        self._stop = threading.Event()
        self._signer = None

    def _on_state(self, msg):
        with self._state_changed:
            self._state = msg
            self._state_changed.notify_all()

    def wait_state(self, what, match, timeout_s=10.0):
        """Block until the valve's latched state satisfies ``match`` (RuntimeError naming ``what`` after the wait)."""
        with self._state_changed:
            if not self._state_changed.wait_for(lambda: self._state is not None and match(self._state), timeout_s):
                last = self._state
                raise RuntimeError(f"the valve did not report {what} within {timeout_s:g} s; last state: "
                                   f"{last and (last.armed, last.fault, last.fault_reason)}")

    def sign(self, command, pulse_ms=None):
        from rollability_ros.core.rig import valve_auth
        from rollability_ros.nodes._convert import auth_msg

        if self._signer is None:
            self._signer = valve_auth.RequestSigner(valve_auth.load_session_key(valve_auth.default_key_path("")))
        return auth_msg(self._signer.sign(command, pulse_ms))

    def ready(self, timeout_s=60.0):
        if not (self.arm_client.wait_for_service(timeout_sec=timeout_s)
                and self.fire_client.wait_for_service(timeout_sec=timeout_s)):
            raise RuntimeError("the valve_controller's services did not appear")
        deadline = time.monotonic() + timeout_s
        while self.heartbeats.get_subscription_count() == 0:
            if time.monotonic() > deadline:
                raise RuntimeError("the valve_controller does not subscribe to rig/heartbeat")
            time.sleep(0.05)
        threading.Thread(target=self._beat, daemon=True).start()

    def _beat(self):
        while not self._stop.wait(0.05):
            self.heartbeats.publish(self._types[2](auth=self.sign("heartbeat")))

    def set_armed(self, armed):
        response = self.arm_client.call(self._types[0].Request(arm=armed, auth=self.sign("arm" if armed else
                                                                                          "disarm")), timeout_sec=10)
        if response is None or not response.success:
            raise RuntimeError(f"{'arm' if armed else 'disarm'} refused: {response and response.message}")

    def fire(self, pulse_ms):
        """``(fired, message)``: the valve's answer to one signed fire request."""
        response = self.fire_client.call(self._types[1].Request(pulse_ms=pulse_ms, auth=self.sign("fire", pulse_ms)),
                                         timeout_sec=10)
        if response is None:
            return False, "no answer within 10 s"
        return response.success, response.message

    def close(self):
        import rclpy

        self._stop.set()
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown()


def measure(countdowns, runs):
    from bench.smoke import isolated_ros
    from rollability_ros.core.rig.relay_device_sim import RelaySim

    scratch = tempfile.TemporaryDirectory(prefix="bench-estop-")   # removed when this returns
    work = scratch.name
    _lock = isolated_ros(work)   # the valve's session key and the ROS logs in ``work`` too
    sim = RelaySim(work).start()
    valve_log = open(os.path.join(work, "valve.log"), "wb")
    valve = subprocess.Popen([sys.executable, "-m", "rollability_ros.nodes.valve_controller", "--ros-args",
                              "-p", "valve.backend:=serial_relay", "-p", f"valve.serial.port:={sim.port}",
                              "-p", "valve.watchdog_ms:=3000", "-p", "valve.heartbeat_period_ms:=50",
                              "-p", "valve.max_pulse_ms:=500", "-p", "valve.arm_timeout_s:=60.0"],
                             stdout=valve_log, stderr=subprocess.STDOUT)
    master, slave = pty.openpty()
    console = subprocess.Popen([sys.executable, "-m", "rollability_ros.cli", "rig", "console", "--namespace", "/",
                                "--timeout-s", "60"], stdin=slave, stdout=slave, stderr=slave, cwd=work)
    os.close(slave)
    rig = Rig()
    rows = []
    try:
        rig.ready()
        read_until(master, "console ready", 90)
        for countdown_s in countdowns:
            for run in range(runs):
                rows.append(("countdown", countdown_s, run, *estop_in_countdown(rig, sim, master, countdown_s)))
                rows.append(("mid-pulse", countdown_s, run, *estop_mid_pulse(rig, sim, master, countdown_s)))
    finally:
        rig.close()
        os.write(master, b"q")
        for process in (console, valve):
            try:
                if process is not console:
                    process.terminate()
                process.wait(10)
            except subprocess.TimeoutExpired:
                process.kill()
        sim.stop()
        valve_log.close()
    return rows


def _entries_after(sim, t0):
    return [e for e in sim.entries() if e["monotonic_s"] > t0]


def _wait_entry(sim, t0, match, timeout_s=5.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for entry in _entries_after(sim, t0):
            if match(entry):
                return entry
        time.sleep(0.005)
    raise RuntimeError(f"the board logged nothing matching within {timeout_s:g} s")


def _press(master):
    pressed = time.monotonic()
    os.write(master, b"e")
    return pressed


def _reset(rig, master):
    """Acknowledge the last stop and arm again, each step confirmed by the valve's own state (not by a sleep:
    on a loaded machine an e-stop still in flight would latch after the acknowledgement and refuse the fire)."""
    rig.set_armed(False)
    rig.wait_state("disarmed without a fault", lambda s: not s.armed and not s.fault)
    rig.set_armed(True)
    rig.wait_state("armed", lambda s: s.armed and not s.fault)


def _latched(rig):
    rig.wait_state("the e-stop latched", lambda s: s.fault and "e-stop" in s.fault_reason)


def estop_in_countdown(rig, sim, master, countdown_s):
    """Arm, count down, the key 0.2 s before the fire, then the fire: ``(latency ms to the board's OFF, fired)``."""
    _reset(rig, master)
    time.sleep(max(0.0, countdown_s - 0.2))
    pressed = _press(master)
    time.sleep(0.2)
    fired, _ = rig.fire(PULSE_MS)
    off = _wait_entry(sim, pressed, lambda e: e["event"] == "command" and e["line"].startswith("OFF"))
    relay_on = any(e["event"] == "relay" and e["relay"] == "on" for e in _entries_after(sim, pressed))
    _latched(rig)
    return (off["monotonic_s"] - pressed) * 1000.0, fired or relay_on


def estop_mid_pulse(rig, sim, master, countdown_s):
    """Arm, count down, fire 450 ms, the key 100 ms into the pulse: ``(latency ms to relay off, pulse ms)``."""
    _reset(rig, master)
    time.sleep(countdown_s)
    started = time.monotonic()
    answer = []
    threading.Thread(target=lambda: answer.append(rig.fire(PULSE_MS)), daemon=True).start()
    deadline = time.monotonic() + 10.0
    on = None
    while on is None and time.monotonic() < deadline:
        on = next((e for e in _entries_after(sim, started) if e["event"] == "relay" and e["relay"] == "on"), None)
        if on is None and answer and not answer[0][0]:
            raise RuntimeError(f"the valve refused the fire: {answer[0][1]}")
        time.sleep(0.005)
    if on is None:
        raise RuntimeError("the board never switched the relay on within 10 s of the fire")
    time.sleep(max(0.0, on["monotonic_s"] + 0.1 - time.monotonic()))
    pressed = _press(master)
    off = _wait_entry(sim, on["monotonic_s"], lambda e: e["event"] == "relay" and e["relay"] == "off")
    _latched(rig)
    return (off["monotonic_s"] - pressed) * 1000.0, (off["monotonic_s"] - on["monotonic_s"]) * 1000.0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--countdowns", type=float, nargs="+", default=[1.0, 2.0, 3.0], help="countdown lengths, s")
    parser.add_argument("--runs", type=int, default=3, help="runs per countdown and case")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: one run of each case at a 1 s countdown; "
                                                             "the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    if args.smoke:
        args.countdowns, args.runs = [1.0], 1
    rows = measure(args.countdowns, args.runs)
    print(f"{'case':10} {'countdown s':>11} {'run':>3} {'keypress->off ms':>16}  detail")
    for case, countdown_s, run, latency_ms, detail in rows:
        if case == "countdown":
            text = "FIRED (e-stop too late)" if detail else "fire refused, relay never on"
        else:
            text = f"relay on {detail:.0f} ms of the {PULSE_MS} ms pulse"
        print(f"{case:10} {countdown_s:11g} {run:3d} {latency_ms:16.1f}  {text}")
    print()
    for case in ("countdown", "mid-pulse"):
        values = [row[3] for row in rows if row[0] == case]
        print(f"{case:10}: keypress->relay off min {min(values):.1f} / median {statistics.median(values):.1f} / "
              f"max {max(values):.1f} ms over {len(values)} runs; worst / target {TARGET_MS:g} ms = "
              f"{max(values) / TARGET_MS:.2f}")
    late = [row for row in rows if row[0] == "countdown" and row[4]]
    print(f"e-stops pressed 0.2 s before the fire that let it fire: {len(late)} of "
          f"{sum(row[0] == 'countdown' for row in rows)}")
    print("raw rows: " + json.dumps([list(row) for row in rows]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
