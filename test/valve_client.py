"""A test's side of a valve_controller: signed services and heartbeats (as the rig node sends them), the latched
state; ``signed=False`` plays a stray participant on the same domain that does not have the session key."""
import contextlib
import functools
import signal
import threading
import time

from ros_fixtures import transitions_qos


class ValveClient:
    """Service clients, publishers and the latched state of a valve_controller, from the test's node."""

    #: every client made in this process, oldest first (a test retried after a stall looks at its own)
    created = []

    def __init__(self, spun, namespace="", signed=True):
        from std_msgs.msg import Bool

        from rollability_ros.msg import ValveHeartbeat, ValveState
        from rollability_ros.srv import ArmValve, FireValve

        self.spun, node = spun, spun.node
        self.namespace = namespace
        ns = namespace.rstrip("/") + "/" if namespace else ""   # the valve's namespace; the test node's is /
        self.signed = signed
        self._signer = None
        self.states = []
        node.create_subscription(ValveState, f"{ns}valve/state", self.states.append, transitions_qos())
        self.arm_client = node.create_client(ArmValve, f"{ns}valve/arm")
        self.fire_client = node.create_client(FireValve, f"{ns}valve/fire")
        self.estop_pub = node.create_publisher(Bool, f"{ns}valve/estop", 10)
        self.heartbeat_pub = node.create_publisher(ValveHeartbeat, f"{ns}rig/heartbeat", 10)
        self._arm, self._fire, self._bool, self._heartbeat = ArmValve, FireValve, Bool, ValveHeartbeat
        self.longest_heartbeat_gap_s = 0.0
        ValveClient.created.append(self)

    def auth(self, command, pulse_ms=None):
        """A ``ValveAuth`` signed with the key file the running valve wrote (or an empty one, unsigned)."""
        from rollability_ros.core.rig import valve_auth
        from rollability_ros.msg import ValveAuth
        from rollability_ros.nodes._convert import auth_msg

        if not self.signed:
            return ValveAuth()
        try:  # the current key file (a restarted valve writes a new one) ...
            key = valve_auth.load_session_key(valve_auth.default_key_path(self.namespace))
            if self._signer is None or self._signer.session_key != key:
                self._signer = valve_auth.RequestSigner(key)
        except valve_auth.AuthError:
            if self._signer is None:
                raise
            # ... or, once the valve removed it at its exit, the last one read (as the rig node does)
        return auth_msg(self._signer.sign(command, pulse_ms))

    def ready(self, log):
        assert self.arm_client.wait_for_service(timeout_sec=30), log()
        assert self.fire_client.wait_for_service(timeout_sec=30), log()
        assert self.spun.wait_for(lambda: self.states, 30), log()
        assert self.spun.wait_for(lambda: self.estop_pub.get_subscription_count() > 0, 30), log()
        # heartbeats sent before the valve has matched this publisher are lost and would trip the watchdog
        assert self.spun.wait_for(lambda: self.heartbeat_pub.get_subscription_count() > 0, 30), log()

    def arm(self, on=True):
        response = self.answered(self.arm_client, lambda: self._arm.Request(arm=on, auth=self.auth(
            "arm" if on else "disarm")), "arm" if on else "disarm")
        return response.success, response.message

    def answered(self, client, request, what, attempts=3, timeout_s=10.0):
        """The answer to an idempotent request (arm, disarm, a refused one), asked again when none came: after a
        server restarts, DDS can drop a request sent before the new server matched this client (a lost request is
        not the valve's verdict). ``request`` builds a freshly signed request per try. Never used for fire."""
        for _ in range(attempts):
            client.wait_for_service(timeout_sec=timeout_s)
            response = client.call(request(), timeout_sec=timeout_s)
            if response is not None:
                return response
        raise AssertionError(f"no answer to {what} in {attempts} tries of {timeout_s:g} s")

    def fire(self, pulse_ms):
        return self.fire_client.call(self.fire_request(pulse_ms), timeout_sec=30)

    def fire_request(self, pulse_ms):
        return self._fire.Request(pulse_ms=pulse_ms, auth=self.auth("fire", pulse_ms))

    def estop(self):
        self.estop_pub.publish(self._bool(data=True))

    def heartbeat(self):
        self.heartbeat_pub.publish(self._heartbeat(auth=self.auth("heartbeat")))

    @contextlib.contextmanager
    def heartbeats(self, period_s=0.05):
        """The rig's heartbeat, sent from a background thread while the block runs (as the rig node does)."""
        stop = threading.Event()

        def beat():
            last = time.monotonic()
            while not stop.wait(period_s):
                self.heartbeat()
                now = time.monotonic()
                self.longest_heartbeat_gap_s = max(self.longest_heartbeat_gap_s, now - last)
                last = now
        thread = threading.Thread(target=beat, daemon=True)
        thread.start()
        try:
            yield
        finally:
            stop.set()
            thread.join()

    def last(self):
        return self.states[-1]


# --- a test process that stalls --------------------------------------------------------------------------------------
# On a shared 2-core machine a process can go unscheduled for hundreds of ms. The valve side handles that as it
# must (the board ends the pulse, the watchdog latches), but a test that stalled misses what it set out to check:
# a pulse's on window or a fault injected mid-pulse. Such a case proves nothing either way and runs again.

class TestProcessStalled(Exception):
    """This test's own process was descheduled long enough to miss what it checks."""

    __test__ = False   # not a test class, whatever its name


def retried_on_stall(watchdog_ms, attempts=3):
    """Decorator: run the test again (new valve processes, same board) when it raised :class:`TestProcessStalled`,
    or failed while this process's heartbeats paused past 80% of ``watchdog_ms`` (the valve then rightly latched
    a watchdog fault the case did not inject); a stall in every attempt fails it. Any other failure fails at once.
    Processes the test started with the ``start_node`` fixture are killed between attempts, and a serial line the
    test cut on the ``relay`` fixture is restored."""
    def decorate(test):
        @functools.wraps(test)
        def run(**fixtures):
            stalls = []
            start = fixtures.get("start_node")
            for _ in range(attempts):
                started = []
                if start is not None:
                    def tracked_start(*args, **kwargs):
                        started.append(start(*args, **kwargs))
                        return started[-1]
                    fixtures["start_node"] = tracked_start
                clients = len(ValveClient.created)
                try:
                    return test(**fixtures)
                except (TestProcessStalled, AssertionError) as failure:
                    gap_ms = max((c.longest_heartbeat_gap_s for c in ValveClient.created[clients:]), default=0.0)
                    gap_ms *= 1000.0
                    if not isinstance(failure, TestProcessStalled) and gap_ms <= 0.8 * watchdog_ms:
                        raise
                    stalls.append(f"{failure} (longest heartbeat gap {gap_ms:.0f} ms)")
                    for process in started:
                        process.signal(signal.SIGKILL)
                        process.stop()
                    relay = fixtures.get("relay")
                    line = [e["event"] for e in relay.entries() if e["event"] in ("cut", "restore")] if relay else []
                    if line and line[-1] == "cut":
                        relay.restore()
            raise AssertionError(f"this test's process stalled in all {attempts} attempts: {stalls}")
        return run
    return decorate


def longest_command_gap_s(relay):
    """The longest time between two consecutive lines the board received (its own log's monotonic clock), s."""
    stamps = [entry["monotonic_s"] for entry in relay.entries() if entry["event"] == "command"]
    return max((later - earlier for earlier, later in zip(stamps, stamps[1:])), default=0.0)


def fire_and_wait_on(valve, spun, relay, pulse_ms, watchdog_ms):
    """Ask for a ``pulse_ms`` pulse without waiting for the answer; return the call's future once the board
    switched the relay on. :class:`TestProcessStalled` if the whole pulse passed while this process was not
    polling, its heartbeats paused past 80% of ``watchdog_ms``, or no line reached the board for longer than its
    keep-alive timeout before the pulse (it then disarmed itself, as it must, before the case began)."""
    pulses_before = len(relay.relay_intervals())
    future = valve.fire_client.call_async(valve.fire_request(pulse_ms))
    if not spun.wait_for(relay.relay_on, 15):
        answer = future.result().message if spun.wait_for(future.done, 5) else "no answer"
        if len(relay.relay_intervals()) > pulses_before:
            raise TestProcessStalled(f"the whole {pulse_ms} ms pulse passed unseen (fire answered: {answer})")
        gap_ms = longest_command_gap_s(relay) * 1000.0
        # the board's own answers say why it disarmed; the valve words it "board fault keepalive" the first time and
        # "board disarmed itself" when that fault was already reported, so its wording is not the evidence
        board_keepalive = any("fault=keepalive" in str(entry.get("answer", "")) for entry in relay.entries())
        if (board_keepalive or "keepalive" in answer) and gap_ms > relay.keepalive_timeout_ms:
            # the board disarmed itself (its safe answer) because no line reached it for longer than its keep-alive
            # timeout before the pulse: the machine starved the valve node or the board, the case never began
            raise TestProcessStalled(f"no command reached the board for {gap_ms:.0f} ms (keep-alive timeout "
                                     f"{relay.keepalive_timeout_ms} ms) before the pulse; the board itself overslept "
                                     f"up to {relay.longest_oversleep_ms():.0f} ms; fire answered: {answer}")
        raise AssertionError(f"the relay never switched on; fire answered: {answer}; longest gap between the "
                             f"board's lines {gap_ms:.0f} ms (keep-alive timeout {relay.keepalive_timeout_ms} ms; "
                             f"the board overslept up to {relay.longest_oversleep_ms():.0f} ms); "
                             f"valve state: "
                             f"{valve.last() if valve.states else None}; board log: {relay.entries()[-5:]}")
    gap_ms = valve.longest_heartbeat_gap_s * 1000.0
    if gap_ms > 0.8 * watchdog_ms:
        raise TestProcessStalled(f"heartbeats paused {gap_ms:.0f} ms (watchdog {watchdog_ms} ms)")
    return future
