"""Quality diversity vs plain CMA-ES at equal evaluation budget, on the quick configuration, over several seeds.

    .venv/bin/python bench/bench_quality_diversity.py [--seeds 1 2 3] [--workers N] [--generations G]

For each seed, two optimizations on config/optimizer.yaml (the quick study's settings: 4 x 4 grid, popsize 12,
20 trials, 30 generations; same evaluator, same objective, same number of profile evaluations), one with
``optimizer.method: cmaes``, one with ``cma_mae``; then the shipped selection (``selection`` of
config/optimizer.yaml: 60 fresh trials and the plausible-world check; the CMA-MAE run's elites are screened first). Printed per seed and as
means with the CMA-MAE / CMA-ES ratio, all measured in this run (simulated):

* QD score and coverage: every evaluated profile of a run placed in the same height x sharpness grid (the
  ``quality_diversity`` section's), each cell keeping its best in-run fitness; QD score = sum over filled cells,
  coverage = filled cells / cells. Both methods are scored on the same grid, so the numbers compare.
* best fitness: the in-run best-so-far (pooled over its re-evaluations) and design A's fresh re-evaluation;
* A/B/C: their maximum heights and the spread (tallest - lowest) as a share of the height bound, and whether each
  chosen design's fresh fitness reaches the top-decile threshold of its archive screen (CMA-MAE only).
"""
import argparse
import os
import sys
import tempfile
import time
import typing

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

from rollability_ros.core.config import from_mapping, section  # noqa: E402
from rollability_ros.core.optimization import design_set, optimization_run, selection  # noqa: E402
from rollability_ros.core.optimization import batch_evaluation, run_directory  # noqa: E402
from bench.smoke import SMOKE_RUN  # noqa: E402
from rollability_ros.core.profile import descriptors  # noqa: E402
from rollability_ros.core.store import Store  # noqa: E402
from rollability_ros.core.sim import evaluation, world_draws, world_fidelity  # noqa: E402

METHODS = ("cmaes", "cma_mae")


def common_grid_scores(candidates, grid, qd_settings):
    """``(qd_score, coverage)`` of a run's evaluated profiles on the archive grid of ``qd_settings``."""
    height_edges = np.linspace(0.0, descriptors.height_bound_mm(grid), qd_settings.height_cells + 1)
    sharp_edges = np.linspace(qd_settings.sharpness_min_deg, qd_settings.sharpness_max_deg,
                              qd_settings.sharpness_cells + 1)
    best: typing.Dict[typing.Tuple[int, int], typing.Any] = {}   # cell -> its best design
    for design in selection.pool_candidates(candidates):
        measured = descriptors.profile_descriptors(design.heights, grid)
        if measured.max_height_mm == 0:
            continue
        cell = (min(max(int(np.searchsorted(height_edges, measured.max_height_mm, side="right")) - 1, 0),
                    qd_settings.height_cells - 1),
                min(max(int(np.searchsorted(sharp_edges, measured.sharpness_deg, side="right")) - 1, 0),
                    qd_settings.sharpness_cells - 1))
        best[cell] = max(best.get(cell, 0.0), design.fitness)
    cells = qd_settings.height_cells * qd_settings.sharpness_cells
    return sum(best.values()), len(best) / cells


def one_run(method, seed, generations, workers, workdir, overrides=None, run_dir=None):
    """Optimize and select with ``method`` and ``seed`` (``overrides``: parameters over the quick config's;
    ``workers`` 0: in this process) in ``run_dir`` (default ``workdir/<method>-<seed>``); return the measurements
    (dict)."""
    parameters = run_directory.load_run_parameters("optimizer")
    parameters.update({**(overrides or {}), "optimizer.method": method, "optimizer.seed": seed})
    if generations:
        parameters["optimizer.max_generations"] = generations
    settings = evaluation.settings_from_parameters(parameters)
    chosen = from_mapping(selection.SelectionSettings, section(parameters, "selection"), "selection")
    qd_settings = optimization_run.run_settings(parameters).quality_diversity
    trials = optimization_run.run_settings(parameters).optimizer.trials
    run_dir = run_dir or os.path.join(workdir, f"{method}-{seed}")
    started = time.perf_counter()
    with evaluation.make_executor(settings.evaluator, workers) if workers != 0 else evaluation.SerialExecutor() \
            as executor:
        run = optimization_run.OptimizationRun(run_dir, optimization_run.run_config(parameters), settings.grid,
                                               batch_evaluation.profile_batch_evaluator(settings, trials, executor))
        result = run.run()
        run.close()
        def world_launch(heights_list, world_seed, launch_seed, launches):   # the shipped selection's world check
            return batch_evaluation.fidelity_batch_evaluator(settings, executor, world_fidelity(world_seed))(
                heights_list, launch_seed, launches)

        with Store(run_dir) as store:
            candidates = store.candidates()
            picked, _ = design_set.select_run(
                store, run.run_id, run_dir, settings.grid, settings.printer, chosen,
                batch_evaluation.profile_batch_evaluator(settings, chosen.reevaluate_trials, executor), seed,
                batch_evaluation.fidelity_batch_evaluator(settings, executor, "launch"), world_launch=world_launch,
                describe_world=world_draws(settings))
    wall_s = time.perf_counter() - started
    qd_score, coverage = common_grid_scores(candidates, settings.grid, qd_settings)
    heights = [d.metrics.max_height_m * 1000 for d in picked.designs]
    fresh = [d.reported[0] / d.reported[1] for d in picked.designs]
    assert result.best is not None, "the run evaluated no generation"
    return {"qd_score": qd_score, "coverage": coverage, "evaluations": result.evaluations,
            "best_in_run": result.best.fitness, "a_fresh": fresh[0] if fresh else float("nan"),
            "heights_mm": heights, "fresh": fresh, "threshold": picked.top_threshold,
            "spread": (max(heights) - min(heights)) / descriptors.height_bound_mm(settings.grid) if heights else 0.0,
            "wall_s": wall_s}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--workers", type=int, default=None, help="worker processes (default: one per core)")
    parser.add_argument("--generations", type=int, default=0, help="generations (default: the quick config's 30)")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    overrides = SMOKE_RUN if args.smoke else {}
    if args.smoke:   # one seed of each method, one generation (SMOKE_RUN), in this process
        args.seeds, args.generations, args.workers = [1], 1, 0
    rows: typing.Dict[str, typing.List[typing.Any]] = {method: [] for method in METHODS}
    with tempfile.TemporaryDirectory() as workdir:
        for seed in args.seeds:
            for method in METHODS:
                row = one_run(method, seed, args.generations, args.workers, workdir, overrides)
                rows[method].append(row)
                threshold = "" if row["threshold"] is None else f", screen top-decile threshold {row['threshold']:.2f}"
                print(f"seed {seed} {method:<8} QD score {row['qd_score']:5.2f}  coverage {row['coverage']:5.1%}  "
                      f"best in-run {row['best_in_run']:.3f}  A fresh {row['a_fresh']:.3f}  A/B/C heights "
                      f"{', '.join(f'{h:.0f}' for h in row['heights_mm'])} mm (spread {row['spread']:.0%}), fresh "
                      f"{', '.join(f'{f:.2f}' for f in row['fresh'])}{threshold}  [{row['evaluations']} evaluations, "
                      f"{row['wall_s']:.0f} s]", flush=True)
    print(f"\nmeans over seeds {args.seeds} (simulated; equal budget per run):")
    print(f"{'':<22}{'cmaes':>10}{'cma_mae':>10}{'ratio':>8}")
    for key, label in (("qd_score", "QD score"), ("coverage", "coverage"), ("best_in_run", "best in-run fitness"),
                       ("a_fresh", "design A fresh fitness"), ("spread", "A/B/C height spread")):
        cmaes, mae = (float(np.mean([r[key] for r in rows[m]])) for m in METHODS)
        ratio = mae / cmaes if cmaes else float("inf")
        print(f"{label:<22}{cmaes:>10.3f}{mae:>10.3f}{ratio:>8.2f}")
    spreads = [r["spread"] for r in rows["cma_mae"]]
    print(f"CMA-MAE runs with A/B/C height spread >= 30% of the bound: {sum(s >= 0.3 for s in spreads)} of "
          f"{len(spreads)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
