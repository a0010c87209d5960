"""The in-process batch evaluators an optimization run (and the selection after it) is handed: ``evaluate_batch(
heights_list, seed)`` and ``evaluate(heights_list, seed, trials)`` over :func:`~rollability_ros.core.sim.
evaluate_profile` on a trial executor (a LocalExecutor, a RayExecutor or None: serial), or over a
:class:`~rollability_ros.core.sim.TrialBatchEngine`. Each returns one ``(successes, trials, eval_time_s,
evaluator_name)`` per height array; the ``optimizer`` node binds EvaluateProfile action clients instead
(:mod:`~rollability_ros.core.optimization.evaluator_pool`)."""
import concurrent.futures
import dataclasses
import threading
import typing

import numpy as np

from rollability_ros.core.sim import EvaluatorSettings, TrialBatchEngine, TrialExecutor


def profile_batch_evaluator(settings: EvaluatorSettings, trials: int, executor: TrialExecutor,
                            name: str = "local", engine: typing.Optional[TrialBatchEngine] = None) -> typing.Callable:
    """``evaluate_batch`` over :func:`evaluation.evaluate_profile` on ``executor`` (a LocalExecutor or RayExecutor).

    The profiles of a batch are evaluated concurrently (one thread each submitting its trial batches; one after
    another on an executor that runs them in this process), so the workers stay busy across candidates; ``trials`` per profile, ``settings`` an ``EvaluatorSettings``. With at
    least two profiles per local worker, each profile's trials go to one worker as one task (one world build and
    one round trip per profile; split into ``evaluator.batch_trials`` tasks, every worker built every profile's
    world: a paper-config generation took 1.84x as long in ``bench/bench_engines.py``).
    ``engine``, a :class:`~rollability_ros.core.sim.evaluation.TrialBatchEngine`, gets each batch of profiles'
    trials in one call instead (an engine that steps many worlds at once); the optimizer is the same.
    """
    from rollability_ros.core.sim import evaluate_jobs, profile_job, settings_at_fidelity

    if engine is not None:
        screen = settings_at_fidelity(settings, "screen")   # the screen's engine (objective.screen_engine)

        def evaluate_engine_batch(heights_list: typing.Sequence[np.ndarray], seed: int) -> typing.List[tuple]:
            """``(successes, trials, eval_time_s, engine)`` of each heights ``(n_variables,)`` on ``engine``."""
            jobs = [profile_job(heights, screen) for heights in heights_list]
            return [(r.successes, r.trials, r.eval_time_s, engine.name)
                    for r in evaluate_jobs(jobs, trials, seed, engine)]
        return evaluate_engine_batch

    evaluate = fidelity_batch_evaluator(settings, executor, "screen", name)

    def evaluate_batch(heights_list: typing.Sequence[np.ndarray], seed: int) -> typing.List[tuple]:
        """``(successes, trials, eval_time_s, evaluator)`` of each heights ``(n_variables,)``, ``trials`` each."""
        return evaluate(heights_list, seed, trials)

    return evaluate_batch


def fidelity_batch_evaluator(settings: EvaluatorSettings, executor: TrialExecutor, fidelity: str = "screen",
                             name: str = "local") -> typing.Callable:
    """``evaluate(heights_list, seed, trials)`` at evaluation ``fidelity`` (``screen``: the configured objective;
    ``launch``: robust twin launches, :func:`evaluation.settings_at_fidelity`) on ``executor``; each result
    ``(successes, trials, eval_time_s, name)``. Concurrency as :func:`profile_batch_evaluator`."""
    from rollability_ros.core.sim import evaluate_profile, settings_at_fidelity

    settings = settings_at_fidelity(settings, fidelity)
    workers = executor.workers if executor is not None else None   # None: serial, in this process
    # in this process the engines keep one world (TrialExecutor.in_process): one profile at a time, never two
    # threads stepping it (MuJoCo's launch twin crashed the process that way)
    in_process = executor is None or executor.in_process

    def evaluate(heights_list: typing.Sequence[np.ndarray], seed: int, trials: int) -> typing.List[tuple]:
        """``(successes, trials, eval_time_s, evaluator)`` of each heights ``(n_variables,)`` at the fidelity."""
        whole = dataclasses.replace(settings, evaluator=dataclasses.replace(settings.evaluator, batch_trials=trials))
        chosen = whole if workers is not None and len(heights_list) >= 2 * workers else settings
        threads = concurrent.futures.ThreadPoolExecutor(max_workers=1 if in_process else max(1, len(heights_list)))
        failed = threading.Event()   # one profile's error stops the others (their threads would outlive the pool)
        try:
            futures = [threads.submit(evaluate_profile, heights, trials, seed, chosen, executor, None, failed)
                       for heights in heights_list]
            for future in concurrent.futures.as_completed(futures):
                future.result()   # the first error raises here (the except below stops the rest)
            results = [future.result() for future in futures]
        except BaseException:
            failed.set()
            raise
        finally:
            threads.shutdown(wait=False, cancel_futures=True)
        return [(r.successes, r.trials, r.eval_time_s, name) for r in results]

    return evaluate
