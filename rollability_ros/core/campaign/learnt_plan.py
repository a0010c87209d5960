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
    docstring). ``samples``: prior draws (n, d), own units, of the likelihood's unknowns; ``draws``: the Monte Carlo
    outcomes per candidate of :meth:`scores`; ``renew``: renew the samples as the posterior narrows.

    Per sample and ensemble member it keeps the log-likelihood of every launch seen (``member_log_likelihood``
    (K, n)); a sample's weight is their mean (the calibration's ``log_likelihood(member=None)``), and
    :attr:`probabilities` (n, c), which the verdict's scores, the design comparison and the proposal read, are the
    members' predictions weighted by those likelihoods at each sample (the predictive given the launches seen)."""

    def __init__(self, table: LearntTable, samples: npt.ArrayLike, rng: typing.Optional[np.random.Generator] = None,
                 renew: bool = True, draws: int = 32, renew_fraction: float = 0.5, moves: int = 4,
                 log_prior: typing.Optional[typing.Callable[[np.ndarray], np.ndarray]] = None) -> None:
        self.table = table
        self.draws = draws
        #: log density (n,) of normalised unknowns (n, d) the samples were drawn from, beside the uniform prior
        #: (the characterisation's readings: ``posterior.characterisation_term``); the renewal's moves target it
        #: times the launches' likelihood
        self.log_prior = log_prior
        self._seen: typing.List[typing.Tuple[int, bool, np.ndarray]] = []
        theta = np.asarray(samples, dtype=np.float64)
        self._member_p, self._location, self._scale = table.predict(theta)
        self.member_log_likelihood = np.zeros((table.members, len(theta)))
        super().__init__(table.unknowns, theta, table.candidates, self._member_p.mean(axis=0),
                         table if renew else None, rng, renew_fraction, moves)

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

    def observe_launch(self, index: int, upright: bool, values: typing.Optional[npt.ArrayLike] = None) -> None:
        """Weigh the samples by one launch at candidate ``index``: its verdict and its transformed outcomes
        ``values`` (k,) (NaN or None: not measured; :meth:`LearntTable.transformed` makes them)."""
        v = np.full(len(self.table.outcomes), np.nan) if values is None else np.asarray(values, dtype=np.float64)
        before = np.logaddexp.reduce(self.member_log_likelihood, axis=0)
        self.member_log_likelihood += self._launch_log_likelihood(self._member_p, self._location, self._scale, index,
                                                                  bool(upright), v)
        self.log_weights += np.logaddexp.reduce(self.member_log_likelihood, axis=0) - before
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
        prior = (lambda x: np.zeros(len(x))) if self.log_prior is None else self.log_prior
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
        self._set_samples(theta, np.einsum("kn,knc->nc", self.member_weights, self._member_p))
        self.log_weights = np.zeros(n)
        self.renewals += 1

    def scores(self) -> np.ndarray:
        """Expected information (nats) about the unknowns of a launch at each candidate (c,), verdict and outcomes
        (module docstring); the exact BALD score of the members' mixture when the table has no continuous
        outcome."""
        if not self.table.outcomes:
            return super().scores()
        return self._estimated_scores(None)

    def group_scores(self, groups: npt.ArrayLike) -> np.ndarray:
        """:meth:`WeightedPosterior.group_scores` over verdict and outcomes (estimated as :meth:`scores`): ``groups``
        (s,), one group per sample; scores (c,), one per candidate."""
        if not self.table.outcomes:
            return super().group_scores(groups)
        return self._estimated_scores(np.asarray(groups))

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
