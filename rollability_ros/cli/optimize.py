"""`rollability optimize`: a CMA-ES or CMA-MAE profile optimization in this process (no ROS graph), resumable."""
import argparse
import math
import os
import sys
import typing

from rollability_ros.cli import Subparsers

if typing.TYPE_CHECKING:  # annotations only: the command imports its core modules when it runs
    from rollability_ros.core.records import CandidateRecord, GenerationRecord


def _duration(seconds):
    """``1h02m``, ``3m05s`` or ``12s``; ``?`` when unknown."""
    if not math.isfinite(seconds):
        return "?"
    seconds = int(round(seconds))
    if seconds >= 3600:
        return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m"
    if seconds >= 60:
        return f"{seconds // 60}m{seconds % 60:02d}s"
    return f"{seconds}s"


class ProgressLine:
    """Prints one line per generation (generation, best fitness, best-so-far, sigma, elapsed, ETA) and, on a
    terminal, a transient count of the candidates evaluated in the current generation."""

    def __init__(self, run, stream=None):
        self.run = run
        self.stream = stream or sys.stdout   # looked up now: sys.stdout may be replaced after import
        self.live = self.stream.isatty()
        self.evaluated = 0

    def candidate(self, record: "CandidateRecord") -> None:
        """``on_candidate`` callback."""
        self.evaluated += 1
        if self.live:
            self.stream.write(f"\r  generation {record.generation}: {self.evaluated} evaluated ")
            self.stream.flush()

    def generation(self, record: "GenerationRecord") -> None:
        """``on_generation`` callback."""
        self.evaluated = 0
        cap = self.run.settings.max_generations or "-"
        line = (f"gen {record.generation:>4}/{cap}  best {record.best_fitness:.3f}  mean {record.mean_fitness:.3f}"
                f"  best-so-far {record.best_so_far:.3f}  sigma {record.sigma:.4f}  evals {record.evaluations}"
                f"  elapsed {_duration(record.elapsed_s)}  ETA {_duration(self.run.eta_s())}")
        self.stream.write(("\r" if self.live else "") + line + "\n")
        self.stream.flush()


def _write_convergence_figure(run):
    """Write ``<run_dir>/convergence.png`` (the paper's Figure 4) if matplotlib is installed; return its path."""
    from rollability_ros.core.results import convergence, convergence_figure
    from rollability_ros.core.optional import MissingDependency

    points = convergence(generations=run.store.generations(run_id=run.run_id))
    try:
        return convergence_figure(os.path.join(run.run_dir, "convergence.png"), points)
    except MissingDependency:
        return None


def run(args: argparse.Namespace) -> int:
    """Start or resume an optimization; return the exit code."""
    from rollability_ros.core.sim import make_executor, settings_from_parameters
    from rollability_ros.core.optimization import (OptimizationRun, fidelity_batch_evaluator, load_run_parameters,
                                                   profile_batch_evaluator, profile_screen, run_config,
                                                   run_generations, run_settings, run_target, with_given_files)

    from rollability_ros.core.config import check_path_component

    if args.resume and args.run_id is not None:
        raise ValueError("--run-id names a new run; --resume takes the run to continue")
    if args.run_id is not None:
        check_path_component(args.run_id, "--run-id")
    given = with_given_files(load_run_parameters(args.config), args.config,
                             "rollability optimize") if args.config else None
    output_dir = run_settings(given).optimizer.output_dir if given else "runs"
    run_dir, parameters = run_target(args.resume or args.run_id or "", bool(args.resume), given,
                                     output_dir)
    settings = settings_from_parameters(parameters)
    config = run_config(parameters)   # a resume: the run's config.yaml
    executor = make_executor(settings.evaluator, args.workers)
    try:
        evaluate_batch = profile_batch_evaluator(settings, config.settings.optimizer.trials, executor)
        run = OptimizationRun(
            run_dir, config, settings.grid, evaluate_batch, resume=bool(args.resume),
            evaluate_trials=fidelity_batch_evaluator(settings, executor, "screen"),
            screen_profiles=profile_screen(config.settings, settings))
        progress = ProgressLine(run)
        run.on_candidate, run.on_generation = progress.candidate, progress.generation
        print(f"{run.start_text(bool(args.resume))}; {settings.grid.rows}x{settings.grid.cols} grid")
        print(run.initial_mean_text())
        try:
            end = run_generations(run)
        except KeyboardInterrupt:
            print(f"\ninterrupted; continue with: rollability optimize --resume {run.run_dir}", file=sys.stderr)
            raise
        figure = _write_convergence_figure(run)
        run.close()
    finally:
        executor.close()
    print(run.end_text(end))
    if end.result.best is None:
        return 0
    best = end.result.best
    print(f"best in-run fitness {best.fitness:.3f} over {best.trials} trials (first seen in generation "
          f"{run.generation_number(best.generation)}): a maximum of noisy estimates, biased upward; the selection's "
          "fresh re-evaluation is the number to quote")
    if figure:
        print(f"convergence curve: {figure}")
    if args.select and end.status == "finished":
        from rollability_ros.cli import select

        print("selecting designs (the decision: robust launches on the twin when selection.race_launches is set)")
        return select.run(argparse.Namespace(run=run.run_dir, output_dir=output_dir, config=[], workers=args.workers,
                                             **{name: None for name in select.OVERRIDES}))
    print(f"choose designs with: rollability select {run.run_dir}")
    return 0


def register(subparsers: Subparsers) -> None:
    """Add the ``optimize`` verb."""
    parser = subparsers.add_parser(
        "optimize", help="run a CMA-ES or CMA-MAE profile optimization in this process (resumable)",
        description="Optimize the profile heights with CMA-ES (paper 2.1.4; optimizer.method cmaes, config paper) or "
                    "CMA-MAE quality diversity over maximum height x sharpness (cma_mae, the quick config), "
                    "evaluating candidates in a local "
                    "process pool (or the Ray cluster of evaluator.ray_address). Every candidate and generation "
                    "goes to <output_dir>/<run_id>/store.sqlite and a checkpoint is written after each "
                    "generation, so a killed run continues with --resume and gives the same results.")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="optimization parameter file or shipped name: 'optimizer' (quick default, minutes on "
                             "2 cores) or 'paper' (the paper's settings); loaded on top of sim, robot and "
                             "evaluator, and on top of 'optimizer' when neither is named (a robot config alone runs on "
                             "the shipped defaults); repeatable, later files win (e.g. --config optimizer --config "
                             "runs/cal/calibrated.yaml). Optional with --resume (then the run's own config.yaml "
                             "is used)")
    parser.add_argument("--resume", metavar="RUN", help="continue run RUN (run id under output_dir, or its "
                                                        "directory) from its last completed generation")
    parser.add_argument("--run-id", help="id of a new run (default: opt-<date>-<time>)")
    parser.add_argument("--workers", type=int, help="worker processes for the trials (default: "
                                                    "evaluator.workers, 0 = one per core)")
    parser.add_argument("--select", action="store_true",
                        help="when the run finishes, choose designs A/B/C as `rollability select RUN` does (with "
                             "the quick config: a race of the best elites on robust twin launches decides)")
    parser.set_defaults(func=run)
