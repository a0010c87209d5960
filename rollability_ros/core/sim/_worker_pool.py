"""Worker processes for the simulation: spawned (no forked PyBullet state), deaf to Ctrl-C, never orphaned.

A ``concurrent.futures.ProcessPoolExecutor`` worker waits on a pipe whose write end it also holds, so when its
parent is killed with SIGKILL it never sees end-of-file and would wait forever, holding memory and a physics
client. Each worker started by :func:`spawn_pool` watches its parent instead: when the parent process is gone
(``os.getppid()`` changed) it exits within :data:`ORPHAN_CHECK_PERIOD_S`. Ctrl-C reaches the whole process
group; workers ignore it and the parent, which owns their lifetime, shuts them down.
"""
import concurrent.futures
import multiprocessing
import os
import signal
import threading
import time

#: How often a worker checks that its parent is still alive (s).
ORPHAN_CHECK_PERIOD_S = 1.0
#: The most worker processes a pool starts: the declared top of ``evaluator.workers`` (config/evaluator.yaml), so a
#: typed ``--workers 100000`` is refused before it starts that many interpreters.
MAX_WORKERS = 1024


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


def spawn_pool(workers: int, period_s: float = ORPHAN_CHECK_PERIOD_S) -> concurrent.futures.ProcessPoolExecutor:
    """A ProcessPoolExecutor of ``workers`` spawned processes that ignore Ctrl-C and exit when orphaned;
    ``ValueError`` for a count outside [1, :data:`MAX_WORKERS`]."""
    if not 1 <= workers <= MAX_WORKERS:
        raise ValueError(f"worker processes must be in [1, {MAX_WORKERS}], got {workers}")
    return concurrent.futures.ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                                  initializer=_worker_init, initargs=(period_s,))
