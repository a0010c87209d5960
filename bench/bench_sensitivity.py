"""The issue-18 sensitivity table redone: the dome profile and the bare chassis, 60 trials each, against each
uncertain factor and with the robust option (every trial under its own draw of all factors).

    nice python bench/bench_sensitivity.py [--trials 60] [--out sensitivity-bench]

Every evaluation uses base seed 0 (common random numbers across factors and profiles); prints each fitness
with its Wilson 95% interval, writes sensitivity.csv and sensitivity.png (the figure in docs/optimization.md).
"""
import argparse
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from bench.bench_launch_twin import dome_mesh  # noqa: E402
from rollability_ros.cli import main as cli_main  # noqa: E402
from rollability_ros.core.profile.geometry import export_mesh  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=60)
    parser.add_argument("--out", default="sensitivity-bench")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        stl = os.path.join(folder, "dome.stl")
        export_mesh(dome_mesh(), stl)
        trials, out = (1, os.path.join(folder, "out")) if args.smoke else (args.trials, args.out)
        workers = ["--workers", "1"] if args.smoke else []
        return cli_main(["sensitivity", "--mesh", f"dome={stl}", "--trials", str(trials), "--out", out, *workers])


if __name__ == "__main__":
    sys.exit(main())
