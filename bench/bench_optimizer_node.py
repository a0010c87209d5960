"""Optimizer node benchmark: optimizer + messaging overhead per generation through the ROS graph, paper projection.

    .venv/bin/python bench/bench_optimizer_node.py [--config paper] [--generations 3] [--evaluators 1] [--repeats 2]
                                                   [--smoke]

The same run (config, seed, generations) on this machine's cores, alternately ``--repeats`` times each way:
1. in-process: ``OptimizationRun`` over ``profile_batch_evaluator`` on a local process pool (all cores);
2. node graph: the ``optimizer`` node and ``--evaluators`` ``sim_evaluator`` nodes (the cores split between
   them), separate processes over DDS on a private ROS domain.
Both runs evaluate identical candidates, so generation g costs the same work in both; each generation's wall
time is the minimum over the repeats (a shared machine only ever adds time). Generation 0 (worker start-up) is
left out. Printed: wall time per generation each way and the node graph's extra time as a fraction of the
in-process generation (target <= 5%); inside the node graph, the time outside the evaluators (optimizer,
store, checkpoint, goals and results over DDS, workers idle between goals) as a fraction of the evaluators'
own time. Then the projected wall time of the paper run (500 generations x (12 + 1
re-evaluation) x 60 trials) from the trial rate measured through the node graph, and a check that both runs
stored the same candidates. The node graph runs in a ROS domain of its own (``bench.smoke.isolated_ros``), its
logs in a temporary folder. ``--smoke``: the quick config, two generations of two candidates on one launch each, one
worker each way, one repeat.
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)  # this checkout first

from rollability_ros.core.sim import evaluation

from rollability_ros.core.optimization import optimization_run as optimization_run  # noqa: E402
from rollability_ros.core.optimization import batch_evaluation, run_directory  # noqa: E402
from rollability_ros.core.optimization.optimization_run import FIRST_GENERATION  # noqa: E402
from rollability_ros.core.config import resolve_config_path  # noqa: E402
from rollability_ros.core.store import Store  # noqa: E402

PAPER_GENERATIONS, PAPER_POPSIZE, PAPER_TRIALS = 500, 12, 60


def stored_run(run_dir, run_id):
    """``(candidates, generations)`` of a run directory's store, sorted."""
    with Store(run_dir) as store:
        candidates = sorted(store.candidates(run_id=run_id), key=lambda c: (c.generation, c.index))
        generations = sorted(store.generations(run_id=run_id), key=lambda g: g.generation)
    return candidates, generations


def per_generation_s(generations):
    """Wall time of each generation after the first, s (from the cumulative ``elapsed_s``)."""
    return np.diff([g.elapsed_s for g in generations])


def evaluator_busy_s(candidates, evaluators):
    """Evaluator time per generation after the first, s: summed ``eval_time_s`` over the evaluator nodes."""
    last = max(c.generation for c in candidates)
    return np.array([sum(c.eval_time_s for c in candidates if c.generation == g) / evaluators
                     for g in range(FIRST_GENERATION + 1, last + 1)])


def run_in_process(parameters, workdir, workers):
    settings = evaluation.settings_from_parameters(parameters)
    executor = evaluation.make_executor(settings.evaluator, workers)
    try:
        executor.warm()
        batch = batch_evaluation.profile_batch_evaluator(settings, optimization_run.run_settings(parameters).optimizer
                                                         .trials, executor)
        run = optimization_run.OptimizationRun(os.path.join(workdir, "inproc"), optimization_run.run_config(parameters), settings.grid, batch)
        run.run()
        run.close()
    finally:
        executor.close()
    return stored_run(os.path.join(workdir, "inproc"), "inproc")


def run_node_graph(config_path, overrides, workdir, evaluators, workers_each):
    """Run the optimizer node against ``evaluators`` sim_evaluator nodes in ``workdir`` (in this process's ROS
    domain: :func:`main` claims one); return the stored run."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [ROOT, os.environ.get("PYTHONPATH")])))
    processes = []

    def start(module, name, args):
        log = open(os.path.join(workdir, f"{name}.log"), "wb")
        processes.append(subprocess.Popen([sys.executable, "-m", f"rollability_ros.nodes.{module}", "--ros-args",
                                           "--params-file", config_path, *args], stdout=log,
                                          stderr=subprocess.STDOUT, env=env, start_new_session=True))
        return os.path.join(workdir, f"{name}.log")

    try:
        for index in range(evaluators):
            start("sim_evaluator", f"eval_{index}", ["-r", f"__ns:=/eval_{index}", "-p",
                                                     f"evaluator.workers:={workers_each}"])
        params = [f"{key}:={value}" for key, value in overrides.items()]
        log_path = start("optimizer", "optimizer", [arg for p in params for arg in ("-p", p)] +
                         ["-p", f"optimizer.output_dir:={workdir}", "-p", "run_id:=graph"])
        deadline = time.monotonic() + 3600
        while time.monotonic() < deadline:
            with open(log_path, encoding="utf-8", errors="replace") as stream:
                text = stream.read()
            if "ended after" in text or processes[-1].poll() is not None:
                break
            time.sleep(0.5)
        if "ended after" not in text:
            raise RuntimeError(f"the optimizer node did not finish:\n{text}")
    finally:
        for process in processes:
            if process.poll() is None:
                os.killpg(process.pid, 2)
        for process in processes:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, 9)
    return stored_run(os.path.join(workdir, "graph"), "graph")


def duration(seconds):
    return f"{seconds:.0f} s = {seconds / 3600:.1f} h"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="paper", help="optimization config (default: paper)")
    parser.add_argument("--generations", type=int, default=3, help="generations per run (>= 2; default 3)")
    parser.add_argument("--evaluators", type=int, default=1, help="sim_evaluator nodes (default 1)")
    parser.add_argument("--workers", type=int, default=os.cpu_count(), help="worker processes of the in-process "
                                                                            "run (default: one per core)")
    parser.add_argument("--evaluator-workers", type=int, help="worker processes per evaluator node (default: "
                                                              "--workers / --evaluators)")
    parser.add_argument("--repeats", type=int, default=2, help="runs each way (default 2)")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers "
                                                             "mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    if args.generations < 2:
        parser.error("--generations must be >= 2 (generation 0 is left out)")
    overrides = {"optimizer.max_generations": args.generations, "optimizer.stagnation_generations": 0}
    if args.smoke:   # the quick config, two generations of two candidates on one launch, one worker each way, once
        from bench.smoke import SMOKE_RUN

        args.config, args.generations, args.workers, args.evaluators, args.repeats = "optimizer", 2, 1, 1, 1
        overrides = {**{k: v for k, v in SMOKE_RUN.items() if k.startswith(("optimizer.", "quality_diversity."))},
                     "optimizer.max_generations": 2, "optimizer.stagnation_generations": 0,
                     "optimizer.popsize": 2, "optimizer.trials": 1}
    scratch = tempfile.TemporaryDirectory(prefix="bench-optimizer-node-")   # ROS logs; removed when main returns
    from bench.smoke import isolated_ros

    domain_lock = isolated_ros(scratch.name)   # noqa: F841 - held while the graph runs
    parameters = {**run_directory.load_run_parameters(args.config), **overrides}
    settings = optimization_run.run_settings(parameters).optimizer
    grid = evaluation.settings_from_parameters(parameters).grid
    workers_each = args.evaluator_workers or max(1, args.workers // args.evaluators)

    def key(c):
        return (c.generation, c.index, c.heights, c.successes, c.trials, c.seed)

    inproc, graph, busy, keys = [], [], [], set()
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory() as workdir:
            candidates, generations = run_in_process(parameters, workdir, args.workers)
            inproc.append(per_generation_s(generations))
            keys.add(tuple(key(c) for c in candidates))
        with tempfile.TemporaryDirectory() as workdir:
            candidates, generations = run_node_graph(resolve_config_path(args.config), overrides, workdir,
                                                     args.evaluators, workers_each)
            graph.append(per_generation_s(generations))
            busy.append(evaluator_busy_s(candidates, args.evaluators))
            keys.add(tuple(key(c) for c in candidates))
    same = len(keys) == 1
    inproc_s = np.min(inproc, axis=0).mean()
    graph_s = np.min(graph, axis=0).mean()
    fastest = int(np.argmin([g.sum() for g in graph]))
    evaluated_s = busy[fastest].mean()
    outside_s = graph[fastest].mean() - evaluated_s
    trials_per_generation = sum(c.trials for c in candidates if c.generation > FIRST_GENERATION) / (args.generations - 1)

    print(f"config {args.config}: {grid.rows}x{grid.cols} grid, popsize {settings.popsize} + 1 re-evaluation, "
          f"{settings.trials} trials, generations 1..{args.generations - 1} timed, best of {args.repeats}, "
          f"{args.workers} workers "
          f"({args.evaluators} evaluator node(s) x {workers_each} in the node graph)")
    print(f"wall time per generation: in-process {inproc_s:.2f} s, node graph {graph_s:.2f} s -> node graph "
          f"overhead {100 * (graph_s - inproc_s) / inproc_s:+.2f}% of the in-process generation (target <= 5%)")
    print(f"inside the node graph: evaluators busy {evaluated_s:.2f} s per generation, outside them (optimizer, "
          f"store, checkpoint, goals/results over DDS) {outside_s * 1000:.0f} ms = "
          f"{100 * outside_s / evaluated_s:.2f}% of evaluation time")
    rate = trials_per_generation / graph_s
    paper_s = PAPER_GENERATIONS * (PAPER_POPSIZE + 1) * PAPER_TRIALS / rate
    print(f"trial rate through the node graph: {rate:.1f} trials/s on {os.cpu_count()} cores; projected paper run "
          f"(500 x (12 + 1) x 60 trials): {duration(paper_s)} (500 x 12 x 60 without re-evaluation: "
          f"{duration(paper_s * PAPER_POPSIZE / (PAPER_POPSIZE + 1))})"
          + ("" if args.config == "paper" else "; trial cost depends on the grid: run with --config paper"))
    print(f"stored candidates identical in all {2 * args.repeats} runs: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
