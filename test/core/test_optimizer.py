"""ProfileOptimizer: same sequence as pycma on its own, convergence, bounds, stop criteria, noise handling."""
import os

import numpy as np
import pytest

cma = pytest.importorskip("cma")

from rollability_ros.core.profile.geometry import ProfileGrid  # noqa: E402
from doubles import SyntheticEvaluator  # noqa: E402
from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config  # noqa: E402
from rollability_ros.core.optimization.cmaes import (  # noqa: E402
    OptimizerSettings,
    ProfileOptimizer,
    derive_seed,
)

N_VARIABLES = 16
OPTIMUM = np.random.default_rng(42).uniform(0.0, 0.45, N_VARIABLES)
OPTIMUM[:3] = 0.45   # optimum on the upper bound for some variables: the bound handling must reach it
OPTIMUM[3:5] = 0.0


def smooth_fitness(heights):
    """Deterministic fitness in [0, 1] with its maximum 0.9 at OPTIMUM."""
    return SyntheticEvaluator(OPTIMUM, trials=1).success_probability(heights)


def settings(**overrides):
    values = dict(popsize=12, sigma0=0.02, seed=7, max_generations=0, reevaluate_incumbent=False)
    values.update(overrides)
    return OptimizerSettings(**values)


def test_same_sequence_as_pycma_on_its_own():
    optimizer = ProfileOptimizer(N_VARIABLES, settings(), 0.0, 0.45)
    reference = cma.CMAEvolutionStrategy(optimizer.initial_mean, 0.02, optimizer.cma_options)
    expected = []
    for _ in range(40):
        population = reference.ask()
        expected.append(population)
        reference.tell(population, [1.0 - smooth_fitness(x) for x in population])
    for population in expected:
        ours = optimizer.ask()
        np.random.rand(5)   # other users of the global generator must not change our sequence
        assert len(ours) == 12
        for x, y in zip(ours, population):
            np.testing.assert_array_equal(x, y)
        optimizer.tell(ours, [smooth_fitness(x) for x in ours])
    assert optimizer.sigma == reference.sigma
    np.testing.assert_array_equal(optimizer.result.mean, reference.result.xfavorite)


def test_initial_mean_is_random_within_bounds_and_seeded():
    a = ProfileOptimizer(N_VARIABLES, settings(seed=3), 0.0, 0.45).initial_mean
    b = ProfileOptimizer(N_VARIABLES, settings(seed=3), 0.0, 0.45).initial_mean
    c = ProfileOptimizer(N_VARIABLES, settings(seed=4), 0.0, 0.45).initial_mean
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert a.min() >= 0.0 and a.max() <= 0.45 and np.ptp(a) > 0.1


def test_converges_to_the_known_optimum_within_bounds():
    optimizer = ProfileOptimizer(N_VARIABLES, settings(max_generations=250, seed=11), 0.0, 0.45)
    while not optimizer.stop():
        population = optimizer.ask()
        stacked = np.array(population)
        assert stacked.min() >= 0.0 and stacked.max() <= 0.45
        optimizer.tell(population, [smooth_fitness(x) for x in population])
    result = optimizer.result
    assert result.stop == {"max_generations": 250}
    assert result.generations == 250 and result.evaluations == 250 * 12
    assert result.best.fitness > 0.89          # the maximum is 0.9
    assert np.sqrt(np.mean((result.mean - OPTIMUM) ** 2)) < 0.01
    initial = np.sqrt(np.mean((optimizer.initial_mean - OPTIMUM) ** 2))
    assert initial > 0.1


def run_constant(optimizer, fitness, generations):
    for _ in range(generations):
        population = optimizer.ask()
        optimizer.tell(population, [fitness] * len(population))
        if optimizer.stop():
            break


@pytest.mark.parametrize("overrides, expected", [
    (dict(max_generations=5), {"max_generations": 5}),
    (dict(target_fitness=0.5), {"target_fitness": 0.5}),
    (dict(stagnation_generations=4), {"stagnation_generations": 4}),
    (dict(max_evaluations=30), {"max_evaluations": 30}),
])
def test_each_stop_criterion(overrides, expected):
    optimizer = ProfileOptimizer(4, settings(**overrides), 0.0, 0.45)
    run_constant(optimizer, 0.5, 100)
    assert optimizer.stop() == expected
    # stagnation: the only improvement is the first generation's, so it stops 4 generations later
    stops_at = {"max_generations": 5, "target_fitness": 1, "stagnation_generations": 5, "max_evaluations": 3}
    assert optimizer.generation == stops_at[next(iter(expected))]


def test_wall_time_cap_uses_the_clock():
    now = [100.0]
    optimizer = ProfileOptimizer(4, settings(max_wall_time_s=10.0), 0.0, 0.45, clock=lambda: now[0])
    run_constant(optimizer, 0.1, 1)
    assert optimizer.stop() == {}
    now[0] += 10.0
    assert optimizer.stop() == {"max_wall_time_s": 10.0}


def test_flat_fitness_does_not_stop_the_run():
    optimizer = ProfileOptimizer(8, settings(max_generations=30), 0.0, 0.45)
    run_constant(optimizer, 0.0, 100)
    assert optimizer.stop() == {"max_generations": 30}


def test_protocol_errors_are_named():
    optimizer = ProfileOptimizer(4, settings(reevaluate_incumbent=True), 0.0, 0.45)
    with pytest.raises(ValueError, match="without a preceding ask"):
        optimizer.tell([], [])
    population = optimizer.ask()
    with pytest.raises(ValueError, match="ask\\(\\) called twice"):
        optimizer.ask()
    with pytest.raises(ValueError, match="not the one asked"):
        optimizer.tell(population[::-1], [0.1] * 12)
    with pytest.raises(ValueError, match="\\[0, 1\\]"):
        optimizer.tell(population, [2.0] * 12)
    optimizer.tell(population, [0.1] * 12)
    with pytest.raises(ValueError, match="re-evaluation .* still pending"):
        optimizer.ask()
    with pytest.raises(ValueError, match=r"^optimizer.seed out of range: 0 is not in \[1, 2147483647\]$"):
        ProfileOptimizer(4, settings(seed=0))


def test_a_lucky_challenger_does_not_replace_a_confirmed_incumbent():
    optimizer = ProfileOptimizer(4, settings(reevaluate_incumbent=True), 0.0, 0.45)
    first = optimizer.ask()
    optimizer.tell(first, [0.5] + [0.1] * 11, [60] * 12)
    np.testing.assert_array_equal(optimizer.reevaluation_request(), first[0])
    optimizer.tell_reevaluation(0.5, 60)                 # confirmed: 60/120
    assert optimizer.best.fitness == 0.5 and optimizer.best.trials == 120
    second = optimizer.ask()
    optimizer.tell(second, [0.1] * 5 + [0.7] + [0.1] * 6, [60] * 12)   # lucky 42/60
    np.testing.assert_array_equal(optimizer.reevaluation_request(), second[5])
    optimizer.tell_reevaluation(0.2, 60)                 # pooled 0.45 < 0.5: the incumbent stays
    np.testing.assert_array_equal(optimizer.best.heights, first[0])
    assert optimizer.best.fitness == 0.5
    third = optimizer.ask()
    optimizer.tell(third, [0.1] * 12, [60] * 12)          # no challenger: the incumbent is re-evaluated
    np.testing.assert_array_equal(optimizer.reevaluation_request(), first[0])
    optimizer.tell_reevaluation(0.2, 60)
    assert optimizer.best.fitness == pytest.approx(1.2 / 3) and optimizer.best.evaluations == 3
    assert optimizer.evaluations == 3 * 13


def test_state_dict_round_trip_continues_identically():
    original = ProfileOptimizer(N_VARIABLES, settings(reevaluate_incumbent=True), 0.0, 0.45)

    def generation(optimizer):
        population = optimizer.ask()
        optimizer.tell(population, [smooth_fitness(x) for x in population])
        optimizer.tell_reevaluation(smooth_fitness(optimizer.reevaluation_request()))
        return population

    for _ in range(5):
        generation(original)
    copy = ProfileOptimizer.from_state_dict(original.state_dict(), N_VARIABLES,
                                            settings(reevaluate_incumbent=True), 0.0, 0.45)
    np.random.seed(123)   # the global generator's state is not part of the optimizer's
    for _ in range(5):
        for x, y in zip(generation(original), generation(copy)):
            np.testing.assert_array_equal(x, y)
    assert copy.best.fitness == original.best.fitness and copy.evaluations == original.evaluations


def test_derived_seeds_are_stable_and_distinct():
    assert derive_seed(1, 0, 0) == derive_seed(1, 0, 0)
    seeds = {derive_seed(1, g, s, i) for g in range(5) for s in range(3) for i in range(3)}
    assert len(seeds) == 45


def noisy_run(tmp_path, seed, common_random_numbers, reevaluate_incumbent, generations=30, trials=20):
    """A short run on the synthetic binomial fitness; returns (true fitness of the incumbent, its estimate,
    true fitness of the final distribution mean)."""
    parameters = {"optimizer.max_generations": generations, "optimizer.seed": seed, "optimizer.trials": trials,
                  "optimizer.common_random_numbers": common_random_numbers,
                  "optimizer.reevaluate_incumbent": reevaluate_incumbent}
    evaluator = SyntheticEvaluator(np.random.default_rng(1000 + seed).uniform(0, 0.45, 16), trials, peak=0.8)
    run_dir = os.path.join(tmp_path, f"s{seed}-{common_random_numbers}-{reevaluate_incumbent}")
    run = OptimizationRun(run_dir, run_config(parameters), ProfileGrid(rows=4, cols=4), evaluator)
    result = run.run()
    run.close()
    return (evaluator.success_probability(result.best.heights), result.best.fitness,
            evaluator.success_probability(result.mean))


def test_common_random_numbers_and_reevaluation_help_on_a_noisy_fitness(tmp_path):
    """CRN makes progress on a 20-trial binomial fitness where independent seeds stall; re-evaluating the
    incumbent cuts the best-so-far overestimate (estimate minus true fitness)."""
    seeds = range(1, 5)
    crn = np.array([noisy_run(tmp_path, s, True, True) for s in seeds])
    independent = np.array([noisy_run(tmp_path, s, False, True) for s in seeds])
    no_reevaluation = np.array([noisy_run(tmp_path, s, True, False) for s in seeds])
    assert crn[:, 2].mean() > independent[:, 2].mean() + 0.15
    overestimate_with = (crn[:, 1] - crn[:, 0]).mean()
    overestimate_without = (no_reevaluation[:, 1] - no_reevaluation[:, 0]).mean()
    assert overestimate_without > 1.5 * overestimate_with
