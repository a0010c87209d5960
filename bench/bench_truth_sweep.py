"""Which twin parameters change the ranking of profiles on the launch-twin objective? (picks the truth of
bench_objective.py)

    nice python bench/bench_truth_sweep.py [--launches 48] [--workers 2]

Eleven fixed 3 x 3 profiles (flat, uniform low / mid / tall, a dome, a ridge along x, front- and back-heavy, three
random ones from a fixed seed) are launched ``--launches`` times each on the small campaign of bench_objective.py
(0.75 m, 0.8 and 1.5 m/s, -30 and +30 deg), on the shipped twin and on single-parameter truths; one line per twin
with every profile's upright launches. All simulated; the same launch seeds for every profile and twin.
"""
import argparse
import os
import sys
import tempfile
import time

import numpy as np
import yaml

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

from bench.bench_objective import CAMPAIGN  # noqa: E402
from rollability_ros.core.campaign import calibration  # noqa: E402
from rollability_ros.core.optimization import run_directory  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402

TRUTHS = [("robot.com_offset_z_m", -0.005), ("robot.com_offset_z_m", 0.006),
          ("launch_twin.foam.lateral_friction", 0.3), ("launch_twin.foam.lateral_friction", 2.5),
          ("launch_twin.foam.restitution", 0.0), ("launch_twin.foam.restitution", 0.8),
          ("launch_twin.foam.contact_stiffness_npm", 8000.0), ("launch_twin.foam.contact_stiffness_npm", 120000.0),
          ("launch_twin.plate.yaw_bias_deg", -12.0), ("launch_twin.plate.yaw_bias_deg", 12.0)]


def profiles():
    """The eleven fixed profiles, ``{name: heights (9,)}`` in simulation units (row-major, rows along x)."""
    rng = np.random.default_rng(5)
    fixed = {"flat": np.zeros(9), "low": np.full(9, 0.1), "mid": np.full(9, 0.25), "tall": np.full(9, 0.45),
             "dome": np.array([.1, .2, .1, .2, .45, .2, .1, .2, .1]),
             "ridge": np.array([.05, .05, .05, .45, .45, .45, .05, .05, .05]),
             "front": np.array([.45, .45, .45, .2, .2, .2, 0, 0, 0]),
             "back": np.array([0, 0, 0, .2, .2, .2, .45, .45, .45])}
    fixed.update({f"random{i}": rng.uniform(0, 0.45, 9) for i in range(3)})
    return fixed


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--launches", type=int, default=48, help="launches per profile and twin")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    truths, shapes = TRUTHS, profiles()
    if args.smoke:   # the shipped twin and one truth, one profile, one launch, one worker
        truths, shapes, args.launches, args.workers = TRUTHS[:1], dict(list(shapes.items())[:1]), 1, 1
    with tempfile.TemporaryDirectory() as folder:
        campaign_file = os.path.join(folder, "campaign.yaml")
        with open(campaign_file, "w", encoding="utf-8") as stream:
            yaml.safe_dump(CAMPAIGN, stream)
        parameters = run_directory.load_run_parameters(["optimizer"])
        parameters.update({"objective.kind": "launch_twin", "objective.campaign_config": [campaign_file],
                           "profile.rows": 3, "profile.cols": 3})
        settings = evaluation.settings_from_parameters(parameters)
        with evaluation.make_executor(evaluation.EvaluatorOptions(workers=args.workers)) as executor:
            for index, truth in enumerate([None, *truths]):
                twin = list(calibration.TWIN_CONFIGS)
                if truth is not None:
                    path = os.path.join(folder, f"truth-{index}.yaml")  # one file per truth: the twin is cached by path
                    with open(path, "w", encoding="utf-8") as stream:
                        yaml.safe_dump(calibration.calibrated_parameter_document(dict([truth])), stream)
                    twin.append(path)
                on_twin = evaluation.with_objective(settings, evaluation.ObjectiveSettings(
                    kind="launch_twin", campaign_config=[campaign_file], twin_config=twin))
                started = time.perf_counter()
                counts = []
                for name, heights in shapes.items():
                    result = evaluation.evaluate_profile(heights, args.launches, 12345, on_twin, executor)
                    counts.append(f"{name} {result.successes}")
                label = "shipped twin" if truth is None else f"{truth[0]} = {truth[1]:g}"
                print(f"{label}: {', '.join(counts)} (of {args.launches}) [{time.perf_counter() - started:.0f} s]",
                      flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
