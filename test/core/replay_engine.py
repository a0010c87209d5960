"""A null trial engine, added to the engine seam as one file (this one) plus one registration line
(test_trial_engines.py): it runs no physics and replays the outcomes recorded from another engine, by seed."""
import dataclasses

from rollability_ros.core.sim.trial_engine import TrialEngine, TrialOutcome


class ReplayTrialWorld(TrialEngine):
    """``sim.engine: replay``: trial ``(index, seed)`` is the outcome recorded for ``seed`` (``recorded``)."""

    #: seed -> the TrialOutcome another engine gave for it
    recorded: dict = {}

    def __init__(self, robot_model, profile, settings, physics):
        self.profile = profile   # built like any engine's world; nothing to simulate

    def run(self, index: int, seed: int) -> TrialOutcome:
        if seed not in self.recorded:
            raise ValueError(f"replay engine: no recorded trial for seed {seed}")
        return dataclasses.replace(self.recorded[seed], index=index)
