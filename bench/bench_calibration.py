"""Synthetic-truth calibration benchmark: "physical" outcomes from the launch twin with hidden parameter values,
calibrated back; prints the recovered values against the truth in units of their bootstrap uncertainty.

    python bench/bench_calibration.py [--repetitions 20] [--sim-repetitions 16] [--generations 8] [--bootstrap 3]
                                      [--two-parameters]

Configurations: the bare chassis and bench_evaluator's dome profile (an STL in a temporary folder). The hidden
truth moves ``robot.com_offset_z_m`` from -0.015 m to +0.006 m (and, with ``--two-parameters``, the foam's
friction from 1.0 to 0.45). Every number is measured in this run; nothing is tuned to it.
"""
import argparse
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from bench.bench_launch_twin import dome_mesh  # noqa: E402
from rollability_ros.core.campaign import calibration  # noqa: E402
from rollability_ros.core.config import load_parameters  # noqa: E402
from rollability_ros.core.profile.geometry import export_mesh  # noqa: E402
from rollability_ros.core.results.records import LaunchCondition  # noqa: E402

#: The grouped conditions launched (configuration, height m, speed m/s, angle deg).
CONDITIONS = (("baseline", 0.75, 0.8, 0.0), ("dome", 0.75, 0.8, 0.0), ("dome", 0.75, 0.8, 30.0),
              ("dome", 0.75, 1.5, 0.0))
def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repetitions", type=int, default=20, help="'physical' launches per condition")
    parser.add_argument("--sim-repetitions", type=int, default=16, help="simulated launches per condition")
    parser.add_argument("--generations", type=int, default=8, help="CMA-ES generations per fit")
    parser.add_argument("--bootstrap", type=int, default=3, help="bootstrap fits")
    parser.add_argument("--two-parameters", action="store_true", help="also fit the foam's friction")
    args = parser.parse_args()
    names, truth = ["robot.com_offset_z_m"], [0.006]
    lower, upper, log_scale = [-0.019], [0.015], [False]
    if args.two_parameters:
        names, truth = names + ["launch_twin.foam.lateral_friction"], truth + [0.45]
        lower, upper, log_scale = lower + [0.2], upper + [3.0], log_scale + [True]
    with tempfile.TemporaryDirectory() as folder:
        stl = os.path.join(folder, "dome.stl")
        export_mesh(dome_mesh(), stl)
        parameters = load_parameters(list(calibration.TWIN_CONFIGS))
        parameters.update({"launch_twin.designs.mesh_labels": ["dome"], "launch_twin.designs.mesh_files": [stl]})
        started = time.perf_counter()
        outcomes = calibration.synthetic_outcomes(parameters, names, truth,
                                                  [LaunchCondition(*c) for c in CONDITIONS], args.repetitions)
        print(f"synthetic outcomes: {len(outcomes)} launches in {time.perf_counter() - started:.1f} s")
        settings = calibration.CalibrationSettings(
            parameters=names, lower=lower, upper=upper, log_scale=log_scale, sim_repetitions=args.sim_repetitions,
            popsize=6, max_generations=args.generations, bootstrap_resamples=args.bootstrap)
        started = time.perf_counter()
        with calibration.LaunchPool() as pool:
            result = calibration.calibrate(outcomes, parameters, settings, pool, on_progress=print)
        wall_s = time.perf_counter() - started
    launches = result.evaluations * len(result.conditions) * settings.sim_repetitions
    print(f"calibration: {result.evaluations} parameter sets, {launches} launches, {wall_s:.0f} s "
          f"({wall_s / launches * 1000:.1f} ms per launch on {os.cpu_count()} cores)")
    print(f"log-likelihood before {result.before_log_likelihood:.2f}, after {result.after_log_likelihood:.2f}")
    for estimate, value in zip(result.estimates, truth):
        error = estimate.fitted - value
        print(f"{estimate.name}: truth {value:.4g}, start {estimate.initial:.4g}, fitted {estimate.fitted:.4g}, "
              f"bootstrap sd {estimate.std:.3g} -> error / sd = {error / estimate.std:+.2f}")
    for row in result.condition_rows():
        print(f"  {row['configuration']:<9} {row['height_m']:.2f} m {row['speed_mps']:.1f} m/s "
              f"{row['angle_deg']:+5.0f} deg  measured {row['measured_rate']:.2f}  before {row['before_rate']:.2f}  after {row['after_rate']:.2f}")
    for label, agreement in result.rank_agreement().items():
        print(f"rank agreement {label}: {agreement.agreement_text()}")


if __name__ == "__main__":
    main()
