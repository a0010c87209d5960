"""Worker processes for the simulation: spawned (no forked PyBullet state), deaf to Ctrl-C, never orphaned.

A ``concurrent.futures.ProcessPoolExecutor`` worker waits on a pipe whose write end it also holds, so when its
parent is killed with SIGKILL it never sees end-of-file and would wait forever, holding memory and a physics
client. Each worker started by :func:`spawn_pool` watches its parent instead: when the parent process is gone
(``os.getppid()`` changed) it exits within :data:`ORPHAN_CHECK_PERIOD_S`. Ctrl-C reaches the whole process
group; workers ignore it and the parent, which owns their lifetime, shuts them down.

A pool is refused before it starts when its workers would need more memory than the machine has available
(:func:`worker_memory_refusal`: :data:`WORKER_RSS_MB` per worker against ``MemAvailable`` of ``/proc/meminfo``; where
that cannot be read nothing is refused).
"""
import concurrent.futures
import multiprocessing
import os
import signal
import threading
import time
import typing

#: How often a worker checks that its parent is still alive (s).
ORPHAN_CHECK_PERIOD_S = 1.0
#: The most worker processes a pool starts: the declared top of ``evaluator.workers`` (config/evaluator.yaml), so a
#: typed ``--workers 100000`` is refused before it starts that many interpreters.
MAX_WORKERS = 1024
#: A simulation worker's resident memory, MB: where one trial worker's RSS levels off over a robust MuJoCo search
#: (``python bench/bench_worker_memory.py --candidates 100 --warmup 50``: 158 MB at start, 290 MB from about the
#: 40th candidate on, +0.04 MB per candidate over candidates 51-100).
WORKER_RSS_MB = 290
#: Where :data:`WORKER_RSS_MB` comes from, as a refusal names it.
WORKER_RSS_SOURCE = "a trial worker's RSS plateau, bench/bench_worker_memory.py"
#: The kernel's estimate of the memory available for new processes (Linux).
MEMINFO_PATH = "/proc/meminfo"


def available_memory_mb(meminfo_path: str = MEMINFO_PATH) -> typing.Optional[float]:
    """``MemAvailable`` of ``meminfo_path``, MB; None where it cannot be read (no such file, no such line)."""
    try:
        with open(meminfo_path, encoding="ascii") as stream:
            for line in stream:
                name, _, value = line.partition(":")
                if name == "MemAvailable" and value.split()[1:] == ["kB"]:
                    return int(value.split()[0]) / 1024.0
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return None


def worker_memory_refusal(workers: int, available_mb: typing.Optional[float]) -> str:
    """Why ``workers`` processes of :data:`WORKER_RSS_MB` each do not fit in ``available_mb`` MB ("" when they
    do, or when the available memory is not known: None)."""
    needed_mb = workers * WORKER_RSS_MB
    if available_mb is None or needed_mb <= available_mb:
        return ""
    fitting = int(available_mb // WORKER_RSS_MB)
    return (f"{workers} worker processes need about {needed_mb} MB ({WORKER_RSS_MB} MB each: {WORKER_RSS_SOURCE}), "
            f"more than the {available_mb:.0f} MB available (MemAvailable, {MEMINFO_PATH}): "
            + (f"use at most {fitting}" if fitting else "free memory first"))


def _exit_when_orphaned(parent_pid, period_s):
    while True:
        time.sleep(period_s)
        if os.getppid() != parent_pid:
            os._exit(1)  # the parent is gone: nobody will collect results or shut the pool down


def _worker_init(period_s):
    """Runs first in every worker: ignore SIGINT, start the orphan watch (a daemon thread)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_exit_when_orphaned, args=(os.getppid(), period_s), name="orphan-watch",
                     daemon=True).start()


def spawn_pool(workers: int, period_s: float = ORPHAN_CHECK_PERIOD_S,
               meminfo_path: str = MEMINFO_PATH) -> concurrent.futures.ProcessPoolExecutor:
    """A ProcessPoolExecutor of ``workers`` spawned processes that ignore Ctrl-C and exit when orphaned;
    ``ValueError`` for a count outside [1, :data:`MAX_WORKERS`] or one whose workers the memory available
    (``MemAvailable`` of ``meminfo_path``) does not hold (:func:`worker_memory_refusal`), before any process starts."""
    if not 1 <= workers <= MAX_WORKERS:
        raise ValueError(f"worker processes must be in [1, {MAX_WORKERS}], got {workers}")
    refusal = worker_memory_refusal(workers, available_memory_mb(meminfo_path))
    if refusal:
        raise ValueError(refusal)
    return concurrent.futures.ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                                  initializer=_worker_init, initargs=(period_s,))
