"""Progress of a long job (``study``, ``bringup``) on a terminal: one live status line, or plain lines.

On a terminal (``stream.isatty()``) with ``rich`` installed (the ``progress`` extra), a spinner line is rewritten in place with the phase,
generation, best fitness, trials stored and ETA, and event lines (:meth:`ProgressDisplay.say`) print above it. In
a pipe, a log file or CI the same facts come as plain lines, each printed once when it changes (no spinner, no
control characters), so a log shows every generation and no repeats.
"""
import dataclasses
import sys
import time
import typing

from rollability_ros.core.optional import require
from rollability_ros.core.records import RunProgress


@dataclasses.dataclass(frozen=True)
class JobProgress:
    """One snapshot of a job: ``phase`` text, generation counters, best-so-far fitness, trials, ETA (s)."""

    phase: str
    generation: int | None = None          # generations completed
    max_generations: int = 0               # 0 = no cap
    best_so_far: float | None = None       # fitness, upright trials / trials
    trials_stored: int | None = None       # trials in the store (simulated trials or launches)
    trials_total: int = 0                  # 0 = open-ended
    eta_s: float | None = None
    trials_label: str = "trials stored"     # what the trials are: launches stored, or simulated trials evaluated

    def text(self) -> str:
        """The status as one line, e.g. ``optimizing | generation 4/30 | best 0.85 | 480 trials stored | ETA 3 min``."""
        parts = [self.phase]
        if self.generation is not None:
            parts.append(f"generation {self.generation}" + (f"/{self.max_generations}" if self.max_generations else ""))
        if self.best_so_far is not None:
            parts.append(f"best {self.best_so_far:.2f}")
        if self.trials_stored is not None:
            parts.append(f"{self.trials_stored}" + (f"/{self.trials_total}" if self.trials_total else "")
                         + f" {self.trials_label}")
        if self.eta_s is not None:
            parts.append(f"ETA {format_duration(self.eta_s)}")
        elif self.trials_total or self.max_generations:   # an end to estimate, not yet estimable
            parts.append("ETA unknown")
        return " | ".join(parts)


def eta_s(done: float, total: float, elapsed_s: float) -> typing.Optional[float]:
    """Seconds left at the rate so far (``done`` of ``total`` units in ``elapsed_s``); None when unknown."""
    if not total or not done or elapsed_s <= 0 or done >= total:
        return 0.0 if total and done >= total else None
    return elapsed_s / done * (total - done)


def format_duration(seconds: float) -> str:
    """``seconds`` as ``42 s``, ``7 min`` or ``1.5 h``."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


class ProgressDisplay:
    """Shows :class:`JobProgress` snapshots and event lines on ``stream`` (see the module docstring).

    ``live`` forces (True) or forbids (False) the in-place line; default: ``stream.isatty()``.
    """

    def __init__(self, stream=None, live=None):
        self.stream = stream or sys.stdout
        self.live = self.stream.isatty() if live is None else live
        self._status = None
        self._console = None
        self._last_text = None

    def __enter__(self):
        if self.live:
            try:
                rich_console = require("rich.console", feature="the live progress display")
            except ImportError:   # without the extra: plain lines, as in a pipe
                self.live = False
                return self
            self._console = rich_console.Console(file=self.stream)
            self._status = self._console.status("starting")
            self._status.start()
        return self

    def __exit__(self, *exc_info):
        self.close()

    def say(self, text: str) -> None:
        """An event line: printed once (above the live line on a terminal)."""
        if self._console is not None:
            self._console.print(text, markup=False, highlight=False)
        else:
            print(text, file=self.stream, flush=True)

    def update(self, progress: typing.Union[JobProgress, str]) -> None:
        """Show a snapshot (a :class:`JobProgress` or text): rewritten in place, or printed when it changed."""
        text = progress.text() if isinstance(progress, JobProgress) else str(progress)
        if self._status is not None:
            self._status.update(text)
        elif text != self._last_text:
            print(f"  {text}", file=self.stream, flush=True)
        self._last_text = text

    def close(self) -> None:
        """Remove the live line (idempotent)."""
        if self._status is not None:
            self._status.stop()
            self._status = None


class Stopwatch:
    """Seconds since construction (monotonic), for rates and ETAs of a phase."""

    def __init__(self, clock=time.monotonic):
        self._clock = clock
        self._start = clock()

    @property
    def elapsed_s(self) -> float:
        """Seconds since the stopwatch was made."""
        return self._clock() - self._start


class GraphObserver(typing.Protocol):
    """What an orchestrator (``study``, ``bringup``) learns from the running node graph: over ROS, never from a
    node's store (the logger and the optimizer may run in directories, or on computers, the orchestrator cannot
    read). The implementation is ``rollability_ros.nodes._graph_observer.RosGraphObserver``: the optimizer's
    latched ``optimizer_progress`` topic, the outcome logger's latched ``summary`` and its ``get_summary``
    service."""

    def optimizer_progress(self) -> typing.List[RunProgress]:
        """Every ``optimizer_progress`` received so far, oldest first (one per generation, and one per run start)."""

    def stored_trials(self, run_id: str) -> typing.Optional[int]:
        """Launch outcomes of ``run_id`` the outcome logger has stored (its latest answer); None before one."""

    def stored_launches(self) -> typing.Optional[int]:
        """Launch outcomes in the outcome logger's store, every run (its latest summary); None before one."""

    def campaign_progress(self) -> typing.Optional[typing.Tuple[str, int, int, typing.Optional[float]]]:
        """The graph campaign's latest ``(run id, trials stored, trials planned, ETA s or None)``; None before
        one."""


def session_progress(observer: GraphObserver, nodes: int, elapsed_s: float) -> JobProgress:
    """A :class:`JobProgress` of a ``bringup`` session: the optimizer's newest run (generation, best so far, ETA
    from the run's generation cap), else the graph campaign's progress (its trials and ETA), else the launches the
    outcome logger stored, learnt through ``observer``;
    ``nodes`` supervised."""
    # whole minutes: in a pipe or log a line is printed per change, not every second (issue 45)
    phase = f"session up {int(elapsed_s // 60)} min, {nodes} nodes supervised"
    generation = best = eta = None
    cap = 0
    history = observer.optimizer_progress()
    if history and history[-1].generation:
        last = history[-1]
        generation, best, cap = last.generation, last.best_so_far, last.max_generations
        phase += f", optimizing run {last.run_id}"
        eta = eta_s(generation, cap, last.elapsed_s)   # generations are numbered from 1
        return JobProgress(phase, generation, cap, best, observer.stored_launches(), eta_s=eta)
    campaign = observer.campaign_progress()
    if campaign is not None:   # the campaign's own count and ETA (issue 45: "ETA unknown" every second)
        run_id, done, total, eta = campaign
        return JobProgress(f"{phase}, campaign {run_id}", trials_stored=done, trials_total=total, eta_s=eta,
                           trials_label="launches stored")
    return JobProgress(phase, generation, cap, best, observer.stored_launches(), eta_s=eta)
