"""Racing by successive halving (core/optimization/racing.py): the stopping rule, common random numbers, the budget."""
import numpy as np
import pytest

from rollability_ros.core.optimization import racing


def fixed(rates):
    """An evaluator whose candidate ``c`` succeeds on the first ``round(rates[c] * trials)`` trials; it records its
    calls (ids, seed, trials)."""
    calls = []

    def evaluate(ids, seed, trials):
        calls.append((list(ids), seed, trials))
        return [(int(round(rates[c] * trials)), trials) for c in ids]
    return evaluate, calls


def test_a_candidate_clearly_worse_than_the_leader_stops_after_the_first_round():
    # 2/20 has Wilson upper bound 0.30 < the leader's lower bound 0.70 (18/20): stopped by the racing rule; 12/20
    # (upper 0.78) overlaps and stays; halving keeps max(min_keep, ceil(0.5 x 3)) = 3 here, so nothing else stops
    evaluate, calls = fixed({"a": 0.9, "b": 0.6, "c": 0.1, "d": 0.55, "base": 0.3})
    result = racing.race(["a", "b", "c", "d"], evaluate, [20, 20], [11, 12], keep_fraction=0.5, min_keep=3,
                         reference="base")
    assert result.stopped["c"][0] == 1 and "clearly worse" in result.stopped["c"][1]
    assert result.survivors == ["a", "b", "d"]
    assert result.totals["a"] == (36, 40) and result.totals["c"] == (2, 20)
    assert result.first_round == {"a": (18, 20), "b": (12, 20), "c": (2, 20), "d": (11, 20)}
    assert result.reference == (12, 40)          # the reference runs every round and never stops
    assert calls[0] == (["a", "b", "c", "d", "base"], 11, 20) and calls[1] == (["a", "b", "d", "base"], 12, 20)
    assert result.trials_spent == 5 * 20 + 4 * 20


def test_halving_keeps_the_better_half_but_never_fewer_than_min_keep():
    rates = {i: 0.4 + 0.02 * i for i in range(10)}        # close rates: the racing rule stops none of them
    evaluate, _ = fixed(rates)
    result = racing.race(list(range(10)), evaluate, [20, 20, 20], [1, 2, 3], keep_fraction=0.5, min_keep=3)
    assert [r["running"] for r in result.rounds] == [10, 5, 3]
    assert set(result.survivors) == {7, 8, 9}
    assert all("halving" in reason for _, reason in result.stopped.values())
    assert result.trials_spent == (10 + 5 + 3) * 20


def test_every_candidate_of_a_round_meets_the_same_draws():
    """Common random numbers: with a seeded noisy evaluator, two identical candidates get identical results in
    every round, so neither is stopped in favour of the other by luck."""
    def evaluate(ids, seed, trials):
        draws = np.random.default_rng(seed).random(trials)
        return [(int(np.sum(draws < (0.5 if c != "bad" else 0.05))), trials) for c in ids]

    result = racing.race(["x", "y", "bad"], evaluate, [30, 30], [5, 6], min_keep=2)
    assert result.totals["x"] == result.totals["y"] and "bad" in result.stopped


def test_bad_race_settings_are_refused():
    evaluate, _ = fixed({"a": 0.5})
    with pytest.raises(ValueError, match="one seed per round"):
        racing.race(["a"], evaluate, [20, 20], [1])
    with pytest.raises(ValueError, match="at least one trial"):
        racing.race(["a"], evaluate, [0], [1])
    with pytest.raises(ValueError, match="distinct"):
        racing.race(["a", "a"], evaluate, [20], [1])


# --- sequential racing inside the optimizer ---------------------------------------------------------------------

def test_the_stop_count_is_the_exact_one_sided_binomial_test():
    from scipy.stats import binom

    for n, bar, level in ((10, 0.7, 0.1 / 3), (20, 0.7, 0.1 / 3), (40, 0.5, 0.025), (12, 0.9, 0.05)):
        x = racing.stop_count(n, bar, level)
        assert binom.cdf(x, n, bar) <= level < binom.cdf(x + 1, n, bar)
    assert racing.stop_count(10, 0.7, 0.1 / 3) == 3            # 3/10 stops against a bar of 0.7, 4/10 does not
    assert racing.stop_count(10, 0.0, 0.05) == -1              # nothing is clearly below a bar of 0
    assert racing.sequential_stops(3, 10, 0.7, [10, 20, 40], 0.1)
    assert not racing.sequential_stops(4, 10, 0.7, [10, 20, 40], 0.1)
    assert not racing.sequential_stops(0, 10, None, [10, 20, 40], 0.1)   # no bar (empty cell): never stops


def test_the_stages_are_the_increments_of_the_looks():
    assert racing.sequential_stages([10, 20, 40], 60) == [10, 10, 20, 20]
    assert racing.sequential_stages([], 60) == [60]
    for looks in ([20, 10], [10, 60], [0, 10], [10, 10]):
        with pytest.raises(ValueError, match="race_looks must be strictly increasing"):
            racing.sequential_stages(looks, 60)


def test_the_error_rate_of_stopping_a_candidate_as_good_as_the_bar_is_at_most_alpha_and_matches_simulation():
    looks, trials, alpha = [10, 20, 40], 60, 0.1
    for bar in (0.3, 0.7, 0.9):
        error, spent = racing.sequential_stop_probability(looks, trials, bar, alpha, bar)
        assert error <= alpha and 55 < spent <= 60
        better, _ = racing.sequential_stop_probability(looks, trials, bar, alpha, min(1.0, bar + 0.05))
        assert better <= error                                  # a better candidate stops less often
    # the exact dynamic programme against a simulation of the staged rule (bar 0.7, a candidate at 0.45)
    stopped_exact, spent_exact = racing.sequential_stop_probability(looks, trials, 0.7, alpha, 0.45)
    rng = np.random.default_rng(5)
    outcomes = rng.random((20000, trials)) < 0.45
    stopped = np.zeros(len(outcomes), bool)
    spent = np.full(len(outcomes), trials)
    for look in looks:
        now = ~stopped & (outcomes[:, :look].sum(axis=1) <= racing.stop_count(look, 0.7, alpha / len(looks)))
        spent[now] = look
        stopped |= now
    assert abs(stopped.mean() - stopped_exact) < 0.015 and abs(spent.mean() - spent_exact) < 0.5
    assert stopped_exact > 0.8 and spent_exact < 30                # clearly worse: most stop, at half the trials


def bernoulli_evaluator(calls):
    """A noisy evaluator with common random numbers: every profile of a call meets the same uniform draws of its
    seed; a profile succeeds on a draw below its mean height / 0.45. Records (seed, trials, profiles) per call."""
    def evaluate_trials(heights_list, seed, trials):
        calls.append((seed, trials, len(heights_list)))
        draws = np.random.default_rng(seed).random(trials)
        return [(int(np.sum(draws < float(np.mean(h)) / 0.45)), trials, 0.0, "fake") for h in heights_list]
    return evaluate_trials


class Killed(Exception):
    pass


def racing_parameters(grid, method="cmaes", **extra):
    return {"optimizer.method": method, "optimizer.max_generations": 5, "optimizer.seed": 4,
            "optimizer.trials": 40, "optimizer.race_looks": [5, 10, 20], "optimizer.race_alpha": 0.2,
            "optimizer.popsize": 8, "optimizer.sigma0": 0.1, "optimizer.initial_mean_screen": 0,
            "optimizer.target_fitness": 2.0, "optimizer.stagnation_generations": 0,
            "profile.rows": grid.rows, "profile.cols": grid.cols, **extra}


def run_rows(run_dir, parameters, grid, evaluate_trials, resume=False):
    from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config
    from rollability_ros.core.store import Store

    run = OptimizationRun(str(run_dir), run_config(parameters), grid, lambda h, s: evaluate_trials(h, s, 40), resume=resume,
                          evaluate_trials=evaluate_trials)
    try:
        run.run()
    finally:
        run.close()
    with Store(str(run_dir)) as store:
        return [(c.generation, c.index, c.successes, c.trials, c.seed) for c in store.candidates()]


@pytest.mark.parametrize("method", ["cmaes", "cma_mae"])
def test_the_optimizer_races_in_stages_and_a_killed_generation_resumes_to_the_same_decisions(tmp_path, method):
    pytest.importorskip("cma")
    if method == "cma_mae":
        pytest.importorskip("ribs")
    from rollability_ros.core.optimization import cmaes
    from rollability_ros.core.profile.geometry import ProfileGrid

    grid = ProfileGrid(rows=2, cols=2)
    parameters = racing_parameters(grid, method)
    calls = []
    whole = run_rows(tmp_path / "whole", parameters, grid, bernoulli_evaluator(calls))
    # every call is one stage of common random numbers (looks 5, 10, 20 of 40: stages of 5, 5, 10 and 20 trials),
    # or an unraced population's / a re-evaluation's 40
    assert {trials for _, trials, _ in calls} == {5, 10, 20, 40}
    race_seeds = {cmaes.derive_seed(4, g, cmaes.STREAM_RACE, k) for g in range(5) for k in (1, 2, 3)}
    population_seeds = {cmaes.derive_seed(4, g, cmaes.STREAM_POPULATION) for g in range(5)}
    assert all(seed in race_seeds for seed, trials, _ in calls if trials in (10, 20))
    first_stages = [seed for seed, trials, _ in calls if trials == 5 and seed in population_seeds]
    assert first_stages and all(count == 8 for seed, _, count in calls if seed in first_stages)  # all 8 start
    raced = [row for row in whole if row[1] < 8 and row[3] < 40]
    assert raced and all(trials in (5, 10, 20) for *_, trials, _ in raced)   # stopped at a look
    # kill the run in the middle of its last raced generation (before its third stage), then resume it afresh
    kill_at = max(number for number, (_, trials, _) in enumerate(calls) if trials == 10)
    killer_calls = []
    inner = bernoulli_evaluator(killer_calls)

    def dying(heights_list, seed, trials):
        if len(killer_calls) == kill_at:
            raise Killed()
        return inner(heights_list, seed, trials)

    with pytest.raises(Killed):
        run_rows(tmp_path / "killed", parameters, grid, dying)
    resumed = run_rows(tmp_path / "killed", parameters, grid, bernoulli_evaluator([]), resume=True)
    assert resumed == whole


def test_the_incumbent_and_the_cell_elite_are_the_bars():
    pytest.importorskip("cma")
    from rollability_ros.core.optimization.cmaes import ProfileOptimizer
    from rollability_ros.core.optimization.optimization_run import make_optimizer, run_settings
    from rollability_ros.core.profile.geometry import ProfileGrid

    grid = ProfileGrid(rows=2, cols=2)
    settings = run_settings(racing_parameters(grid)).optimizer
    optimizer = ProfileOptimizer(grid.n_variables, settings, grid.height_min, grid.height_max)
    population = optimizer.ask()
    assert optimizer.race_reference(population[0]) is None          # no incumbent yet: nobody stops
    optimizer.tell(population, [0.25 * (i % 4) for i in range(8)], [40] * 8)
    optimizer.tell_reevaluation(0.5, 40)
    assert optimizer.race_reference(population[0]) == (50, 80)      # the incumbent pooled: 30/40 + 20/40
    pytest.importorskip("ribs")
    qd = make_optimizer(grid, run_settings(racing_parameters(grid, "cma_mae")), clock=lambda: 0.0)
    population = qd.ask()
    assert all(qd.race_reference(h) is None for h in population)    # empty archive
    qd.tell(population, [0.5] * 8, [20] * 8)
    rows = qd.archive_rows()
    assert all(qd.race_reference(h) is not None for h in population)
    assert {qd.race_reference(h) for h in population} == {(10, 20)}  # the cell's elite: 0.5 of 20 trials
    assert len(rows) >= 1


def test_bad_racing_settings_are_refused(tmp_path):
    pytest.importorskip("cma")
    from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config, run_settings
    from rollability_ros.core.profile.geometry import ProfileGrid

    grid = ProfileGrid(rows=2, cols=2)
    for extra, message in (({"optimizer.race_looks": [10, 5]}, "race_looks must be strictly increasing"),
                           ({"optimizer.race_looks": [40]}, "race_looks must be strictly increasing"),
                           ({"optimizer.race_alpha": 0.0}, r"race_alpha out of range: 0.0 is not in \(0.0, 1.0\)"),
                           ({"optimizer.common_random_numbers": False}, "needs common_random_numbers"),
                           ({"optimizer.race_survivors": 8}, "race_survivors must be below popsize 8"),
                           ({"optimizer.race_survivors": -1}, r"race_survivors out of range: -1 is not in \[0, 100000\]"),
                           ({"optimizer.race_survivors": 2, "optimizer.race_looks": [0]},
                            "race_survivors needs race_looks")):
        with pytest.raises(ValueError, match=message):
            run_settings(racing_parameters(grid, **extra)).optimizer.validate()
    run_settings(racing_parameters(grid, **{"optimizer.race_looks": [0]})).optimizer.validate()   # [0]: off
    with pytest.raises(ValueError, match="race_looks needs an evaluator"):
        OptimizationRun(str(tmp_path / "c"), run_config(racing_parameters(grid)), grid, lambda h, s: [])


def test_a_kept_mujoco_world_gives_the_same_trials_when_racing_comes_back_to_its_profile():
    """Racing runs a generation's profiles once per stage; each process keeps their MuJoCo worlds
    (evaluation.MUJOCO_WORLD_CACHE), and a world it comes back to after another profile's trials gives the trials a
    fresh one gives."""
    pytest.importorskip("mujoco")
    import dataclasses

    from rollability_ros.core.sim import evaluation

    base = evaluation.load_settings()
    settings = dataclasses.replace(base, physics=dataclasses.replace(base.physics, engine="mujoco"))
    grid = settings.grid
    rng = np.random.default_rng(8)
    jobs = [evaluation.profile_job(rng.uniform(grid.height_min, grid.height_max, grid.n_variables), settings)
            for _ in range(2)]
    batch = [(index, evaluation.trial_seed(17, index)) for index in range(3)]
    evaluation._mujoco_worlds.clear()
    first = evaluation.run_batch(jobs[0], batch)
    evaluation.run_batch(jobs[1], batch)
    assert len(evaluation._mujoco_worlds) == 2
    again = evaluation.run_batch(jobs[0], batch)                 # the kept world, after the other profile's trials
    evaluation._mujoco_worlds.clear()
    fresh = evaluation.run_batch(jobs[0], batch)                  # a world built anew
    assert again == first == fresh


# --- successive halving inside the optimizer (optimizer.race_survivors) -------------------------------------------

def test_halving_keeps_the_best_improvements_over_the_reference_ties_to_the_earlier():
    totals = {0: (3, 8), 1: (5, 8), 2: (5, 8), 3: (1, 8), 4: (6, 8)}
    assert racing.halving_survivors(totals, {}, 2) == [1, 4]            # 6/8, then the earlier of two 5/8
    assert racing.halving_survivors(totals, {}, 9) == [0, 1, 2, 3, 4]
    # CMA-MAE: improvement over the cell's elite; an empty cell (None) counts as 0
    references = {0: None, 1: (9, 10), 2: (1, 10), 3: None, 4: (10, 10)}
    # improvements 0.375, -0.275, 0.525, 0.125, -0.25
    assert racing.halving_survivors(totals, references, 2) == [0, 2]
    with pytest.raises(ValueError, match="survivors must be >= 1"):
        racing.halving_survivors(totals, {}, 0)


def test_the_halving_budget_and_its_drop_chance_are_exact():
    assert racing.halving_trials(12, [8], 60, 2) == 12 * 8 + 2 * 52
    assert racing.halving_trials(12, [8, 20], 60, 2) == 12 * 8 + 2 * 52
    # nobody is dropped when all are kept; a certain winner is never dropped
    assert racing.halving_drop_probability(8, 12, 11, 0.3, 0.1) == pytest.approx(0.0)
    assert racing.halving_drop_probability(8, 2, 11, 0.0, 1.0) == pytest.approx(0.0)
    # equal rates: by symmetry every candidate is kept with chance survivors / popsize
    for n, rate in ((8, 0.2), (10, 0.5), (3, 0.9)):
        assert racing.halving_drop_probability(n, 2, 11, rate, 0.0) == pytest.approx(1 - 2 / 12)
    # against a simulation of independent counts with random tie-breaks
    rng = np.random.default_rng(3)
    draws = 40000
    mine = rng.binomial(8, 0.35, draws)
    theirs = rng.binomial(8, 0.2, (draws, 5))
    above = (theirs > mine[:, None]).sum(axis=1)
    tied = (theirs == mine[:, None]).sum(axis=1)
    position = np.floor(rng.random(draws) * (tied + 1))
    simulated = np.mean(above + position >= 2)
    assert abs(simulated - racing.halving_drop_probability(8, 2, 5, 0.2, 0.15)) < 0.01
    assert racing.halving_drop_probability(8, 2, 5, 0.2, 0.15) < 1 - 2 / 6     # better than the rest: kept more


def survivor_rows(rows, popsize, trials):
    """{generation: sorted trial counts of its population} of stored rows."""
    generations = {}
    for generation, index, _, ran, _ in rows:
        if index < popsize:
            generations.setdefault(generation, []).append(ran)
    return {g: sorted(counts) for g, counts in generations.items()}


@pytest.mark.parametrize("method", ["cmaes", "cma_mae"])
def test_halving_runs_at_most_the_survivors_on_and_a_killed_generation_resumes_to_the_same_decisions(tmp_path,
                                                                                                       method):
    pytest.importorskip("cma")
    if method == "cma_mae":
        pytest.importorskip("ribs")
    from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config
    from rollability_ros.core.profile.geometry import ProfileGrid

    grid = ProfileGrid(rows=2, cols=2)
    parameters = racing_parameters(grid, method, **{"optimizer.race_looks": [5], "optimizer.race_survivors": 2})
    calls = []
    whole = run_rows(tmp_path / "whole", parameters, grid, bernoulli_evaluator(calls))
    counts = survivor_rows(whole, 8, 40)
    assert sorted(counts) == [1, 2, 3, 4, 5]                       # generation 1 is halved too (no bar needed)
    for generation, ran in counts.items():
        assert all(t in (5, 40) for t in ran) and sum(t == 40 for t in ran) <= 2
        assert sum(ran) <= 8 * 5 + 2 * 35                               # racing.halving_trials
    assert sum(sum(ran) for ran in counts.values()) < 0.4 * 5 * 8 * 40
    # killed after the race, while the population is being stored (3 of 8 stored), then resumed afresh: the
    # stored three are raced again with the rest (the same results) and the same two go on
    stored = []

    def dying(record):
        stored.append(record)
        if record.generation == 4 and sum(r.generation == 4 for r in stored) == 3:
            raise Killed()

    run = OptimizationRun(str(tmp_path / "killed"), run_config(parameters), grid,
                          lambda h, s: bernoulli_evaluator([])(h, s, 40), on_candidate=dying,
                          evaluate_trials=bernoulli_evaluator([]))
    try:
        with pytest.raises(Killed):
            run.run()
    finally:
        run.close()
    resumed = run_rows(tmp_path / "killed", parameters, grid, bernoulli_evaluator([]), resume=True)
    assert resumed == whole
