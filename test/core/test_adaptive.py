"""Which launch next (BALD over posterior samples) and when a design comparison is decided (issue 44.4)."""
import math

import numpy as np
import pytest

from rollability_ros.core.campaign.adaptive import LogisticToyPredictor, Unknowns, WeightedPosterior, bald_scores
from rollability_ros.core.campaign.plan_comparison import compare_plans
from rollability_ros.core.campaign.sequential import (PairedSequentialTest, comparison_decision, first_decisions,
                                                      paired_differences)
from rollability_ros.core.records import LaunchCondition, LaunchOutcome

UNKNOWNS = Unknowns(("robot.com_offset_z_m", "launch_twin.foam.lateral_friction"), (-0.019, 0.2), (0.015, 3.0),
                    (False, True))
#: The paper's matrix of the bare chassis and three designs: 4 x 2 heights x 2 speeds x 5 angles = 80.
MATRIX = [LaunchCondition(c, h, s, a) for c in ("baseline", "A", "B", "C") for h in (0.75, 1.3) for s in (0.8, 1.5)
          for a in (-60.0, -30.0, 0.0, 30.0, 60.0)]


def test_bald_is_the_mutual_information_of_known_cases():
    # every sample predicts 50 %: a coin flip whatever theta is, nothing to learn; half 0 half 1: log 2 nats
    p = np.array([[0.5, 0.0, 0.9], [0.5, 1.0, 0.9]])
    scores = bald_scores(p)
    assert scores[0] == pytest.approx(0.0, abs=1e-12)
    assert scores[1] == pytest.approx(math.log(2))
    assert scores[2] == pytest.approx(0.0, abs=1e-12)     # agreed, even if uncertain: nothing to learn
    # by hand: samples 0.2 and 0.8 -> H(0.5) - H(0.2)
    h = lambda q: -(q * math.log(q) + (1 - q) * math.log(1 - q))  # noqa: E731
    assert bald_scores(np.array([[0.2], [0.8]]))[0] == pytest.approx(h(0.5) - h(0.2))
    # weights: all the weight on one sample leaves nothing to learn
    assert bald_scores(np.array([[0.2], [0.8]]), weights=[1.0, 0.0])[0] == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(ValueError, match="weights"):
        bald_scores(p, weights=[0.0, 0.0])


def test_unknowns_map_log_and_linear_scales_both_ways_and_refuse_bad_bounds():
    values = UNKNOWNS.to_values([[0.5, 0.5]])
    assert values[0, 0] == pytest.approx(-0.002) and values[0, 1] == pytest.approx(math.sqrt(0.2 * 3.0))
    assert UNKNOWNS.to_normalised(values) == pytest.approx(np.array([[0.5, 0.5]]))
    with pytest.raises(ValueError, match="lower > 0 on a log scale"):
        Unknowns(("x",), (0.0,), (1.0,), (True,))


def test_the_proposal_is_the_candidate_whose_outcome_separates_the_plausible_unknowns():
    """One unknown; candidate 0 is saturated (always upright), 1 is a coin flip for every theta, 2 is the
    threshold the unknown moves: the proposal is 2, and after its outcomes the posterior narrows."""
    one = Unknowns(("x",), (0.0,), (1.0,), (False,))
    candidates = [LaunchCondition("A", 0.75, 0.8, a) for a in (0.0, 30.0, 60.0)]
    theta = np.linspace(0.0, 1.0, 201)[:, None]
    table = np.column_stack([np.full(201, 0.99), np.full(201, 0.5), 1.0 / (1.0 + np.exp(-20.0 * (theta[:, 0] - 0.5)))])
    posterior = WeightedPosterior(one, theta, candidates, table)
    proposal = posterior.propose()
    assert proposal.condition == candidates[2] and proposal.score_nats > 0.5
    assert proposal.predicted_low < 0.1 and proposal.predicted_high > 0.9 and "expected information" in proposal.why()
    width_before = posterior.normalised_widths()[0]
    rng = np.random.default_rng(3)
    for _ in range(12):   # the truth x = 0.7: P(upright) at candidate 2 about 0.98
        posterior.observe(2, bool(rng.random() < 1.0 / (1.0 + math.exp(-20.0 * 0.2))))
    assert posterior.normalised_widths()[0] < 0.6 * width_before
    low, high = posterior.intervals()[0]
    assert low < 0.7 < high
    with pytest.raises(ValueError, match="not a candidate"):
        posterior.candidate_index(LaunchCondition("B", 0.75, 0.8, 0.0))


def test_stored_outcomes_weigh_the_samples_and_invalid_launches_do_not():
    predictor = LogisticToyPredictor(UNKNOWNS, seed=4)
    posterior = WeightedPosterior.from_predictor(UNKNOWNS, predictor, MATRIX[:10], 500, np.random.default_rng(1))
    outcomes = [LaunchOutcome("r", f"t{i}", MATRIX[i % 10], "physical", i % 3 == 0) for i in range(30)]
    invalid = LaunchOutcome("r", "bad", MATRIX[0], "physical", False, note="invalid launch: did not leave the ledge")
    elsewhere = LaunchOutcome("r", "far", LaunchCondition("Z", 0.75, 0.8, 0.0), "physical", True)
    assert posterior.observe_outcomes(outcomes + [invalid, elsewhere]) == 30 and posterior.launches == 30
    assert 1.0 <= posterior.effective_sample_size < 500


def test_the_adaptive_plan_on_the_toy_needs_fewer_launches_than_the_matrix_on_the_same_truths():
    """The plan comparison on an analytic predictor (cheap): both plans, same truths and prior draws. It fails when
    the BALD choice is no better than cycling the matrix."""
    predictor = LogisticToyPredictor(UNKNOWNS, seed=7)
    comparison = compare_plans(UNKNOWNS, predictor, MATRIX, truths=3, target_width=0.25, budget=250, samples=1500,
                               seed=11)
    adaptive = [r.launches_to_target or 251 for r in comparison.adaptive]
    matrix = [r.launches_to_target or 251 for r in comparison.matrix]
    assert sum(adaptive) < 0.5 * sum(matrix)         # measured: 88 against 450 launches
    assert all(r.final_widths.shape == (2,) for r in comparison.adaptive)
    assert "median: matrix" in comparison.summary()


def _decisions(alpha, runs, pairs, p_a, p_b, seed):
    """When each of ``runs`` simulated comparisons (``pairs`` pairs of Bernoulli verdicts) first decided."""
    rng = np.random.default_rng(seed)
    differences = (rng.random((runs, pairs)) < p_b).astype(float) - (rng.random((runs, pairs)) < p_a)
    return differences, first_decisions(differences, alpha)


def test_the_vectorised_simulation_decides_exactly_where_the_test_does():
    differences, first = _decisions(0.1, runs=20, pairs=60, p_a=0.4, p_b=0.7, seed=5)
    for run, stop in zip(differences, first):
        test = PairedSequentialTest(0.1, grid=3)   # -1, 0, +1: the decision needs m = 0 only
        decided_at = 0
        for pair, difference in enumerate(run, start=1):
            test.update(difference)
            if test.decided and not decided_at:
                decided_at = pair
        assert decided_at == stop
    assert (first > 0).sum() >= 5           # some decided: the comparison is not vacuous


def test_a_comparison_of_equal_designs_is_wrongly_decided_at_most_alpha_of_the_time_however_often_it_looks():
    """Under equal designs (both 50 %; and both 90 %), looking after every one of 300 pairs: the stated 5 % holds (a
    t-test repeated after every pair would decide wrongly in about a quarter of the runs)."""
    for p in (0.5, 0.9):
        _, first = _decisions(0.05, runs=2000, pairs=300, p_a=p, p_b=p, seed=2)
        assert (first > 0).mean() <= 0.05 + 2 * math.sqrt(0.05 * 0.95 / 2000)


def test_a_clear_difference_is_decided_early_and_the_right_way():
    differences, first = _decisions(0.05, runs=200, pairs=200, p_a=0.3, p_b=0.85, seed=3)
    assert (first > 0).all() and np.median(first) < 40
    assert all(differences[run, :stop].sum() > 0 for run, stop in enumerate(first))   # B ahead when it stopped
    test = PairedSequentialTest(0.05)
    for d in [1.0] * 30:
        test.update(d)
    low, high = test.confidence_sequence()
    assert test.decided == 1 and 0 < low < high <= 1.0
    with pytest.raises(ValueError, match=r"in \[-1, 1\]"):
        test.update(2.0)


def test_paired_differences_pair_launches_at_the_same_condition_and_repetition():
    def outcome(configuration, angle, repetition, upright, note=""):
        return LaunchOutcome("r", f"{configuration}{angle}{repetition}",
                             LaunchCondition(configuration, 0.75, 0.8, angle, repetition), "sim", upright, note=note)
    outcomes = [outcome("A", 0.0, 0, False), outcome("B", 0.0, 0, True), outcome("B", 30.0, 0, False),
                outcome("A", 30.0, 1, True), outcome("A", 30.0, 0, True), outcome("C", 0.0, 0, True),
                outcome("B", 30.0, 1, False, note="invalid launch: landed outside the foam")]
    assert paired_differences(outcomes, "A", "B") == [1.0, -1.0]
    decision, test = comparison_decision(outcomes, "A", "B")
    assert decision == 0 and test.pairs == 2


def test_a_campaign_stops_once_its_comparison_is_decided_and_says_so(tmp_path):
    """The campaign loop with the comparison's stop rule: B always upright, A never, paired by condition; it ends
    decided (exit 0) long before the 2 x 40 launches planned, every stored launch kept."""
    from rollability_ros.core.campaign.plan import CampaignSpec, plan_trials
    from rollability_ros.core.campaign.runner import report_exit_code, run_campaign, store_writer
    from rollability_ros.core.campaign.sequential import comparison_stop_rule
    from rollability_ros.core.store import Store

    spec = CampaignSpec(run_id="cmp", configurations=["A", "B"], heights_m=[0.75], speeds_mps=[0.8],
                        angles_deg=[0.0], repetitions=40, random_block="repetition")
    # pairs: A then B at each repetition (the order a comparison campaign launches in)
    plan = sorted(plan_trials(spec), key=lambda t: (t.condition.repetition, t.condition.configuration))

    def launch(trial):
        return LaunchOutcome("cmp", trial.trial_id, trial.condition, "sim", trial.condition.configuration == "B")

    lines = []
    with Store(tmp_path / "s.sqlite") as store:
        report = run_campaign(plan, "cmp", set(), launch, store_writer(store), say=lines.append,
                              stop_rule=comparison_stop_rule([], "A", "B", 0.05))
        stored = store.launch_outcomes("cmp")
    assert report.decided and report.complete and report.stored_now == len(stored) < 40
    assert "B rights the robot more often than A" in report.decided and "at most 5%" in report.decided
    assert report_exit_code(report, say=lines.append) == 0 and lines[-1].startswith("campaign decided: B rights")


def test_an_adaptive_campaign_launches_the_proposed_conditions_and_learns_from_each(tmp_path):
    from rollability_ros.core.campaign.adaptive import adaptive_next_trial
    from rollability_ros.core.campaign.plan import PlannedTrial
    from rollability_ros.core.campaign.runner import run_campaign, store_writer
    from rollability_ros.core.store import Store

    predictor = LogisticToyPredictor(UNKNOWNS, seed=7)
    posterior = WeightedPosterior.from_predictor(UNKNOWNS, predictor, MATRIX, 1000, np.random.default_rng(0))
    truth = predictor.probabilities(UNKNOWNS.to_values([[0.3, 0.7]]), MATRIX)[0]
    rng = np.random.default_rng(1)

    def launch(trial):
        index = posterior.candidate_index(trial.condition)
        return LaunchOutcome("ad", trial.trial_id, trial.condition, "sim", bool(rng.random() < truth[index]))

    lines = []
    budget = [PlannedTrial(i, f"budget-{i}", MATRIX[0]) for i in range(25)]
    with Store(tmp_path / "s.sqlite") as store:
        report = run_campaign(budget, "ad", set(), launch, store_writer(store), say=lines.append,
                              next_trial=adaptive_next_trial(posterior, set(), say=lines.append))
        stored = store.launch_outcomes("ad")
    assert report.complete and len(stored) == 25 and posterior.launches == 24   # the last is weighed at the next
    assert len({o.trial_id for o in stored}) == 25                               # a repeated condition: r1, r2, ...
    assert sum(line.startswith("next launch: ") for line in lines) == 25 and any("why: expected" in l for l in lines)
    assert np.all(posterior.normalised_widths() < 0.6)


def _tiny_campaign(tmp_path):
    path = tmp_path / "tiny.yaml"
    path.write_text("/**:\n  ros__parameters:\n    campaign:\n      run_id: tiny\n      configurations: [baseline]\n"
                    "      heights_m: [0.75, 1.3]\n      speeds_mps: [0.8]\n      angles_deg: [0.0]\n"
                    "      repetitions: 1\n", encoding="utf-8")
    return str(path)


@pytest.mark.parametrize("extra, message", [
    (["--stop-when-decided", "baseline,Z"], "Z not in campaign.configurations"),
    (["--stop-when-decided", "baseline"], "two different configurations"),
    (["--plan", "adaptive", "--graph"], "run in process"),
    (["--propose-next", "--prior-samples", "1"], "--prior-samples must be >= 2"),
    (["--fit", "robot.com_offset_z_m"], "--fit, --twin-config, --likelihood and --about are for --plan adaptive"),
    (["--propose-next", "--about", "baseline,Q"], "--about: Q not in campaign.configurations"),
    (["--stop-when-decided", "baseline,baseline", "--alpha", "nan"], "two different"),
    (["--alpha", "0.7"], "--alpha must be in"),
])
def test_adaptive_campaign_arguments_are_refused_in_one_line(tmp_path, capsys, extra, message):
    from rollability_ros.cli import main

    assert main(["campaign", "--backend", "sim", "--config", _tiny_campaign(tmp_path),
                 "--store", str(tmp_path / "s.sqlite"), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "s.sqlite").exists()     # refused before anything is written


def test_propose_next_prints_the_launch_as_the_technician_sets_it_up(tmp_path, capsys):
    """`rollability campaign --propose-next` on the simulation-based likelihood (TwinPredictor: the real twin, 2
    conditions x 3 samples x 1 launch) from a store holding one launch; a missing store is refused, never created."""
    pytest.importorskip("pybullet")
    from rollability_ros.cli import main
    from rollability_ros.core.store import Store

    config = _tiny_campaign(tmp_path)
    command = ["campaign", "--backend", "physical", "--config", config, "--store", str(tmp_path / "s.sqlite"),
               "--propose-next", "--prior-samples", "3", "--sim-repetitions", "1", "--workers", "1",
               "--fit", "robot.com_offset_z_m"]
    assert main(command) == 2 and "no store at" in capsys.readouterr().err
    with Store(tmp_path / "s.sqlite") as store:
        store.add_launch_outcome(LaunchOutcome("tiny", "t0", LaunchCondition("baseline", 1.3, 0.8, 0.0), "physical",
                                               False, final_orientation=(math.nan,) * 4, classified_by="operator"))
    assert main(command) == 0
    out = capsys.readouterr().out
    assert "weighed by 1 stored launches of run tiny" in out
    assert "next launch: baseline at " in out and "\nwhy: expected information" in out
    assert "unknown robot.com_offset_z_m: 95% of the weighted samples in [" in out
    with Store(tmp_path / "s.sqlite") as store:
        assert len(store.launch_outcomes()) == 1                     # it launched nothing on the rig
    # --plan adaptive on the twin rig continues the run: each launch chosen after the previous one is stored
    adaptive_run = ["campaign", "--backend", "sim", "--config", config, "--store", str(tmp_path / "s.sqlite"),
                    "--plan", "adaptive", "--budget", "2", "--prior-samples", "3", "--sim-repetitions", "1",
                    "--workers", "1", "--fit", "robot.com_offset_z_m"]
    assert main(adaptive_run) == 2 and "pass --resume" in capsys.readouterr().err   # a stored run needs --resume
    assert main([*adaptive_run, "--resume"]) == 0
    out = capsys.readouterr().out
    assert out.count("next launch: baseline at ") == 2 and "campaign complete: 2/2 trials stored" in out
    with Store(tmp_path / "s.sqlite") as store:
        stored = store.launch_outcomes("tiny")
    assert len(stored) == 3 and [o.backend for o in stored] == ["physical", "sim", "sim"]
    assert all(not math.isnan(o.final_tilt_deg) for o in stored[1:])   # the twin's continuous outcomes, stored


class _Thresholds:
    """One unknown x in [0, 1]; P(upright) at candidate c = sigmoid(12 (x - a_c)), a = 0.2, 0.4, 0.6, 0.8."""

    thresholds = np.array([0.2, 0.4, 0.6, 0.8])

    def probabilities(self, theta, conditions):
        return 1.0 / (1.0 + np.exp(-12.0 * (np.atleast_2d(theta)[:, :1] - self.thresholds[None, :len(conditions)])))


def test_renewed_samples_describe_the_exact_posterior_after_many_launches():
    """400 launches pin x far more narrowly than the prior: without renewal about 5 % of the prior draws remain; with
    it the samples' mean and 95 % interval match the posterior computed exactly on a fine grid."""
    one = Unknowns(("x",), (0.0,), (1.0,), (False,))
    candidates = [LaunchCondition("A", 0.75, 0.8, a) for a in (0.0, 10.0, 20.0, 30.0)]
    predictor = _Thresholds()
    rng = np.random.default_rng(8)
    truth = predictor.probabilities(np.array([[0.37]]), candidates)[0]
    launches = [(i % 4, bool(rng.random() < truth[i % 4])) for i in range(400)]
    renewed = WeightedPosterior.from_predictor(one, predictor, candidates, 1000, np.random.default_rng(1), renew=True)
    plain = WeightedPosterior.from_predictor(one, predictor, candidates, 1000, np.random.default_rng(1))
    for index, upright in launches:
        renewed.observe(index, upright)
        plain.observe(index, upright)
    grid = np.linspace(0.0, 1.0, 20001)
    p = np.clip(predictor.probabilities(grid[:, None], candidates), 1e-3, 1 - 1e-3)
    log_posterior = sum(np.log(p[:, i]) if up else np.log1p(-p[:, i]) for i, up in launches)
    weights = np.exp(log_posterior - log_posterior.max())
    weights /= weights.sum()
    exact_mean = float(grid @ weights)
    exact_low, exact_high = np.interp([0.025, 0.975], np.cumsum(weights), grid)
    assert renewed.renewals > 0 and renewed.effective_sample_size > 300
    assert float(renewed.samples[:, 0] @ renewed.weights) == pytest.approx(exact_mean, abs=0.005)
    low, high = renewed.intervals()[0]
    assert low == pytest.approx(exact_low, abs=0.01) and high == pytest.approx(exact_high, abs=0.01)
    assert plain.effective_sample_size < 100         # the prior draws alone: about 50 of 1000 left


def test_a_per_launch_likelihood_plugs_in_through_the_adapter():
    """The learnt likelihood's interface (predict_upright_probability per design and condition) feeds the same
    posterior: the adapter's table equals the per-launch predictions column by column."""
    from rollability_ros.core.campaign.adaptive import PerLaunchAdapter

    toy = LogisticToyPredictor(UNKNOWNS, seed=3)

    class PerLaunch:
        def predict_upright_probability(self, theta, design, condition):
            return toy.probabilities(theta, [LaunchCondition(design, *condition)])[:, 0]

    theta = UNKNOWNS.draw(50, np.random.default_rng(2))
    table = PerLaunchAdapter(PerLaunch()).probabilities(theta, MATRIX[:6])
    assert table.shape == (50, 6) and np.allclose(table, toy.probabilities(theta, MATRIX[:6]))
    posterior = WeightedPosterior.from_predictor(UNKNOWNS, PerLaunchAdapter(PerLaunch()), MATRIX[:6], 200,
                                                 np.random.default_rng(0), renew=True)
    assert posterior.propose().condition in MATRIX[:6]


def test_the_comparison_score_looks_for_the_launch_that_tells_which_design_is_better():
    """Two designs, one unknown x: A is 60 % everywhere; B is 90 % at the first condition when x > 1/2 and 30 %
    otherwise, and 50 % at the second whatever x. Which design is better depends on x only through the first
    condition: the comparison score picks B there and scores the second condition's launches 0."""
    one = Unknowns(("x",), (0.0,), (1.0,), (False,))
    conditions = [LaunchCondition(c, 0.75, 0.8, a) for c in ("A", "B") for a in (0.0, 30.0)]
    x = np.linspace(0.0, 1.0, 101)
    high = x > 0.5
    table = np.column_stack([np.full(101, 0.6), np.full(101, 0.6), np.where(high, 0.9, 0.3), np.full(101, 0.5)])
    posterior = WeightedPosterior(one, x[:, None], conditions, table)
    assert np.array_equal(posterior.design_difference("A", "B") > 0, x > 0.5 + 1e-9)   # (0.9 + 0.5)/2 > 0.6
    scores = posterior.comparison_scores("A", "B")
    assert int(np.argmax(scores)) == 2 and scores[3] == pytest.approx(0.0, abs=1e-12)
    assert posterior.propose(comparison=("A", "B")).condition == conditions[2]
    with pytest.raises(ValueError, match="share no candidate"):
        posterior.design_difference("A", "Z")


class _Separate:
    """Two unknowns x, y in [0, 1]; the first candidate's P(upright) moves with x only, the second's with y only."""

    def probabilities(self, theta, conditions):
        t = np.atleast_2d(theta)
        return np.column_stack([1.0 / (1.0 + np.exp(-10.0 * (t[:, 0] - 0.5))),
                                1.0 / (1.0 + np.exp(-10.0 * (t[:, 1] - 0.5)))])[:, :len(conditions)]


def test_the_targeted_score_narrows_the_unknown_that_lags_its_target_width():
    """Each sample its own group is BALD itself; information about one unknown picks the launch that moves it; the
    targeted score picks the launch of the unknown farthest from its target width, and BALD once all are under."""
    two = Unknowns(("x", "y"), (0.0, 0.0), (1.0, 1.0), (False, False))
    conditions = [LaunchCondition("A", 0.75, 0.8, a) for a in (0.0, 30.0)]
    posterior = WeightedPosterior.from_predictor(two, _Separate(), conditions, 4000, np.random.default_rng(0))
    assert np.allclose(posterior.group_scores(np.arange(4000)), posterior.scores())
    assert int(np.argmax(posterior.unknown_scores(0))) == 0 and int(np.argmax(posterior.unknown_scores(1))) == 1
    for _ in range(30):
        posterior.observe(0, True)
        posterior.observe(0, False)   # x pinned near 1/2, y still at its prior width
    widths = posterior.normalised_widths()
    assert widths[0] < 0.5 < widths[1]
    assert int(np.argmax(posterior.targeted_scores([0.5, 0.5]))) == 1
    assert np.array_equal(posterior.targeted_scores([widths[0] / 2, 1.0]), posterior.unknown_scores(0))
    assert np.array_equal(posterior.targeted_scores([1.0, 1.0]), posterior.scores())


class _ScriptedPosterior:
    """A stand-in posterior for plan_comparison.match_matrix_on_truth: records the launches it weighs; its widths
    are scripted (``widths(plan, launches)``), so the strict and the tolerance-aware counts are known by hand."""

    def __init__(self, plan, widths, log):
        self.plan, self.widths, self.launches, self.candidates = plan, widths, [], MATRIX[:8]
        self.effective_sample_size = 100.0
        log.append(self)

    def observe_launch(self, index, upright, values=None, reading=None):
        self.launches.append((index, upright, reading))

    def scores(self):
        return np.arange(len(self.candidates), dtype=float)

    def normalised_widths(self, level=0.95):
        return self.widths(self.plan, len(self.launches))


def test_the_matrix_widths_monte_carlo_error_is_measured_on_the_same_launches_and_both_counts_kept():
    """Replicas of the matrix's posterior weigh the very launches the matrix made; the adaptive plan's launches are
    counted to the matrix's own widths (strict) and to the replicas' mean plus their sd (tolerance-aware). Matrix
    estimates (0.20, 0.10), (0.26, 0.12), (0.23, 0.08): mean (0.23, 0.10), sd (0.03, 0.02); the adaptive widths
    are 3/n and 1.2/n after n launches: strict at n = 15 (3/15 <= 0.20, 1.2/15 <= 0.10 from 12), tolerant at
    n = 12 (3/12 = 0.25 <= 0.26, 1.2/12 = 0.10 <= 0.12)."""
    from rollability_ros.core.campaign.plan_comparison import match_matrix_on_truth

    estimates = {0: (0.20, 0.10), 2: (0.26, 0.12), 3: (0.23, 0.08)}
    log = []

    def widths(plan, launches):
        return np.array(estimates[plan]) if plan != 1 else np.array([3.0, 1.2]) / max(launches, 1)

    def launch(index, rng):
        return bool(rng.random() < 0.5), None, float(index)
    result = match_matrix_on_truth(lambda plan: _ScriptedPosterior(plan, widths, log), launch, 24, (1, 2),
                                   replicas=2)
    matrix, *replicas = [p for p in log if p.plan != 1]
    assert len(matrix.launches) == 24 and all(r.launches == matrix.launches for r in replicas)
    assert sorted(i for i, _, _ in matrix.launches) == sorted(list(range(8)) * 3)   # each candidate once per round
    assert result.width_error == pytest.approx([0.03, 0.02])
    assert result.tolerant_widths == pytest.approx([0.26, 0.12])
    assert (result.adaptive_launches, result.tolerant_launches) == (15, 12)
    assert result.adaptive_launched == (7,) * 15                                        # the highest score each time
    plain = match_matrix_on_truth(lambda plan: _ScriptedPosterior(plan, widths, []), launch, 24, (1, 2))
    assert (plain.adaptive_launches, plain.tolerant_launches) == (15, None) and len(plain.adaptive_launched) == 15
    with pytest.raises(ValueError, match="replicas"):
        match_matrix_on_truth(lambda plan: _ScriptedPosterior(plan, widths, []), launch, 24, (1, 2), replicas=1)


def test_the_lagging_score_pays_only_for_unknowns_not_yet_at_their_width():
    """Candidate 0's verdict tells unknown 0 apart sharply, candidate 1's unknown 1 mildly: the joint score takes
    candidate 0; once unknown 0 is at its target width only unknown 1 counts, so the lagging score takes candidate 1;
    with both lagging it sums both (more than either alone); with none lagging it is the joint score."""
    rng = np.random.default_rng(3)
    u = rng.uniform(size=(2000, 2))
    p = np.column_stack([np.where(u[:, 0] > 0.5, 0.95, 0.05), 0.35 + 0.3 * u[:, 1]])
    posterior = WeightedPosterior(UNKNOWNS, UNKNOWNS.to_values(u), MATRIX[:2], p)
    widths = posterior.normalised_widths()
    joint = posterior.scores()
    assert np.argmax(joint) == 0
    only_1 = posterior.lagging_scores([widths[0] + 0.01, widths[1] - 0.01])
    assert np.argmax(only_1) == 1
    assert only_1 == pytest.approx(posterior.unknown_scores(1))
    both = posterior.lagging_scores(widths - 0.01)
    assert both == pytest.approx(posterior.unknown_scores(0) + posterior.unknown_scores(1))
    assert posterior.lagging_scores(widths + 0.01) == pytest.approx(joint)
