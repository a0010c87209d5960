"""The orchestrators' window on the running graph, over ROS: ``rollability study`` and ``bringup`` show their
progress from what the nodes publish, never from a node's store (the logger or the optimizer may write where the
orchestrator cannot read, or on another computer).

:class:`RosGraphObserver` implements :class:`~rollability_ros.core.graph.progress.GraphObserver` with a small
rclpy node of its own (own context, one executor thread) in the orchestrator's process:

- ``optimizer_progress`` (rollability_ros/OptimizerProgress, the optimizer's latched topic): generations done, the
  run's cap, best so far, simulated trials evaluated;
- ``summary`` (rollability_ros/OutcomeSummary, the outcome logger's latched topic): launch outcomes stored;
- ``campaign_progress`` (rollability_ros/CampaignProgress, the graph campaign's latched topic): its trials stored,
  planned and its ETA;
- ``get_summary`` (rollability_ros/GetSummary, the outcome logger's service): launch outcomes stored for one run,
  asked again at most once per call while no answer is pending (the callers poll about once a second); a request
  unanswered for :data:`REQUEST_TIMEOUT_S` (its logger was killed: a restarted one never answers it) is dropped
  and asked again, so the count goes on through a logger's restart.
"""
import threading
import time
import typing

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from rollability_ros.core.records import RunProgress
from rollability_ros.msg import CampaignProgress, OptimizerProgress, OutcomeSummary
from rollability_ros.nodes._convert import progress_from_msg
from rollability_ros.nodes._support import LATCHED_QOS, ExecutorThread
from rollability_ros.srv import GetSummary

#: The optimizer publishes progress latched (depth 1); this side keeps a deeper queue so that generations
#: published between two executor turns are all received.
_PROGRESS_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL, history=HistoryPolicy.KEEP_LAST)


#: Longest wait for the logger's answer before the request is dropped and asked again, s.
REQUEST_TIMEOUT_S = 5.0


class RosGraphObserver:
    """A :class:`~rollability_ros.core.graph.progress.GraphObserver` over ROS in namespace ``namespace`` (see the
    module docstring); a context manager (``close`` stops its node and context)."""

    def __init__(self, namespace: str = "", node_name: str = "graph_observer",
                 request_timeout_s: float = REQUEST_TIMEOUT_S) -> None:
        self._request_timeout_s = request_timeout_s
        self._pending_since = 0.0
        self._context = rclpy.Context()
        rclpy.init(args=[], context=self._context, signal_handler_options=SignalHandlerOptions.NO)
        self._node = Node(node_name, namespace=namespace or None, context=self._context,
                          start_parameter_services=False)
        self._lock = threading.Lock()
        self._progress: typing.List[RunProgress] = []
        self._launches: typing.Optional[int] = None
        self._run_trials: typing.Dict[str, int] = {}
        self._pending: typing.Any = None
        self._node.create_subscription(OptimizerProgress, "optimizer_progress", self._on_progress, _PROGRESS_QOS)
        self._node.create_subscription(OutcomeSummary, "summary", self._on_summary, LATCHED_QOS)
        self._campaign: typing.Optional[typing.Tuple[str, int, int, typing.Optional[float]]] = None
        self._node.create_subscription(CampaignProgress, "campaign_progress", self._on_campaign, LATCHED_QOS)
        self._summary_client = self._node.create_client(GetSummary, "get_summary")
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)
        self._spinner = ExecutorThread(self._executor, name="graph-observer").start()

    def _on_progress(self, msg: typing.Any) -> None:
        with self._lock:
            self._progress.append(progress_from_msg(msg))

    def _on_summary(self, msg: typing.Any) -> None:
        with self._lock:
            self._launches = int(msg.trials)

    def _on_campaign(self, msg: typing.Any) -> None:
        eta = float(msg.eta_s)
        with self._lock:
            self._campaign = (msg.run_id, int(msg.done), int(msg.total), None if eta != eta else eta)

    def campaign_progress(self) -> typing.Optional[typing.Tuple[str, int, int, typing.Optional[float]]]:
        with self._lock:
            return self._campaign

    def optimizer_progress(self) -> typing.List[RunProgress]:
        with self._lock:
            return list(self._progress)

    def stored_launches(self) -> typing.Optional[int]:
        with self._lock:
            return self._launches

    def stored_trials(self, run_id: str) -> typing.Optional[int]:
        pending = self._pending
        if pending is not None and not pending.done() and \
                time.monotonic() - self._pending_since > self._request_timeout_s:
            self._summary_client.remove_pending_request(pending)   # its server is gone: ask whoever serves now
            pending = self._pending = None
        if (pending is None or pending.done()) and self._summary_client.service_is_ready():
            future = self._summary_client.call_async(GetSummary.Request(run_id=run_id))
            future.add_done_callback(lambda done: self._on_answer(run_id, done))
            self._pending, self._pending_since = future, time.monotonic()
        with self._lock:
            return self._run_trials.get(run_id)

    def _on_answer(self, run_id: str, future: typing.Any) -> None:
        if future.exception() is None:
            with self._lock:
                self._run_trials[run_id] = int(future.result().summary.trials)

    def close(self) -> None:
        """Stop the node, its executor thread and its context (idempotent)."""
        if self._context.ok():
            self._spinner.stop(timeout_s=2.0)
            self._node.destroy_node()
            self._context.try_shutdown()

    def __enter__(self) -> "RosGraphObserver":
        return self

    def __exit__(self, *exc_info: typing.Any) -> None:
        self.close()
