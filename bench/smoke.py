"""Every bench script once at its tiny size, in this one process: ``python bench/smoke.py [bench_name ...]``.

A bench's ``--smoke`` option runs each of its steps once on the smallest inputs that still take the same code
path (a launch or two, a few messages, one repeat, one generation); every line it prints is printed, from tiny
samples, so the numbers mean nothing. The README's test command runs :data:`SMOKE`, every bench script
(test/test_bench_smoke.py), so a bench that no longer runs against the package fails there, not weeks later when
someone measures. The benches share this process: numpy, PyBullet and the package are imported once.

A bench passes when its ``main(["--smoke"])`` returns 0 (or None) and what it printed holds each of its
:data:`HEADLINES`. Prints one ``smoke <bench>: ok (<wall> s wall, <cpu> s CPU)`` line per bench (CPU: this
process and the children it waited for, the load-independent cost) and exits 1 naming each bench that raised,
returned non-zero or left out a headline. Without names it runs :data:`SMOKE`.
"""
import contextlib
import importlib
import os
import resource
import sys
import tempfile
import time
import traceback
import typing

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

#: The bench scripts run at their ``--smoke`` size by the README's test command (bench/<name>.py, each
#: ``main(argv) -> int``): all of them, cheapest first (the ROS-graph and calibration ones last; the last three
#: prepare a learnt likelihood or run a whole study through the node graph, each at its smallest size).
#: docs/testing.md gives each one's measured time.
SMOKE = ("bench_bag_writer", "bench_adaptive_plan", "bench_profile_mass", "bench_launch_twin", "bench_worker_memory",
         "verify_early_decision", "bench_pad_size", "bench_mass_range", "bench_design_space", "bench_bare_breakdown",
         "bench_truth_sweep", "bench_optimizer", "bench_estop_latency", "bench_pool_split", "bench_evaluator",
         "bench_sensitivity", "bench_quality_diversity", "bench_initial_mean_screen", "bench_race_truth",
         "bench_shape_ceiling",
         "bench_engines", "bench_racing", "bench_recorder", "bench_calibration_direct", "bench_objective",
         "bench_optimizer_node", "bench_calibration", "bench_recalibrate", "bench_transfer")

#: What each bench must print at its smoke size: one piece of each line that carries its result (its ratio, table
#: or verdict), so a bench that stops before its report, or drops a line of it, fails.
HEADLINES: typing.Dict[str, typing.Tuple[str, ...]] = {
    "bench_bag_writer": ("writer", "msg/s"),
    "bench_worker_memory": ("growth per candidate", "steady state", "launch twins alive"),
    "bench_adaptive_plan": ("likelihood; unknowns",),
    "bench_profile_mass": ("robot.profile_print = ", "mass g / COM rise mm", "profile_body(dome): print"),
    "bench_launch_twin": ("wall per launch", "steps per launch", "projected", "travel time / (0.34 m",
                          "flight time / sqrt(2 h / g)", "upright "),
    "verify_early_decision": ("engine: ", "steps full", "total: "),
    "bench_pad_size": ("upright of ", "small pad"),
    "bench_mass_range": ("robot 1.62 kg (x 1), pybullet: 0 deg: valid ",),
    "bench_optimizer": ("paper scale: ", "evaluation: ", "optimizer overhead per generation, real run",
                        "optimizer overhead per generation, zero-cost evaluator", "projected paper run",
                        "CRN / independent seeds", "best-so-far overestimate without / with re-evaluation"),
    "bench_pool_split": ("measured in this run: goal overhead", "2 evaluators: generation wall",
                         "unsplit / split = ", "results identical: True", "simulated evaluators"),
    "bench_bare_breakdown": ("bare chassis, ", "overall:", "conditions with a majority upright"),
    "bench_truth_sweep": (" (of ",),
    "bench_shape_ceiling": ("simple profiles on the ", "screen (", "fresh (", "minus bare", "came to rest"),
    "bench_engines": ("launch twin: ", "vs PyBullet twin", "best: ", "vs naive loop", "fastest: ",
                      "one evaluation of ", "projected paper-scale run (500 x 13 x 60", "paper-config generation (",
                      "whole candidates per worker", "paper-scale run with racing", "racing: "),
    "bench_design_space": ("option shipped (", "nominal: bare robot", "robust: bare robot", "g  ", "minus bare"),
    "bench_calibration_direct": ("coverage robot.com_offset_z_m: ", "synthetic outcomes: ", "calibration: ",
                                 "log-likelihood before", ": truth 0.006, start", "measured ", "rank agreement after"),
    "bench_objective": ("calibrated launch_twin.foam.lateral_friction = ", "optimizing on the uncalibrated twin",
                        "optimizing on the calibrated twin", "best pooled design", "-twin design on the truth: ",
                        "pooled over 2 seed(s)", "over the 2 seeds (paired by seed)", "wall "),
    "bench_evaluator": ("profile: dome", "trials/s per core", "steps per trial", "evaluation, serial",
                        "evaluation, 1 worker", "evaluation, 2 workers", "speed-up 2 workers vs 1",
                        "overhead vs raw stepSimulation", "world: build once per profile", "peak RSS per worker"),
    "bench_initial_mean_screen": ("seed 1 screen   0: ", "seed 1 screen   2: start P(upright)", "first-generation best",
                                  "final best-so-far", "screen time / run time"),
    "bench_quality_diversity": ("seed 1 cmaes ", "seed 1 cma_mae ", "means over seeds", "QD score", "coverage",
                                "best in-run fitness", "design A fresh fitness", "A/B/C height spread",
                                "CMA-MAE runs with A/B/C height spread"),
    "bench_optimizer_node": ("config optimizer: ", "wall time per generation: in-process",
                             "inside the node graph: evaluators busy", "trial rate through the node graph",
                             "stored candidates identical in all 2 runs: True"),
    "bench_recorder": ("consumer", "bare_callback", "bare_drained", "recorder ", "raw_mcap", "bag_writer",
                       "outcome: recorder/bare_callback = ", "pose: recorder/bare_callback = "),
    "bench_estop_latency": ("keypress->off ms", "ms of the 450 ms pulse",
                            "countdown : keypress->relay off min", "mid-pulse : keypress->relay off min",
                            "e-stops pressed 0.2 s before the fire that let it fire: ", "raw rows: "),
    "bench_recalibrate": ("calibrate -> re-optimise -> validate: ",),
    "bench_transfer": ("localhost discovery (this bench's studies only)", "seed 1: study ", "search: objective",
                       "campaign on the twin (simulated)", "baseline ", "selection (", "transfer: screen vs race round 1",
                       "fresh robust launches on the pybullet twin",
                       "fresh robust launches on the mujoco twin", "robust sensitivity row (1 trials)",
                       "over seeds (simulated", "A's campaign target met in"),
    "bench_race_truth": ("3 raced elites; bare robot", "  elite label  screen round 1", "screen vs nominal launches: "
                         "Spearman rho", "race round 1 vs nominal launches", "race (pooled) vs nominal launches",
                         "robust vs nominal launches", "nominal launches: A ", "a final round of 2 more robust"),
    "bench_sensitivity": ("baseline   disturbance_scale", "dome       robust", "baseline   robust",
                          "each design minus the bare chassis per unknown factor", "wrote ", "sensitivity.png"),
    "bench_calibration": ("preparation: ", "(2 of 2): ", "calibration of 5 unknowns", "coverage robot.com_offset_z_m: ",
                          "coverage robot.profile_mass_scale: ", "split 95% sets", "learnt P(upright) on these",
                          "adaptive plan vs the paper's matrix", "rollability calibrate --likelihood, 2 unknowns, "
                          "launches only", "rollability calibrate --likelihood, 2 unknowns, with the slide angles"),
    "bench_racing": ("the rule, exactly", "successive halving: ", "racing verification (simulated)", "seed 1: full ",
                     "| pooled |", "over seeds (", "raced design's pooled fresh fitness", "what if (",
                     "first look, measured on the full-budget runs"),
}

#: The optimization run's parameters at a smoke size, over a bench's own (``--smoke``): one generation of a few
#: candidates with two trials each, no start-point screen, and a selection that re-evaluates, races on two
#: launches and checks one plausible world on one launch per design.
SMOKE_RUN = {"optimizer.popsize": 4, "optimizer.trials": 2, "optimizer.max_generations": 1,
             "optimizer.initial_mean_screen": 0, "quality_diversity.emitters": 1,
             "selection.reevaluate_trials": 2, "selection.race_launches": [2], "selection.race_elites": 2,
             "selection.race_keep": 1, "selection.launch_trials": 2, "selection.world_count": 1,
             "selection.world_launches": 1}


def isolated_ros(work: str) -> typing.TextIO:
    """Give this process, and the nodes it starts, a DDS of their own and every variable they read: a ROS domain no
    one else holds (101..200: clear of the tests' 20..100), localhost discovery, no static peers, and ROS logs and
    valve session keys in ``work``. Returns the domain's lock (hold it for the bench's life)."""
    from rollability_ros.core.graph import claim_domain

    domain, lock = claim_domain(101, 200)
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
                      ROS_LOG_DIR=os.path.join(work, "ros-log"), XDG_RUNTIME_DIR=work)
    for name in ("ROS_STATIC_PEERS", "ROS_LOCALHOST_ONLY"):
        os.environ.pop(name, None)
    return lock


class _Tee:
    """Writes to ``stream`` and keeps a copy (a bench's printed report)."""

    def __init__(self, stream: typing.TextIO) -> None:
        self.stream, self.parts = stream, []   # type: typing.TextIO, typing.List[str]

    def write(self, text: str) -> int:
        self.parts.append(text)
        return self.stream.write(text)

    def __getattr__(self, name: str) -> typing.Any:   # flush, fileno, isatty, encoding: the stream's
        return getattr(self.stream, name)


def _cpu_s() -> float:
    """CPU seconds of this process and of its children that were waited for."""
    return sum(usage.ru_utime + usage.ru_stime for usage in (resource.getrusage(resource.RUSAGE_SELF),
                                                             resource.getrusage(resource.RUSAGE_CHILDREN)))


def run(names: typing.Sequence[str]) -> typing.List[str]:
    """Run ``main(["--smoke"])`` of each bench in ``names`` (each in a fresh working directory, so what it writes by
    default lands there) and check its :data:`HEADLINES`; return the names that failed."""
    failed = []
    for name in names:
        started, cpu_started = time.perf_counter(), _cpu_s()
        tee = _Tee(sys.stdout)
        here, environment = os.getcwd(), dict(os.environ)   # a ROS bench claims a domain of its own: undone after it
        try:
            with tempfile.TemporaryDirectory(prefix=f"smoke-{name}-") as work, contextlib.redirect_stdout(tee):
                os.chdir(work)
                try:
                    module = importlib.import_module(f"bench.{name}")
                    code = module.main(["--smoke"])
                finally:
                    os.chdir(here)
                    os.environ.clear()
                    os.environ.update(environment)
        except BaseException as exc:   # noqa: BLE001 - SystemExit from argparse included: it is this bench's failure
            traceback.print_exc()
            code = f"{type(exc).__name__}: {exc}"
        printed = "".join(tee.parts)
        missing = [line for line in HEADLINES.get(name, ()) if line not in printed]
        if code in (0, None) and missing:
            code = "no line with " + ", ".join(repr(line) for line in missing)
        elif code in (0, None) and name not in HEADLINES:
            code = "no HEADLINES entry in bench/smoke.py"
        if code not in (0, None):
            failed.append(name)
            print(f"smoke {name}: FAILED ({code})", flush=True)
        else:
            print(f"smoke {name}: ok ({time.perf_counter() - started:.1f} s wall, {_cpu_s() - cpu_started:.1f} s CPU)",
                  flush=True)
    return failed


def main(argv: typing.Optional[typing.Sequence[str]] = None) -> int:
    names = list(sys.argv[1:] if argv is None else argv) or list(SMOKE)
    print(f"load average {' '.join(f'{v:.1f}' for v in os.getloadavg())} on {os.cpu_count()} cores", flush=True)
    failed = run(names)
    if failed:
        print(f"smoke: {len(failed)} of {len(names)} benches failed: {', '.join(failed)}", flush=True)
        return 1
    print(f"smoke: {len(names)} benches ran", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
