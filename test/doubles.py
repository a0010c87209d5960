"""Test doubles: cheap stand-ins with known answers, for tests and benchmarks (never imported by the package).

- :class:`SyntheticEvaluator`: an ``evaluate_batch`` with a known optimum, for optimization-loop tests and for
  timing the plumbing without physics (bench/bench_optimizer.py);
- :func:`synthetic_outcomes`: "physical" launch outcomes made on the launch twin with hidden parameter values, to
  test that a calibration recovers them (bench/bench_calibration_direct.py);
- :func:`tree_checksums`: the SHA-256 of every file under a folder, to show a command changed nothing recorded;
- :func:`design_twin_files`: a designs file of one design (A, a ramp) and a launch twin parameter file naming it.

Tests import them as ``from doubles import ...`` (pytest puts test/ on the path through test/conftest.py); the
benchmarks add test/ to ``sys.path`` themselves.
"""
import dataclasses
import hashlib
import os

import numpy as np

from rollability_ros.core.records import LaunchOutcome


class SyntheticEvaluator:
    """A cheap stand-in evaluator with a known optimum, for tests, benchmarks and dry runs of the plumbing.

    Success probability ``p(h) = peak * exp(-d**2 / (2 * width**2))`` with ``d`` the RMS distance between the
    heights and ``optimum`` (simulation units). Trial ``j`` of a seed draws ``u_j ~ U(0, 1)`` from that seed and
    succeeds when ``u_j < p(h)``: profiles evaluated with the same seed share their disturbances (common random
    numbers), exactly like the physics evaluator's seeded trials.
    """

    def __init__(self, optimum, trials, width=0.1, peak=0.9, name="synthetic"):
        self.optimum = np.asarray(optimum, dtype=np.float64)
        self.trials, self.width, self.peak, self.name = int(trials), float(width), float(peak), name

    def success_probability(self, heights):
        """The true fitness ``p(h)`` of ``heights``."""
        distance = np.sqrt(np.mean((np.asarray(heights, dtype=np.float64) - self.optimum) ** 2))
        return float(self.peak * np.exp(-0.5 * (distance / self.width) ** 2))

    def __call__(self, heights_list, seed):
        """``evaluate_batch``: one (successes, trials, eval_time_s, name) per height array."""
        draws = np.random.default_rng(seed).random(self.trials)
        return [(int(np.sum(draws < self.success_probability(h))), self.trials, 0.0, self.name) for h in heights_list]


def synthetic_outcomes(twin, names, values, conditions, repetitions, first_seed=100_000):
    """"Physical" outcomes made on the typed twin ``twin`` with ``names`` set to hidden ``values``, to test a
    calibration.

    ``conditions`` are LaunchConditions (their repetition is ignored); each is launched ``repetitions`` times with
    seeds from ``first_seed`` on, which the calibration's own seeds (:func:`simulation_seeds`) do not reuse.
    Returns LaunchOutcomes (backend ``physical``, run ``synthetic``).
    """
    from rollability_ros.core.campaign import calibration
    from rollability_ros.core.records import INVALID_LAUNCH
    from rollability_ros.core.sim.launch.twin import simulate_valid_launch

    hidden = calibration.twin_settings_with(twin, names, values)
    outcomes: "list[LaunchOutcome]" = []
    for condition in conditions:
        for repetition in range(repetitions):
            launch = dataclasses.replace(condition, repetition=repetition)
            result = simulate_valid_launch(launch, hidden, first_seed + repetition)
            note = "" if result.valid else INVALID_LAUNCH + result.invalid_reason
            outcomes.append(LaunchOutcome("synthetic", f"synthetic-{len(outcomes)}", launch, "physical",
                                          result.upright and result.valid, classified_by="operator", note=note))
    return outcomes


def tree_checksums(root):
    """``{path relative to root: SHA-256 of the file}`` for every file under ``root`` (empty when it is missing)."""
    sums = {}
    for folder, _, names in os.walk(root):
        for name in names:
            path = os.path.join(folder, name)
            with open(path, "rb") as stream:
                sums[os.path.relpath(path, root)] = hashlib.sha256(stream.read()).hexdigest()
    return sums


def design_twin_files(folder):
    """A designs file (``designs.yaml``: design A, a ramp on a 4 x 3 grid, selected in run ``run-1``) and a launch
    twin parameter file (``twin.yaml``) that launches it, both in ``folder``; returns their paths."""
    import yaml

    from rollability_ros.core.optimization.design_set import designs_document
    from rollability_ros.core.optimization.selection import PooledDesign, SelectedDesign, SelectionResult
    from rollability_ros.core.profile.geometry import ProfileGrid

    grid = ProfileGrid(rows=4, cols=3)
    chosen = [SelectedDesign("A", PooledDesign(np.repeat(np.linspace(0.05, 0.4, grid.rows), grid.cols), 9, 10, 1, 1),
                             mesh=None, metrics=None, reason="a ramp")]
    designs = os.path.join(folder, "designs.yaml")
    with open(designs, "w", encoding="utf-8") as stream:
        yaml.safe_dump(designs_document(SelectionResult(designs=chosen, requested=1, considered=1, rejected={}),
                                        grid, "run-1"), stream)
    twin = os.path.join(folder, "twin.yaml")
    with open(twin, "w", encoding="utf-8") as stream:
        yaml.safe_dump({"/**": {"ros__parameters": {"launch_twin": {"designs": {"designs_file": designs}}}}}, stream)
    return designs, twin


def damaged_store(path, run_id="camp", outcomes=300):
    """A store of ``outcomes`` launch outcomes of ``run_id`` whose header (page 1) is intact and one of whose table
    pages in the middle is overwritten: it opens, and reading its outcomes meets "database disk image is
    malformed", as a disk error or a stray write leaves a store."""
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.store import Store

    with Store(path) as store:
        for i in range(outcomes):
            store.add_launch_outcome(LaunchOutcome(
                run_id=run_id, trial_id=f"t{i:04d}", condition=LaunchCondition("baseline", 0.75, 0.8, 0.0),
                backend="sim", upright=i % 2 == 0, note="n" * 200))
    size = os.path.getsize(path)
    with open(path, "r+b") as stream:
        stream.seek(size // 2 // 4096 * 4096 + 100)
        stream.write(b"\xff" * 3000)
    return path
