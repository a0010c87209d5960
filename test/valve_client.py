"""A test's side of a valve_controller: signed services and heartbeats (as the rig node sends them), the latched
state; ``signed=False`` plays a stray participant on the same domain that does not have the session key."""
import contextlib
import threading


class ValveClient:
    """Service clients, publishers and the latched state of a valve_controller, from the test's node."""

    def __init__(self, spun, namespace="", signed=True):
        from std_msgs.msg import Bool

        from rollability_ros.msg import ValveHeartbeat, ValveState
        from rollability_ros.nodes._support import LATCHED_QOS
        from rollability_ros.srv import ArmValve, FireValve

        self.spun, node = spun, spun.node
        self.namespace = namespace
        ns = namespace.rstrip("/") + "/" if namespace else ""   # the valve's namespace; the test node's is /
        self.signed = signed
        self._signer = None
        self.states = []
        node.create_subscription(ValveState, f"{ns}valve/state", self.states.append, LATCHED_QOS)
        self.arm_client = node.create_client(ArmValve, f"{ns}valve/arm")
        self.fire_client = node.create_client(FireValve, f"{ns}valve/fire")
        self.estop_pub = node.create_publisher(Bool, f"{ns}valve/estop", 10)
        self.heartbeat_pub = node.create_publisher(ValveHeartbeat, f"{ns}rig/heartbeat", 10)
        self._arm, self._fire, self._bool, self._heartbeat = ArmValve, FireValve, Bool, ValveHeartbeat

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
        response = self.arm_client.call(self._arm.Request(arm=on, auth=self.auth("arm" if on else "disarm")),
                                        timeout_sec=30)
        return response.success, response.message

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
