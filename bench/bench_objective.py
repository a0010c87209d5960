"""Calibrate -> re-optimize -> validate on a synthetic truth: does a design optimized on the calibrated launch twin
beat one optimized on the uncalibrated twin, when both are scored on the truth?

    nice python bench/bench_objective.py [--generations 4] [--popsize 6] [--validate 48] [--workers 2]

1. Truth: the launch twin with the chassis's centre of mass moved from -0.015 m to ``--truth`` (m, z of the body
   box); "physical" outcomes of the bare chassis and bench_evaluator's dome profile are launched on it.
2. Calibrate ``robot.com_offset_z_m`` to those outcomes (``rollability calibrate``'s core) -> calibrated.yaml.
3. Optimize twice with ``objective.kind: launch_twin`` (the same seeds, grid and budget): on the uncalibrated
   twin and on the calibrated one (its file appended to ``objective.twin_config``). Each run's design is its
   best pooled logged design (the selection's ranking).
4. Validate: both designs launched ``--validate`` times on the truth with fresh seeds (never used above); success
   with Wilson 95% intervals and the difference with Newcombe's 95% interval.
Everything is measured in this run; nothing is tuned to it. The launch conditions are a small campaign (0.75 m,
0.8 and 1.5 m/s, -30 and +30 deg) to keep it to minutes on 2 cores.
"""
import argparse
import dataclasses
import math
import os
import sys
import tempfile
import time

import yaml

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(1, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "test"))  # doubles

from bench.bench_launch_twin import dome_mesh  # noqa: E402
from doubles import synthetic_outcomes  # noqa: E402
from rollability_ros.core.campaign import calibration  # noqa: E402
from rollability_ros.core.config import load_parameters  # noqa: E402
from rollability_ros.core.optimization import optimization_run, selection  # noqa: E402
from rollability_ros.core.profile.geometry import export_mesh  # noqa: E402
from rollability_ros.core.results.records import LaunchCondition  # noqa: E402
from rollability_ros.core.results.stats import wilson_interval  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402

PARAMETER = "robot.com_offset_z_m"
CAMPAIGN = {"/**": {"ros__parameters": {"campaign": {"heights_m": [0.75], "speeds_mps": [0.8, 1.5],
                                                     "angles_deg": [-30.0, 30.0]}}}}


def newcombe_difference(k1, n1, k2, n2):
    """Newcombe's hybrid-score 95% interval of p1 - p2 (from the two Wilson intervals)."""
    p1, p2 = k1 / n1, k2 / n2
    (l1, u1), (l2, u2) = wilson_interval(k1, n1), wilson_interval(k2, n2)
    return (p1 - p2 - math.sqrt((p1 - l1) ** 2 + (u2 - p2) ** 2),
            p1 - p2 + math.sqrt((u1 - p1) ** 2 + (p2 - l2) ** 2))


def optimize(run_dir, twin_config, campaign_file, args, executor):
    """One launch-twin optimization; return its best pooled design's heights."""
    parameters = optimization_run.load_run_parameters(["optimizer"])
    parameters.update({"objective.kind": "launch_twin", "objective.campaign_config": [campaign_file],
                       "objective.twin_config": list(twin_config), "optimizer.popsize": args.popsize,
                       "optimizer.max_generations": args.generations, "optimizer.trials": 8,
                       "optimizer.initial_mean_screen": 0, "optimizer.stagnation_generations": 0,
                       "profile.rows": 3, "profile.cols": 3, "optimizer.seed": 3})
    settings = evaluation.settings_from_parameters(parameters)
    batch = optimization_run.profile_batch_evaluator(settings, 8, executor)
    run = optimization_run.OptimizationRun(run_dir, parameters, settings.grid, batch)
    result = run.run()
    pooled = selection.pool_candidates(run.store.candidates(run_id=run.run_id))
    best = max(pooled, key=lambda d: (d.wilson_low, d.fitness))
    run.close()
    print(f"  {result.generations} generations, {result.evaluations} evaluations; best pooled design "
          f"{best.successes}/{best.trials}")
    return best.heights, settings


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--truth", type=float, default=0.006, help="hidden robot.com_offset_z_m, m")
    parser.add_argument("--generations", type=int, default=4)
    parser.add_argument("--popsize", type=int, default=6)
    parser.add_argument("--validate", type=int, default=48, help="launches per design on the truth")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        stl = os.path.join(folder, "dome.stl")
        export_mesh(dome_mesh(), stl)
        campaign_file = os.path.join(folder, "campaign.yaml")
        with open(campaign_file, "w", encoding="utf-8") as stream:
            yaml.safe_dump(CAMPAIGN, stream)
        parameters = load_parameters(list(calibration.TWIN_CONFIGS))
        parameters.update({"launch_twin.designs.mesh_labels": ["dome"], "launch_twin.designs.mesh_files": [stl]})
        conditions = [LaunchCondition("baseline", 0.75, 0.8, 0.0), LaunchCondition("dome", 0.75, 0.8, 0.0)]
        outcomes = synthetic_outcomes(parameters, [PARAMETER], [args.truth], conditions, 24)
        settings = calibration.CalibrationSettings(parameters=[PARAMETER], lower=[-0.019], upper=[0.015],
                                                   log_scale=[False], sim_repetitions=8, popsize=4,
                                                   max_generations=4, bootstrap_resamples=0)
        with calibration.LaunchPool(args.workers) as pool:
            fitted = calibration.calibrate(outcomes, parameters, settings, pool).estimates[0].fitted
        calibrated = os.path.join(folder, "calibrated.yaml")
        with open(calibrated, "w", encoding="utf-8") as stream:
            yaml.safe_dump(calibration.calibrated_parameter_document({PARAMETER: fitted}), stream)
        print(f"calibrated {PARAMETER} = {fitted:+.4f} m (truth {args.truth:+.4f}, uncalibrated -0.015) "
              f"[{time.perf_counter() - started:.0f} s]")
        truth_file = os.path.join(folder, "truth.yaml")
        with open(truth_file, "w", encoding="utf-8") as stream:
            yaml.safe_dump(calibration.calibrated_parameter_document({PARAMETER: args.truth}), stream)
        designs = {}
        with evaluation.make_executor(evaluation.EvaluatorOptions(workers=args.workers)) as executor:
            for label, twin in (("uncalibrated", calibration.TWIN_CONFIGS),
                                ("calibrated", (*calibration.TWIN_CONFIGS, calibrated))):
                print(f"optimizing on the {label} twin")
                designs[label] = optimize(os.path.join(folder, label), twin, campaign_file, args, executor)
                print(f"  [{time.perf_counter() - started:.0f} s]")
            scores = {}
            for label, (heights, settings) in designs.items():
                on_truth = dataclasses.replace(settings, objective=evaluation.ObjectiveSettings(
                    kind="launch_twin", campaign_config=[campaign_file],
                    twin_config=[*calibration.TWIN_CONFIGS, truth_file]))
                result = evaluation.evaluate_profile(heights, args.validate, 987_654_321, on_truth, executor)
                scores[label] = (result.successes, result.trials)
                print(f"{label:>12}-twin design on the truth: {result.successes}/{result.trials} = "
                      f"{result.fitness:.2f} [{result.ci_low:.2f}, {result.ci_high:.2f}]")
    (k1, n1), (k2, n2) = scores["calibrated"], scores["uncalibrated"]
    low, high = newcombe_difference(k1, n1, k2, n2)
    print(f"calibrated - uncalibrated on the truth: {k1 / n1 - k2 / n2:+.2f} [{low:+.2f}, {high:+.2f}] "
          f"(95%, Newcombe); wall {time.perf_counter() - started:.0f} s on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
