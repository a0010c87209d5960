"""Which launch next from a learnt likelihood, with the continuous outcomes (issue 44.2 and 44.4).

A prepared likelihood (:mod:`~rollability_ros.core.campaign.likelihood`) predicts more than P(upright): per launch
it gives each continuous outcome the rig measures (the gate's speed, the IMU's final tilt, peak deceleration and
time to rest, the operator's tape) a Student-t given the unknowns, the configuration, the condition and the verdict.
:class:`LearntTable` evaluates those predictions of a set of samples of the unknowns at every candidate condition
at once; :class:`OutcomePosterior` is the adaptive plan's :class:`~rollability_ros.core.campaign.adaptive.
WeightedPosterior` over them:

- each launch weighs the samples by its whole likelihood, log P(verdict) plus the log densities of the outcomes it
  measured (a missing one, NaN, adds nothing), exactly as the calibration's posterior does
  (``LearntLikelihood.log_likelihood``; a test holds the two equal);
- the expected information of a candidate launch about the unknowns, I(y; theta) with y = (verdict, outcomes),
  has no closed form for a Student-t mixture, so it is estimated by nested Monte Carlo with common random numbers
  across the candidates (:meth:`OutcomePosterior.scores`): ``draws`` outcomes y_m from the predictive (a sample
  theta_m by weight, a verdict, then the outcomes), I ~ mean_m [log p(y_m | theta_m) - log sum_s w_s p(y_m |
  theta_s)]. With ``outcomes=()`` it is the verdict's BALD score, exact;
- the samples are renewed as the posterior narrows (resample by weight, Metropolis moves on the prior times the
  likelihood of every launch seen), since a learnt likelihood is cheap to ask again;
- the speed gate's readings, where given (``gate``: the exact term of
  :mod:`~rollability_ros.core.campaign.likelihood_gate`, whose readings share the table's error per configuration
  and set speed, so the term is rebuilt from all readings rather than multiplied per launch), weigh the samples
  beside the learnt likelihood, as in the calibration's ``--gate``; the learnt table must then not weigh the same
  reading (``outcomes`` without ``measured_speed_mps``). The gate's ``shots`` (the launcher's characterisation:
  bare-robot shots on the bench) join their set speed's group; the samples are then taken to be drawn from a
  density that holds their term (the start of both plans: bench_adaptive_plan.py's ``--gate-shots``);
- the ensemble (``LearntLikelihood.ensemble_size`` members) enters as the calibration's does: a sample's weight is
  the members' mean likelihood of every launch seen (``log_likelihood(member=None)``; a test holds the two equal),
  and its prediction of the next launch is the members' mixture weighted by how well each member explained the
  launches seen at that sample (equal weights before any launch: the members' mean). The score is the information
  about the unknowns, I(y; theta), with the member marginalised at every theta; not BALD over (theta, member),
  whose extra term I(y; member | theta) is information about which network is right: it would send the rig to
  where the emulator is unsure, an experiment on the emulator, not on the rig. Where the members disagree the
  launch's outcome is less predictable at every theta, so it teaches less about the unknowns and scores lower.

numpy only (the likelihood's networks are plain arrays).
"""
import math
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core.campaign import likelihood as learnt
from rollability_ros.core.campaign.adaptive import EPSILON, Unknowns, WeightedPosterior
from rollability_ros.core.optional import require
from rollability_ros.core.records import LaunchCondition, LaunchOutcome

if typing.TYPE_CHECKING:
    from rollability_ros.core.campaign.likelihood_gate import GateModel

#: A log density (s,) of normalised unknowns (s, d).
LogDensity = typing.Callable[[np.ndarray], np.ndarray]
#: Monte Carlo (verdict, reading) pairs per candidate of the gate's expected information (:meth:`OutcomePosterior.
#: scores`), the same random numbers for every candidate.
GATE_DRAWS = 256

#: Samples of the unknowns evaluated per network pass (bounds the memory of a table: samples x conditions x 64).
CHUNK = 256


class LearntTable:
    """A learnt likelihood's predictions at ``candidates``: P(upright) (s, c) and, per continuous outcome of
    ``outcomes`` (default: every one the likelihood has learnt), the Student-t's location and scale on the
    transformed scale (s, c, 2, k), verdict slot 0 upright, 1 not. The candidates must be configurations and
    levels the likelihood was learnt on (``ValueError`` naming the first that is not)."""

    def __init__(self, likelihood: learnt.LearntLikelihood, candidates: typing.Sequence[LaunchCondition],
                 outcomes: typing.Optional[typing.Sequence[str]] = None) -> None:
        self.likelihood = likelihood
        self.candidates = list(candidates)
        wanted = learnt.OUTCOMES if outcomes is None else tuple(outcomes)
        unknown = [name for name in wanted if name not in learnt.OUTCOMES]
        if unknown:
            raise ValueError(f"unknown outcome {unknown[0]!r} (known: {', '.join(learnt.OUTCOMES)})")
        self.outcomes = tuple(name for name in wanted if name in likelihood.location)
        d = len(likelihood.unknowns.names)
        zeros = np.zeros((1, d))
        self._rest = np.array([likelihood.features(zeros, c.configuration, c.height_m, c.speed_mps, c.angle_deg)[0, d:]
                               for c in self.candidates]).reshape(len(self.candidates), -1)
        self.set_speeds = np.array([c.speed_mps for c in self.candidates])

    @property
    def unknowns(self) -> Unknowns:
        return self.likelihood.unknowns

    def _theta(self, theta: npt.ArrayLike) -> np.ndarray:
        u = self.unknowns.to_normalised(np.atleast_2d(np.asarray(theta, dtype=np.float64)))
        d = u.shape[1]
        return (u - self.likelihood.feature_mean[:d]) / self.likelihood.feature_std[:d]

    @property
    def members(self) -> int:
        """The ensemble's members (K)."""
        return self.likelihood.ensemble_size

    def predict(self, theta: npt.ArrayLike, columns: typing.Optional[typing.Sequence[int]] = None
                ) -> typing.Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each ensemble member's prediction for parameter sets ``theta`` (s, d) (own units) at the candidates
        ``columns`` (default all): ``(p (K, s, c), location (K, s, c, 2, k), scale (s, c, 2, k))`` (the members
        share their scales: ``likelihood.Member``)."""
        index = np.arange(len(self.candidates)) if columns is None else np.asarray(columns, dtype=int)
        standard = self._theta(theta)
        rest = self._rest[index]
        verdict = np.concatenate([np.repeat(rest, 2, axis=0), np.tile([[1.0], [-1.0]], (len(rest), 1))], axis=1)
        s, c, k = len(standard), len(index), len(self.outcomes)
        p = np.empty((self.members, s, c))  # filled by _fill
        location, scale = np.empty((self.members, s, c, 2, k)), np.empty((s, c, 2, k))
        with _one_blas_thread():
            for member in range(self.members):
                self._fill(member, standard, rest, verdict, p[member], location[member], scale)
        return p, location, scale

    def _fill(self, member: int, standard: np.ndarray, rest: np.ndarray, verdict: np.ndarray, p: np.ndarray,
              location: np.ndarray, scale: np.ndarray) -> None:
        likelihood = self.likelihood   # its own forward pass (a test holds the weights equal to its log_likelihood)
        networks = likelihood.member(member)
        s, c = p.shape
        for start in range(0, s, CHUNK):
            part = slice(start, start + CHUNK)
            logit = likelihood.upright_logit(networks, standard[part], rest)
            p[part] = np.clip(1.0 / (1.0 + np.exp(-logit)), learnt.PROBABILITY_FLOOR, 1.0 - learnt.PROBABILITY_FLOOR)
            for j, name in enumerate(self.outcomes):
                mean, spread = likelihood.outcome_distribution(networks, name, standard[part], verdict)
                location[part, :, :, j], scale[part, :, :, j] = mean.reshape(-1, c, 2), spread.reshape(-1, c, 2)

    def probabilities(self, theta: np.ndarray, conditions: typing.Sequence[LaunchCondition]) -> np.ndarray:
        """P(upright) (s, c) at ``conditions``, the members' mean as ``LearntLikelihood.predict_upright_probability``
        (the :class:`~rollability_ros.core.campaign.adaptive.UprightPredictor` interface; each must be a
        candidate)."""
        keys = {c.group_key: i for i, c in enumerate(self.candidates)}
        missing = [c for c in conditions if c.group_key not in keys]
        if missing:
            raise ValueError(f"{missing[0].configuration} at {missing[0].height_m:g} m, {missing[0].speed_mps:g} m/s, "
                             f"{missing[0].angle_deg:+g} deg is not a candidate condition")
        return self.predict(theta, [keys[c.group_key] for c in conditions])[0].mean(axis=0)

    def transformed(self, index: int, values: typing.Mapping[str, float]) -> np.ndarray:
        """The outcomes (k,) of one launch at candidate ``index`` on their Student-t's scale, NaN where not measured
        (``values``: own units by name, as ``Observation.outcomes``)."""
        return np.array([float(learnt.transform(name, values.get(name, math.nan), self.set_speeds[index]))
                         for name in self.outcomes])

    def draw(self, theta: npt.ArrayLike, index: int, rng: np.random.Generator) -> typing.Tuple[bool, np.ndarray]:
        """One simulated launch at candidate ``index`` under one parameter set ``theta`` (d,): the verdict and the
        transformed outcomes (k,), drawn from the learnt model (a hidden truth's launches in the plan comparison):
        from a member drawn at random, so the verdict's probability is the members' mean."""
        p, location, scale = self.predict(np.atleast_2d(theta), [index])
        member = int(rng.integers(self.members))
        upright = bool(rng.random() < p[member, 0, 0])
        slot = 0 if upright else 1
        values = (location[member, 0, 0, slot]
                  + scale[0, 0, slot] * rng.standard_t(learnt.STUDENT_DF, len(self.outcomes)))
        return upright, values


def _one_blas_thread() -> typing.ContextManager[typing.Any]:
    """One BLAS thread for the networks' small matrices (threads only contend on them: posterior.py measured it)."""
    import contextlib

    try:
        return typing.cast(typing.ContextManager[typing.Any], require("threadpoolctl").threadpool_limits(1))
    except ImportError:
        return contextlib.nullcontext()


class OutcomePosterior(WeightedPosterior):
    """The adaptive plan's weighted samples over a learnt likelihood's verdicts and continuous outcomes (module
    docstring). ``samples``: prior draws (n, d), own units, of the likelihood's unknowns (times ``log_prior``'s
    density, and the term of ``gate``'s shots where it has any); ``draws``: the Monte Carlo
    outcomes per candidate of :meth:`scores`; ``renew``: renew the samples as the posterior narrows.

    Per sample and ensemble member it keeps the log-likelihood of every launch seen (``member_log_likelihood``
    (K, n)); a sample's weight is their mean (the calibration's ``log_likelihood(member=None)``), and
    :attr:`probabilities` (n, c), which the verdict's scores, the design comparison and the proposal read, are the
    members' predictions weighted by those likelihoods at each sample (the predictive given the launches seen)."""

    def __init__(self, table: LearntTable, samples: npt.ArrayLike, rng: typing.Optional[np.random.Generator] = None,
                 renew: bool = True, draws: int = 32, renew_fraction: float = 0.5, moves: int = 4,
                 log_prior: typing.Optional[typing.Callable[[np.ndarray], np.ndarray]] = None,
                 gate: typing.Optional["GateModel"] = None) -> None:
        if gate is not None and "measured_speed_mps" in table.outcomes:
            raise ValueError("the gate's term and the learnt measured_speed_mps would weigh the same reading twice")
        self.table = table
        self.draws = draws
        #: the speed gate's term from the readings so far (module docstring), and its log density at the samples
        self.gate = gate
        self._readings: typing.List[learnt.Observation] = []
        self._gate_term: typing.Optional[LogDensity] = None
        #: log density (n,) of normalised unknowns (n, d) the samples were drawn from, beside the uniform prior
        #: (the characterisation's readings: ``posterior.characterisation_term``); the renewal's moves target it
        #: times the launches' likelihood
        self.log_prior = log_prior
        self._seen: typing.List[typing.Tuple[int, bool, np.ndarray]] = []
        theta = np.asarray(samples, dtype=np.float64)
        self._member_p, self._location, self._scale = table.predict(theta)
        self.member_log_likelihood = np.zeros((table.members, len(theta)))
        self._gate_log_likelihood = np.zeros(len(theta))
        super().__init__(table.unknowns, theta, table.candidates, self._member_p.mean(axis=0),
                         table if renew else None, rng, renew_fraction, moves)
        if gate is not None and gate.shots:   # the launcher's shots: in the density the samples were drawn from
            self._gate_term = gate.term([])
            self._gate_log_likelihood = self._gate_term(self.unknowns.to_normalised(theta))

    @classmethod
    def from_prior(cls, table: LearntTable, samples: int, rng: np.random.Generator, renew: bool = True,
                   draws: int = 32) -> "OutcomePosterior":
        """``samples`` prior draws of the likelihood's unknowns (uniform on each one's search scale)."""
        return cls(table, table.unknowns.draw(samples, rng), rng, renew, draws)

    @property
    def member_weights(self) -> np.ndarray:
        """P(member | launches seen, sample) (K, n): each member's likelihood of the launches seen at each sample,
        normalised over the members (uniform before any launch)."""
        ll = self.member_log_likelihood
        w = np.exp(ll - ll.max(axis=0))
        return w / w.sum(axis=0)

    def _mix(self) -> None:
        """:attr:`probabilities` (n, c): the members' P(upright) weighted by :attr:`member_weights`."""
        self._set_samples(self.samples, np.einsum("kn,knc->nc", self.member_weights, self._member_p))

    @staticmethod
    def _launch_log_likelihood(p: np.ndarray, location: np.ndarray, scale: np.ndarray, column: int,
                               upright: bool, values: np.ndarray) -> np.ndarray:
        """log p(verdict, outcomes) (K, n) under each member of one launch at table column ``column`` (``p``
        (K, n, c), ``location`` (K, n, c, 2, k), ``scale`` (n, c, 2, k): :meth:`LearntTable.predict`)."""
        slot = 0 if upright else 1
        verdict = np.log(np.clip(p[:, :, column] if upright else 1.0 - p[:, :, column], EPSILON, 1.0))
        density = learnt.measured_log_density(values[None, None, :], location[:, :, column, slot],
                                              scale[None, :, column, slot])
        return verdict + density.sum(axis=2)

    def observe_launch(self, index: int, upright: bool, values: typing.Optional[npt.ArrayLike] = None,
                       reading: typing.Optional[float] = None) -> None:
        """Weigh the samples by one launch at candidate ``index``: its verdict and its transformed outcomes
        ``values`` (k,) (NaN or None: not measured; :meth:`LearntTable.transformed` makes them), and the speed
        gate's ``reading`` (m/s; None or NaN: not read) through :attr:`gate`'s term."""
        v = np.full(len(self.table.outcomes), np.nan) if values is None else np.asarray(values, dtype=np.float64)
        before = np.logaddexp.reduce(self.member_log_likelihood, axis=0)
        self.member_log_likelihood += self._launch_log_likelihood(self._member_p, self._location, self._scale, index,
                                                                  bool(upright), v)
        self.log_weights += np.logaddexp.reduce(self.member_log_likelihood, axis=0) - before
        if reading is not None and math.isfinite(reading):
            if self.gate is None:
                raise ValueError("a speed gate reading needs the posterior's gate term (gate=)")
            c = self.candidates[index]
            self._readings.append(learnt.Observation(c.configuration, c.height_m, c.speed_mps, c.angle_deg,
                                                     bool(upright), {"measured_speed_mps": float(reading)}))
            self._gate_term = self.gate.term(self._readings)
            now = self._gate_term(self.unknowns.to_normalised(self.samples))
            self.log_weights += now - self._gate_log_likelihood
            self._gate_log_likelihood = now
        self._mix()
        self._seen.append((index, bool(upright), v))
        self._successes[index] += bool(upright)
        self._trials[index] += 1
        self.launches += 1
        self._after_observing()

    def observe(self, index: int, upright: bool) -> None:
        """A launch whose verdict only is known."""
        self.observe_launch(index, upright)

    def observe_counts(self, index: int, successes: int, trials: int) -> None:
        """``successes`` upright of ``trials`` launches at candidate ``index``, verdicts only."""
        if not 0 <= successes <= trials:
            raise ValueError(f"need 0 <= successes <= trials, got {successes} of {trials}")
        for i in range(trials):
            self.observe_launch(index, i < successes)

    def observe_outcomes(self, outcomes: typing.Iterable[LaunchOutcome]) -> int:
        """Weigh by every valid outcome at a candidate condition with the continuous outcomes its record carries
        (``likelihood.observations_from_outcomes``: the gate's speed, the IMU's tilt, ...); returns how many were
        used (invalid launches and conditions off the candidates are left out)."""
        used = 0
        for outcome in outcomes:
            if not (outcome.valid and outcome.condition.group_key in self._index):
                continue
            observation, = learnt.observations_from_outcomes([outcome])
            index = self._index[outcome.condition.group_key]
            self.observe_launch(index, observation.upright, self.table.transformed(index, observation.outcomes))
            used += 1
        return used

    def _seen_log_likelihood(self, theta: np.ndarray) -> np.ndarray:
        """log p(every launch seen) (K, n) under each member of parameter sets ``theta`` (n, d), from their
        predictions at the seen candidates only."""
        columns = sorted({index for index, _, _ in self._seen})
        total = np.zeros((self.table.members, len(theta)))
        if not columns:
            return total
        where = {index: i for i, index in enumerate(columns)}
        p, location, scale = self.table.predict(theta, columns)
        for index, upright, values in self._seen:
            total += self._launch_log_likelihood(p, location, scale, where[index], upright, values)
        return total

    def renew(self) -> None:
        """Resample by weight, ``moves`` Metropolis steps each on the prior (times :attr:`log_prior`'s density) times
        the members' mean likelihood of every launch seen (verdicts and outcomes), then the new samples' predictions
        at every candidate."""
        n, d = self.samples.shape
        w = self.weights
        picks = np.minimum(np.searchsorted(np.cumsum(w), (self.rng.random() + np.arange(n)) / n), n - 1)
        u = self.unknowns.to_normalised(self.samples[picks])
        members = self.member_log_likelihood[:, picks]
        start = (lambda x: np.zeros(len(x))) if self.log_prior is None else self.log_prior
        gate = self._gate_term
        prior = start if gate is None else (lambda x: start(x) + gate(x))   # the readings' term moves with the samples
        log_likelihood = np.logaddexp.reduce(members, axis=0)
        log_prior = prior(u)
        step = np.maximum(np.sqrt(np.cov(u, rowvar=False).reshape(d, d).diagonal()), 1e-3) * 2.38 / math.sqrt(d)
        for _ in range(self.moves):
            proposed = u + self.rng.normal(0.0, 1.0, u.shape) * step
            inside = np.all((proposed >= 0.0) & (proposed <= 1.0), axis=1)
            new_members = self._seen_log_likelihood(self.unknowns.to_values(np.clip(proposed, 0.0, 1.0)))
            log_new, prior_new = np.logaddexp.reduce(new_members, axis=0), prior(np.clip(proposed, 0.0, 1.0))
            accept = inside & (np.log(self.rng.random(n)) < log_new + prior_new - log_likelihood - log_prior)
            u[accept], log_likelihood[accept], log_prior[accept] = proposed[accept], log_new[accept], prior_new[accept]
            members[:, accept] = new_members[:, accept]
        theta = self.unknowns.to_values(u)
        self._member_p, self._location, self._scale = self.table.predict(theta)
        self.member_log_likelihood = members
        self._gate_log_likelihood = np.zeros(n) if gate is None else gate(u)
        self._set_samples(theta, np.einsum("kn,knc->nc", self.member_weights, self._member_p))
        self.log_weights = np.zeros(n)
        self.renewals += 1

    def scores(self) -> np.ndarray:
        """Expected information (nats) about the unknowns of a launch at each candidate (c,), verdict and outcomes
        (module docstring); the exact BALD score of the members' mixture when the table has no continuous
        outcome."""
        scores = super().scores() if not self.table.outcomes else self._estimated_scores(None)
        return scores if self.gate is None else self._with_gate(scores)

    def _gate_predictive(self) -> typing.Tuple[np.ndarray, np.ndarray]:
        """The next reading's Gaussian at each sample and weighed group given the readings so far (the group's
        shared table error conditioned on them): mean, variance (n, g) of :attr:`gate`'s groups."""
        assert self.gate is not None and self.gate.predict is not None
        mean, sd = self.gate.predict(self.unknowns.to_normalised(self.samples))
        count, total = np.zeros(len(self.gate.groups)), np.zeros(len(self.gate.groups))
        where = {g: i for i, g in enumerate(self.gate.groups)}
        for o in (*self.gate.shots, *self._readings):   # the shots share their groups' error
            i = where.get((o.configuration, float(o.speed_mps)))
            if i is not None:
                count[i] += 1
                total[i] += o.outcomes["measured_speed_mps"]
        shared, variance = (self.gate.model_error * mean) ** 2, sd ** 2
        gain = count * shared / (variance + count * shared)   # the shared error's posterior, per reading seen
        average = np.where(count > 0, total / np.maximum(count, 1.0), mean)
        return mean + gain * (average - mean), variance + shared * (1.0 - gain)

    def _with_gate(self, scores: np.ndarray, groups: typing.Optional[np.ndarray] = None) -> np.ndarray:
        """``scores`` with the candidates whose reading :attr:`gate` weighs scored by the information of verdict and
        reading together, I((verdict, reading); theta) (``groups`` (n,): about the sample's group instead, as
        :meth:`group_scores`), by nested Monte Carlo (:data:`GATE_DRAWS`; the verdict and the reading independent
        given theta, as the posterior weighs them)."""
        assert self.gate is not None
        where = {g: i for i, g in enumerate(self.gate.groups)}
        columns = [(c, where[(k.configuration, float(k.speed_mps))]) for c, k in enumerate(self.candidates)
                   if (k.configuration, float(k.speed_mps)) in where]
        if not columns:
            return scores
        mean, variance = self._gate_predictive()
        w = self.weights
        log_w = np.log(np.maximum(w, 1e-300))
        rng = np.random.default_rng([self.launches, self.renewals, 11])
        m = GATE_DRAWS
        picks = np.minimum(np.searchsorted(np.cumsum(w), (rng.random() + np.arange(m)) / m), len(w) - 1)
        uniform, z = rng.random(m), rng.standard_normal(m)
        mass = None if groups is None else np.array([w[groups == groups[i]].sum() for i in picks])
        out = scores.copy()
        for c, g in columns:
            upright = uniform < self.probabilities[picks, c]                                     # (m,)
            y = mean[picks, g] + np.sqrt(variance[picks, g]) * z
            verdict = np.where(upright[:, None], self._log_p[None, :, c], self._log_q[None, :, c])   # (m, n)
            log_f = verdict - 0.5 * ((y[:, None] - mean[None, :, g]) ** 2 / variance[None, :, g]
                                     + np.log(2.0 * math.pi * variance[None, :, g]))
            joint = log_f + log_w[None, :]
            top = joint.max(axis=1)
            mixture = top + np.log(np.exp(joint - top[:, None]).sum(axis=1))   # log-sum-exp, faster than a reduce
            if groups is None:
                conditional = log_f[np.arange(m), picks]
            else:   # the group's weighted mixture: log sum_{s in g} w_s f(y | s) - log w(g)
                assert mass is not None
                same = groups[None, :] == groups[picks][:, None]
                inside = np.where(same, np.exp(joint - top[:, None]), 0.0).sum(axis=1)
                conditional = top + np.log(np.maximum(inside, 1e-300)) - np.log(mass)
            out[c] = max(float(np.mean(conditional - mixture)), 0.0)
        return out

    def group_scores(self, groups: npt.ArrayLike) -> np.ndarray:
        """:meth:`WeightedPosterior.group_scores` over verdict and outcomes (estimated as :meth:`scores`): ``groups``
        (s,), one group per sample; scores (c,), one per candidate."""
        scores = super().group_scores(groups) if not self.table.outcomes else self._estimated_scores(np.asarray(groups))
        return scores if self.gate is None else self._with_gate(scores, np.asarray(groups))

    def _estimated_scores(self, groups: typing.Optional[np.ndarray]) -> np.ndarray:
        """I(y; group of theta) (c,) by nested Monte Carlo; ``groups`` None: each sample its own group (I(y; theta)):
        mean_m [log p(y_m | g_m) - log p(y_m)], p(y | g) the group's weighted mixture, p(y | theta) the members'
        mixture by :attr:`member_weights`."""
        w = self.weights
        log_w = np.log(np.maximum(w, 1e-300))
        log_members = np.log(np.maximum(self.member_weights, 1e-300))                           # (K, n)
        rng = np.random.default_rng([self.launches, self.renewals, 7])   # common numbers across the candidates
        m = self.draws
        picks = np.minimum(np.searchsorted(np.cumsum(w), (rng.random() + np.arange(m)) / m), len(w) - 1)
        member_cdf = np.cumsum(self.member_weights[:, picks], axis=0)                           # (K, m)
        drawn = np.minimum((rng.random(m)[None, :] > member_cdf).sum(axis=0), self.table.members - 1)
        uniform = rng.random(m)
        noise = rng.standard_t(learnt.STUDENT_DF, (m, len(self.table.outcomes)))
        scores = np.empty(len(self.candidates))
        log_p, log_q = np.log(self._member_p), np.log1p(-self._member_p)                          # (K, n, c)
        for c in range(len(self.candidates)):
            upright = uniform < self._member_p[drawn, picks, c]                                  # (m,)
            slot = np.where(upright, 0, 1)
            y = self._location[drawn, picks, c, slot] + self._scale[picks, c, slot] * noise      # (m, k)
            verdict = np.where(upright[None, :, None], log_p[:, None, :, c], log_q[:, None, :, c])   # (K, m, n)
            location = self._location[:, :, c][:, :, slot].transpose(0, 2, 1, 3)               # (K, m, n, k)
            scale = self._scale[:, c][:, slot].transpose(1, 0, 2)                                # (m, n, k)
            density = learnt.measured_log_density(y[None, :, None, :], location, scale[None]).sum(axis=3)
            log_f = np.logaddexp.reduce(log_members[:, None, :] + verdict + density, axis=0)     # (m, n)
            mixture = np.logaddexp.reduce(log_f + log_w[None, :], axis=1)
            if groups is None:
                conditional = log_f[np.arange(m), picks]
            else:
                same = groups[None, :] == groups[picks][:, None]                                  # (m, n)
                weighted = np.where(same, log_f + log_w[None, :], -np.inf)
                mass = np.array([w[groups == groups[i]].sum() for i in picks])
                conditional = np.logaddexp.reduce(weighted, axis=1) - np.log(mass)
            scores[c] = float(np.mean(conditional - mixture))
        return np.maximum(scores, 0.0)


#: Draws of the importance-sampling width estimate (:func:`importance_widths`), and the kernel proposal's
#: bandwidth: each source's kernel covariance is ``KERNEL_SCALE`` squared x that source's weighted covariance.
WIDTH_DRAWS, KERNEL_SCALE = 8000, 0.5
#: Kernel centres drawn (by weight) from each source of the proposal.
KERNEL_CENTRES = 400

#: One launch of a plan as the width estimate replays it: (candidate index, upright, transformed outcomes (k,) or
#: None, the speed gate's reading in m/s or None).
Launch = typing.Tuple[int, bool, typing.Optional[np.ndarray], typing.Optional[float]]


class KernelProposal:
    """A mixture of Gaussian kernels over normalised unknowns, equal weight per source: each source (samples (n, d)
    own units, weights (n,)) gives :data:`KERNEL_CENTRES` centres drawn by weight and one kernel covariance,
    ``scale`` squared x its weighted covariance (a floor of 1e-4 of the range per unknown). Its density is known
    exactly, so self-normalised importance weights against it are unbiased in the limit."""

    def __init__(self, unknowns: Unknowns, sources: typing.Sequence[typing.Tuple[np.ndarray, np.ndarray]],
                 rng: np.random.Generator, scale: float = KERNEL_SCALE, centres: int = KERNEL_CENTRES) -> None:
        if not sources:
            raise ValueError("the kernel proposal needs at least one source of samples")
        self.parts = []
        for samples, weights in sources:
            u = unknowns.to_normalised(np.atleast_2d(samples))
            w = np.asarray(weights, dtype=np.float64) / np.sum(weights)
            mean = w @ u
            covariance = (u - mean).T @ ((u - mean) * w[:, None]) * scale ** 2
            covariance += np.eye(u.shape[1]) * 1e-8
            picks = np.minimum(np.searchsorted(np.cumsum(w), (rng.random() + np.arange(centres)) / centres), len(w) - 1)
            cholesky = np.linalg.cholesky(covariance)
            inverse = np.linalg.inv(cholesky)
            log_norm = -np.log(np.diag(cholesky)).sum() - 0.5 * u.shape[1] * math.log(2.0 * math.pi)
            self.parts.append((u[picks], cholesky, inverse, log_norm))

    def draw(self, count: int, rng: np.random.Generator) -> np.ndarray:
        """``count`` draws (count, d) of normalised unknowns (not clipped to the prior's bounds)."""
        source = rng.integers(len(self.parts), size=count)
        out = np.empty((count, self.parts[0][0].shape[1]))
        for s, (centres, cholesky, _, _) in enumerate(self.parts):
            mine = np.flatnonzero(source == s)
            start = centres[rng.integers(len(centres), size=len(mine))]
            out[mine] = start + rng.standard_normal(start.shape) @ cholesky.T
        return out

    def log_density(self, u: np.ndarray) -> np.ndarray:
        """log q(u) (n,) of normalised unknowns ``u`` (n, d)."""
        per_source = []
        for centres, _, inverse, log_norm in self.parts:
            x, c = u @ inverse.T, centres @ inverse.T
            squared = (x * x).sum(axis=1)[:, None] + (c * c).sum(axis=1)[None, :] - 2.0 * x @ c.T
            per_source.append(np.logaddexp.reduce(-0.5 * np.maximum(squared, 0.0), axis=1) + log_norm
                              - math.log(len(centres)))
        return np.logaddexp.reduce(np.array(per_source), axis=0) - math.log(len(self.parts))


def importance_widths(table: LearntTable, plans: typing.Sequence[typing.Sequence[Launch]],
                      checkpoints: typing.Sequence[typing.Sequence[int]], proposal: KernelProposal,
                      rng: np.random.Generator, draws: int = WIDTH_DRAWS,
                      log_prior: typing.Optional[LogDensity] = None, gate: typing.Optional["GateModel"] = None,
                      level: float = 0.95) -> typing.List[typing.Tuple[np.ndarray, np.ndarray]]:
    """The unknowns' equal-tailed ``level`` widths (fractions of each range on its search scale) after the first
    n launches of each plan of ``plans``, for each n of its ``checkpoints``, by self-normalised importance sampling:
    ``draws`` draws from ``proposal``, each weighed by the posterior :class:`OutcomePosterior` targets (the uniform
    prior on the bounds, ``log_prior``'s density, the members' mean likelihood of the launches, ``gate``'s term of
    their readings) over the proposal's density. The same draws serve every plan and checkpoint (common random
    numbers: the comparison of two plans' widths does not carry two independent samplers' errors), and many more
    of them than a plan's renewed samples (the Monte Carlo error of a width: docs/calibration.md). Returns, per
    plan, the widths (m, d) and the importance weights' effective sample sizes (m,) at its m checkpoints."""
    u = proposal.draw(draws, rng)
    inside = np.all((u >= 0.0) & (u <= 1.0), axis=1)
    clipped = np.clip(u, 0.0, 1.0)
    base = np.where(inside, -proposal.log_density(u), -np.inf)
    if log_prior is not None:
        base = base + np.where(inside, log_prior(clipped), 0.0)
    columns = sorted({launch[0] for plan in plans for launch in plan})
    where = {index: i for i, index in enumerate(columns)}
    if columns:
        p, location, scale = table.predict(table.unknowns.to_values(clipped), columns)
    weigh_readings = None   # the gate's term of a plan's readings so far, at every draw
    if gate is not None and gate.predict is not None:
        from rollability_ros.core.campaign.likelihood_gate import groups_log_density

        predicted, groups, model_error = gate.predict(clipped), gate.groups, gate.model_error

        def weigh_readings(observations: typing.Sequence[learnt.Observation]) -> np.ndarray:
            """The gate's log-density (draws,) of the readings of ``observations``; 0 outside the bounds."""
            return np.where(inside, groups_log_density(groups, predicted, observations, model_error), 0.0)
    order = np.argsort(u, axis=0, kind="stable")
    tail = (1.0 - level) / 2.0
    results = []
    for plan, stops in zip(plans, checkpoints):
        wanted = sorted(set(int(n) for n in stops))
        if wanted and (wanted[0] < 0 or wanted[-1] > len(plan)):
            raise ValueError(f"checkpoints must lie in 0..{len(plan)} launches")
        total = np.zeros((table.members, draws))
        observations: typing.List[learnt.Observation] = []
        found: typing.Dict[int, typing.Tuple[np.ndarray, float]] = {}
        for n in range(len(plan) + 1):
            if n > 0:
                index, upright, values, reading = plan[n - 1]
                v = np.full(len(table.outcomes), np.nan) if values is None else np.asarray(values, dtype=np.float64)
                total += OutcomePosterior._launch_log_likelihood(p, location, scale, where[index], bool(upright), v)
                if reading is not None and math.isfinite(reading):
                    c = table.candidates[index]
                    observations.append(learnt.Observation(c.configuration, c.height_m, c.speed_mps, c.angle_deg,
                                                           bool(upright), {"measured_speed_mps": float(reading)}))
            if n not in wanted:
                continue
            log_w = base + np.logaddexp.reduce(total, axis=0)
            if weigh_readings is not None and (observations or gate is not None and gate.shots):
                log_w = log_w + weigh_readings([*(gate.shots if gate is not None else ()), *observations])
            w = np.exp(log_w - log_w.max())
            w /= w.sum()
            widths = np.empty(u.shape[1])
            for j in range(u.shape[1]):
                cumulative = np.cumsum(w[order[:, j]])
                low, high = np.minimum(np.searchsorted(cumulative, (tail, 1.0 - tail), side="left"), draws - 1)
                widths[j] = u[order[high, j], j] - u[order[low, j], j]
            found[n] = widths, float(1.0 / np.sum(w * w))
        results.append((np.array([found[int(n)][0] for n in stops]).reshape(len(stops), u.shape[1]),
                        np.array([found[int(n)][1] for n in stops])))
    return results
