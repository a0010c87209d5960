"""Every bench script once at its tiny size, in this one process: ``python bench/smoke.py [bench_name ...]``.

A bench's ``--smoke`` option runs each of its steps once on the smallest inputs that still take the same code
path (a launch or two, a few messages, one repeat); the numbers it prints then mean nothing. The README's test
command runs this (test/test_bench_smoke.py), so a bench that no longer runs against the package fails there, not
weeks later when someone measures. The benches share this process: numpy, PyBullet and the package are imported
once. Prints one ``smoke <bench>: ok (<seconds> s)`` line per bench and exits 1 naming each bench that raised or
returned non-zero. Without names it runs :data:`SMOKE`.
"""
import importlib
import os
import sys
import time
import traceback
import typing

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

#: The bench scripts with a ``--smoke`` size, cheapest first (bench/<name>.py, each ``main(argv) -> int``).
SMOKE = ("bench_bag_writer", "bench_adaptive_plan", "bench_profile_mass", "bench_launch_twin", "verify_early_decision",
         "bench_pad_size")


def run(names: typing.Sequence[str]) -> typing.List[str]:
    """Run ``main(["--smoke"])`` of each bench in ``names``; return the names that failed."""
    failed = []
    for name in names:
        started = time.perf_counter()
        try:
            module = importlib.import_module(f"bench.{name}")
            code = module.main(["--smoke"])
        except BaseException as exc:   # noqa: BLE001 - SystemExit from argparse included: it is this bench's failure
            traceback.print_exc()
            code = f"{type(exc).__name__}: {exc}"
        if code not in (0, None):
            failed.append(name)
            print(f"smoke {name}: FAILED ({code})", flush=True)
        else:
            print(f"smoke {name}: ok ({time.perf_counter() - started:.1f} s)", flush=True)
    return failed


def main(argv: typing.Optional[typing.Sequence[str]] = None) -> int:
    names = list(sys.argv[1:] if argv is None else argv) or list(SMOKE)
    failed = run(names)
    if failed:
        print(f"smoke: {len(failed)} of {len(names)} benches failed: {', '.join(failed)}", flush=True)
        return 1
    print(f"smoke: {len(names)} benches ran", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
