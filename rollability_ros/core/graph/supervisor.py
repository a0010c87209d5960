"""Supervise a node graph as separate OS processes: start in order, restart or stop on death, stop in order.

Each child runs in its own session (process group), so a Ctrl-C on the terminal reaches only the supervisor,
which then stops the children itself in reverse start order (the recorder, started first, stops last and
closes its bag after everything else has been recorded). If the supervisor itself is killed (SIGKILL), the
kernel sends every child SIGTERM (Linux ``PR_SET_PDEATHSIG``, set in the child before it runs its command), so
no node outlives it: each stops as on a plain SIGTERM (the recorder closes its bag). The death signal follows
the thread that started the child, so start and restart children from one long-lived thread (the main one). A child that dies is restarted up to
``max_restarts`` times when its spec says ``restart=True``; a ``critical`` child that dies for good stops the
whole graph cleanly, so a run is never left half alive.
"""
import ctypes
import dataclasses
import os
import signal
import subprocess
import time
import typing

#: ``prctl`` option: the signal this process gets when its parent dies (linux/prctl.h).
PR_SET_PDEATHSIG = 1


@dataclasses.dataclass
class ProcessSpec:
    """One supervised process.

    ``argv`` is the full command; ``restart``: restart it when it exits while the graph runs; ``critical``: if it
    exits for good (no restart left), stop the graph; ``stop_timeout_s``: how long SIGINT gets before SIGTERM, and
    SIGTERM before SIGKILL.
    """

    name: str
    argv: list
    restart: bool = True
    max_restarts: int = 3
    critical: bool = True
    stop_timeout_s: float = 10.0
    env: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass
class SupervisorEvent:
    """Something the operator should see: ``kind`` is started | exited | restarted | gave_up | finished | stopping |
    stopped."""

    kind: str
    name: str
    detail: str = ""

    def text(self) -> str:
        return f"[{self.name}] {self.kind}" + (f": {self.detail}" if self.detail else "")


def _die_with(parent_pid):
    """A ``preexec_fn``: in the child, before its command runs, ask for SIGTERM when ``parent_pid`` dies.

    None where the C library has no ``prctl`` (not Linux): children then outlive a killed supervisor.
    """
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl   # resolved before the fork: the child only calls it
    except AttributeError:
        return None

    def preexec() -> None:
        prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != parent_pid:   # the parent died before the request took effect
            os._exit(1)
    return preexec


class _Child:
    def __init__(self, spec, log_dir):
        self.spec = spec
        self.restarts = 0
        self.process: typing.Optional[subprocess.Popen] = None
        self.log_path = os.path.join(log_dir, f"{spec.name}.log")
        self.finished = False   # exited and not to be restarted

    def start(self) -> subprocess.Popen:
        """Start the process (its output appended to its log); return it."""
        log = open(self.log_path, "ab")
        env = dict(os.environ, **self.spec.env)
        try:
            process = subprocess.Popen(self.spec.argv, stdout=log, stderr=subprocess.STDOUT, env=env,
                                       start_new_session=True, stdin=subprocess.DEVNULL,
                                       preexec_fn=_die_with(os.getpid()))
        finally:
            log.close()
        self.process = process
        return process

    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def tail(self, lines: int = 5) -> str:
        try:
            with open(self.log_path, encoding="utf-8", errors="replace") as stream:
                return "".join(stream.readlines()[-lines:]).strip()
        except OSError:
            return ""


class Supervisor:
    """Starts, watches and stops a list of :class:`ProcessSpec` (in list order; stopped in reverse).

    Parameters
    ----------
    specs : list of ProcessSpec
    log_dir : str
        Each child's stdout and stderr go to ``<log_dir>/<name>.log``.
    on_event : callable(SupervisorEvent), optional
        Progress reporting (default: print).
    """

    def __init__(self, specs, log_dir, on_event=None):
        names = [spec.name for spec in specs]
        if len(set(names)) != len(names):
            raise ValueError(f"process names must be unique, got {names}")
        os.makedirs(log_dir, exist_ok=True)
        self.log_dir = log_dir
        self._children = [_Child(spec, log_dir) for spec in specs]
        self._on_event = on_event or (lambda event: print(event.text(), flush=True))
        self.failed = ""   # why the graph was stopped, when a critical child died for good

    def _emit(self, kind, child, detail=""):
        self._on_event(SupervisorEvent(kind, child.spec.name, detail))

    def child(self, name: str) -> typing.Optional[subprocess.Popen]:
        """The ``subprocess.Popen`` of the named process (None before start)."""
        for child in self._children:
            if child.spec.name == name:
                return child.process
        raise KeyError(name)

    def add(self, spec: ProcessSpec) -> None:
        """Add and start one more process while the graph runs (e.g. the rig once designs exist)."""
        if any(child.spec.name == spec.name for child in self._children):
            raise ValueError(f"a process named {spec.name!r} is already supervised")
        child = _Child(spec, self.log_dir)
        self._children.append(child)
        process = child.start()
        self._emit("started", child, f"pid {process.pid}")

    def start(self) -> None:
        """Start every process in order."""
        for child in self._children:
            if child.process is None:
                process = child.start()
                self._emit("started", child, f"pid {process.pid}")

    def poll(self) -> bool:
        """Check every child once: restart the dead ones that may restart; return False when the graph must stop."""
        for child in self._children:
            if child.finished or child.alive() or child.process is None:
                continue
            code = child.process.returncode
            self._emit("exited", child, f"exit code {code}; last log lines:\n{child.tail()}")
            if child.spec.restart and child.restarts < child.spec.max_restarts:
                child.restarts += 1
                process = child.start()
                self._emit("restarted", child,
                           f"attempt {child.restarts} of {child.spec.max_restarts}, pid {process.pid}")
                continue
            child.finished = True
            if child.spec.critical:
                self.failed = f"{child.spec.name} exited with code {code} and was not restarted"
                self._emit("gave_up", child, "stopping the whole graph")
                return False
        return True

    def finish(self, name: str) -> None:
        """Mark a process as expected to end (e.g. a one-shot job): its exit is no failure, and it is not restarted."""
        for child in self._children:
            if child.spec.name == name:
                child.spec.restart = False
                child.spec.critical = False
                return
        raise KeyError(name)

    def wait_for_exit(self, name: str, timeout_s: typing.Optional[float] = None, period_s: float = 0.2,
                      stop_requested: typing.Callable[[], bool] = lambda: False,
                      on_tick: typing.Optional[typing.Callable[[], None]] = None,
                      tick_period_s: float = 10.0) -> typing.Tuple[typing.Optional[int], str]:
        """Supervise until process ``name`` exits (it is :meth:`finish`-ed first).

        Returns ``(exit code, reason)``: the code is None when waiting ended otherwise, and ``reason`` then says
        why (operator stop, a critical process gave up, timeout); a non-zero exit also has a reason.
        ``on_tick()`` runs every ``tick_period_s`` while waiting (progress display).
        """
        self.finish(name)
        process = self.child(name)
        if process is None:
            raise ValueError(f"{name} has not been started")
        deadline = None if not timeout_s else time.monotonic() + timeout_s
        last_tick = 0.0
        while process.poll() is None:
            if stop_requested():
                return None, "stopped by the operator"
            if not self.poll():
                return None, self.failed
            if deadline is not None and time.monotonic() > deadline:
                return None, f"{name} did not finish within {timeout_s:.0f} s"
            if on_tick is not None and time.monotonic() - last_tick >= tick_period_s:
                on_tick()
                last_tick = time.monotonic()
            time.sleep(period_s)
        code = process.returncode
        last = ""
        for child in self._children:
            if child.spec.name == name:
                child.finished = True
                self._emit("finished", child, f"exit code {code}")
                last = child.tail(1)[:300]   # a node's last line as it exits: its one-line error
        if code == 0:
            return code, ""
        return code, f"{name} exited with code {code}{f': {last}' if last else ''} (its log: {self.log_dir}/{name}.log)"

    def wait_for_output(self, name: str, text: str, timeout_s: float, period_s: float = 0.1) -> bool:
        """Wait until process ``name`` has written ``text`` to its log (a readiness line); True if it did."""
        child = next(child for child in self._children if child.spec.name == name)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                with open(child.log_path, encoding="utf-8", errors="replace") as stream:
                    if text in stream.read():
                        return True
            except OSError:
                pass
            if not child.alive():
                return False
            time.sleep(period_s)
        return False

    def stop(self) -> None:
        """Stop every running child in reverse start order: SIGINT, then SIGTERM, then SIGKILL."""
        for child in reversed(self._children):
            child.finished = True
            if not child.alive():
                continue
            self._emit("stopping", child)
            process = child.process
            assert process is not None   # alive
            code = None
            for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
                try:
                    os.killpg(process.pid, signum)
                except ProcessLookupError:
                    break
                try:
                    code = process.wait(timeout=child.spec.stop_timeout_s)
                    break
                except subprocess.TimeoutExpired:
                    continue
            self._emit("stopped", child, f"exit code {code if code is not None else process.wait()}")

