"""Calibrate -> re-optimize -> validate on a synthetic truth: does a design optimized on the calibrated launch twin
beat one optimized on the uncalibrated twin, when both are scored on the truth?

    nice python bench/bench_objective.py [--parameter launch_twin.foam.lateral_friction] [--truth 2.5]
        [--generations 15] [--popsize 8] [--trials 24] [--sigma0 0.1] [--screen 16] [--seeds 3,4,...,20]
        [--validate 96] [--workers 2] [--smoke]

1. Truth: the launch twin with ``--parameter`` moved to ``--truth`` (default: the foam's friction from 1.0 to
   2.5, a truth under which the profiles rank differently: docs/calibration.md); "physical" outcomes of the bare
   chassis and bench_evaluator's dome profile are launched on it.
2. Calibrate that parameter to those outcomes (``rollability calibrate``'s core, its default bounds) ->
   calibrated.yaml.
3. For each optimizer seed of ``--seeds``, optimize twice with ``objective.kind: launch_twin`` (the same seed, grid
   and budget): on the uncalibrated twin and on the calibrated one (its file appended to
   ``objective.twin_config``). Each run's design is its best pooled logged design (the selection's ranking).
4. Validate: every design launched ``--validate`` times on the truth with fresh seeds (never used above); success
   with Wilson 95% intervals, and calibrated - uncalibrated with Newcombe's 95% interval, per seed and pooled;
   over the seeds (each pair of optimizations is one replicate), the mean difference with a t interval and a
   Wilcoxon signed-rank test.
Everything is measured in this run; nothing is tuned to it. The launch conditions are a small campaign (0.75 m,
0.8 and 1.5 m/s, -30 and +30 deg) on a 3 x 3 grid; the defaults (18 seed pairs) take about an hour on 2 cores,
about 3.5 minutes per pair at 15 generations. docs/calibration.md gives the measured runs (15 and 30 generations).
"""
import argparse
import math
import os
import sys
import tempfile
import time

import numpy as np
import yaml

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(1, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "test"))  # doubles

from bench.bench_launch_twin import dome_mesh  # noqa: E402
from doubles import synthetic_outcomes  # noqa: E402
from rollability_ros.core.campaign import calibration  # noqa: E402
from rollability_ros.core.config import load_parameters  # noqa: E402
from rollability_ros.core.optimization import optimization_run, selection  # noqa: E402
from rollability_ros.core.optimization import batch_evaluation, run_directory  # noqa: E402
from rollability_ros.core.profile.geometry import export_mesh  # noqa: E402
from rollability_ros.core.records import LaunchCondition  # noqa: E402
from rollability_ros.core.stats import newcombe_interval  # noqa: E402
from rollability_ros.core.sim import evaluation, launch_twin_settings_from_parameters  # noqa: E402

CAMPAIGN = {"/**": {"ros__parameters": {"campaign": {"heights_m": [0.75], "speeds_mps": [0.8, 1.5],
                                                     "angles_deg": [-30.0, 30.0]}}}}


def optimize(run_dir, twin_config, campaign_file, args, seed, executor):
    """One launch-twin optimization with optimizer seed ``seed``; return its best pooled design's heights."""
    parameters = run_directory.load_run_parameters(["optimizer"])
    parameters.update({"optimizer.method": "cmaes", "objective.kind": "launch_twin",
                       "objective.campaign_config": [campaign_file], "objective.twin_config": list(twin_config),
                       "optimizer.popsize": args.popsize, "optimizer.sigma0": args.sigma0,
                       "optimizer.max_generations": args.generations, "optimizer.trials": args.trials,
                       "optimizer.initial_mean_screen": args.screen, "optimizer.stagnation_generations": 0,
                       "optimizer.target_fitness": 2.0,
                       "profile.rows": 3, "profile.cols": 3, "optimizer.seed": seed})
    settings = evaluation.settings_from_parameters(parameters)
    batch = batch_evaluation.profile_batch_evaluator(settings, args.trials, executor)
    config = optimization_run.run_config(parameters)
    run = optimization_run.OptimizationRun(run_dir, config, settings.grid, batch,
                                           screen_profiles=optimization_run.profile_screen(config.settings, settings))
    result = run.run()
    pooled = selection.pool_candidates(run.store.candidates(run_id=run.run_id))
    best = max(pooled, key=lambda d: (d.wilson_low, d.fitness))
    run.close()
    print(f"  {result.generations} generations, {result.evaluations} evaluations; best pooled design "
          f"{best.successes}/{best.trials}")
    return best.heights, settings


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    defaults = calibration.CalibrationSettings()
    parser.add_argument("--parameter", default="launch_twin.foam.lateral_friction", choices=defaults.parameters,
                        help="the twin parameter the truth moves and the calibration fits")
    parser.add_argument("--truth", type=float, default=2.5, help="its hidden value (in its units)")
    parser.add_argument("--generations", type=int, default=15)
    parser.add_argument("--popsize", type=int, default=8)
    parser.add_argument("--trials", type=int, default=24, help="launches per candidate evaluation")
    parser.add_argument("--sigma0", type=float, default=0.1,
                        help="CMA-ES step size, simulation units (the paper's 0.02 barely leaves a random start in "
                             "this budget)")
    parser.add_argument("--screen", type=int, default=16,
                        help="random means screened by the stable-pose screen for the start (both arms alike)")
    parser.add_argument("--seeds", default=",".join(str(seed) for seed in range(3, 21)),
                        help="optimizer seeds, comma-separated: one pair of runs each")
    parser.add_argument("--validate", type=int, default=96, help="launches per design on the truth")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (0: in this process)")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers "
                                                             "mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    physical, repetitions, fit_popsize, fit_generations = 24, 8, 4, 4
    if args.smoke:   # one launch per condition, a fit of one generation of two, two seed pairs of 2 x 2 launches
        physical, repetitions, fit_popsize, fit_generations = 1, 1, 2, 1
        args.generations, args.popsize, args.trials, args.screen, args.seeds = 1, 2, 2, 0, "3,4"
        args.validate, args.workers = 2, 0
    index = defaults.parameters.index(args.parameter)
    lower, upper, log_scale = defaults.lower[index], defaults.upper[index], defaults.log_scale[index]
    seeds = [int(seed) for seed in args.seeds.split(",")]
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        stl = os.path.join(folder, "dome.stl")
        export_mesh(dome_mesh(), stl)
        campaign_file = os.path.join(folder, "campaign.yaml")
        with open(campaign_file, "w", encoding="utf-8") as stream:
            yaml.safe_dump(CAMPAIGN, stream)
        parameters = load_parameters(list(calibration.TWIN_CONFIGS))
        parameters.update({"launch_twin.designs.mesh_labels": ["dome"], "launch_twin.designs.mesh_files": [stl]})
        uncalibrated_value = parameters[args.parameter]
        conditions = [LaunchCondition("baseline", 0.75, 0.8, 0.0), LaunchCondition("dome", 0.75, 0.8, 0.0)]
        uncalibrated = launch_twin_settings_from_parameters(parameters)
        outcomes = synthetic_outcomes(uncalibrated, [args.parameter], [args.truth], conditions, physical)
        settings = calibration.CalibrationSettings(parameters=[args.parameter], lower=[lower], upper=[upper],
                                                   log_scale=[log_scale], sim_repetitions=repetitions,
                                                   popsize=fit_popsize, max_generations=fit_generations,
                                                   bootstrap_resamples=0)
        with calibration.LaunchPool(args.workers or 1) as pool:   # 1: in this process
            fitted = calibration.calibrate(outcomes, uncalibrated, settings, pool).estimates[0].fitted
        calibrated = os.path.join(folder, "calibrated.yaml")
        with open(calibrated, "w", encoding="utf-8") as stream:
            yaml.safe_dump(calibration.calibrated_parameter_document({args.parameter: fitted}), stream)
        print(f"calibrated {args.parameter} = {fitted:+.4g} (truth {args.truth:+.4g}, uncalibrated "
              f"{uncalibrated_value:+.4g}) [{time.perf_counter() - started:.0f} s]", flush=True)
        truth_file = os.path.join(folder, "truth.yaml")
        with open(truth_file, "w", encoding="utf-8") as stream:
            yaml.safe_dump(calibration.calibrated_parameter_document({args.parameter: args.truth}), stream)
        totals = {"calibrated": [0, 0], "uncalibrated": [0, 0]}
        differences = []
        with evaluation.make_executor(evaluation.EvaluatorOptions(workers=args.workers)) if args.workers \
                else evaluation.SerialExecutor() as executor:
            for seed in seeds:
                scores = {}
                for label, twin in (("uncalibrated", calibration.TWIN_CONFIGS),
                                    ("calibrated", (*calibration.TWIN_CONFIGS, calibrated))):
                    print(f"seed {seed}: optimizing on the {label} twin", flush=True)
                    heights, run_settings = optimize(os.path.join(folder, f"{label}-{seed}"), twin, campaign_file,
                                                     args, seed, executor)
                    on_truth = evaluation.with_objective(run_settings, evaluation.ObjectiveSettings(
                        kind="launch_twin", campaign_config=[campaign_file],
                        twin_config=[*calibration.TWIN_CONFIGS, truth_file]))
                    result = evaluation.evaluate_profile(heights, args.validate, 987_654_321, on_truth, executor)
                    scores[label] = (result.successes, result.trials)
                    totals[label][0] += result.successes
                    totals[label][1] += result.trials
                    print(f"seed {seed}: {label:>12}-twin design on the truth: {result.successes}/{result.trials} = "
                          f"{result.fitness:.2f} [{result.ci_low:.2f}, {result.ci_high:.2f}] "
                          f"[{time.perf_counter() - started:.0f} s]", flush=True)
                differences.append(report_difference(f"seed {seed}: ", scores["calibrated"], scores["uncalibrated"]))
    report_difference(f"pooled over {len(seeds)} seed(s) (these designs' launches): ", totals["calibrated"],
                      totals["uncalibrated"])
    if len(differences) >= 2:  # the optimization runs are the replicates: their spread, not only the launches'
        from scipy import stats

        mean, spread = float(np.mean(differences)), float(np.std(differences, ddof=1))
        half = stats.t.ppf(0.975, len(differences) - 1) * spread / math.sqrt(len(differences))
        print(f"over the {len(differences)} seeds (paired by seed): mean {mean:+.2f} [{mean - half:+.2f}, "
              f"{mean + half:+.2f}] (95%, t on {len(differences) - 1} df); calibrated ahead in "
              f"{sum(d > 0 for d in differences)} of {len(differences)}")
        if any(differences):  # a rank test: no normality assumed for a difference between two optimizer outcomes
            wilcoxon = stats.wilcoxon(differences, alternative="two-sided")
            print(f"Wilcoxon signed-rank over the seeds: statistic {wilcoxon.statistic:.1f}, two-sided p = "
                  f"{wilcoxon.pvalue:.3f}")
    print(f"wall {time.perf_counter() - started:.0f} s on {os.cpu_count()} cores (simulated twin and truth)")
    return 0


def report_difference(lead, calibrated, uncalibrated):
    """Print calibrated - uncalibrated success on the truth with Newcombe's 95% interval; return the difference."""
    (k1, n1), (k2, n2) = calibrated, uncalibrated
    _, low, high = newcombe_interval(k1, n1, k2, n2)
    print(f"{lead}calibrated {k1}/{n1} - uncalibrated {k2}/{n2} on the truth: {k1 / n1 - k2 / n2:+.2f} "
          f"[{low:+.2f}, {high:+.2f}] (95%, Newcombe)", flush=True)
    return k1 / n1 - k2 / n2


if __name__ == "__main__":
    sys.exit(main())
