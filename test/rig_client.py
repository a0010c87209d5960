"""A test's side of a rig node: the Launch action, the operator services and the outcome topic, signed with the
valve's session key as the operator's tools sign them; ``signed=False`` plays a stray participant without the key."""
import math
import time

from rollability_ros.core.records import LaunchCondition


def wait_for_session_key(namespace="", timeout_s=30.0):
    """The valve_controller's session key, once the valve_controller started just before has written it: a
    process start on a loaded machine takes seconds, and the operator's tools refuse to sign without the key."""
    from rollability_ros.core.rig import valve_auth

    path = valve_auth.default_key_path(namespace)
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            return valve_auth.load_session_key(path)
        except valve_auth.AuthError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


class RigClient:
    """Launch action client, operator services and the outcome topic, from the test's node; goals and answers are
    signed with the valve's session key as the operator's tools sign them (``signed=False``: a stray participant)."""

    def __init__(self, spun, signed=True, namespace=""):
        from rollability_ros.nodes._support import ThreadSafeActionClient

        from rollability_ros.action import Launch
        from rollability_ros.core.rig import rig_auth, valve_auth
        from rollability_ros.msg import LaunchOutcome, ValveAuth
        from rollability_ros.nodes._support import RECORD_QOS
        from rollability_ros.srv import ConfirmRegulator, RecordOutcome

        ns = namespace.rstrip("/") + "/" if namespace else ""
        self.spun = spun
        if signed:
            wait_for_session_key(namespace)
        self.signer = rig_auth.KeyFileSigner(valve_auth.default_key_path(namespace)) if signed else None
        self.action = ThreadSafeActionClient(spun.node, Launch, f"{ns}launch")
        self.confirm_client = spun.node.create_client(ConfirmRegulator, f"{ns}rig/confirm")
        self.record_client = spun.node.create_client(RecordOutcome, f"{ns}record_outcome")
        self.outcomes = []
        self.resends = []   # goals sent again because their answer was lost (send_goal_resending)
        spun.node.create_subscription(LaunchOutcome, f"{ns}launch_outcomes", self.outcomes.append, RECORD_QOS)
        self._launch, self._confirm, self._record, self._auth = Launch, ConfirmRegulator, RecordOutcome, ValveAuth

    def auth(self, sign):
        from rollability_ros.nodes._convert import auth_msg

        return auth_msg(sign(self.signer)) if self.signer is not None else self._auth()

    def goal(self, trial_id, condition, run_id="rig-test"):
        from rollability_ros.nodes._convert import condition_to_msg

        goal = self._launch.Goal(run_id=run_id, trial_id=trial_id)
        goal.condition = condition if not isinstance(condition, LaunchCondition) else condition_to_msg(condition)
        goal.auth = self.auth(lambda signer: signer.launch(run_id, trial_id, goal.condition))
        return goal

    def send(self, trial_id, condition, feedback, goal=None):
        from rollability_ros.nodes._support import send_goal_resending

        assert self.action.wait_for_server(timeout_sec=30)
        make = (lambda: goal) if goal is not None else (lambda: self.goal(trial_id, condition))   # signed afresh
        handle = send_goal_resending(self.action, make, self.spun.wait_for, 30, feedback_callback=lambda fb: (
            feedback.append((fb.feedback.phase, fb.feedback.detail))), on_resend=self.resends.append)
        assert handle is not None, "the rig did not answer the goal within 30 s"
        return handle.get_result_async()

    def result(self, future, timeout_s=30):
        assert self.spun.wait_for(future.done, timeout_s)
        return future.result()

    def confirm(self, trial_id="", request=None):
        assert self.confirm_client.wait_for_service(timeout_sec=30)
        request = request or self._confirm.Request(trial_id=trial_id,
                                                   auth=self.auth(lambda signer: signer.confirm(trial_id)))
        return self.confirm_client.call(request, timeout_sec=30)

    def record(self, upright, trial_id="", travel_time_s=math.nan, note="", rest_distance_m=-1.0):
        assert self.record_client.wait_for_service(timeout_sec=30)
        return self.record_client.call(self._record.Request(
            trial_id=trial_id, upright=upright, travel_time_s=travel_time_s, note=note, rest_distance_m=rest_distance_m,
            auth=self.auth(lambda signer: signer.outcome(trial_id, upright, travel_time_s, note, rest_distance_m))),
            timeout_sec=30)
