"""Benchmark of the simulated launch twin over the paper's launch matrix; every number is measured in this run.

    python bench/bench_launch_twin.py [--repetitions 5]

Launches the bare chassis and a dome profile (test_physics' dome, standing in for the selected designs) at both
heights, both speeds and the five angles, ``--repetitions`` seeds each, one process. Prints wall time and steps per
launch, the real-time factor (simulated s per wall s), the projected wall time of the full 400-trial campaign,
the travel-time and flight-time ratios to 0.34 m / speed and sqrt(2 h / g), and the upright rates per condition.
"""
import argparse
import collections
import math
import os
import statistics
import sys
import tempfile
import time
import typing

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from bench.bench_evaluator import dome_heights  # noqa: E402
from rollability_ros.core.sim.evaluation import EvaluatorSettings  # noqa: E402
from rollability_ros.core.profile.geometry import export_mesh, profile_mesh  # noqa: E402
from rollability_ros.core.sim.launch.settings import load_launch_twin_settings
from rollability_ros.core.sim.launch.twin import simulate_launch  # noqa: E402
from rollability_ros.core.records import LaunchCondition  # noqa: E402

HEIGHTS_M, SPEEDS_MPS, ANGLES_DEG = (0.75, 1.30), (0.8, 1.5), (-60.0, -30.0, 0.0, 30.0, 60.0)
CAMPAIGN_TRIALS = 400


def dome_mesh():
    """bench_evaluator's (and test_physics') dome profile solid."""
    grid = EvaluatorSettings().grid
    return profile_mesh(dome_heights(grid), grid)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repetitions", type=int, default=5, help="seeds per condition (default 5)")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    heights, speeds, angles = (HEIGHTS_M[:1], SPEEDS_MPS[:1], ANGLES_DEG[:1]) if args.smoke else (HEIGHTS_M, SPEEDS_MPS,
                                                                                                    ANGLES_DEG)
    if args.smoke:
        args.repetitions = 1
    with tempfile.TemporaryDirectory() as folder:
        stl = os.path.join(folder, "dome.stl")
        export_mesh(dome_mesh(), stl)
        settings = load_launch_twin_settings(overrides={"twin.designs.mesh_labels": ["dome"],
                                                        "twin.designs.mesh_files": [stl]})
        walls: typing.List[float] = []
        steps: typing.List[float] = []
        sim_s: typing.List[float] = []
        travel_ratio: typing.List[float] = []
        flight_ratio: typing.List[float] = []
        upright = collections.defaultdict(list)
        for configuration in ("baseline", "dome"):
            for height_m in heights:
                for speed_mps in speeds:
                    for angle_deg in angles:
                        for repetition in range(args.repetitions):
                            condition = LaunchCondition(configuration, height_m, speed_mps, angle_deg, repetition)
                            started = time.perf_counter()
                            result = simulate_launch(condition, settings, seed=len(walls))
                            walls.append(time.perf_counter() - started)
                            steps.append(result.steps)
                            sim_s.append(result.sim_time_s)
                            travel_ratio.append(result.travel_time_s * speed_mps / 0.34)
                            flight_ratio.append(result.flight_time_s / math.sqrt(2 * height_m / 9.81))
                            upright[(configuration, height_m, speed_mps)].append(result.upright)
    per_launch = statistics.fmean(walls)
    print(f"launches: {len(walls)}   wall per launch: mean {per_launch * 1000:.1f} ms, "
          f"median {statistics.median(walls) * 1000:.1f} ms, max {max(walls) * 1000:.1f} ms")
    print(f"steps per launch: mean {statistics.fmean(steps):.0f}, max {max(steps)}   "
          f"real-time factor: {sum(sim_s) / sum(walls):.1f}x")
    print(f"projected {CAMPAIGN_TRIALS}-trial campaign (twin only, one core): {CAMPAIGN_TRIALS * per_launch:.1f} s")
    print(f"travel time / (0.34 m / nominal speed): median {statistics.median(travel_ratio):.3f}, "
          f"range {min(travel_ratio):.3f}..{max(travel_ratio):.3f}")
    print(f"flight time / sqrt(2 h / g): median {statistics.median(flight_ratio):.3f}, "
          f"range {min(flight_ratio):.3f}..{max(flight_ratio):.3f}")
    for (configuration, height_m, speed_mps), outcomes in sorted(upright.items()):
        print(f"upright {configuration:8s} h={height_m:.2f} m v={speed_mps:.1f} m/s: "
              f"{sum(outcomes)}/{len(outcomes)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
