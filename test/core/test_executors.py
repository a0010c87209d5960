"""The executor contract (core/sim/evaluation.py TrialExecutor): the built-in executors are on it, callers read its
``workers`` / ``in_process`` instead of asking which kind they hold, and a new executor is one class."""
import pytest

from rollability_ros.core.sim import evaluation
from rollability_ros.core.sim.evaluation import LocalExecutor, RayExecutor, SerialExecutor, TrialExecutor


class Reversed(TrialExecutor):
    """Runs the batches in this process, last first (outcomes must not depend on the order)."""

    in_process = True

    def __init__(self):
        self.batches = 0

    def iter_batches(self, job, batches, should_stop):
        for batch in reversed(batches):
            self.batches += 1
            yield evaluation.run_batch(job, batch)


def test_the_built_in_executors_are_on_the_contract():
    assert all(issubclass(cls, TrialExecutor) for cls in (SerialExecutor, LocalExecutor, RayExecutor))
    assert (SerialExecutor.in_process, SerialExecutor.workers) == (True, None)
    assert not LocalExecutor.in_process and not RayExecutor.in_process
    with pytest.raises(TypeError, match="iter_batches"):
        type("NoBatches", (TrialExecutor,), {})()
    with SerialExecutor() as executor:           # the context manager comes from the contract
        assert isinstance(executor, TrialExecutor)


def test_a_new_executor_is_one_class_and_gives_the_serial_outcomes():
    pytest.importorskip("pybullet")
    settings = evaluation.EvaluatorSettings()
    serial = evaluation.evaluate_profile(None, 6, 3, settings)
    executor = Reversed()
    other = evaluation.evaluate_profile(None, 6, 3, settings, executor)
    assert executor.batches >= 1 and other.trial_results == serial.trial_results
