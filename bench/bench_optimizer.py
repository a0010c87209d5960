"""Optimizer benchmark: overhead per generation vs evaluation time, projected paper-scale wall time, noise handling.

    .venv/bin/python bench/bench_optimizer.py [--generations 2] [--workers N] [--noise-seeds 8]

1. Real evaluation at the paper's scale (config/paper.yaml: 10 x 10 grid, popsize 12, 60 trials) through
   ``OptimizationRun`` for a few generations: time inside the evaluator vs the rest of each generation (CMA-ES
   ask/tell, SQLite writes with fsync, checkpoint). Target: overhead <= 5% of evaluation time.
2. The same loop with a zero-cost synthetic evaluator at N = 100 for a stable overhead figure, split into
   CMA-ES alone and store + checkpoint.
3. Projected wall time of the paper run (500 generations x (12 + 1 re-evaluation) x 60 trials) from the
   measured evaluation rate.
4. Noise handling on a synthetic binomial fitness with a known optimum (16 variables, 20 trials, 60
   generations): common random numbers vs independent seeds (true fitness of the final mean), and the
   best-so-far overestimate with and without re-evaluation of the incumbent.
The messaging overhead through the ROS node is measured by the node's own benchmark.
"""
import argparse
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first
sys.path.insert(1, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "test"))  # doubles

from rollability_ros.core.sim import evaluation

from doubles import SyntheticEvaluator  # noqa: E402
from rollability_ros.core.optimization import optimization_run as optimization_run  # noqa: E402
from rollability_ros.core.profile.geometry import ProfileGrid  # noqa: E402
from rollability_ros.core.optimization.cmaes import ProfileOptimizer  # noqa: E402

PAPER_GENERATIONS = 500


def timed(evaluate_batch, spent):
    """Wrap ``evaluate_batch`` so the wall time spent inside it is added to ``spent[0]``."""
    def wrapper(heights_list, seed):
        started = time.perf_counter()
        try:
            return evaluate_batch(heights_list, seed)
        finally:
            spent[0] += time.perf_counter() - started
    return wrapper


def run_generations(parameters, grid, evaluate_batch, generations, workdir, name):
    """Run ``generations`` generations; return (mean s per generation, mean s inside the evaluator)."""
    spent = [0.0]
    parameters = dict(parameters, **{"optimizer.max_generations": generations})
    run = optimization_run.OptimizationRun(os.path.join(workdir, name), optimization_run.run_config(parameters), grid,
                                           timed(evaluate_batch, spent))
    started = time.perf_counter()
    run.run()
    total = time.perf_counter() - started
    run.close()
    return total / generations, spent[0] / generations


def cma_only_s(n_variables, generations):
    """Mean s per generation of ProfileOptimizer ask + tell alone (N variables, popsize 12)."""
    parameters = {"optimizer.max_generations": generations, "optimizer.reevaluate_incumbent": False}
    optimizer = ProfileOptimizer(n_variables, optimization_run.run_settings(parameters).optimizer)
    fitness = np.linspace(0.0, 0.9, 12)   # below the target fitness: no early stop
    started = time.perf_counter()
    while not optimizer.stop():
        optimizer.tell(optimizer.ask(), fitness)
    return (time.perf_counter() - started) / generations


def noise_study(seeds, workdir, generations=60, trials=20):
    """Return {(crn, reevaluate): (true fitness of final mean, overestimate of best-so-far)} averaged over seeds."""
    grid = ProfileGrid(rows=4, cols=4)
    table = {}
    for crn, reevaluate in ((True, True), (False, True), (True, False), (False, False)):
        rows = []
        for seed in range(1, seeds + 1):
            parameters = {"optimizer.max_generations": generations, "optimizer.seed": seed,
                          "optimizer.trials": trials, "optimizer.common_random_numbers": crn,
                          "optimizer.reevaluate_incumbent": reevaluate}
            evaluator = SyntheticEvaluator(
                np.random.default_rng(1000 + seed).uniform(0, 0.45, grid.n_variables), trials, peak=0.8)
            run = optimization_run.OptimizationRun(os.path.join(workdir, f"noise-{crn}-{reevaluate}-{seed}"),
                                                   optimization_run.run_config(parameters), grid, evaluator)
            result = run.run()
            run.close()
            assert result.best is not None, "the run evaluated no generation"
            rows.append((evaluator.success_probability(result.mean),
                         result.best.fitness - evaluator.success_probability(result.best.heights)))
        table[(crn, reevaluate)] = tuple(np.mean(rows, axis=0))
    return table


def duration(seconds):
    return f"{seconds:.0f} s = {seconds / 3600:.2f} h"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generations", type=int, default=2, help="real paper-scale generations to time")
    parser.add_argument("--workers", type=int, default=None, help="worker processes (default: one per core)")
    parser.add_argument("--noise-seeds", type=int, default=8, help="seeds per noise-study arm (0 = skip)")
    args = parser.parse_args(argv)

    parameters = optimization_run.load_run_parameters("paper")
    settings = evaluation.settings_from_parameters(parameters)
    trials = optimization_run.run_settings(parameters).optimizer.trials
    with tempfile.TemporaryDirectory() as workdir:
        executor = evaluation.make_executor(settings.evaluator, args.workers)
        try:
            executor.warm()
            batch = optimization_run.profile_batch_evaluator(settings, trials, executor)
            real_total_s, real_eval_s = run_generations(parameters, settings.grid, batch, args.generations,
                                                        workdir, "real")
        finally:
            executor.close()
        synthetic = SyntheticEvaluator(np.full(settings.grid.n_variables, 0.2), trials)
        loop_total_s, _ = run_generations(parameters, settings.grid, synthetic, 50, workdir, "synthetic")
        cma_s = cma_only_s(settings.grid.n_variables, 200)
        noise = noise_study(args.noise_seeds, workdir) if args.noise_seeds else None

    workers = getattr(executor, "workers", "?")
    popsize = optimization_run.run_settings(parameters).optimizer.popsize
    evaluations = popsize + 1   # population + incumbent re-evaluation
    trials_per_generation = evaluations * trials
    rate = trials_per_generation / real_eval_s
    real_overhead_s = real_total_s - real_eval_s
    print(f"paper scale: {settings.grid.rows}x{settings.grid.cols} grid ({settings.grid.n_variables} variables), "
          f"popsize {popsize} + 1 re-evaluation, {trials} trials, {workers} workers")
    print(f"evaluation: {trials_per_generation} trials per generation in {real_eval_s:.2f} s = {rate:.1f} trials/s "
          f"({args.generations} real generations)")
    print(f"optimizer overhead per generation, real run: {real_overhead_s * 1000:.1f} ms = "
          f"{100 * real_overhead_s / real_eval_s:.2f}% of evaluation time (target <= 5%)")
    print(f"optimizer overhead per generation, zero-cost evaluator: {loop_total_s * 1000:.1f} ms "
          f"(CMA-ES ask/tell {cma_s * 1000:.2f} ms, store + checkpoint {(loop_total_s - cma_s) * 1000:.1f} ms) = "
          f"{100 * loop_total_s / real_eval_s:.2f}% of evaluation time")
    projected = PAPER_GENERATIONS * (real_eval_s + loop_total_s)
    without = PAPER_GENERATIONS * (popsize * trials / rate + loop_total_s)
    print(f"projected paper run (500 x {evaluations} x {trials} trials): {duration(projected)} on this machine "
          f"(500 x {popsize} x {trials} without re-evaluation: {duration(without)}); trial cost varies with "
          f"the profile, so the projection holds for profiles like these first generations")
    if noise:
        (crn_mean, crn_over), (ind_mean, _) = noise[(True, True)], noise[(False, True)]
        _, no_re_over = noise[(True, False)]
        print(f"noise (synthetic binomial fitness, 16 variables, 20 trials, 60 generations, "
              f"{args.noise_seeds} seeds):")
        for (crn, reevaluate), (mean_fitness, overestimate) in noise.items():
            print(f"  CRN {'on ' if crn else 'off'}  re-evaluation {'on ' if reevaluate else 'off'}: "
                  f"true fitness of final mean {mean_fitness:.3f}, best-so-far overestimate {overestimate:+.3f}")
        print(f"  CRN / independent seeds, true fitness of final mean: {crn_mean / ind_mean:.2f}x")
        print(f"  best-so-far overestimate without / with re-evaluation: {no_re_over / crn_over:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
