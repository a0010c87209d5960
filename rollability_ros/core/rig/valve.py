"""The launcher's solenoid valve as a fail-closed state machine, and the valve's configuration.

:class:`ValveController` owns one backend (:mod:`rollability_ros.core.rig.valve_backends`) and is the only thing that
commands it. The valve is driven closed explicitly at start, on disarm, on e-stop, on a missed rig heartbeat, on
a backend error, at the end of every pulse and at shutdown; a fire is refused unless armed and fault-free, and
its length is bounded by ``max_pulse_ms``.

Re-arming after a fault: a fault (e-stop, watchdog, backend error) disarms the valve and latches. ``arm()`` is
refused while a fault is latched; the operator acknowledges it with ``disarm()`` (which drives the valve closed
again and clears the fault if that close succeeds) and then calls ``arm()``.

Software alone cannot make the valve fail-safe (a SIGKILLed process closes nothing): on the ``serial_relay`` backend
the relay board times each pulse and drops the relay without keep-alives (:mod:`.relay_protocol`); faults the
board reports on its own reach :meth:`ValveController.device_fault`. See docs/valve-safety.md.

Thread model: ``fire()`` blocks for the pulse without holding the controller's lock, so ``estop()``,
``check_watchdog()`` and ``disarm()`` from other threads cut a running pulse at once. Every backend call runs on the
controller's own backend thread and is bounded (the backend's ``call_timeout_s``, by default
:data:`~rollability_ros.core.rig._valve_backend.DEFAULT_CALL_TIMEOUT_S`): a call that does not return in time
latches a fault and later calls are refused at once until it returns (the valve is then driven closed again), so
the lock is never held longer than one bound.
``heartbeat()`` takes no lock and ``health()`` waits for it at most :data:`HEALTH_LOCK_WAIT_S`, so a stuck serial
call cannot silence the node's state and diagnostics (issue 30).
"""
import dataclasses
import logging
import math
import queue
import threading
import time
import typing

from rollability_ros.core.rig._valve_backend import VALVE_BACKENDS, ValveBackend

if typing.TYPE_CHECKING:  # annotations only
    from rollability_ros.core.rig.relay_protocol import DeviceLimits

_LOG = logging.getLogger(__name__)

#: Longest :meth:`ValveController.health` waits for the controller's lock before it reports the last state, s.
HEALTH_LOCK_WAIT_S = 0.05


class BackendStuck(RuntimeError):
    """A backend call did not return within its bound (or an earlier one still has not)."""


class _Job:
    def __init__(self, name, fn, args):
        self.name, self.fn, self.args = name, fn, args
        self.queued_at = time.monotonic()
        self.done = threading.Event()
        self.result = self.error = None


class _BackendCaller:
    """Runs backend calls one at a time on its own daemon thread; the caller waits for each at most a bound.

    A call that overruns its bound is *stuck*: :meth:`call` raises :class:`BackendStuck`, and every later call is
    refused at once (raising :class:`BackendStuck`) until it returns; then ``on_late_return(name, seconds, error)``
    runs on a fresh thread (``error``: what the call raised, or None).
    """

    def __init__(self, timeout_s, on_late_return):
        self.timeout_s = timeout_s
        self._on_late_return = on_late_return
        self._jobs: "queue.SimpleQueue[typing.Optional[_Job]]" = queue.SimpleQueue()   # None: stop
        self._guard = threading.Lock()
        self._running = None
        self._stuck = None
        threading.Thread(target=self._loop, name="valve-backend", daemon=True).start()

    def running(self) -> typing.Optional[typing.Tuple[str, float]]:
        """``(name, seconds so far)`` of the call in progress, or None."""
        job = self._running
        return None if job is None else (job.name, time.monotonic() - job.queued_at)

    def call(self, name: str, fn: typing.Callable[..., typing.Any], *args: typing.Any,
             timeout_s: typing.Optional[float] = None) -> typing.Any:
        """Run ``fn(*args)`` on the backend thread; return its result or raise its exception or BackendStuck."""
        stuck = self._stuck
        if stuck is not None:
            raise BackendStuck(f"backend still stuck in {stuck.name} for {time.monotonic() - stuck.queued_at:.1f} s; "
                               f"{name} not sent")
        bound = self.timeout_s if timeout_s is None else timeout_s
        job = _Job(name, fn, args)
        self._jobs.put(job)
        if not job.done.wait(bound):
            with self._guard:
                if not job.done.is_set():
                    self._stuck = job
                    raise BackendStuck(f"backend {name} did not return within {bound:.1f} s")
        if job.error is not None:
            raise job.error
        return job.result

    def stop(self) -> None:
        """End the thread after the calls already queued (a stuck call keeps it until it returns)."""
        self._jobs.put(None)

    def _loop(self):
        while True:
            job = self._jobs.get()
            if job is None:
                return
            self._running = job
            try:
                job.result = job.fn(*job.args)
            except BaseException as exc:  # noqa: BLE001 - handed to the caller, who turns it into a fault
                job.error = exc
            with self._guard:
                self._running = None
                job.done.set()
                late = self._stuck is job
                if late:
                    self._stuck = None
            if late:
                threading.Thread(target=self._on_late_return,
                                 args=(job.name, time.monotonic() - job.queued_at, job.error),
                                 name="valve-backend-returned", daemon=True).start()


@dataclasses.dataclass(frozen=True)
class ValveStatus:
    """One valve state (``msg/ValveState.msg`` without the header).

    ``open`` is True from the moment an open command is issued until a close command succeeds, so after a
    failed close it stays True: the valve is not known to be closed.
    """

    armed: bool
    open: bool
    fault: bool
    fault_reason: str
    backend: str
    last_pulse_ms: int
    pulses: int


class ValveController:
    """Fail-closed controller of the launcher valve.

    Parameters
    ----------
    backend : ValveBackend
        The driver (:class:`~rollability_ros.core.rig._valve_backend.ValveBackend`); its optional methods are
        called unconditionally (their defaults do nothing).
    max_pulse_ms : int
        Longest pulse ever fired, ms; longer requests are refused.
    watchdog_ms : int
        While armed, the rig must call :meth:`heartbeat` at least this often, ms; otherwise
        :meth:`check_watchdog` closes the valve and latches a fault.
    clock : callable
        Steady clock in seconds (``time.monotonic``); never ROS time, so sim time cannot stall the watchdog.
    on_state : callable, optional
        Called with a :class:`ValveStatus` after every state change (also logged). Exceptions it raises are
        logged and swallowed: a broken publisher must not keep the valve open.
    arm_timeout_s : float, optional
        An armed valve that fires no pulse for this long (since arming or the end of its last pulse) is disarmed
        by :meth:`check_watchdog` (no fault: nothing went wrong, the arming just was not used), so an arming
        outside a launch sequence (``rollability rig arm``), which the rig's heartbeats would keep alive, does not
        leave the valve armed and idle. None: no limit.
    """

    def __init__(self, backend, max_pulse_ms, watchdog_ms, clock=time.monotonic, on_state=None, arm_timeout_s=None):
        if arm_timeout_s is not None and not 0 < arm_timeout_s < math.inf:
            raise ValueError(f"arm_timeout_s must be a positive number of seconds or None, got {arm_timeout_s!r}")
        self.arm_timeout_s = arm_timeout_s
        self._armed_idle_since = clock()
        if not isinstance(max_pulse_ms, (int, float)) or not 0 < max_pulse_ms < math.inf:
            raise ValueError(f"max_pulse_ms must be a positive number, got {max_pulse_ms!r}")
        if not isinstance(watchdog_ms, (int, float)) or not 0 < watchdog_ms < math.inf:
            raise ValueError(f"watchdog_ms must be a positive number, got {watchdog_ms!r}")
        if not isinstance(backend, ValveBackend):
            raise TypeError(f"backend must be a ValveBackend, got {type(backend).__name__}")
        self._backend = backend
        self.max_pulse_ms = max_pulse_ms
        self.watchdog_ms = watchdog_ms
        self._clock = clock
        self._on_state = on_state
        self._lock = threading.RLock()
        self._cut = threading.Event()          # set to end a running pulse early
        self._backend_started = False
        self._armed = False
        self._open = False
        self._fault_reason = ""
        self._last_pulse_ms: float = 0
        self._pulses = 0
        self._firing = False
        self._shut_down = False
        self._released = False
        self._last_heartbeat = clock()
        self._watchdog_stop = None
        self._stall_reported = False
        self._last_status: ValveStatus   # set by _emit("started") below, before anyone can ask
        self._caller = _BackendCaller(backend.call_timeout_s, self._backend_returned)
        backend.set_fault_listener(self.device_fault)
        with self._lock:
            self._drive_closed()
            self._emit("started")

    # ------------------------------------------------------------------ state
    def device_limits(self) -> typing.Optional["DeviceLimits"]:
        """The device's own limits (``relay_protocol.DeviceLimits``) when the backend reports them, else None."""
        return self._backend.limits

    def startup_warning(self) -> str:
        """The backend's start-up warning for the operator ("" when it has none)."""
        return self._backend.startup_warning()

    def status(self) -> "ValveStatus":
        """Return the current :class:`ValveStatus`."""
        with self._lock:
            return ValveStatus(
                armed=self._armed, open=self._open, fault=bool(self._fault_reason), fault_reason=self._fault_reason,
                backend=self._backend.name,
                last_pulse_ms=int(self._last_pulse_ms), pulses=self._pulses,
            )

    def _call(self, method, *args, timeout_s=None):
        """Call the bound backend ``method`` on the backend thread, bounded in time (see :class:`_BackendCaller`)."""
        return self._caller.call(method.__name__, method, *args, timeout_s=timeout_s)

    def _open_bound_s(self):
        """Bound of the backend's ``open()``: a board that boots after its port opens is waited for (HELLO)."""
        return self._backend.boot_wait_s + 4 * self._caller.timeout_s

    def _backend_returned(self, name, seconds, error):
        """A backend call that overran its bound returned at last: drive the valve closed again (fault stays)."""
        _LOG.warning("valve backend call %s returned after %.1f s%s", name, seconds, f" ({error})" if error else "")
        with self._lock:
            if name == "open" and error is None:
                self._backend_started = True   # started late: not a second time
            if self._shut_down:
                if not self._released:  # the backend thread has ended: release from here, once more
                    try:
                        self._backend.release()
                        self._released = True
                    except Exception:  # noqa: BLE001
                        _LOG.exception("valve backend release after a stuck call failed")
                return
            self._drive_closed()
            self._emit(f"backend {name} returned after {seconds:.1f} s")

    def _emit(self, event):
        status = self._last_status = self.status()
        level = logging.ERROR if status.fault else logging.INFO
        _LOG.log(level, "valve %s: armed=%s open=%s fault=%s%s pulses=%d last_pulse_ms=%d", event, status.armed,
                 status.open, status.fault, f" ({status.fault_reason})" if status.fault else "", status.pulses,
                 status.last_pulse_ms)
        if self._on_state is not None:
            try:
                self._on_state(status)
            except Exception:  # noqa: BLE001 - a failing subscriber must not break the safety path
                _LOG.exception("valve on_state callback failed")

    def _latch_fault(self, reason):
        """Record the first fault reason (later ones are appended) and disarm."""
        self._fault_reason = f"{self._fault_reason}; {reason}" if self._fault_reason else reason
        self._armed = False

    def _drive_closed(self):
        """Command the valve closed (starting the backend if needed); a failure latches a fault. Lock held."""
        if self._released:
            return True  # release() already drove it closed; the backend is gone
        try:
            if not self._backend_started:
                self._call(self._backend.open, timeout_s=self._open_bound_s())
                self._backend_started = True
            self._call(self._backend.close_valve)
        except Exception as exc:  # noqa: BLE001 - any backend failure is a fault, whatever its type
            self._latch_fault(f"backend error on close: {exc}")
            return False
        self._open = False
        if not self._armed:
            try:
                self._call(self._backend.disarm)  # the device, too, stops accepting pulses
            except Exception as exc:  # noqa: BLE001
                self._latch_fault(f"backend error on disarm: {exc}")
                return False
        return True

    # --------------------------------------------------------------- commands
    def arm(self) -> typing.Tuple[bool, str]:
        """Allow firing. Returns ``(ok, reason)``; refused while a fault is latched or after shutdown."""
        with self._lock:
            if self._shut_down:
                return False, "valve controller is shut down"
            if self._fault_reason:
                return False, (f"fault latched ({self._fault_reason}); acknowledge it with a disarm (`rollability rig "
                               "disarm`); a launch sequence then arms by itself")
            if self._armed:
                return True, "already armed"
            try:
                self._call(self._backend.arm)
            except Exception as exc:  # noqa: BLE001
                self._latch_fault(f"backend error on arm: {exc}")
                self._drive_closed()
                self._emit("arm failed")
                return False, self._fault_reason
            self._armed = True
            self._last_heartbeat = self._armed_idle_since = self._clock()  # both windows start at arming
            self._emit("armed")
            return True, "armed"

    def disarm(self) -> typing.Tuple[bool, str]:
        """Drive the valve closed, disarm and clear a latched fault. Returns ``(ok, reason)``.

        The fault is cleared only if the close command succeeds; otherwise a new fault stays latched.
        """
        with self._lock:
            self._cut.set()
            self._armed = False
            self._fault_reason = ""
            closed = self._drive_closed()
            if closed:
                try:
                    self._call(self._backend.clear)  # acknowledge a fault the device latched itself (its e-stop button)
                except Exception as exc:  # noqa: BLE001
                    self._latch_fault(f"device fault not cleared: {exc}")
                    closed = False
            self._emit("disarmed")
            if not closed:
                return False, f"disarmed but the close command failed: {self._fault_reason}"
            return True, "disarmed, valve closed"

    def estop(self, reason: str = "e-stop") -> None:
        """Latch a fault, cut any pulse and drive the valve closed."""
        self._cut.set()  # before the lock: a pulse ends even while another thread waits for the backend
        with self._lock:
            self._latch_fault(reason)
            self._cut.set()
            self._drive_closed()
            self._emit("e-stop")

    def device_fault(self, reason: str) -> None:
        """The backend's device faulted on its own (board e-stop, keep-alive timeout, link lost): latch and close."""
        if not self._shut_down:
            self._cut.set()
        with self._lock:
            if self._shut_down:
                return
            self._latch_fault(f"device: {reason}")
            self._cut.set()
            self._drive_closed()
            self._emit("device fault")

    def health(self) -> typing.Tuple["ValveStatus", typing.Optional[float], str]:
        """Diagnostics: ``(status, watchdog margin ms or None when disarmed, device link line)``.

        Never waits for a backend call: while another thread holds the lock for one, the last state emitted is
        reported and the link line says which call is running and for how long.
        """
        margin_ms = None
        if self._lock.acquire(timeout=HEALTH_LOCK_WAIT_S):
            try:
                status = self.status()
                if self._armed:
                    margin_ms = self.watchdog_ms - (self._clock() - self._last_heartbeat) * 1000.0
            finally:
                self._lock.release()
        else:
            status = self._last_status
        line = self._backend.link_state()
        running = self._caller.running()
        if running is not None and running[1] > HEALTH_LOCK_WAIT_S:
            line = f"backend call {running[0]} running for {running[1] * 1000:.0f} ms; {line}"
        return status, margin_ms, line

    def heartbeat(self) -> None:
        """Record a heartbeat from the rig (steady clock). Takes no lock: one store, never behind a backend call."""
        self._last_heartbeat = self._clock()

    def check_backend(self) -> bool:
        """Latch a device fault when the backend reports one of its own calls stalled (its ``stalled()``, e.g.
        a keep-alive stuck in a serial write). Returns True when it latched one now."""
        reason = self._backend.stalled()
        if not reason:
            self._stall_reported = False
            return False
        if self._stall_reported:
            return False
        self._stall_reported = True
        self.device_fault(reason)
        return True

    def check_watchdog(self) -> bool:
        """Trip if armed and the last heartbeat is older than ``watchdog_ms``. Returns True when it tripped now.

        Also disarms (no fault) an armed valve idle longer than ``arm_timeout_s`` (see the class docstring)."""
        with self._lock:
            if not self._armed or self._fault_reason:
                return False
            idle_s = self._clock() - self._armed_idle_since
            if self.arm_timeout_s is not None and not self._firing and idle_s > self.arm_timeout_s:
                self._armed = False
                self._drive_closed()
                self._emit(f"disarmed: armed {idle_s:.1f} s without a pulse (valve.arm_timeout_s "
                           f"{self.arm_timeout_s:g})")
                return False
            silent_ms = (self._clock() - self._last_heartbeat) * 1000.0
            if silent_ms <= self.watchdog_ms:
                return False
            self._latch_fault(f"watchdog: no rig heartbeat for {silent_ms:.0f} ms (limit {self.watchdog_ms} ms)")
            self._cut.set()
            self._drive_closed()
            self._emit("watchdog trip")
            return True

    def fire(self, pulse_ms: float) -> typing.Tuple[bool, str]:
        """Open the valve for ``pulse_ms`` ms, then drive it closed. Blocks for the pulse.

        Returns ``(ok, reason)``. Refused (valve untouched) when shut down, disarmed, faulted, already firing,
        or ``pulse_ms`` is not in ``(0, max_pulse_ms]``. The pulse ends early on e-stop, watchdog trip or
        disarm; the valve is driven closed at the end whatever happens, exceptions included.
        """
        with self._lock:
            refusal = self._refusal(pulse_ms)
            if refusal:
                _LOG.warning("valve fire of %r ms refused: %s", pulse_ms, refusal)
                return False, refusal
            self._firing = True
            self._cut.clear()
            self._open = True  # from here on the valve may be open until a close succeeds
            try:
                self._call(self._backend.open_valve, pulse_ms)
            except Exception as exc:  # noqa: BLE001
                self._latch_fault(f"backend error on open: {exc}")
                self._drive_closed()
                self._firing = False
                self._emit("fire failed")
                return False, self._fault_reason
            opened_at = self._clock()
            self._emit("open")
        cut_early = True
        try:
            cut_early = self._cut.wait(pulse_ms / 1000.0)
        finally:
            with self._lock:
                held_ms = (self._clock() - opened_at) * 1000.0
                closed = self._drive_closed()
                self._last_pulse_ms = min(pulse_ms, round(held_ms)) if cut_early else pulse_ms
                self._pulses += 1
                self._firing = False
                self._armed_idle_since = self._clock()
                self._emit("closed after pulse")
                reason = self._fault_reason
        if cut_early:
            return False, f"pulse cut after {self._last_pulse_ms} ms: {reason or 'disarmed'}"
        if not closed:
            return False, reason
        return True, f"fired {pulse_ms} ms"

    def _refusal(self, pulse_ms):
        if self._shut_down:
            return "valve controller is shut down"
        if isinstance(pulse_ms, bool) or not isinstance(pulse_ms, (int, float)) or not math.isfinite(pulse_ms):
            return f"pulse_ms must be a number, got {pulse_ms!r}"
        if pulse_ms <= 0:
            return f"pulse_ms must be > 0, got {pulse_ms}"
        if pulse_ms > self.max_pulse_ms:
            return f"pulse_ms {pulse_ms} exceeds max_pulse_ms {self.max_pulse_ms}"
        if self._fault_reason:
            return f"fault latched: {self._fault_reason}"
        if not self._armed:
            return "valve is disarmed"
        backend_refusal = self._backend.fire_refusal()
        if backend_refusal:
            return backend_refusal
        if self._firing:
            return "a pulse is already in progress"
        return ""

    # ---------------------------------------------------------- watchdog thread
    def start_watchdog(self, period_s: float) -> None:
        """Check the watchdog (and the backend's own calls, :meth:`check_backend`) every ``period_s`` seconds
        (steady clock) on a daemon thread until shutdown.

        Use this rather than a ROS timer: a ROS timer follows ``use_sim_time`` and could stall.
        """
        if not period_s > 0:
            raise ValueError(f"watchdog period must be > 0 s, got {period_s!r}")
        with self._lock:
            if self._watchdog_stop is not None:
                raise RuntimeError("the watchdog thread is already running")
            stop = self._watchdog_stop = threading.Event()

        def loop() -> None:
            while not stop.wait(period_s):
                try:
                    self.check_watchdog()
                    self.check_backend()
                except Exception:  # noqa: BLE001 - keep watching whatever happened
                    _LOG.exception("valve watchdog check failed")

        threading.Thread(target=loop, name="valve-watchdog", daemon=True).start()

    def shutdown(self) -> None:
        """Cut any pulse, drive closed, disarm, stop the watchdog thread and release the backend. Idempotent."""
        with self._lock:
            if self._shut_down:
                return
            self._shut_down = True
            self._armed = False
            self._cut.set()
            if self._watchdog_stop is not None:
                self._watchdog_stop.set()
            self._drive_closed()
            try:
                # backends drive closed once more before freeing the line / port
                self._call(self._backend.release, timeout_s=4 * self._caller.timeout_s)
                self._released = True
            except Exception as exc:  # noqa: BLE001
                self._latch_fault(f"backend error on release: {exc}")
            self._caller.stop()
            self._emit("shut down")


@dataclasses.dataclass
class GpioValveConfig:
    """``valve.gpio.*``: the GPIO line driving the valve's solenoid driver."""

    chip: str = dataclasses.field(default="/dev/gpiochip0", metadata={
        "description": "GPIO chip device driving the solenoid (e.g. /dev/gpiochip0)"})
    line_offset: int = dataclasses.field(default=17, metadata={
        "description": "line offset on that chip that drives the solenoid driver", "range": (0, 1023)})
    active_high: bool = dataclasses.field(default=True, metadata={
        "description": "true: a high level on the line opens the valve; false: an active-low driver"})
    hardware_pulse_limiter: bool = dataclasses.field(default=False, metadata={
        "description": "true declares the hardware pulse limiter of docs/firmware.md (monostable or watchdog relay) "
                       "is wired; without it the gpio backend refuses to fire, since a dead process cannot close "
                       "the line"})
    line_holder: bool = dataclasses.field(default=True, metadata={
        "description": "true: a small child process owns the GPIO line and drops it when the valve node dies"})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if not self.chip:
            raise ValueError("gpio.chip must name a GPIO chip (e.g. /dev/gpiochip0)")


@dataclasses.dataclass
class SerialRelayConfig:
    """``valve.serial.*``: the valve relay board (``firmware/``) on a serial port."""

    port: str = dataclasses.field(default="/dev/ttyACM0", metadata={
        "description": "serial device of the relay board running firmware/arduino/valve_relay (e.g. /dev/ttyACM0)"})
    baud: int = dataclasses.field(default=115200, metadata={
        "description": "serial baud rate of the relay board, bit/s (the firmware uses 115200)", "range": (1, 10000000)})
    timeout_s: float = dataclasses.field(default=0.2, metadata={
        "description": "longest wait for the board's answer, s; a missing or late one faults and closes",
        "range": (0.0, 60.0), "exclusive": "low"})
    keepalive_period_ms: int = dataclasses.field(default=50, metadata={
        "description": "how often this side sends KA while armed, ms; the board drops the relay after its own "
                       "keep-alive timeout (250 ms) without one", "range": (1, 10000)})
    boot_wait_s: float = dataclasses.field(default=3.0, metadata={
        "description": "how long HELLO is repeated while the board boots after its port opens (an Uno resets), s",
        "range": (0.0, 60.0)})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if not self.port:
            raise ValueError("serial.port must name a serial device")


@dataclasses.dataclass
class RegulatorConfig:
    """``valve.regulator.*``: the supply pressure that gives each target launch speed (paper 2.2)."""

    speeds_mps: list[float] = dataclasses.field(default_factory=lambda: [0.8, 1.5], metadata={
        "description": "target launch speeds that have a regulator pressure, m/s"})
    pressures_psi: list[float] = dataclasses.field(default_factory=lambda: [30.0, 60.0], metadata={
        "description": "regulator supply pressure for each target speed in valve.regulator.speeds_mps, psi"})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if len(self.speeds_mps) != len(self.pressures_psi) or not self.speeds_mps:
            raise ValueError("regulator.speeds_mps and regulator.pressures_psi must be non-empty and equally long")
        if not all(0 < value < math.inf for value in (*self.speeds_mps, *self.pressures_psi)):
            raise ValueError("regulator speeds and pressures must be finite and > 0")

    def pressure_psi(self, speed_mps: float) -> float:
        """Return the regulator pressure (psi) for a target speed (m/s); ``ValueError`` if none is configured."""
        for speed, pressure in zip(self.speeds_mps, self.pressures_psi):
            if math.isclose(speed, speed_mps, rel_tol=1e-6, abs_tol=1e-9):
                return pressure
        raise ValueError(f"no regulator pressure configured for {speed_mps} m/s (configured: {self.speeds_mps})")


class RegulatorCheck:
    """Remembers the pressure the operator confirmed, so the rig asks again only when a speed block changes."""

    def __init__(self, regulator):
        self._regulator = regulator
        self._confirmed_psi = None

    def pending_psi(self, speed_mps: float) -> typing.Optional[float]:
        """Return the pressure (psi) the operator must set and confirm for ``speed_mps``, or None if confirmed."""
        pressure = self._regulator.pressure_psi(speed_mps)
        return None if pressure == self._confirmed_psi else pressure

    def confirm(self, speed_mps: float) -> None:
        """Record that the regulator is set for ``speed_mps``."""
        self._confirmed_psi = self._regulator.pressure_psi(speed_mps)


@dataclasses.dataclass
class ValveConfig:
    """``valve.*`` of ``config/rig.yaml`` (build with ``config.from_mapping(ValveConfig, section(p, "valve"), ...)``)."""

    backend: str = dataclasses.field(default="dry_run", metadata={
        "description": "valve driver: dry_run (logs only), gpio (a libgpiod line) or serial_relay (a relay board)"})
    max_pulse_ms: int = dataclasses.field(default=500, metadata={
        "description": "longest valve opening ever fired, ms; longer fire requests are refused", "range": (1, 600000)})
    launch_pulse_ms: int = dataclasses.field(default=150, metadata={
        "description": "valve opening the rig commands for one launch, ms (at most max_pulse_ms)",
        "range": (1, 600000)})
    watchdog_ms: int = dataclasses.field(default=500, metadata={
        "description": "an armed valve closes and faults when the rig's keep-alive is silent this long, ms",
        "range": (1, 600000)})
    watchdog_check_ms: int = dataclasses.field(default=20, metadata={
        "description": "how often the watchdog looks at the heartbeat (steady clock), ms (at most half the watchdog)",
        "range": (1, 600000)})
    heartbeat_period_ms: int = dataclasses.field(default=100, metadata={
        "description": "how often the rig sends its keep-alive to the valve, ms (at most half the watchdog)",
        "range": (1, 600000)})
    arm_timeout_s: float = dataclasses.field(default=15.0, metadata={
        "description": "an armed valve that fires nothing this long (since arming or its last pulse) is disarmed, s: "
                       "an arming outside a launch sequence does not stay armed; longer than rig.countdown_s",
        "range": (0.1, 3600.0)})
    session_key_file: str = dataclasses.field(default="", metadata={
        "description": "file of the per-session arming key the valve node writes (mode 0600) and the rig reads; "
                       "empty: a per-user runtime file named by ROS domain and namespace"})
    gpio: GpioValveConfig = dataclasses.field(default_factory=GpioValveConfig)
    serial: SerialRelayConfig = dataclasses.field(default_factory=SerialRelayConfig)
    regulator: RegulatorConfig = dataclasses.field(default_factory=RegulatorConfig)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        VALVE_BACKENDS.check(self.backend)
        if not self.launch_pulse_ms <= self.max_pulse_ms:
            raise ValueError(f"launch_pulse_ms must be at most max_pulse_ms={self.max_pulse_ms}, got "
                             f"{self.launch_pulse_ms}")
        if self.watchdog_check_ms > self.watchdog_ms / 2:
            raise ValueError(f"watchdog_check_ms ({self.watchdog_check_ms}) must be at most half of watchdog_ms "
                             f"({self.watchdog_ms})")
        if not self.heartbeat_period_ms <= self.watchdog_ms / 2:
            raise ValueError(f"heartbeat_period_ms ({self.heartbeat_period_ms}) must be at most watchdog_ms / 2: "
                             "one lost heartbeat must not trip the watchdog")
