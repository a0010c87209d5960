"""Which launch next from a learnt likelihood (core/campaign/learnt_plan.py): the weights are the calibration's own
likelihood, the continuous outcomes add information the verdict alone does not carry, and the table refuses
conditions the likelihood was not learnt on. The networks are test_learnt_likelihood's hand-built ones (a known
model: P(upright) moves with unknown a, the gate's reading with unknown b)."""
import dataclasses
import math

import numpy as np
import pytest

from rollability_ros.core.campaign import likelihood as learnt
from rollability_ros.core.campaign.learnt_plan import LearntTable, OutcomePosterior
from rollability_ros.core.records import INVALID_LAUNCH, LaunchCondition, LaunchOutcome

from test_learnt_likelihood import CONFIGURATIONS, LEVELS, UNKNOWNS, model, simulate

CANDIDATES = [LaunchCondition(c, h, v, a) for c in CONFIGURATIONS for h in LEVELS.heights_m
              for v in LEVELS.speeds_mps for a in LEVELS.angles_deg]


def test_the_weights_are_the_calibrations_likelihood_of_verdicts_and_outcomes():
    likelihood = model()
    table = LearntTable(likelihood, CANDIDATES)
    assert table.outcomes == ("measured_speed_mps",)
    posterior = OutcomePosterior.from_prior(table, 300, np.random.default_rng(0), renew=False)
    rng = np.random.default_rng(1)
    cells = [(c.configuration, c.height_m, c.speed_mps, c.angle_deg) for c in CANDIDATES[::5]]
    observations = simulate((0.7, 0.3), cells, rng)
    for o in observations:
        index = posterior.candidate_index(LaunchCondition(o.configuration, o.height_m, o.speed_mps, o.angle_deg))
        posterior.observe_launch(index, o.upright, table.transformed(index, o.outcomes))
    expected = likelihood.log_likelihood(UNKNOWNS.to_normalised(posterior.samples), observations)
    floor = learnt.PROBABILITY_FLOOR   # the two clip P(upright) alike
    assert floor > 1e-3
    assert np.allclose(posterior.log_weights - posterior.log_weights.max(), expected - expected.max(), atol=1e-9)


def test_continuous_outcomes_teach_what_the_verdict_cannot_and_the_score_says_so():
    """b moves only the gate's reading: verdicts alone leave b at its prior width; with the reading, the score of
    every launch is above the verdict-only BALD score and 12 launches pin b to a fraction of its range."""
    likelihood = model()
    candidates = CANDIDATES[:12]   # one configuration: enough to separate a and b, and cheap
    with_outcomes = OutcomePosterior.from_prior(LearntTable(likelihood, candidates), 400, np.random.default_rng(0),
                                                draws=16)
    verdicts = OutcomePosterior.from_prior(LearntTable(likelihood, candidates, outcomes=()), 400,
                                           np.random.default_rng(0))
    assert np.all(with_outcomes.scores() > verdicts.scores() + 0.5)   # the reading is worth more than a nat here
    rng = np.random.default_rng(3)
    for _ in range(12):
        for posterior in (with_outcomes, verdicts):
            index = int(np.argmax(posterior.scores()))
            c = candidates[index]
            o, = simulate((0.7, 0.3), [(c.configuration, c.height_m, c.speed_mps, c.angle_deg)], rng)
            posterior.observe_launch(index, o.upright, posterior.table.transformed(index, o.outcomes))
    assert with_outcomes.normalised_widths()[1] < 0.15 < 0.8 < verdicts.normalised_widths()[1]
    low, high = with_outcomes.intervals()[1]
    assert low <= UNKNOWNS.to_values([[0.7, 0.3]])[0, 1] <= high


def test_stored_outcomes_enter_with_their_readings_and_off_matrix_conditions_are_refused():
    likelihood = model()
    table = LearntTable(likelihood, CANDIDATES)
    posterior = OutcomePosterior.from_prior(table, 200, np.random.default_rng(0), renew=False)
    condition = CANDIDATES[3]
    stored = [LaunchOutcome("r", "t0", condition, "physical", True, measured_speed_mps=condition.speed_mps,
                            classified_by="imu"),
              LaunchOutcome("r", "t1", condition, "physical", False, note=f"{INVALID_LAUNCH}: misfire")]
    assert posterior.observe_outcomes(stored) == 1
    index = CANDIDATES.index(condition)
    expected = likelihood.log_likelihood(UNKNOWNS.to_normalised(posterior.samples), learnt.observations_from_outcomes(
        stored[:1]))
    assert np.allclose(posterior.log_weights - posterior.log_weights.max(), expected - expected.max())
    assert posterior._trials[index] == 1
    with pytest.raises(ValueError, match="not one of the levels"):
        LearntTable(likelihood, [LaunchCondition("A", 0.9, 0.8, 0.0)])
    with pytest.raises(ValueError, match="configuration 'Z'"):
        LearntTable(likelihood, [LaunchCondition("Z", 0.75, 0.8, 0.0)])
    assert math.isnan(table.transformed(0, {})[0])


def test_propose_next_from_a_prepared_likelihood_and_bad_files_refused_in_one_line(tmp_path, capsys):
    """`rollability campaign --propose-next --likelihood FILE`: the stored launch (verdict and gate reading) weighs
    the samples and the launch is proposed; a damaged file, one prepared for another twin, one whose levels miss the
    campaign's, and --fit beside it are each refused in one line, with nothing stored."""
    from rollability_ros.cli import main
    from rollability_ros.core.campaign import calibration
    from rollability_ros.core.config import load_parameters
    from rollability_ros.core.store import Store

    from test_adaptive import _tiny_campaign

    names = ("robot.com_offset_z_m", "launch_twin.foam.lateral_friction")
    unknowns = type(UNKNOWNS)(names, (-0.019, 0.3), (0.015, 3.0), (False, True))
    fingerprint = learnt.twin_fingerprint(load_parameters([*calibration.TWIN_CONFIGS, "calibration"]), names)
    good, other_levels = tmp_path / "good.npz", tmp_path / "levels.npz"
    model(unknowns, ("baseline",), learnt.ConditionLevels((0.75, 1.3), (0.8,), (0.0,)), fingerprint).save(good)
    model(unknowns, ("baseline",), learnt.ConditionLevels((0.75, 1.3), (1.5,), (0.0,)), fingerprint).save(other_levels)
    config, store_file = _tiny_campaign(tmp_path), tmp_path / "s.sqlite"
    with Store(store_file) as store:
        store.add_launch_outcome(LaunchOutcome("tiny", "t0", LaunchCondition("baseline", 1.3, 0.8, 0.0), "physical",
                                               True, measured_speed_mps=0.79, classified_by="imu"))
    command = ["campaign", "--backend", "physical", "--config", config, "--store", str(store_file),
               "--propose-next", "--prior-samples", "200"]
    assert main([*command, "--likelihood", str(good)]) == 0
    out = capsys.readouterr().out
    assert "the learnt likelihood" in out and "verdicts and measured_speed_mps" in out
    assert "weighed by 1 stored launches of run tiny" in out and "next launch: baseline at " in out
    assert "unknown launch_twin.foam.lateral_friction: 95% of the weighted samples in [" in out
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"PK\x03\x04 not an archive")
    other = tmp_path / "other.yaml"
    other.write_text("/**:\n  ros__parameters:\n    launch_twin:\n      foam:\n        restitution: 0.2\n")
    for extra, message in ((["--likelihood", str(broken)], "not a prepared likelihood file"),
                           (["--likelihood", str(good), "--twin-config", str(other)], "prepared for another twin"),
                           (["--likelihood", str(other_levels)], "launch speed 0.8 is not one of the levels"),
                           (["--likelihood", str(good), "--fit", names[0]], "--fit is for the twin's predictions")):
        assert main([*command, *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1, err
    with Store(store_file) as store:
        assert len(store.launch_outcomes()) == 1


@pytest.mark.slow
def test_an_adaptive_campaign_on_the_twin_proposes_each_launch_from_the_learnt_likelihood(tmp_path, capsys):
    """`rollability campaign --plan adaptive --likelihood FILE` on the twin rig: two launches, each proposed from the
    hand-built likelihood after the previous one (with its gate reading) is stored."""
    pytest.importorskip("pybullet")
    from rollability_ros.cli import main
    from rollability_ros.core.campaign import calibration
    from rollability_ros.core.config import load_parameters
    from rollability_ros.core.store import Store

    from test_adaptive import _tiny_campaign

    names = ("robot.com_offset_z_m", "launch_twin.foam.lateral_friction")
    unknowns = type(UNKNOWNS)(names, (-0.019, 0.3), (0.015, 3.0), (False, True))
    fingerprint = learnt.twin_fingerprint(load_parameters([*calibration.TWIN_CONFIGS, "calibration"]), names)
    good = tmp_path / "good.npz"
    model(unknowns, ("baseline",), learnt.ConditionLevels((0.75, 1.3), (0.8,), (0.0,)), fingerprint).save(good)
    store_file = tmp_path / "s.sqlite"
    assert main(["campaign", "--backend", "sim", "--config", _tiny_campaign(tmp_path), "--store", str(store_file),
                 "--plan", "adaptive", "--budget", "2", "--prior-samples", "200", "--likelihood", str(good)]) == 0
    out = capsys.readouterr().out
    assert "the learnt likelihood" in out and out.count("next launch: baseline at ") == 2
    with Store(store_file) as store:
        stored = store.launch_outcomes("tiny")
    assert len(stored) == 2 and all(math.isfinite(o.measured_speed_mps) for o in stored)


def test_the_estimated_information_about_groups_is_the_score_when_each_sample_is_its_own_group():
    posterior = OutcomePosterior.from_prior(LearntTable(model(), CANDIDATES[:6]), 300, np.random.default_rng(0))
    assert np.allclose(posterior.group_scores(np.arange(300)), posterior.scores())
    one_group = posterior.group_scores(np.zeros(300, dtype=int))
    assert np.allclose(one_group, 0.0)   # knowing that the truth is among the samples teaches nothing
    # the gate's reading moves with b only: information about b's bins is most of the information there is
    about_b = posterior.unknown_scores(1)
    assert np.all(about_b > 0.5 * posterior.scores()) and np.all(about_b > posterior.unknown_scores(0))


def test_the_plan_reads_the_ensemble_as_the_calibration_does():
    """Two members whose verdicts differ (the second's logit shifted by 3): the weights are the members' mean
    likelihood (``log_likelihood(member=None)``, the calibration's), before any launch the predicted P(upright)
    is the members' mean (``predict_upright_probability``), and after launches each sample's prediction is the
    members' mixture weighted by how well each explained them. A plan that read the first member only fails all
    three; renewing the samples keeps the weights the members' mean."""
    from test_learnt_likelihood import shifted

    single = model()
    ensemble = dataclasses.replace(single, members=(shifted(single, 3.0),))
    table = LearntTable(ensemble, CANDIDATES)
    posterior = OutcomePosterior.from_prior(table, 300, np.random.default_rng(0), renew=False)
    first = CANDIDATES[7]
    mean = ensemble.predict_upright_probability(posterior.samples, first.configuration,
                                                (first.height_m, first.speed_mps, first.angle_deg))
    # (each member clipped to the floor, as log_likelihood clips them, before the mean: within the floor)
    assert np.allclose(posterior.probabilities[:, 7], mean, rtol=0.0, atol=learnt.PROBABILITY_FLOOR)
    alone = single.predict_upright_probability(posterior.samples, first.configuration,
                                               (first.height_m, first.speed_mps, first.angle_deg))
    assert np.abs(mean - alone).max() > 0.2   # the members disagree: the first alone is not the mean
    rng = np.random.default_rng(1)
    cells = [(c.configuration, c.height_m, c.speed_mps, c.angle_deg) for c in CANDIDATES[::5]]
    observations = simulate((0.3, 0.6), cells * 2, rng)
    for o in observations:
        index = posterior.candidate_index(LaunchCondition(o.configuration, o.height_m, o.speed_mps, o.angle_deg))
        posterior.observe_launch(index, o.upright, table.transformed(index, o.outcomes))
    u = UNKNOWNS.to_normalised(posterior.samples)
    expected = ensemble.log_likelihood(u, observations)
    assert np.allclose(posterior.log_weights - posterior.log_weights.max(), expected - expected.max(), atol=1e-9)
    members = np.array([ensemble.log_likelihood(u, observations, member=k) for k in range(2)])
    weights = np.exp(members - members.max(axis=0))
    weights /= weights.sum(axis=0)
    p = [1 / (1 + np.exp(-(8.0 * u[:, 0] - 4.0 + 1.0 - 0.5 + shift))) for shift in (0.0, 3.0)]   # "A", angle 0
    column = CANDIDATES.index(LaunchCondition("A", 0.75, 0.8, 0.0))
    floor = learnt.PROBABILITY_FLOOR
    assert np.allclose(posterior.probabilities[:, column],
                       weights[0] * np.clip(p[0], floor, 1 - floor) + weights[1] * np.clip(p[1], floor, 1 - floor))
    posterior.renew()
    renewed = ensemble.log_likelihood(UNKNOWNS.to_normalised(posterior.samples), observations)
    assert np.allclose(np.logaddexp.reduce(posterior.member_log_likelihood, axis=0) - np.log(2), renewed)


def test_renewals_keep_the_density_the_samples_were_drawn_from():
    """The adaptive plan's start from bench readings (``log_prior``, plan_comparison's ``start``): a renewal moves
    the samples on that density times the launches' likelihood; without it they spread back over the prior."""
    table = LearntTable(model(), CANDIDATES, ())   # verdicts only: they say nothing about b
    readings = lambda u: -0.5 * ((u[:, 1] - 0.2) / 0.03) ** 2   # noqa: E731  (a bench reading of b)
    start = np.column_stack([np.random.default_rng(2).uniform(size=400),
                             0.2 + 0.03 * np.random.default_rng(3).standard_normal(400).clip(-3, 3)])
    spreads = []
    for log_prior in (readings, None):
        posterior = OutcomePosterior(table, UNKNOWNS.to_values(start), np.random.default_rng(4), moves=20,
                                     log_prior=log_prior)
        posterior.renew()
        spreads.append(np.std(UNKNOWNS.to_normalised(posterior.samples)[:, 1]))
    assert spreads[0] == pytest.approx(0.03, rel=0.3) and spreads[1] > 0.06


class FakeGate:
    """A stand-in for likelihood_gate.GateModel without twin launches: the bare robot's reading at set speed v is
    v (0.9 + 0.2 b_u), scatter 0.02 v, with the gate term's shared table error (model_error x the reading)."""

    model_error = 0.004

    def __init__(self, candidates, shots=()):
        self.groups = sorted({(c.configuration, float(c.speed_mps)) for c in candidates
                              if c.configuration == "baseline"})
        self.speeds = np.array([v for _, v in self.groups])
        self.shots = tuple(shots)   # the launcher characterisation's readings, in their groups (GateModel's)

    def predict(self, u):
        mean = (0.9 + 0.2 * u[:, 1])[:, None] * self.speeds[None, :]
        return mean, np.full_like(mean, 0.02) * self.speeds[None, :]

    def term(self, observations):
        from rollability_ros.core.campaign import likelihood_gate

        observations = [*self.shots, *observations]

        def log_density(u):   # the exact term's Gaussian (shared error per group), through its own code path
            mean, sd = self.predict(u)
            total = np.zeros(len(u))
            for g, group in enumerate(self.groups):
                values = np.array([o.outcomes["measured_speed_mps"] for o in observations
                                   if (o.configuration, float(o.speed_mps)) == group])
                if len(values):
                    cov = sd[:, g, None, None] ** 2 * np.eye(len(values)) + (self.model_error * mean[:, g]) [
                        :, None, None] ** 2
                    r = values[None, :] - mean[:, g, None]
                    total += -0.5 * (np.einsum("si,sij,sj->s", r, np.linalg.inv(cov), r)
                                     + np.linalg.slogdet(cov)[1] + len(values) * math.log(2 * math.pi))
            return total
        assert likelihood_gate.GateModel.term   # the real model has the same interface
        return log_density


def test_the_gate_reading_enters_both_the_weights_and_the_choice_of_launch():
    """b moves only the gate's reading, which the verdict-only table does not weigh: with the gate's term the
    posterior weighs each reading (the weights are verdicts plus the term of all readings so far, renewed or not),
    the bare robot's launches score above the verdict-only BALD score, and 16 chosen launches pin b, which the
    verdicts leave at its prior width."""
    likelihood = model()
    candidates = CANDIDATES
    gate = FakeGate(candidates)
    table = LearntTable(likelihood, candidates, outcomes=())
    with pytest.raises(ValueError, match="twice"):
        OutcomePosterior(LearntTable(likelihood, candidates), UNKNOWNS.draw(10, np.random.default_rng(0)), gate=gate)
    plain = OutcomePosterior.from_prior(table, 300, np.random.default_rng(0), renew=False)
    with_gate = OutcomePosterior(table, plain.samples, np.random.default_rng(0), renew=False, gate=gate)
    bare = np.array([c.configuration == "baseline" for c in candidates])
    assert np.all(with_gate.scores()[bare] > plain.scores()[bare] + 0.5)
    assert np.allclose(with_gate.scores()[~bare], plain.scores()[~bare])
    about_b = with_gate.unknown_scores(1)   # the targeted score's: about b alone, which only the reading sees
    assert np.all(about_b[bare] > plain.unknown_scores(1)[bare] + 0.5)
    assert np.all(about_b[bare] <= with_gate.scores()[bare] + 0.05)   # about b: at most about both unknowns
    rng = np.random.default_rng(5)
    cells = [(c.configuration, c.height_m, c.speed_mps, c.angle_deg) for c in candidates[::3]]
    observations = simulate((0.7, 0.3), cells, rng)
    for o in observations:
        index = with_gate.candidate_index(LaunchCondition(o.configuration, o.height_m, o.speed_mps, o.angle_deg))
        reading = o.outcomes["measured_speed_mps"] if o.configuration == "baseline" else None
        with_gate.observe_launch(index, o.upright, None, reading)
    u = UNKNOWNS.to_normalised(with_gate.samples)
    expected = likelihood.log_likelihood(u, [dataclasses.replace(o, outcomes={}) for o in observations]) + gate.term(
        [o for o in observations if o.configuration == "baseline"])(u)
    assert np.allclose(with_gate.log_weights - with_gate.log_weights.max(), expected - expected.max(), atol=1e-6)
    renewed, verdicts = (OutcomePosterior.from_prior(table, 300, np.random.default_rng(1)) for _ in range(2))
    renewed.gate = gate
    for _ in range(16):
        for posterior in (renewed, verdicts):
            index = int(np.argmax(posterior.scores()))
            c = candidates[index]
            o, = simulate((0.7, 0.3), [(c.configuration, c.height_m, c.speed_mps, c.angle_deg)], rng)
            reading = o.outcomes["measured_speed_mps"] if posterior.gate and c.configuration == "baseline" else None
            posterior.observe_launch(index, o.upright, None, reading)
    assert renewed.renewals > 0
    assert renewed.normalised_widths()[1] < 0.25 < 0.8 < verdicts.normalised_widths()[1]
    low, high = renewed.intervals()[1]
    assert low <= UNKNOWNS.to_values([[0.7, 0.3]])[0, 1] <= high


def test_the_matrix_replicas_start_from_their_own_samples_and_measure_a_width_error():
    """plan_comparison.learnt_to_match_matrix with replicas: the two plans share the start samples (replica 0),
    each replica of the matrix's posterior asks for its own (replica 1, 2), and the widths' spread over them is
    the reported Monte Carlo error (positive: 60 samples cannot agree to the last digit)."""
    from rollability_ros.core.campaign.plan_comparison import learnt_to_match_matrix

    table = LearntTable(model(), CANDIDATES, ())
    asked = []

    def start(t, truth, replica):
        asked.append((t, replica))
        return table.unknowns.draw(60, np.random.default_rng([9, replica])), lambda u: np.zeros(len(u))
    _, (result,) = learnt_to_match_matrix(table, truths=1, matrix_launches=16, samples=60, seed=3, budget=16,
                                          start=start, replicas=2)
    assert asked == [(0, 0), (0, 1), (0, 2)]
    assert result.width_error.shape == (2,) and np.all(result.width_error > 0)
    assert np.all(result.tolerant_widths > result.width_error)
    assert 1 <= len(result.adaptive_launched) <= 16


def test_the_importance_sampled_widths_correct_for_their_proposal():
    """learnt_plan.importance_widths without launches: the target is the start density (a Gaussian in both
    normalised unknowns, sd 0.05: its 95 % width is 0.196), the proposal a kernel mixture over samples of another,
    wider and shifted Gaussian; the weights' division by the proposal's density brings the widths to the target's
    (without it they would be the proposal's, about 0.3)."""
    from rollability_ros.core.campaign.learnt_plan import KernelProposal, importance_widths

    table = LearntTable(model(), CANDIDATES, ())
    rng = np.random.default_rng(0)
    wide = UNKNOWNS.to_values((0.52 + 0.07 * rng.standard_normal((2000, 2))).clip(0.0, 1.0))
    proposal = KernelProposal(UNKNOWNS, [(wide, np.ones(len(wide)))], rng)
    start = lambda u: -0.5 * (((u - 0.5) / 0.05) ** 2).sum(axis=1)   # noqa: E731
    (widths, ess), = importance_widths(table, [[]], [[0]], proposal, rng, draws=8000, log_prior=start)
    assert widths.shape == (1, 2) and ess[0] > 1000
    assert widths[0] == pytest.approx([0.196, 0.196], rel=0.08)
    (plain, _), = importance_widths(table, [[]], [[0]], proposal, rng, draws=8000)   # the proposal's own widths
    assert np.all(plain[0] > 0.27)


def test_the_importance_sampled_widths_weigh_launches_and_readings_as_the_plan_does():
    """After launches (verdicts and the gate's readings), importance_widths at each checkpoint agrees with the
    plan's own posterior on the same launches (20,000 prior draws weighed, not renewed), and checkpoint 0 is the
    prior's 95 % width; the same draws serve two plans (the first plan's estimate is unchanged by the second)."""
    from rollability_ros.core.campaign.learnt_plan import KernelProposal, importance_widths

    table = LearntTable(model(), CANDIDATES, ())
    gate = FakeGate(CANDIDATES)
    rng = np.random.default_rng(7)
    cells = [(c.configuration, c.height_m, c.speed_mps, c.angle_deg) for c in CANDIDATES[::2]]
    launches = []
    for o in simulate((0.6, 0.4), cells, rng):
        index = CANDIDATES.index(LaunchCondition(o.configuration, o.height_m, o.speed_mps, o.angle_deg))
        reading = o.outcomes["measured_speed_mps"] if o.configuration == "baseline" else None
        launches.append((index, o.upright, None, reading))
    reference = OutcomePosterior(table, UNKNOWNS.draw(5000, np.random.default_rng(1)), renew=False, gate=gate)
    expected = {0: reference.normalised_widths()}
    for n, launch in enumerate(launches, 1):
        reference.observe_launch(*launch)
        if n in (6, len(launches)):
            expected[n] = reference.normalised_widths()
    sources = [(reference.samples, reference.weights), (UNKNOWNS.draw(500, rng), np.ones(500))]
    proposal = KernelProposal(UNKNOWNS, sources, np.random.default_rng(2))
    stops = sorted(expected)
    both = importance_widths(table, [launches, launches[:6]], [stops, [6]], proposal, np.random.default_rng(3),
                             draws=8000, gate=gate)
    (widths, ess), (again, _) = both
    assert expected[len(launches)][1] < 0.5 * expected[0][1]   # the readings narrowed b
    for row, n in zip(widths, stops):
        assert row == pytest.approx(expected[n], abs=0.04)
    assert again[0] == pytest.approx(widths[stops.index(6)])
    assert np.all(ess > 500)


def test_the_precise_comparison_runs_the_adaptive_plan_to_its_budget_and_counts_on_every_draw_set():
    """plan_comparison.learnt_to_match_matrix with ``precise``: the adaptive plan launches its whole budget (the
    widths are estimated afterwards), each draw set gives the matrix's widths and a count, the tolerance-aware
    count uses their spread, and first_truth skips truths without changing them."""
    from rollability_ros.core.campaign.plan_comparison import learnt_to_match_matrix

    table = LearntTable(model(), CANDIDATES, ())
    hidden, (result,) = learnt_to_match_matrix(table, truths=2, matrix_launches=16, samples=60, seed=3, budget=12,
                                               precise=2000, precise_sets=2, first_truth=1)
    assert len(result.adaptive_launched) == 12
    e = result.precise
    assert e.matrix_widths.shape == (2, 2) and len(e.launches) == 2 and e.adaptive_widths.shape == (2, 2)
    assert np.all(e.matrix_widths > 0) and np.all(e.matrix_widths < 1)
    assert all(count is None or 1 <= count <= 12 for count in e.launches)
    assert e.tolerant_launches is None or 1 <= e.tolerant_launches <= 12
    for tolerance, per_set in e.within:   # a tolerance can only bring the count forward
        assert all(n is None or c is None or n <= c for n, c in zip(per_set, e.launches)) and len(per_set) == 2
    assert len(e.per_unknown) == 2   # each unknown's own first crossing: none after the strict count (set 0)
    assert e.launches[0] is None or all(n is not None and n <= e.launches[0] for n in e.per_unknown)
    whole, _ = learnt_to_match_matrix(table, truths=2, matrix_launches=1, samples=60, seed=3, budget=1)
    assert np.allclose(hidden, whole)


def test_the_first_launch_under_the_allowed_widths():
    from rollability_ros.core.campaign.plan_comparison import first_launch

    widths = np.array([[0.3, 0.2], [0.2, 0.25], [0.1, 0.1]])
    assert first_launch(widths, np.array([0.25, 0.25])) == 2
    assert first_launch(widths, np.array([0.05, 0.5])) is None


def test_gate_shots_are_in_the_start_and_share_their_groups_with_the_plans_readings():
    """The launcher's characterisation (gate shots of the bare robot, in the gate model's ``shots``): a plan's
    samples are drawn from a density that holds their term, so it starts with equal weights and every reading then
    moves the weights by the term of shots and readings together less the shots' alone (never the shots twice);
    the next reading's predictive and the importance-sampled widths hold them before any launch."""
    from rollability_ros.core.campaign import likelihood_gate
    from rollability_ros.core.campaign.characterisation import GateShot
    from rollability_ros.core.campaign.learnt_plan import KernelProposal, importance_widths

    table = LearntTable(model(), CANDIDATES, ())
    rng = np.random.default_rng(21)
    truth_b = 0.3
    shots = likelihood_gate.shot_observations(
        [GateShot(v, v * (0.9 + 0.2 * truth_b) * (1 + 0.02 * rng.standard_normal())) for v in LEVELS.speeds_mps
         for _ in range(20)])
    gate, bare = FakeGate(CANDIDATES, shots), FakeGate(CANDIDATES)
    samples = UNKNOWNS.draw(2000, np.random.default_rng(2))
    with_shots = OutcomePosterior(table, samples, np.random.default_rng(0), renew=False, gate=gate)
    without = OutcomePosterior(table, samples, np.random.default_rng(0), renew=False, gate=bare)
    assert np.all(with_shots.log_weights == 0.0)
    assert np.all(with_shots._gate_predictive()[1] < without._gate_predictive()[1])   # the shared error learnt
    cells = [(c.configuration, c.height_m, c.speed_mps, c.angle_deg) for c in CANDIDATES[::4]]
    observations = simulate((0.7, truth_b), cells, rng)
    readings = []
    for o in observations:
        index = with_shots.candidate_index(LaunchCondition(o.configuration, o.height_m, o.speed_mps, o.angle_deg))
        reading = o.outcomes["measured_speed_mps"] if o.configuration == "baseline" else None
        with_shots.observe_launch(index, o.upright, None, reading)
        readings += [o] if reading is not None else []
    assert readings
    u = UNKNOWNS.to_normalised(samples)
    expected = (model().log_likelihood(u, [dataclasses.replace(o, outcomes={}) for o in observations])
                + gate.term(readings)(u) - gate.term([])(u))
    assert np.allclose(with_shots.log_weights - with_shots.log_weights.max(), expected - expected.max(), atol=1e-6)
    sources = [(samples, np.ones(len(samples)))]
    (shot_widths, _), = importance_widths(table, [[]], [[0]], KernelProposal(UNKNOWNS, sources, rng), rng, 2000,
                                          gate=gate)
    (prior_widths, _), = importance_widths(table, [[]], [[0]], KernelProposal(UNKNOWNS, sources, rng), rng, 2000,
                                           gate=bare)
    assert shot_widths[0, 1] < 0.3 * prior_widths[0, 1] and prior_widths[0, 1] > 0.8
