"""Memory of an evaluator's trial worker over a search: RSS growth per candidate while it warms up and after.

    nice python bench/bench_worker_memory.py [--config optimizer paper] [--candidates 40] [--warmup 20]
        [--trials 10] [--trim] [--smoke]

The path of a study's evaluator worker, in this process: fresh random profiles (heights uniform in the grid's
bounds, a new one per candidate, as a search's) each evaluated by ``evaluate_profile`` at fidelity ``screen`` under
``--config`` (the study's: robust launches on the MuJoCo twin; each draw weighs the profile by its own mass scale,
part of the twin's key, so every launch compiles a twin of its own and the cache drops one), no executor. Prints
this process's RSS after each candidate, then the mean growth per candidate over the first ``--warmup`` candidates
(caches filling) and over the rest (the steady state: a bounded process grows by about 0 MB per candidate there),
and how many launch twins are alive at the end against the cache's ``CACHE_SIZE`` (alive twins beyond it are dropped
ones not yet freed). The garbage collector runs as it would in a worker: never forced. RSS also holds memory the
allocator keeps after a free (each compile allocates afresh), so the steady state's growth is not all live memory:
``--trim`` calls glibc's ``malloc_trim(0)`` before each reading, so RSS reads what is in use.
"""
import argparse
import ctypes
import gc
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

import numpy as np  # noqa: E402

from rollability_ros.core.optimization import run_directory  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402


def rss_mb(trim: bool = False) -> float:
    """This process's resident set size (MB); ``trim``: after returning the allocator's free memory (glibc)."""
    if trim:
        ctypes.CDLL(None).malloc_trim(0)
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


def live_twins() -> int:
    """MuJoCo launch twins alive in this process (cached or dropped but not yet freed)."""
    from rollability_ros.core.sim.launch.mujoco_twin import MujocoLaunchTwin
    return sum(isinstance(obj, MujocoLaunchTwin) for obj in gc.get_objects())


def growth_per_candidate(rss, first, last):
    """Mean RSS growth per candidate (MB) from candidate ``first`` to ``last`` (indices into ``rss``)."""
    return (rss[last] - rss[first]) / max(last - first, 1)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", nargs="+", default=["optimizer", "paper"], help="shipped config names or paths")
    parser.add_argument("--candidates", type=int, default=40, help="profiles evaluated")
    parser.add_argument("--warmup", type=int, default=20, help="candidates before the steady state")
    parser.add_argument("--trials", type=int, default=10, help="robust launches per candidate")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random profiles and of the evaluations")
    parser.add_argument("--trim", action="store_true", help="malloc_trim(0) before each RSS reading (glibc)")
    parser.add_argument("--smoke", action="store_true", help="3 candidates, 1 warm-up, 2 trials")
    args = parser.parse_args(argv)
    if args.smoke:
        args.candidates, args.warmup, args.trials = 3, 1, 2
    if not 0 < args.warmup < args.candidates - 1:
        parser.error("--warmup must be at least 1 and leave at least 2 candidates after it")
    from rollability_ros.core.sim.launch.mujoco_twin import CACHE_SIZE
    settings = evaluation.settings_at_fidelity(
        evaluation.settings_from_parameters(run_directory.load_run_parameters(args.config)), "screen")
    grid = settings.grid
    print(f"worker memory (simulated launches): --config {' '.join(args.config)}, engine {settings.physics.engine}, "
          f"robust {settings.objective.robust.enabled}, {args.trials} trials per candidate")
    rng = np.random.default_rng(args.seed)
    rss = [rss_mb(args.trim)]
    started = time.perf_counter()
    for index in range(args.candidates):
        heights = rng.uniform(grid.height_min, grid.height_max, grid.n_variables)
        evaluation.evaluate_profile(heights, args.trials, args.seed + index, settings, executor=None)
        rss.append(rss_mb(args.trim))
        print(f"candidate {index + 1:3d}: rss {rss[-1]:7.1f} MB ({time.perf_counter() - started:6.1f} s)", flush=True)
    print(f"rss{' after malloc_trim' if args.trim else ''} growth per candidate: warm-up (candidates 1-{args.warmup}) "
          f"{growth_per_candidate(rss, 0, args.warmup):.2f} MB, steady state (candidates {args.warmup + 1}-"
          f"{args.candidates}) {growth_per_candidate(rss, args.warmup, args.candidates):.2f} MB")
    print(f"launch twins alive at the end: {live_twins()} (cache keeps {CACHE_SIZE})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
