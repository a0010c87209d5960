"""Splitting a lone request over idle evaluators: generation wall time with and without (simulated evaluators).

    nice python bench/bench_pool_split.py [--config paper] [--evaluators 2 4 12] [--generations 3]
                                          [--measure-trials 40] [--time-scale 1] [--smoke]

A CMA-ES generation over the node graph is one batch of ``optimizer.popsize`` candidates and then the incumbent's
re-evaluation, a batch of one request (``core/optimization/optimization_run.py``); without splitting, every other
evaluator idles during it. This bench first measures, in this process, what one evaluator's goal costs on the
config's trial (``--config``, default the paper's): the profile job and world build of a goal (once per goal) and
``--measure-trials`` single trials, each timed alone (``run_batch``; the early decision as the config sets it), on
a ridge and on a random profile. Then, for each evaluator count, an :class:`EvaluatorPool` runs ``--generations`` generations
(popsize requests + one re-evaluation, ``optimizer.trials`` trials each) over simulated evaluators: each goal
sleeps the measured goal overhead plus the measured durations of its trials (trial ``i`` of candidate ``c`` always
takes the same sample, so a split and an unsplit request do the same work), times ``--time-scale`` (1: the
measured costs; the pool's own cost per goal, a thread and a few locks here, does not scale, so a scale well below 1
makes it a larger share and understates the gain). The evaluators run one goal at a time on one worker, as
``rollability study`` starts them. About 40 s of wall time at the defaults, 2 s of CPU (the evaluators sleep).

Prints per evaluator count: the generation wall time without and with splitting, their ratio, the evaluators' idle
share of each, the ideal rounds (trial-rounds of a generation with every evaluator busy: (popsize + 1) / N) against
ceil(popsize / N) + 1 unsplit, and whether the split run's results (successes and per-trial results) equal the
unsplit run's. Simulated: sleeping evaluators, measured trial durations; no ROS, no DDS.
"""
import argparse
import math
import os
import sys
import threading
import time
import typing

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

from rollability_ros.core.optimization import run_directory  # noqa: E402
from rollability_ros.core.optimization.evaluator_pool import (EvaluationRequest, EvaluatorPool,  # noqa: E402
                                                              PoolSettings, Ticket)
from rollability_ros.core.profile.geometry import grid_xy  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402
from rollability_ros.core.sim.trial_engine import TrialOutcome  # noqa: E402


def measure_costs(config: str, trials: int, seed: int = 5) -> typing.Tuple[float, np.ndarray, typing.Any]:
    """``(goal overhead s, per-trial durations s, settings)`` of ``config``'s trial, in this process, on two profiles
    (a ridge along the centre line and uniform random heights in the grid's bounds, as a random initial mean),
    ``trials`` trials in all: a goal's overhead is its profile job plus its world's build (the first trial's time
    beyond the profile's median trial), averaged over the two; then each trial is timed alone. A baseline trial
    runs first, so the engine's import is in neither."""
    settings = evaluation.settings_from_parameters(run_directory.load_run_parameters(config))
    grid = settings.grid
    evaluation.run_batch(evaluation.profile_job(None, settings), [(0, evaluation.trial_seed(seed, 0))])
    profiles = [0.4 * (1.0 - grid_xy(grid)[:, 1] / (grid.width_m / 2)),
                np.random.default_rng(seed).uniform(grid.height_min, grid.height_max, grid.n_variables)]
    overheads_s, durations_s = [], []
    for number, heights in enumerate(profiles):
        started = time.perf_counter()
        job = evaluation.profile_job(heights, settings)
        job_s = time.perf_counter() - started
        timed = []
        for index in range(max(1, trials // len(profiles)) + (number < trials % len(profiles)) + 1):
            started = time.perf_counter()
            evaluation.run_batch(job, [(index, evaluation.trial_seed(seed, index))])
            timed.append(time.perf_counter() - started)
        durations_s += timed[1:]
        overheads_s.append(job_s + max(0.0, timed[0] - float(np.median(timed[1:]))))
    return float(np.mean(overheads_s)), np.asarray(durations_s), settings


class SleepingEvaluators:
    """``submit`` of an :class:`EvaluatorPool` over evaluators that sleep a goal's cost (overhead + its trials'
    sampled durations, x ``scale``) and report each trial (upright drawn from the trial's seed), one goal at a time."""

    def __init__(self, overhead_s: float, durations_s: np.ndarray, scale: float) -> None:
        self.overhead_s, self.durations_s, self.scale = overhead_s, durations_s, scale
        self.busy_s = 0.0
        self._lock = threading.Lock()

    def trial_s(self, request: EvaluationRequest, index: int) -> float:
        """The sampled duration of trial ``index`` of ``request``'s profile (the same for every split of it)."""
        key = abs(hash((request.heights, request.seed, index)))
        return float(self.durations_s[key % len(self.durations_s)])

    def submit(self, name: str, request: EvaluationRequest, ticket: Ticket) -> None:
        cost_s = self.scale * (self.overhead_s + sum(self.trial_s(request, i) for i in request.trial_range))

        def work() -> None:
            ticket.progress()
            time.sleep(cost_s)
            outcomes = [TrialOutcome(i, evaluation.trial_seed(request.seed, i),
                                     evaluation.trial_seed(request.seed, i) % 3 != 0, True, 0, 0.0)
                        for i in request.trial_range]
            with self._lock:
                self.busy_s += cost_s
            ticket.succeed(sum(o.upright for o in outcomes), request.trials, cost_s, name, trial_results=outcomes)

        threading.Thread(target=work, daemon=True).start()


def run_generations(evaluators: int, split: bool, generations: int, popsize: int, trials: int,
                    costs: SleepingEvaluators) -> typing.Tuple[float, float, list]:
    """``(wall s per generation, evaluators' idle share, results)`` of ``generations`` generations (a popsize batch,
    then a batch of one re-evaluation) over ``evaluators`` sleeping evaluators."""
    costs.busy_s = 0.0
    pool = EvaluatorPool(costs.submit, PoolSettings(timeout_s=600.0, split_trials=split),
                         log=lambda level, message: None)
    pool.set_evaluators([f"eval_{n:02d}" for n in range(evaluators)])
    rng = np.random.default_rng(1)
    results = []
    started = time.perf_counter()
    for generation in range(generations):
        population = [EvaluationRequest(tuple(rng.uniform(0, 0.45, 4).round(6)), trials, 1000 + generation)
                      for _ in range(popsize)]
        results += pool.evaluate(population)
        results += pool.evaluate([EvaluationRequest(population[0].heights, trials, 5000 + generation)])
    wall_s = time.perf_counter() - started
    pool.close()
    return wall_s / generations, 1.0 - costs.busy_s / (evaluators * wall_s), results


def main(argv: typing.Optional[typing.Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="paper", help="shipped config name or path whose trial is measured")
    parser.add_argument("--evaluators", type=int, nargs="+", default=[2, 4, 12])
    parser.add_argument("--generations", type=int, default=3)
    parser.add_argument("--measure-trials", type=int, default=40, help="trials timed to sample durations from")
    parser.add_argument("--time-scale", type=float, default=1.0, help="sleep this share of the measured costs")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes (bench/smoke.py); the numbers mean nothing")
    args = parser.parse_args(argv)
    if args.smoke:
        args.evaluators, args.generations, args.measure_trials, args.time_scale = [2], 1, 2, 0.01
    if min(args.evaluators) < 1 or args.generations < 1 or args.measure_trials < 1 or args.time_scale <= 0:
        parser.error("--evaluators, --generations and --measure-trials must be >= 1 and --time-scale > 0")
    parameters = run_directory.load_run_parameters(args.config)
    popsize, trials = int(parameters["optimizer.popsize"]), int(parameters["optimizer.trials"])
    print(f"load average {' '.join(f'{v:.1f}' for v in os.getloadavg())} on {os.cpu_count()} cores")
    overhead_s, durations_s, settings = measure_costs(args.config, args.measure_trials)
    print(f"config {args.config}: popsize {popsize} + 1 re-evaluation, {trials} trials, engine "
          f"{settings.physics.engine}, objective {settings.objective.kind}")
    print(f"measured in this run: goal overhead {overhead_s * 1000:.0f} ms (profile job + world build); per trial "
          f"median {np.median(durations_s) * 1000:.1f} ms, p90 {np.percentile(durations_s, 90) * 1000:.1f} ms "
          f"({len(durations_s)} trials); simulated evaluators sleep x{args.time_scale:g} of it")
    costs = SleepingEvaluators(overhead_s, durations_s, args.time_scale)
    failures = 0
    for evaluators in args.evaluators:
        whole_s, whole_idle, whole = run_generations(evaluators, False, args.generations, popsize, trials, costs)
        split_s, split_idle, split = run_generations(evaluators, True, args.generations, popsize, trials, costs)
        same = [(r.successes, r.trials, r.trial_results) for r in whole] == \
            [(r.successes, r.trials, r.trial_results) for r in split]
        failures += not same
        rounds_whole, rounds_ideal = math.ceil(popsize / evaluators) + 1, (popsize + 1) / evaluators
        print(f"{evaluators} evaluators: generation wall {whole_s:.3f} s unsplit, {split_s:.3f} s split "
              f"(x{args.time_scale:g} scale): unsplit / split = {whole_s / split_s:.2f}; idle {whole_idle:.0%} -> "
              f"{split_idle:.0%}; rounds {rounds_whole} unsplit, ideal {rounds_ideal:.2f} "
              f"(ratio {rounds_whole / rounds_ideal:.2f}); results identical: {same}")
    print("simulated evaluators (sleeping the measured costs); no ROS graph", flush=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
