"""valve_controller node over real DDS, in its own process: dry_run, and serial_relay against the relay
simulator on a pty (the relay's own log proves the valve was switched off at every fault)."""
import contextlib
import signal
import threading
import time

import pytest

from rollability_ros.core.rig.relay_device_sim import RelaySim

WATCHDOG_MS = 3000   # the test beats every 50 ms; a loaded 2-core machine has shown 1 s gaps


class ValveClient:
    """Service clients, publishers and the latched state of a valve_controller, from the test's node."""

    def __init__(self, spun):
        from std_msgs.msg import Bool, Header
        from std_srvs.srv import SetBool

        from rollability_ros.msg import ValveState
        from rollability_ros.nodes._support import LATCHED_QOS
        from rollability_ros.srv import FireValve

        self.spun, node = spun, spun.node
        self.states = []
        node.create_subscription(ValveState, "valve/state", self.states.append, LATCHED_QOS)
        self.arm_client = node.create_client(SetBool, "valve/arm")
        self.fire_client = node.create_client(FireValve, "valve/fire")
        self.estop_pub = node.create_publisher(Bool, "valve/estop", 10)
        self.heartbeat_pub = node.create_publisher(Header, "rig/heartbeat", 10)
        self._set_bool, self._fire, self._bool, self._header = SetBool, FireValve, Bool, Header

    def ready(self, log):
        assert self.arm_client.wait_for_service(timeout_sec=30), log()
        assert self.fire_client.wait_for_service(timeout_sec=30), log()
        assert self.spun.wait_for(lambda: self.states, 30), log()
        assert self.spun.wait_for(lambda: self.estop_pub.get_subscription_count() > 0, 30), log()
        # heartbeats sent before the valve has matched this publisher are lost and would trip the watchdog
        assert self.spun.wait_for(lambda: self.heartbeat_pub.get_subscription_count() > 0, 30), log()

    def arm(self, on=True):
        response = self.arm_client.call(self._set_bool.Request(data=on), timeout_sec=30)
        return response.success, response.message

    def fire(self, pulse_ms):
        return self.fire_client.call(self._fire.Request(pulse_ms=pulse_ms), timeout_sec=30)

    def estop(self):
        self.estop_pub.publish(self._bool(data=True))

    def heartbeat(self):
        self.heartbeat_pub.publish(self._header())

    @contextlib.contextmanager
    def heartbeats(self, period_s=0.05):
        """The rig's heartbeat, sent from a background thread while the block runs (as the rig node does)."""
        stop = threading.Event()

        def beat():
            while not stop.wait(period_s):
                self.heartbeat()
        thread = threading.Thread(target=beat, daemon=True)
        thread.start()
        try:
            yield
        finally:
            stop.set()
            thread.join()

    def last(self):
        return self.states[-1]


def start_valve(start_node, backend="dry_run", **params):
    return start_node("valve_controller", params={"valve.backend": backend, "valve.watchdog_ms": WATCHDOG_MS,
                                                  "valve.max_pulse_ms": 400, **params})


def test_dry_run_arm_fire_refusals_estop_and_watchdog(ros_node, start_node):
    process = start_valve(start_node)
    valve = ValveClient(ros_node)
    valve.ready(process.log)
    first = valve.last()
    assert (first.armed, first.open, first.fault, first.backend) == (False, False, False, "dry_run")

    refused = valve.fire(100)
    assert not refused.success and "disarmed" in refused.message and refused.state.pulses == 0
    with valve.heartbeats():
        assert valve.arm() == (True, "armed")
        too_long = valve.fire(401)
        assert not too_long.success and "exceeds max_pulse_ms 400" in too_long.message
        fired = valve.fire(50)
        assert fired.success and fired.state.pulses == 1 and fired.state.last_pulse_ms == 50
        assert not fired.state.open
        assert ros_node.wait_for(lambda: valve.last().pulses == 1 and not valve.last().open, 10)

        valve.estop()
        assert ros_node.wait_for(lambda: valve.last().fault, 10), process.log()
        assert "e-stop" in valve.last().fault_reason and not valve.last().armed
        ok, reason = valve.arm()
        assert not ok and "fault latched" in reason
        assert not valve.fire(50).success
        assert valve.arm(False)[0] and not valve.last().fault                     # acknowledge
        assert valve.arm()[0]
        # heartbeats keep it armed past the watchdog limit; silence (after this block) trips it
        time.sleep(1.5 * WATCHDOG_MS / 1000)
        assert valve.last().armed and not valve.last().fault, process.log()
    silent_from = time.monotonic()
    assert ros_node.wait_for(lambda: valve.last().fault, 5 * WATCHDOG_MS / 1000), process.log()
    assert time.monotonic() - silent_from < 5 * WATCHDOG_MS / 1000
    assert "watchdog" in valve.last().fault_reason and not valve.last().armed
    assert "valve state: armed=False open=False fault=True (watchdog" in process.log()

    assert process.stop() == 0


def test_parameters_are_fixed_and_invalid_ones_refused_at_start(ros_node, start_node):
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    bad = start_node("valve_controller", params={"valve.launch_pulse_ms": 900}, name="bad_valve")
    assert ros_node.wait_for(lambda: not bad.alive(), 30)
    assert bad.process.returncode == 2 and "launch_pulse_ms" in bad.log()

    process = start_valve(start_node)
    client = ros_node.node.create_client(SetParameters, "valve_controller/set_parameters")
    assert client.wait_for_service(timeout_sec=30), process.log()
    request = SetParameters.Request(parameters=[Parameter("valve.max_pulse_ms", value=5000).to_parameter_msg()])
    result = client.call(request, timeout_sec=30).results[0]
    assert not result.successful and "read-only" in result.reason   # read_only in its descriptor


def _relay_events(sim, event="command"):
    return [e for e in sim.entries() if e["event"] == event]


@pytest.fixture
def relay(tmp_path):
    with RelaySim(tmp_path) as sim:
        yield sim


def test_serial_relay_pulse_estop_cuts_pulse_and_sigterm_closes(ros_node, start_node, relay):
    process = start_valve(start_node, "serial_relay", **{"valve.serial.port": relay.port,
                                                         "valve.max_pulse_ms": 5000})
    valve = ValveClient(ros_node)
    valve.ready(process.log)
    assert valve.last().backend == "serial_relay" and not valve.last().fault, process.log()
    assert [e["line"] for e in _relay_events(relay)] == ["RELAY 1 OFF"]      # driven closed at start

    with valve.heartbeats():
        assert valve.arm()[0]
        before = len(_relay_events(relay))
        assert valve.fire(60).success
        # the simulator logs a command just after acknowledging it: wait for both entries
        assert ros_node.wait_for(lambda: len(_relay_events(relay)) >= before + 2, 10)
        on, off = _relay_events(relay)[-2:]
        assert (on["line"], off["line"], off["relay"]) == ("RELAY 1 ON", "RELAY 1 OFF", "off")
        assert 0.04 < off["monotonic_s"] - on["monotonic_s"] < 0.5

        # an e-stop cuts a long pulse: the relay is off long before the 3 s pulse would have ended
        future = valve.fire_client.call_async(valve._fire.Request(pulse_ms=3000))
        assert ros_node.wait_for(relay.relay_on, 10), process.log()
        valve.estop()
        estop_at = time.monotonic()
        assert ros_node.wait_for(lambda: not relay.relay_on(), 5)
        assert ros_node.wait_for(future.done, 10)
        assert not future.result().success and "pulse cut" in future.result().message
        assert _relay_events(relay)[-1]["monotonic_s"] - estop_at < 1.0
        assert valve.arm(False)[0] and valve.arm()[0]

        # SIGTERM while armed: the node drives the relay off before exiting
        before = len(_relay_events(relay))
        process.signal(signal.SIGTERM)
        assert ros_node.wait_for(lambda: not process.alive(), 15), process.log()
    assert process.process.returncode == 0, process.log()
    closing = _relay_events(relay)[before:]
    assert closing and all(e["line"] == "RELAY 1 OFF" and e["acked"] for e in closing)
    assert not relay.relay_on()


def test_serial_relay_watchdog_and_sigint_mid_pulse(ros_node, start_node, relay):
    process = start_valve(start_node, "serial_relay", **{"valve.serial.port": relay.port})
    valve = ValveClient(ros_node)
    valve.ready(process.log)
    assert valve.arm()[0]
    assert ros_node.wait_for(lambda: valve.last().fault, 5 * WATCHDOG_MS / 1000)   # nobody sends heartbeats
    assert "watchdog" in valve.last().fault_reason
    assert _relay_events(relay)[-1]["line"] == "RELAY 1 OFF" and not relay.relay_on()
    with valve.heartbeats():
        assert valve.arm(False)[0] and valve.arm()[0]
        valve.fire_client.call_async(valve._fire.Request(pulse_ms=400))   # the node is stopped mid-pulse
        assert ros_node.wait_for(relay.relay_on, 10), process.log()
        process.signal(signal.SIGINT)
    assert ros_node.wait_for(lambda: not relay.relay_on(), 5), process.log()
    assert ros_node.wait_for(lambda: not process.alive(), 15), process.log()
    assert not relay.relay_on()


def test_operator_cli_estop_disarm_arm(ros_node, start_node):
    import subprocess
    import sys

    process = start_valve(start_node)
    valve = ValveClient(ros_node)
    valve.ready(process.log)

    def rig_cli(*args):
        return subprocess.run([sys.executable, "-m", "rollability_ros.cli", "rig", *args], capture_output=True,
                              text=True, timeout=60)

    assert rig_cli("arm").returncode == 0 and ros_node.wait_for(lambda: valve.last().armed, 10)
    assert "e-stop sent" in rig_cli("estop").stdout
    assert ros_node.wait_for(lambda: valve.last().fault, 10)
    refused = rig_cli("arm")
    assert refused.returncode == 1 and "fault latched" in refused.stdout
    assert rig_cli("disarm").returncode == 0 and ros_node.wait_for(lambda: not valve.last().fault, 10)
    stray = rig_cli("outcome", "upright", "--timeout-s", "1")
    assert stray.returncode == 2 and "record_outcome is not available" in stray.stderr
