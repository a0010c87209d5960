"""Does ranking random initial means by the stable-pose screen help the optimizer? Measured, same run, same seeds.

    .venv/bin/python bench/bench_initial_mean_screen.py [--seeds 4] [--screen 16] [--generations 10] [--workers N]
                                                        [--config optimizer] [--config husky ...]

For each seed, two quick optimizations with real physics (the given configs, default config/optimizer.yaml with
``--generations`` generations): ``optimizer.initial_mean_screen`` 0 (the paper: one random mean) and N (the
best of N random means by quasi-static P(upright), ties by the lowest barrier; the N means include the paper's
one). Prints per seed the screened start's P(upright), the simulated fitness of first generation's best candidate and
the pooled best-so-far fitness at the end, then the means over seeds and their ratios (screened / paper), and
the time the screen took against the run's evaluation time. The fitnesses are binomial estimates (trials per
candidate from the config), so a difference of a few percentage points over a few seeds is noise.
"""
import argparse
import os
import sys
import tempfile
import time
import typing

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

from rollability_ros.core.sim import evaluation

from rollability_ros.core.optimization import optimization_run as optimization_run  # noqa: E402
from rollability_ros.core.optimization import batch_evaluation, run_directory  # noqa: E402
from bench.smoke import SMOKE_RUN  # noqa: E402


def one_run(parameters, settings, executor, run_dir):
    """Run to the end; return (start P(upright) or None, first-generation best fitness, final best fitness, s in the
    screen, s in total)."""
    trials = optimization_run.run_settings(parameters).optimizer.trials
    started = time.perf_counter()
    run = optimization_run.OptimizationRun(
        run_dir, optimization_run.run_config(parameters), settings.grid, batch_evaluation.profile_batch_evaluator(settings, trials, executor),
        screen_profiles=optimization_run.profile_screen(optimization_run.run_settings(parameters), settings))
    screen_s = time.perf_counter() - started
    run.run()
    total_s = time.perf_counter() - started
    generations = run.store.generations(run.run_id)
    best = run.optimizer.result.best.fitness
    run.close()
    screened = run.initial_mean_screen
    start_probability = screened["upright_probability"][screened["chosen"]] if screened else None
    return start_probability, generations[0].best_fitness, best, screen_s, total_s


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--screen", type=int, default=16, help="random initial means screened (default 16)")
    parser.add_argument("--generations", type=int, default=10)
    parser.add_argument("--workers", type=int, default=None, help="worker processes (default: evaluator.workers; "
                                                                  "0: in this process)")
    parser.add_argument("--config", action="append", default=[], help="parameter files (default: optimizer)")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)

    base = run_directory.load_run_parameters(args.config or ["optimizer"])
    if args.smoke:   # one seed, one generation, a screen of two means (SMOKE_RUN), in this process
        base.update(SMOKE_RUN)
        args.seeds, args.generations, args.screen, args.workers = 1, 1, 2, 0
    settings = evaluation.settings_from_parameters(base)
    executor = evaluation.make_executor(settings.evaluator, args.workers) if args.workers != 0 \
        else evaluation.SerialExecutor()
    rows: typing.Dict[int, typing.List[typing.Any]] = {0: [], args.screen: []}
    try:
        with tempfile.TemporaryDirectory(prefix="bench_screen_") as workdir:
            for seed in range(1, args.seeds + 1):
                for screen in rows:
                    parameters = dict(base, **{"optimizer.seed": seed, "optimizer.max_generations": args.generations,
                                               "optimizer.stagnation_generations": 0,
                                               "optimizer.initial_mean_screen": screen,
                                               # this bench measures the stable-pose screen of random means (the
                                               # quick default ranks them and simple profiles on its own measure)
                                               "optimizer.initial_mean_measure": "stable_poses",
                                               "optimizer.initial_mean_shapes": False})
                    row = one_run(parameters, settings, executor, os.path.join(workdir, f"s{seed}-k{screen}"))
                    rows[screen].append(row)
                    start = "      -" if row[0] is None else f"{row[0]:7.2f}"
                    print(f"seed {seed} screen {screen:>3}: start P(upright) {start}, first-generation best "
                          f"{row[1]:.3f}, final best {row[2]:.3f}, screen {row[3]:.1f} s of {row[4]:.1f} s",
                          flush=True)
    finally:
        executor.close()

    paper, screened = (np.array([r[1:] for r in rows[k]]) for k in rows)
    print(f"\n{args.seeds} seeds x {args.generations} generations, configs {args.config or ['optimizer']}")
    print(f"{'':24} {'paper (1 mean)':>15} {f'screened ({args.screen})':>15} {'ratio':>7}")
    for label, column in (("first-generation best", 0), ("final best-so-far", 1)):
        a, b = paper[:, column].mean(), screened[:, column].mean()
        print(f"{label:24} {a:15.3f} {b:15.3f} {b / a if a else float('nan'):7.2f}")
    print(f"screen time / run time: {screened[:, 2].sum():.1f} s / {screened[:, 3].sum():.1f} s = "
          f"{screened[:, 2].sum() / screened[:, 3].sum():.1%}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
