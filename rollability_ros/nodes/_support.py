"""What every node shares: validated parameters declared from core dataclasses, QoS presets, a Jazzy-safe main.

Parameters: a node declares the fields of a core settings dataclass as ROS parameters (``prefix.field``) with a
description, validates them at start-up with the dataclass's own checks, and refuses later ``ros2 param set``
calls that would make them invalid (``SetParametersResult(successful=False, reason=...)``).
"""
import dataclasses
import faulthandler
import os
import re
import signal
import sys
import threading
import time
import typing

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.action import ActionClient
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor
from rclpy._rclpy_pybind11 import RCLError
from rclpy.signals import SignalHandlerOptions
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from rollability_ros.core.config import ConfigError, from_mapping, interval, out_of_range, section, wrong_type

#: State topics (valve state, summaries, tip state): the last value reaches late joiners.
LATCHED_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL, history=HistoryPolicy.KEEP_LAST)
#: Records that must not be dropped (outcomes, candidates, tip events), on both publisher and subscriber:
#: reliable, and transient-local with a deep history, so a logger or recorder that matches the publisher late
#: (DDS discovery takes a moment after a node starts) or restarts mid-campaign still receives every record in
#: the publisher's history; the store de-duplicates by record key, so a re-delivered record is stored once.
RECORD_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL, history=HistoryPolicy.KEEP_LAST)
#: High-rate streams (poses, IMU): newest wins.
STREAM_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT,
                        durability=DurabilityPolicy.VOLATILE, history=HistoryPolicy.KEEP_LAST)


class ParameterError(RuntimeError):
    """A node's parameters are invalid at start-up; the message names the parameter."""


def _field_description(field):
    return field.metadata.get("description", "") if field.metadata else ""


def _ros_default(value, field_type):
    """ROS parameters cannot hold tuples, None or empty untyped lists: map to declarable values."""
    if isinstance(value, tuple):
        value = list(value)
    if isinstance(value, list) and not value:
        args = typing.get_args(field_type)
        item = args[0] if args else str
        from rclpy.parameter import Parameter

        return {float: Parameter.Type.DOUBLE_ARRAY, int: Parameter.Type.INTEGER_ARRAY,
                bool: Parameter.Type.BOOL_ARRAY}.get(item, Parameter.Type.STRING_ARRAY)
    return value


#: A core settings dataclass, declared as parameters and read back.
_Settings = typing.TypeVar("_Settings")


def declare_settings(node: Node, prefix: str, settings_cls: typing.Type[_Settings],
                     descriptions: typing.Optional[typing.Mapping[str, str]] = None,
                     read_only: bool = False) -> _Settings:
    """Declare the fields of ``settings_cls`` (recursively) as parameters ``prefix.field`` with descriptors.

    Field descriptions come from ``descriptions[name]`` or the dataclass field's ``metadata["description"]``; a
    field's ``metadata["range"]`` ``(low, high)`` becomes the descriptor's FloatingPointRange / IntegerRange
    (inclusive; an end the metadata leaves out, ``"exclusive"``, is said in the descriptor's
    ``additional_constraints`` and refused by the same builder as the CLI's, :func:`~rollability_ros.core.config.
    from_mapping`); ``read_only`` marks parameters the node fixes at start-up. Returns the settings object built
    from the declared values (checked; raises :class:`ParameterError`, also for a value outside its range, with
    the CLI's message).
    """
    descriptions = descriptions or {}
    hints = typing.get_type_hints(settings_cls)
    default_obj = settings_cls() if _has_all_defaults(settings_cls) else None
    for field in dataclasses.fields(typing.cast(typing.Any, settings_cls)):   # refuses a non-dataclass
        name = f"{prefix}.{field.name}" if prefix else field.name
        field_type = hints[field.name]
        if isinstance(field_type, type) and dataclasses.is_dataclass(field_type):
            declare_settings(node, name, field_type, descriptions, read_only)
            continue
        default = getattr(default_obj, field.name) if default_obj is not None else None
        text = descriptions.get(field.name) or _field_description(field) or field.name.replace("_", " ")
        try:
            node.declare_parameter(name, _ros_default(default, field_type),
                                   parameter_descriptor(text, field.metadata.get("range"), field_type, read_only,
                                                        name=name, exclusive=field.metadata.get("exclusive", "")))
        except InvalidParameterValueException as exc:
            raise ParameterError(refusal(name, exc, field.metadata)) from None
        except InvalidParameterTypeException as exc:
            raise ParameterError(type_refusal(name, exc, field_type, field.metadata)) from None
    return read_settings(node, prefix, settings_cls)


def refusal(name: str, exc: Exception, metadata: typing.Optional[typing.Mapping[str, typing.Any]] = None) -> str:
    """One line for a value rclpy refused at declaration: the parameter, the value and the declared range
    (``metadata["range"]``), in the words the CLI uses (:func:`~rollability_ros.core.config.out_of_range`).

    rclpy's own text (``Invalid parameter value (-1.0) for parameter. Reason: Parameter player.rate out of range
    Min: 0.0, Max: 1000.0, value: -1.0: player.rate``) says it twice and ends with the name again.
    """
    text = " ".join(str(exc).split())
    reason = re.search(r"Reason: (.*?)(?:: " + re.escape(name) + r")?$", text)
    value = re.search(r"value \((.*?)\) for parameter", text)
    if metadata is not None and "range" in metadata and reason is not None and "out of range" in reason.group(1):
        return out_of_range(name, value.group(1) if value else "the value", metadata)
    return f"{name}: {reason.group(1) if reason else text}"


#: How rclpy names the type of a value it refused, and how to read the value back from its text.
_READ_BACK: typing.Dict[str, typing.Callable[[str], typing.Any]] = {
    "STRING": str, "INTEGER": int, "DOUBLE": float, "BOOL": lambda text: text == "True"}


def type_refusal(name: str, exc: Exception, field_type: type,
                 metadata: typing.Optional[typing.Mapping[str, typing.Any]] = None) -> str:
    """One line for a value of the wrong type rclpy refused at declaration, in the words the CLI uses
    (:func:`~rollability_ros.core.config.wrong_type`): rclpy's own text (``Trying to set parameter 'x' to 'abc' of
    type 'STRING', expecting type 'DOUBLE'``) names ROS types rather than the setting's range."""
    found = re.search(r"to '(.*)' of type '(\w+)'", " ".join(str(exc).split()))
    if found is None or found.group(2) not in _READ_BACK:
        return f"{name}: {' '.join(str(exc).split())}"
    try:
        value = _READ_BACK[found.group(2)](found.group(1))
    except ValueError:
        value = found.group(1)
    return wrong_type(name, field_type, value, metadata)


#: Parameter types that carry a numeric range in their descriptor (rclpy checks INTEGER and DOUBLE values only).
NUMERIC_TYPES = (int, float)


def parameter_descriptor(description: str, value_range: typing.Optional[typing.Sequence[float]] = None,
                         field_type: typing.Optional[type] = None, read_only: bool = False,
                         name: typing.Optional[str] = None, exclusive: str = "") -> ParameterDescriptor:
    """A ParameterDescriptor with the description, an inclusive numeric range, and read_only; an end of the range
    that ``exclusive`` (``"low"``, ``"high"``, ``"both"``) leaves out is said in ``additional_constraints``
    (ROS ranges are inclusive; the settings builder refuses the end itself).

    Every ``int`` or ``float`` parameter must give ``value_range`` ``(low, high)``: a numeric parameter declared
    without one raises ``TypeError`` (a programming error, caught by test/test_parameter_ranges.py before any node
    starts), so ``ros2 param describe`` shows every bound and rclpy refuses a value outside it.
    """
    if value_range is None and field_type in NUMERIC_TYPES:
        raise TypeError(f"numeric parameter {name or description!r} declared without a range")
    descriptor = ParameterDescriptor(description=description, read_only=read_only)
    if value_range is not None and field_type is float:
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(value_range[0]),
                                                              to_value=float(value_range[1]))]
    elif value_range is not None and field_type is int:
        descriptor.integer_range = [IntegerRange(from_value=int(value_range[0]), to_value=int(value_range[1]))]
    if value_range is not None and exclusive:
        descriptor.additional_constraints = f"in {interval({'range': value_range, 'exclusive': exclusive})}"
    return descriptor


def _has_all_defaults(cls):
    return all(f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING
               for f in dataclasses.fields(cls))


def _current_values(node, prefix, overrides=None):
    # a parameter declared with a type only (an empty-list default) and never set has the value None: leave it
    # out so the dataclass default applies
    flat = {name: param.value for name, param in node.get_parameters_by_prefix(prefix).items()
            if param.value is not None}
    lead = prefix + "." if prefix else ""
    for param in overrides or ():
        if param.name.startswith(lead):
            flat[param.name[len(lead):]] = param.value
    return section(flat, "")


def read_settings(node: Node, prefix: str, settings_cls: typing.Type[_Settings],
                  overrides: typing.Optional[typing.Sequence[typing.Any]] = None) -> _Settings:
    """Build ``settings_cls`` from the node's current parameters under ``prefix`` (validated).

    ``overrides`` (a list of rclpy Parameters) are applied on top: used to check a pending parameter change.
    Raises :class:`ParameterError` naming the parameter and the problem.
    """
    values = _current_values(node, prefix, overrides)
    hints = typing.get_type_hints(settings_cls)
    known = {f.name for f in dataclasses.fields(typing.cast(typing.Any, settings_cls))}
    values = {k: v for k, v in values.items() if k in known}
    for name, value in list(values.items()):
        if hints[name] is float and isinstance(value, int) and not isinstance(value, bool):
            values[name] = float(value)
        if isinstance(value, list) and typing.get_origin(hints[name]) is tuple:
            values[name] = tuple(value)
    try:
        return from_mapping(settings_cls, values, prefix or node.get_name())
    except (ConfigError, ValueError, TypeError) as exc:
        raise ParameterError(str(exc)) from exc


def guard_settings(node: Node, prefix: str, settings_cls: typing.Type[_Settings],
                   on_change: typing.Optional[typing.Callable[[_Settings], None]] = None) -> None:
    """Refuse parameter changes under ``prefix`` that would make ``settings_cls`` invalid.

    ``on_change(new_settings)`` is called after an accepted change; a ``ValueError`` it raises (a file the new
    settings name cannot be read: ``ConfigError``) refuses the change with its message.
    """
    lead = prefix + "."

    def check(params: typing.Sequence[typing.Any]) -> SetParametersResult:
        relevant = [p for p in params if p.name.startswith(lead)]
        if not relevant:
            return SetParametersResult(successful=True)
        try:
            new_settings = read_settings(node, prefix, settings_cls, overrides=relevant)
        except ParameterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        if on_change is not None:
            try:
                on_change(new_settings)
            except ValueError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(check)


#: Once a node starts stopping, the most its shutdown may take before the process exits anyway (s).
SHUTDOWN_GRACE_S = 25.0

#: After the grace period, how much longer a C-level watchdog waits before it ends a process whose Python threads
#: are all stuck (s).
HARD_DEADLINE_EXTRA_S = 5.0

#: How often a node's main thread looks for a stop signal while the executor spins in its own thread (s).
STOP_POLL_S = 0.1


def _exit_after_grace():
    print(f"shutdown took longer than {SHUTDOWN_GRACE_S:g} s: exiting now", file=sys.stderr, flush=True)
    os._exit(1)


def _arm_hard_deadline():
    """Exit ``HARD_DEADLINE_EXTRA_S`` after the grace period even when no Python thread can run any more.

    The grace timer above is a Python thread: it needs the GIL, so a C call that blocks while holding it (a
    middleware call that never returns) would keep a stopped node alive until someone sends SIGKILL. faulthandler's
    watchdog is a C thread: it prints every Python thread's stack (what hung) and exits 1 without the GIL. Like
    the grace timer it stays armed after ``run_node`` returns, so interpreter exit is bounded too.
    """
    stream = sys.stderr if _has_fileno(sys.stderr) else sys.__stderr__
    if _has_fileno(stream):
        faulthandler.dump_traceback_later(SHUTDOWN_GRACE_S + HARD_DEADLINE_EXTRA_S, exit=True, file=stream)


def _dump_stacks_on_sigusr1():
    """``kill -USR1 <pid>`` prints every thread's Python stack to stderr (a C-level handler: it works even when
    the node hangs in a C call holding the GIL), to see where a stuck node is."""
    stream = sys.stderr if _has_fileno(sys.stderr) else sys.__stderr__
    if _has_fileno(stream) and threading.current_thread() is threading.main_thread():
        faulthandler.register(signal.SIGUSR1, file=stream, all_threads=True)


def _has_fileno(stream: typing.Optional[typing.TextIO]) -> "typing.TypeGuard[typing.TextIO]":
    try:
        return stream is not None and stream.fileno() >= 0
    except (AttributeError, OSError, ValueError):
        return False


def init_ros(args: typing.Optional[typing.List[str]] = None) -> None:
    """``rclpy.init`` without rclpy's own SIGINT / SIGTERM handlers.

    rclpy's handlers shut the context down at the signal, underneath callbacks still running: a last valve state
    cannot be published any more ("publisher's context is invalid") and running callbacks die with RCLError /
    InvalidHandle tracebacks. The caller decides what a stop signal does and shuts the context down last.
    """
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)


#: How long an executor thread waits for work before it looks at its stop request again, s.
SPIN_POLL_S = 0.1


class ExecutorThread:
    """An rclpy executor spun on a thread of its own and stopped without racing it.

    rclpy 7.1 (Jazzy) ``Executor.shutdown`` destroys the executor's guard conditions at once, also while another
    thread is building a wait set from them: the spinning thread then dies with ``AttributeError: 'NoneType'
    object has no attribute 'handle'`` (seen in CI at a node's SIGINT). So the thread spins ``spin_once`` until
    asked to stop (:meth:`request_stop`, from any thread, also a callback), until ``finished`` is set, or until
    the context is shut down; :meth:`stop` shuts the executor down only once the thread has left it.
    """

    def __init__(self, executor: typing.Any, name: str = "executor",
                 finished: typing.Optional[threading.Event] = None) -> None:
        self.executor = executor
        self.stopped = threading.Event()   # set when the thread has left the executor, whoever stopped it
        self.failures: typing.List[BaseException] = []   # what ended the spin other than a stop
        self._stop = threading.Event()
        self._finished = finished
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> "ExecutorThread":
        self._thread.start()
        return self

    def request_stop(self) -> None:
        self._stop.set()

    def _stop_requested(self) -> bool:
        return self._stop.is_set() or (self._finished is not None and self._finished.is_set())

    def _run(self) -> None:
        context = self.executor.context
        try:
            while not self._stop_requested() and context.ok():
                self.executor.spin_once(timeout_sec=SPIN_POLL_S)
        except (ExternalShutdownException, RCLError) as exc:
            # the node ended its own context (e.g. the optimizer with exit_on_finish) while the executor waited
            if context.ok():
                self.failures.append(exc)
        except Exception as exc:  # a callback's exception: the node stops (cleanly) and the process says so
            self.failures.append(exc)
        finally:
            self.stopped.set()

    def stop(self, timeout_s: typing.Optional[float] = None) -> None:
        """Stop spinning, wait for the thread (and a multi-threaded executor's callbacks), shut the executor down."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout_s)
        if self._thread.is_alive():   # still inside a callback after timeout_s: leave the executor to it
            return
        _join_callback_threads(self.executor)
        self.executor.shutdown()


def _join_callback_threads(executor):
    """Wait for the callbacks still running in a multi-threaded executor's threads.

    rclpy 7.1 (Jazzy) ``MultiThreadedExecutor.shutdown`` leaves them running (later rclpy joins them), and a
    callback that outlives its node dies with an InvalidHandle traceback.
    """
    threads = getattr(executor, "_executor", None)
    if threads is not None:
        threads.shutdown(wait=True)


def run_node(node_factory: typing.Callable[[], Node], args: typing.Optional[typing.List[str]] = None,
             threads: int = 4) -> int:
    """Create the node with ``node_factory()`` after ``rclpy.init`` and spin it until SIGINT / SIGTERM.

    ``threads`` > 1 spins a multi-threaded executor (long callbacks do not block the node); ``threads=1`` a
    single-threaded one, which keeps up with high-rate streams best (e.g. a 300 Hz IMU on a busy 2-core machine).

    A stop signal (Ctrl-C, ``ros2 launch``, systemd, our supervisor) stops the node in this order, whoever sent
    it: the node's ``close()`` (if any) runs while the executor still spins and the context is valid (the valve
    publishes its closed state, a running goal finishes or aborts cleanly), then the executor stops, the node is
    destroyed and the context shut down; no traceback. A node may also end itself: by setting its ``finished``
    event (a ``threading.Event`` attribute) or by shutting its context down (never its executor: see
    :class:`ExecutorThread`). A :class:`ParameterError` or ``ConfigError`` at start-up prints one line naming the problem
    and exits 2.
    """
    init_ros(args)
    _dump_stacks_on_sigusr1()
    signalled: typing.List[int] = []   # a handler only appends: taking a lock in a signal handler can deadlock
    on_main_thread = threading.current_thread() is threading.main_thread()
    if on_main_thread:
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, lambda signum, _frame: signalled.append(signum))   # a second one changes nothing
    node: typing.Optional[Node] = None
    spinner: typing.Optional[ExecutorThread] = None
    try:
        try:
            node = node_factory()
        except (ParameterError, ConfigError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        executor = MultiThreadedExecutor(num_threads=threads) if threads > 1 else SingleThreadedExecutor()
        executor.add_node(node)
        finished = getattr(node, "finished", None)
        spinner = ExecutorThread(executor, finished=finished if isinstance(finished, threading.Event) else None)
        spinner.start()
        while not signalled and not spinner.stopped.wait(STOP_POLL_S if on_main_thread else None):
            pass
    finally:
        if on_main_thread:
            # a second signal must not cut the safe stop short, not even at interpreter exit (which resets Python
            # handlers to the default action; an ignored signal stays ignored)
            for signum in (signal.SIGINT, signal.SIGTERM):
                signal.signal(signum, signal.SIG_IGN)
        # a callback still running (e.g. an evaluation) must not keep a stopped node alive for ever
        deadline = threading.Timer(SHUTDOWN_GRACE_S, _exit_after_grace)
        deadline.daemon = True                             # never what keeps the process alive
        deadline.start()
        _arm_hard_deadline()
        if node is not None:
            close = getattr(node, "close", None)
            if callable(close):
                close()
        if spinner is not None:
            spinner.stop()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    if spinner is not None and spinner.failures:
        raise spinner.failures[0]
    return 0


class ThreadSafeActionClient(ActionClient):
    """An ActionClient whose requests may be sent from any thread.

    rclpy's ActionClient registers a request's future only after sending the request, so a response that the
    executor handles in between is dropped ("Ignoring unexpected goal response"). Sending and handling
    responses under one lock closes that window.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._request_lock = threading.RLock()

    def send_goal_async(self, *args: typing.Any, **kwargs: typing.Any) -> typing.Any:
        with self._request_lock:
            return super().send_goal_async(*args, **kwargs)

    def _cancel_goal_async(self, goal_handle):
        with self._request_lock:
            return super()._cancel_goal_async(goal_handle)

    def _get_result_async(self, goal_handle):
        with self._request_lock:
            return super()._get_result_async(goal_handle)

    async def execute(self, taken_data: typing.Any) -> None:
        with self._request_lock:   # execute never suspends: its callbacks are plain functions
            await super().execute(taken_data)


#: A goal its server has not answered within this time is sent again, s (:func:`send_goal_resending`).
GOAL_RESEND_S = 5.0


def send_goal_resending(client: ActionClient, goal: typing.Any, wait: typing.Callable[..., bool], timeout_s: float,
                        feedback_callback: typing.Optional[typing.Callable[[typing.Any], None]] = None,
                        resend_after_s: float = GOAL_RESEND_S,
                        on_resend: typing.Optional[typing.Callable[[int], None]] = None) -> typing.Any:
    """The goal handle of ``goal`` once ``client``'s server answered it; None without an answer within ``timeout_s``.

    A client sees its server (``server_is_ready``) once *its* endpoints matched the server's; the server's answer
    goes over a writer that discovery may not yet have matched to this client's reader. The server's rmw then waits
    for the match only for the writer's max blocking time (rmw_fastrtps: 100 ms, "client will not receive
    response"). Under load the first goal after discovery can lose its answer that way (seen in CI: no answer in
    30 s). rclpy (Jazzy) then either drops the goal ("Failed to send goal response") or, when the rmw only warns
    (``RuntimeWarning: failed to send response (timeout)``), runs it all the same. So:

    - a copy whose feedback arrives is running, answer or not: it is the one used (a handle is made for it from
      its goal id, which this function chose), and no further copy is sent: a resent copy of a running launch would
      be a second launch, or (signed once) a replay the server refuses;
    - a goal unanswered and silent for ``resend_after_s`` is sent again (same content, a new goal id;
      ``on_resend(copies_sent_so_far)`` is told). Should an earlier copy's answer still come, the first answer is the
      one returned and any other accepted copy is cancelled.

    ``goal`` may be a function that makes the goal: a signed goal must be signed again for each copy (a signature is
    fresh for a few seconds only). ``wait(predicate, timeout_s) -> bool`` waits however the caller spins.
    """
    import uuid

    from rclpy.action.client import ClientGoalHandle
    from unique_identifier_msgs.msg import UUID

    copies: typing.List[typing.Tuple[typing.Any, typing.Any]] = []   # (goal id, the answer's future)
    running: typing.List[bytes] = []                                 # goal ids whose feedback arrived

    def on_feedback(message: typing.Any) -> None:
        goal_id = bytes(message.goal_id.uuid)
        if goal_id not in running:
            running.append(goal_id)
        if feedback_callback is not None:
            feedback_callback(message)

    def settled() -> bool:
        return bool(running) or any(future.done() for _goal_id, future in copies)

    deadline = time.monotonic() + timeout_s
    while True:
        copy = goal() if callable(goal) else goal   # a signed goal is signed afresh for each copy
        goal_id = UUID(uuid=list(uuid.uuid4().bytes))
        copies.append((goal_id, client.send_goal_async(copy, feedback_callback=on_feedback, goal_uuid=goal_id)))
        remaining = deadline - time.monotonic()
        if wait(settled, max(0.0, min(resend_after_s, remaining))):
            break
        if time.monotonic() >= deadline:
            break
        if on_resend is not None:
            on_resend(len(copies))
    if running and not any(future.done() for _goal_id, future in copies):
        wait(lambda: any(future.done() for _goal_id, future in copies), 1.0)   # its answer may be on its way
    answered = next((future for _goal_id, future in copies if future.done()), None)
    if answered is not None:
        handle = answered.result()
    elif running:   # running without an answer: a handle of our own, from the goal id we chose
        goal_id = next(goal_id for goal_id, _future in copies if bytes(goal_id.uuid) == running[0])
        handle = ClientGoalHandle(client, goal_id, client._action_type.Impl.SendGoalService.Response(accepted=True))
    else:
        return None
    for goal_id, future in copies:
        if future is not answered and bytes(goal_id.uuid) != bytes(handle.goal_id.uuid):
            future.add_done_callback(_cancel_if_accepted)
    return handle


def _cancel_if_accepted(future: typing.Any) -> None:
    """Done callback of a goal copy that is not the one used: cancel it if its server accepted it."""
    if future.cancelled() or future.exception() is not None:
        return
    handle = future.result()
    if handle is not None and handle.accepted:
        handle.cancel_goal_async()


#: How often the acknowledgements are looked at, s. rclpy's ``wait_for_all_acked`` holds the GIL for as long as it
#: waits (rclpy 7, Jazzy), so every Python thread, the main thread's stop-signal check too, would freeze for the
#: whole timeout of each topic whose subscriber stopped acknowledging (a stalled or SIGSTOPped one): it is only
#: ever called with a ~zero timeout, and the wait between looks releases the GIL (issue 30).
ACK_POLL_S = 0.02


def wait_for_acks(publishers: typing.Iterable[typing.Any], timeout_s: float, stop: threading.Event) -> int:
    """Wait until every publisher's messages are acknowledged by its reliable subscribers, ``timeout_s`` in all, or
    until ``stop`` (a ``threading.Event``) is set; return how many publishers are still waiting.

    Never holds the GIL for longer than one ~zero-timeout ``wait_for_all_acked`` (see :data:`ACK_POLL_S`).
    """
    deadline = time.monotonic() + timeout_s
    pending = list(publishers)
    while pending:
        pending = [p for p in pending if not p.wait_for_all_acked(Duration(nanoseconds=1000))]
        if not pending or stop.wait(min(ACK_POLL_S, max(0.0, deadline - time.monotonic()))) \
                or time.monotonic() >= deadline:
            break
    return len(pending)


class SessionMembership:
    """A node's ``session.*`` parameters (:class:`~rollability_ros.core.config.SessionSettings`) and its refusals
    of other sessions' goals and results, each logged once per session and kind (docs/sessions.md)."""

    def __init__(self, node: Node) -> None:
        from rollability_ros.core.config import SessionSettings

        self.settings = declare_settings(node, "session", SessionSettings, read_only=True)
        self.id = self.settings.id
        self._logger = node.get_logger()
        self._logged: typing.Set[typing.Tuple[str, str]] = set()

    def refusal(self, other: str, what: str) -> str:
        """"" when ``what`` of session ``other`` belongs here, else the reason (logged the first time)."""
        reason = self.settings.refusal(other, what)
        if reason and (other, what) not in self._logged:
            self._logged.add((other, what))
            self._logger.warning(f"{reason} (logged once; later ones are refused silently)")
        return reason
