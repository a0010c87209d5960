"""Synthetic-truth benchmark of the direct-simulation calibration (bench_calibration.py benches the learnt
likelihood): "physical" outcomes from the launch twin with hidden parameter values, calibrated back; prints the
recovered values against the truth and their stated 95% intervals.

    python bench/bench_calibration_direct.py [--repetitions 20] [--sim-repetitions 16] [--generations 8] [--bootstrap 0]
                                      [--two-parameters]
    nice python bench/bench_calibration_direct.py --coverage 20 [--repetitions 20] [--sim-repetitions 24]
                                           [--coverage-only launch_twin.foam.lateral_friction]

``--coverage N``: for each parameter of ``COVERAGE_PARAMETERS`` (the centre of mass, three foam parameters and the
push plate's yaw bias, an asymmetry, on mirrored launch angles (``MIRRORED_CONDITIONS``); one at a time, the others
at their defaults), N truths drawn evenly at random inside the inner 80% of its calibration bounds; each truth's
"physical" outcomes (fresh seeds per truth) get the calibration's 95% likelihood interval (the grid of simulated
launches does not depend on the truth, so it is launched once); prints how many intervals hold their
truth (target: at least 90%) and their mean width.

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
sys.path.insert(1, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "test"))  # doubles

from bench.bench_launch_twin import dome_mesh  # noqa: E402
from doubles import synthetic_outcomes  # noqa: E402
from rollability_ros.core.campaign import calibration  # noqa: E402
from rollability_ros.core.config import load_parameters  # noqa: E402
from rollability_ros.core.profile.geometry import export_mesh  # noqa: E402
from rollability_ros.core.records import LaunchCondition  # noqa: E402
from rollability_ros.core.sim import launch_twin_settings_from_parameters  # noqa: E402

#: The grouped conditions launched (configuration, height m, speed m/s, angle deg).
CONDITIONS = (("baseline", 0.75, 0.8, 0.0), ("dome", 0.75, 0.8, 0.0), ("dome", 0.75, 0.8, 30.0),
              ("dome", 0.75, 1.5, 0.0))
#: Parameters of the coverage bench: (config key, lower, upper, log scale).
COVERAGE_PARAMETERS = (("robot.com_offset_z_m", -0.019, 0.015, False),
                       ("launch_twin.foam.lateral_friction", 0.3, 3.0, True),
                       ("launch_twin.foam.restitution", 0.0, 1.0, False),
                       ("launch_twin.foam.contact_stiffness_npm", 5000.0, 160000.0, True),
                       ("launch_twin.plate.yaw_bias_deg", -15.0, 15.0, False))
#: An asymmetry shows only between mirrored launch angles: its coverage uses these conditions instead.
MIRRORED_CONDITIONS = (("dome", 0.75, 0.8, -30.0), ("dome", 0.75, 0.8, 30.0), ("dome", 0.75, 1.5, -30.0),
                       ("dome", 0.75, 1.5, 30.0))
CONDITIONS_FOR = {"launch_twin.plate.yaw_bias_deg": MIRRORED_CONDITIONS}


def coverage(args, parameters, twin):
    """The coverage bench (module docstring); prints one line per truth and the coverage per parameter."""
    import numpy as np

    from rollability_ros.core.results import analysis

    rng = np.random.default_rng(2026)
    with calibration.LaunchPool() as pool:
        for name, low, high, log in COVERAGE_PARAMETERS[:args.coverage_parameters]:
            u = rng.uniform(0.1, 0.9, args.coverage)   # drawn for every parameter: --coverage-only keeps the truths
            if args.coverage_only and name not in args.coverage_only:
                continue
            conditions = [LaunchCondition(*c) for c in CONDITIONS_FOR.get(name, CONDITIONS)]
            settings = calibration.CalibrationSettings(parameters=[name], lower=[low], upper=[high],
                                                       log_scale=[log], sim_repetitions=args.sim_repetitions,
                                                       interval_points=args.interval_points)
            truths = low * (high / low) ** u if log else low + u * (high - low)
            started = time.perf_counter()
            grouped = None
            covered, covered_interpolated, widths = 0, 0, []
            for number, truth in enumerate(truths):
                outcomes = synthetic_outcomes(twin, [name], [truth], conditions, args.repetitions,
                                                          first_seed=1_000_000 + 1000 * number)
                physical = analysis.group_conditions(outcomes)
                if grouped is None:
                    grouped = calibration.predicted_on_grid(physical, twin, settings, pool,
                                                            [parameters[name]], 0)
                grid, curve = calibration.likelihood_profile(physical, twin, settings, pool,
                                                            [parameters[name]], 0, grouped)
                interval = calibration.likelihood_interval(grid, curve)
                interpolated = calibration.likelihood_interval(grid, curve, ends="interpolate")
                hit = interval[0] <= truth <= interval[1]
                covered += hit
                covered_interpolated += interpolated[0] <= truth <= interpolated[1]
                widths.append(interval[1] - interval[0])
                print(f"  {name} truth {truth:.4g}: 95% interval [{interval[0]:.4g}, {interval[1]:.4g}] "
                      f"{'holds it' if hit else 'MISSES'} (interpolated ends [{interpolated[0]:.4g}, "
                      f"{interpolated[1]:.4g}])", flush=True)
            print(f"coverage {name}: {covered}/{len(truths)} = {covered / len(truths):.0%} of the 95% intervals hold "
                  f"the truth (target >= 90%; with interpolated ends {covered_interpolated}/{len(truths)}); "
                  f"mean width {np.mean(widths):.4g}; {args.repetitions} 'physical' "
                  f"launches x {len(conditions)} conditions per truth, grid {settings.interval_points} x "
                  f"{settings.sim_repetitions} launches; {time.perf_counter() - started:.0f} s")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repetitions", type=int, default=20, help="'physical' launches per condition")
    parser.add_argument("--sim-repetitions", type=int, default=16, help="simulated launches per condition")
    parser.add_argument("--generations", type=int, default=8, help="CMA-ES generations per fit")
    parser.add_argument("--bootstrap", type=int, default=0, help="bootstrap fits")
    parser.add_argument("--two-parameters", action="store_true", help="also fit the foam's friction")
    parser.add_argument("--coverage", type=int, default=0, help="truths per parameter of the coverage bench")
    parser.add_argument("--interval-points", type=int, default=13, help="grid points of the likelihood interval")
    parser.add_argument("--coverage-parameters", type=int, default=len(COVERAGE_PARAMETERS),
                        choices=range(1, len(COVERAGE_PARAMETERS) + 1),
                        help="coverage of the first N parameters of COVERAGE_PARAMETERS (default: all)")
    parser.add_argument("--coverage-only", action="append", default=[], metavar="KEY",
                        help="run the coverage of this parameter only (repeatable; same truths as without it)")
    args = parser.parse_args()
    if args.coverage:
        with tempfile.TemporaryDirectory() as folder:
            stl = os.path.join(folder, "dome.stl")
            export_mesh(dome_mesh(), stl)
            parameters = load_parameters(list(calibration.TWIN_CONFIGS))
            parameters.update({"launch_twin.designs.mesh_labels": ["dome"],
                               "launch_twin.designs.mesh_files": [stl]})
            coverage(args, parameters, launch_twin_settings_from_parameters(parameters))
        return
    names, truth = ["robot.com_offset_z_m"], [0.006]
    lower, upper, log_scale = [-0.019], [0.015], [False]
    if args.two_parameters:
        names, truth = names + ["launch_twin.foam.lateral_friction"], truth + [0.45]
        lower, upper, log_scale = lower + [0.3], upper + [3.0], log_scale + [True]
    with tempfile.TemporaryDirectory() as folder:
        stl = os.path.join(folder, "dome.stl")
        export_mesh(dome_mesh(), stl)
        parameters = load_parameters(list(calibration.TWIN_CONFIGS))
        parameters.update({"launch_twin.designs.mesh_labels": ["dome"], "launch_twin.designs.mesh_files": [stl]})
        started = time.perf_counter()
        twin = launch_twin_settings_from_parameters(parameters)
        outcomes = synthetic_outcomes(twin, names, truth,
                                                  [LaunchCondition(*c) for c in CONDITIONS], args.repetitions)
        print(f"synthetic outcomes: {len(outcomes)} launches in {time.perf_counter() - started:.1f} s")
        settings = calibration.CalibrationSettings(
            parameters=names, lower=lower, upper=upper, log_scale=log_scale, sim_repetitions=args.sim_repetitions,
            popsize=6, max_generations=args.generations, bootstrap_resamples=args.bootstrap)
        started = time.perf_counter()
        with calibration.LaunchPool() as pool:
            result = calibration.calibrate(outcomes, twin, settings, pool, on_progress=print)
        wall_s = time.perf_counter() - started
    launches = result.evaluations * len(result.conditions) * settings.sim_repetitions
    print(f"calibration: {result.evaluations} parameter sets, {launches} launches, {wall_s:.0f} s "
          f"({wall_s / launches * 1000:.1f} ms per launch on {os.cpu_count()} cores)")
    print(f"log-likelihood before {result.before_log_likelihood:.2f}, after {result.after_log_likelihood:.2f}")
    for estimate, value in zip(result.estimates, truth):
        error = estimate.fitted - value
        print(f"{estimate.name}: truth {value:.4g}, start {estimate.initial:.4g}, fitted {estimate.fitted:.4g} "
              f"(error {error:+.3g}), 95% interval [{estimate.interval_low:.4g}, {estimate.interval_high:.4g}] "
              f"({estimate.interval_method}): "
              f"{'holds' if estimate.interval_low <= value <= estimate.interval_high else 'MISSES'} the truth")
    for row in result.condition_rows():
        print(f"  {row['configuration']:<9} {row['height_m']:.2f} m {row['speed_mps']:.1f} m/s "
              f"{row['angle_deg']:+5.0f} deg  measured {row['measured_rate']:.2f}  before {row['before_rate']:.2f}  after {row['after_rate']:.2f}")
    for label, agreement in result.rank_agreement().items():
        print(f"rank agreement {label}: {agreement.agreement_text()}")


if __name__ == "__main__":
    main()
