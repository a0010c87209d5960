"""Which launch next, and when a comparison is decided (issue 44.4).

Which launch next
    The unknowns of the twin (``calibration.parameters``: centre of mass, foam friction, ...) are uncertain; each
    launch of a (configuration, condition) answers upright or not. The launch that teaches most about the unknowns
    is the one whose outcome the current posterior is least sure of *for reasons of the unknowns*: the BALD score
    (Houlsby et al. 2011), the mutual information between the outcome y and the unknowns theta,

        I(y; theta) = H[E_theta p(theta)] - E_theta H[p(theta)],   H[p] = -p log p - (1 - p) log(1 - p) (nats),

    over posterior samples of theta. A condition where every plausible theta predicts 50 % scores 0 (the outcome is
    a coin flip whatever theta is: it teaches nothing); one where half the plausible thetas predict 5 % and half 95 %
    scores about log 2.

    It needs two things, each behind a small interface: samples of the unknowns (prior draws, in their calibration
    bounds, on their own scale), and a predictor p(upright | theta, configuration, condition)
    (:class:`UprightPredictor`): the simulation-based likelihood (:class:`TwinPredictor`: the upright fraction of
    ``repetitions`` twin launches, common random numbers), a learnt likelihood, or an analytic model
    (:class:`LogisticToyPredictor`). :class:`WeightedPosterior` keeps the prior samples with their predictions at
    every candidate condition once, and weighs them by the likelihood of the launches seen (importance
    sampling from the prior): each new outcome is one multiplication, each proposal one pass over a (samples x
    candidates) table, so the operator gets the next launch at once. Its effective sample size says when the prior
    draws are too few to describe the posterior (then draw more).

The always-valid test that stops a design comparison: :mod:`~rollability_ros.core.campaign.sequential`; the
comparison of the adaptive plan with the paper's matrix: :mod:`~rollability_ros.core.campaign.plan_comparison`.

numpy only (the twin predictor imports the calibration's launch pool when it is used).
"""
import dataclasses
import math
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core.records import LaunchCondition, LaunchOutcome

if typing.TYPE_CHECKING:   # annotations only: calibration loads the twin; plan is light but keeps this module lean
    from rollability_ros.core.campaign.calibration import CalibrationSettings, LaunchPool
    from rollability_ros.core.campaign.plan import PlannedTrial
    from rollability_ros.core.sim import LaunchTwinSettings

#: Predicted probabilities are kept in [EPSILON, 1 - EPSILON]: one impossible outcome must not zero a sample.
EPSILON = 1e-3


class UprightPredictor(typing.Protocol):
    """p(upright | theta, configuration, condition): the likelihood the proposal and the posterior use."""

    def probabilities(self, theta: np.ndarray, conditions: typing.Sequence[LaunchCondition]) -> np.ndarray:
        """P(upright) (s, c) for parameter sets ``theta`` (s, d) (own units, in the unknowns' order) at each
        grouped condition of ``conditions`` (c) (the repetition is ignored)."""
        ...


class HasBounds(typing.Protocol):
    """Anything that names unknowns with their bounds and scales (a learnt likelihood's own unknowns)."""

    @property
    def names(self) -> typing.Sequence[str]: ...

    @property
    def lower(self) -> typing.Sequence[float]: ...

    @property
    def upper(self) -> typing.Sequence[float]: ...

    @property
    def log_scale(self) -> typing.Sequence[bool]: ...


@dataclasses.dataclass(frozen=True)
class Unknowns:
    """The unknowns: config keys with their bounds and scales (own units), as ``calibration.parameters`` declares
    them. Normalised coordinates u in [0, 1] map to ``lower + u (upper - lower)``, or ``lower (upper / lower) ** u``
    on a log scale."""

    names: typing.Tuple[str, ...]
    lower: typing.Tuple[float, ...]
    upper: typing.Tuple[float, ...]
    log_scale: typing.Tuple[bool, ...]

    def __post_init__(self) -> None:
        if not self.names or not len(self.names) == len(self.lower) == len(self.upper) == len(self.log_scale):
            raise ValueError("unknowns need one lower, upper and log_scale per name, and at least one name")
        for name, low, high, log in zip(self.names, self.lower, self.upper, self.log_scale):
            if not (math.isfinite(low) and math.isfinite(high) and low < high) or (log and not low > 0):
                raise ValueError(f"{name}: need finite lower < upper (and lower > 0 on a log scale), got "
                                 f"[{low}, {high}]")

    @classmethod
    def like(cls, other: "HasBounds") -> "Unknowns":
        """The unknowns of any object with ``names``, ``lower``, ``upper`` and ``log_scale`` (a learnt likelihood's)."""
        return cls(tuple(other.names), tuple(float(v) for v in other.lower), tuple(float(v) for v in other.upper),
                   tuple(bool(v) for v in other.log_scale))

    @classmethod
    def from_settings(cls, settings: "CalibrationSettings") -> "Unknowns":
        """The unknowns of :class:`~rollability_ros.core.campaign.calibration.CalibrationSettings`."""
        return cls(tuple(settings.parameters), tuple(settings.lower), tuple(settings.upper), tuple(settings.log_scale))

    def to_values(self, normalised: npt.ArrayLike) -> np.ndarray:
        """Own units (..., d) of normalised coordinates (..., d)."""
        u = np.clip(np.asarray(normalised, dtype=np.float64), 0.0, 1.0)
        low, high = np.array(self.lower), np.array(self.upper)
        log = np.array(self.log_scale)
        linear = low + u * (high - low)
        with np.errstate(divide="ignore", invalid="ignore"):
            logged = low * (high / np.where(log, low, 1.0)) ** u
        return np.where(log, logged, linear)

    def to_normalised(self, values: npt.ArrayLike) -> np.ndarray:
        """Normalised coordinates (..., d) of values in own units (..., d)."""
        v = np.asarray(values, dtype=np.float64)
        low, high = np.array(self.lower), np.array(self.upper)
        log = np.array(self.log_scale)
        with np.errstate(divide="ignore", invalid="ignore"):
            logged = np.log(v / np.where(log, low, 1.0)) / np.log(np.where(log, high / low, 2.0))
        return np.where(log, logged, (v - low) / (high - low))

    def draw(self, count: int, rng: np.random.Generator) -> np.ndarray:
        """``count`` prior draws (count, d), own units: uniform on each unknown's search scale."""
        return self.to_values(rng.uniform(0.0, 1.0, (count, len(self.names))))


def binary_entropy(p: npt.ArrayLike) -> np.ndarray:
    """H[p] in nats, elementwise (any shape, e.g. (s, c) -> (s, c)); 0 at p = 0 and 1."""
    q = np.clip(np.asarray(p, dtype=np.float64), 0.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = -(q * np.log(q) + (1.0 - q) * np.log1p(-q))
    return np.nan_to_num(h, nan=0.0)


def bald_scores(probabilities: npt.ArrayLike, weights: typing.Optional[npt.ArrayLike] = None) -> np.ndarray:
    """The BALD score (nats) of each candidate: H[mean p] - mean H[p] over the samples.

    Parameters
    ----------
    probabilities : (s, c) array
        P(upright) of each posterior sample (s) at each candidate (c).
    weights : (s,) array, optional
        Sample weights (normalised here); equal weights by default.
    """
    p = np.asarray(probabilities, dtype=np.float64)
    if p.ndim != 2:
        raise ValueError(f"probabilities must be (samples, candidates), got shape {p.shape}")
    w = np.full(p.shape[0], 1.0 / p.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != (p.shape[0],) or not np.all(w >= 0) or not w.sum() > 0:
        raise ValueError("weights must be one nonnegative number per sample, not all zero")
    w = w / w.sum()
    return binary_entropy(w @ p) - w @ binary_entropy(p)


@dataclasses.dataclass(frozen=True)
class Proposal:
    """The proposed next launch: the condition, its BALD score (nats), and the predicted P(upright) with its spread
    over the posterior (mean, 5 % and 95 % quantiles), next best candidates' scores for context."""

    condition: LaunchCondition
    score_nats: float
    predicted_mean: float
    predicted_low: float
    predicted_high: float
    runner_up: typing.Tuple[typing.Tuple[LaunchCondition, float], ...] = ()
    about: str = "the unknowns"   # what the information is about: the unknowns, or which of two designs is better

    def why(self) -> str:
        """One line for the operator: the expected information and what the plausible unknowns predict."""
        if self.score_nats < 0.01:   # below 1.5 % of a bit: nothing left that these conditions can teach
            return (f"expected information {self.score_nats:.3f} nats: every plausible value of the unknowns predicts "
                    f"about the same P(upright) at every candidate ({self.predicted_mean:.0%} here), so no launch of "
                    "these conditions is expected to teach much more (the unknowns are as pinned as these conditions "
                    "pin them, or the prior samples are too few)")
        bits = self.score_nats / math.log(2)
        return (f"expected information about {self.about} {self.score_nats:.3f} nats ({bits:.2f} bits, of at most 1 "
                f"bit per launch): the plausible unknowns predict P(upright) from {self.predicted_low:.0%} to "
                f"{self.predicted_high:.0%} here (mean {self.predicted_mean:.0%}), so its outcome tells them apart")


class WeightedPosterior:
    """Prior samples of the unknowns weighted by the launches seen (module docstring).

    Parameters
    ----------
    unknowns : Unknowns
    samples : (n, d) array
        Prior draws, own units (:meth:`Unknowns.draw`).
    candidates : list of LaunchCondition
        The grouped conditions a launch may be proposed at (c).
    probabilities : (n, c) array
        P(upright) of every sample at every candidate (``predictor.probabilities(samples, candidates)``).
    predictor : UprightPredictor, optional
        With it, the samples are renewed whenever the effective sample size falls below ``renew_fraction`` of n
        (sequential Monte Carlo: resample by weight, then ``moves`` Metropolis steps each, a random walk in the
        normalised unknowns with the prior's bounds, targeting the prior times the likelihood of every launch
        seen): many launches pin the unknowns far more narrowly than the prior's spread, and prior draws alone
        then describe the posterior with a handful of samples. Each move predicts P(upright) of n new samples at
        every candidate: cheap with an analytic or learnt likelihood, launches with the twin's (leave it out).
    rng : numpy Generator, optional
        For the renewal (default: seeded with 0).
    """

    def __init__(self, unknowns: Unknowns, samples: npt.ArrayLike, candidates: typing.Sequence[LaunchCondition],
                 probabilities: npt.ArrayLike, predictor: typing.Optional[UprightPredictor] = None,
                 rng: typing.Optional[np.random.Generator] = None, renew_fraction: float = 0.5,
                 moves: int = 4) -> None:
        self.unknowns = unknowns
        self.candidates = list(candidates)
        self._set_samples(samples, probabilities)
        self.predictor = predictor
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.renew_fraction = renew_fraction
        self.moves = moves
        self.log_weights = np.zeros(len(self.samples))
        self._index = {c.group_key: i for i, c in enumerate(self.candidates)}
        self._successes = np.zeros(len(self.candidates))
        self._trials = np.zeros(len(self.candidates))
        self.launches = 0
        self.renewals = 0

    def _set_samples(self, samples: npt.ArrayLike, probabilities: npt.ArrayLike) -> None:
        self.samples = np.asarray(samples, dtype=np.float64)
        p = np.asarray(probabilities, dtype=np.float64)
        if self.samples.ndim != 2 or self.samples.shape[1] != len(self.unknowns.names):
            raise ValueError(f"samples must be (n, {len(self.unknowns.names)}), got shape {self.samples.shape}")
        if p.shape != (len(self.samples), len(self.candidates)):
            raise ValueError(f"probabilities must be ({len(self.samples)}, {len(self.candidates)}), got {p.shape}")
        if not np.all(np.isfinite(p)) or np.any(p < 0) or np.any(p > 1):
            raise ValueError("probabilities must be finite numbers in [0, 1]")
        self.probabilities = np.clip(p, EPSILON, 1.0 - EPSILON)
        self._log_p = np.log(self.probabilities)
        self._log_q = np.log1p(-self.probabilities)
        self._entropy = binary_entropy(self.probabilities)   # E_theta H[p] needs it at every proposal

    def _log_likelihood(self, probabilities: np.ndarray) -> np.ndarray:
        """Log-likelihood (n,) of every launch seen for samples with these P(upright) (n, c)."""
        p = np.clip(probabilities, EPSILON, 1.0 - EPSILON)
        return np.log(p) @ self._successes + np.log1p(-p) @ (self._trials - self._successes)

    def renew(self) -> None:
        """Resample by weight and move each sample ``moves`` Metropolis steps (class docstring)."""
        if self.predictor is None:
            raise ValueError("renewing the samples needs a predictor")
        n, d = self.samples.shape
        w = self.weights
        picks = np.minimum(np.searchsorted(np.cumsum(w), (self.rng.random() + np.arange(n)) / n), n - 1)
        u = self.unknowns.to_normalised(self.samples[picks])
        p = self.probabilities[picks]
        log_likelihood = self._log_likelihood(p)
        step = np.maximum(np.sqrt(np.cov(u, rowvar=False).reshape(d, d).diagonal()), 1e-3) * 2.38 / math.sqrt(d)
        for _ in range(self.moves):
            proposed = u + self.rng.normal(0.0, 1.0, u.shape) * step
            inside = np.all((proposed >= 0.0) & (proposed <= 1.0), axis=1)
            p_new = self.predictor.probabilities(self.unknowns.to_values(np.clip(proposed, 0.0, 1.0)),
                                                 self.candidates)
            log_new = self._log_likelihood(p_new)
            accept = inside & (np.log(self.rng.random(n)) < log_new - log_likelihood)
            u[accept], p[accept], log_likelihood[accept] = proposed[accept], p_new[accept], log_new[accept]
        self._set_samples(self.unknowns.to_values(u), p)
        self.log_weights = np.zeros(n)
        self.renewals += 1

    def _after_observing(self) -> None:
        if self.predictor is not None and self.effective_sample_size < self.renew_fraction * len(self.samples):
            self.renew()

    @classmethod
    def from_predictor(cls, unknowns: Unknowns, predictor: UprightPredictor,
                       candidates: typing.Sequence[LaunchCondition], samples: int,
                       rng: np.random.Generator, renew: bool = False) -> "WeightedPosterior":
        """``samples`` prior draws and their predictions at every candidate; ``renew``: renew the samples with the
        predictor as launches accumulate (class docstring)."""
        theta = unknowns.draw(samples, rng)
        return cls(unknowns, theta, candidates, predictor.probabilities(theta, candidates),
                   predictor if renew else None, rng)

    def candidate_index(self, condition: LaunchCondition) -> int:
        """The column of ``condition``'s grouped condition; ``ValueError`` when it is no candidate."""
        try:
            return self._index[condition.group_key]
        except KeyError:
            raise ValueError(f"{condition.configuration} at {condition.height_m:g} m, {condition.speed_mps:g} m/s, "
                             f"{condition.angle_deg:+g} deg is not a candidate condition") from None

    def observe(self, index: int, upright: bool) -> None:
        """Weigh the samples by one launch at candidate ``index``."""
        self.log_weights += self._log_p[:, index] if upright else self._log_q[:, index]
        self._successes[index] += bool(upright)
        self._trials[index] += 1
        self.launches += 1
        self._after_observing()

    def observe_launch(self, index: int, upright: bool, values: typing.Optional[npt.ArrayLike] = None,
                       reading: typing.Optional[float] = None) -> None:
        """One launch at candidate ``index``; ``values`` (o,), the continuous outcomes of a likelihood that has them,
        and the speed gate's ``reading`` (m/s) are weighed by :class:`~rollability_ros.core.campaign.learnt_plan.
        OutcomePosterior`, not by the verdict's posterior."""
        self.observe(index, upright)

    def observe_counts(self, index: int, successes: int, trials: int) -> None:
        """Weigh the samples by ``successes`` upright of ``trials`` launches at candidate ``index``."""
        if not 0 <= successes <= trials:
            raise ValueError(f"need 0 <= successes <= trials, got {successes} of {trials}")
        self.log_weights += successes * self._log_p[:, index] + (trials - successes) * self._log_q[:, index]
        self._successes[index] += successes
        self._trials[index] += trials
        self.launches += trials
        self._after_observing()

    def observe_outcomes(self, outcomes: typing.Iterable[LaunchOutcome]) -> int:
        """Weigh by every valid outcome at a candidate condition; returns how many were used (others are ignored:
        an invalid launch, or a condition not among the candidates)."""
        used = 0
        for outcome in outcomes:
            if outcome.valid and outcome.condition.group_key in self._index:
                self.observe(self._index[outcome.condition.group_key], outcome.upright)
                used += 1
        return used

    @property
    def weights(self) -> np.ndarray:
        """Normalised weights (n,)."""
        w = np.exp(self.log_weights - self.log_weights.max())
        return w / w.sum()

    @property
    def effective_sample_size(self) -> float:
        """Kish's effective sample size of the weights, 1..n: under about 50 the prior draws are too few."""
        w = self.weights
        return float(1.0 / np.sum(w * w))

    def scores(self) -> np.ndarray:
        """BALD score (nats) of every candidate (c,) (:func:`bald_scores`, with the samples' entropies kept)."""
        w = self.weights
        return binary_entropy(w @ self.probabilities) - w @ self._entropy

    def propose(self, runner_up: int = 3, comparison: typing.Optional[typing.Tuple[str, str]] = None) -> Proposal:
        """The candidate with the highest BALD score (ties: the first listed), with the predicted P(upright); with
        ``comparison`` (first, second), the highest :meth:`comparison_scores` instead (information about which of
        the two designs is better)."""
        scores = self.scores() if comparison is None else self.comparison_scores(*comparison)
        order = np.argsort(-scores, kind="stable")
        best = int(order[0])
        low, mean, high = self._predicted(best)
        about = "the unknowns" if comparison is None else f"which of {comparison[0]} and {comparison[1]} is better"
        return Proposal(self.candidates[best], float(scores[best]), mean, low, high,
                        tuple((self.candidates[int(i)], float(scores[int(i)])) for i in order[1:1 + runner_up]), about)

    def design_difference(self, first: str, second: str) -> np.ndarray:
        """Per sample (n,): the mean over the candidate conditions of P(upright) of ``second`` minus that of
        ``first`` at the same condition (the campaign's measure of which design rights the robot more often under
        that sample's unknowns); ``ValueError`` when either has no candidate condition the other shares."""
        columns = {c.group_key: i for i, c in enumerate(self.candidates)}
        pairs = [(columns[(first, *c.group_key[1:])], i) for i, c in enumerate(self.candidates)
                 if c.configuration == second and (first, *c.group_key[1:]) in columns]
        if not pairs:
            raise ValueError(f"{first} and {second} share no candidate condition to compare them at")
        a, b = (np.array(index) for index in zip(*pairs))
        return (self.probabilities[:, b] - self.probabilities[:, a]).mean(axis=1)

    def comparison_scores(self, first: str, second: str) -> np.ndarray:
        """Expected information (nats) of a launch at each candidate (c,) about *which design is better*: the mutual
        information between its outcome and the sign of :meth:`design_difference`, H[mean p] - sum_s P(s) H[mean p
        | s] over the two groups of samples. 0 where both groups predict the same P(upright), whatever they
        predict elsewhere; the launch that settles the comparison soonest, not the one that pins the unknowns."""
        return self.group_scores((self.design_difference(first, second) > 0).astype(int))

    def group_scores(self, groups: npt.ArrayLike) -> np.ndarray:
        """Expected information (nats) of a launch at each candidate (c,) about which group of samples holds the
        truth (``groups``: a label per sample, (n,)): H[mean p] - sum_g P(g) H[mean p | g]. Every sample its own
        group: :meth:`scores`; two groups by the sign of a design difference: :meth:`comparison_scores`; bins of
        one unknown: :meth:`unknown_scores`."""
        labels = np.asarray(groups)
        w = self.weights
        total = binary_entropy(w @ self.probabilities)
        conditional = np.zeros(len(self.candidates))
        for label in np.unique(labels):
            group = labels == label
            mass = w[group].sum()
            if mass > 0:
                conditional += mass * binary_entropy((w[group] / mass) @ self.probabilities[group])
        return total - conditional

    def unknown_groups(self, unknown: int, bins: int = 8) -> np.ndarray:
        """A label per sample (n,): which of ``bins`` weighted-quantile bins of unknown ``unknown`` it falls in."""
        quantiles = [float(q) for q in np.linspace(0.0, 1.0, bins + 1)[1:-1]]
        edges = weighted_quantiles(self.samples[:, unknown], self.weights, quantiles)
        return np.searchsorted(edges, self.samples[:, unknown], side="right")

    def unknown_scores(self, unknown: int, bins: int = 8) -> np.ndarray:
        """Expected information (nats) of a launch at each candidate (c,) about one unknown alone (which of
        ``bins`` posterior-quantile bins holds it; the others marginalised): the launch that narrows that
        unknown's interval, where :meth:`scores` may prefer one that teaches about the others."""
        return self.group_scores(self.unknown_groups(unknown, bins))

    def targeted_scores(self, target_widths: npt.ArrayLike, level: float = 0.95) -> np.ndarray:
        """The expected information about the unknown farthest from its target width (the largest ratio of its
        current normalised :meth:`normalised_widths` to ``target_widths`` (d,)): a plan that must bring *every*
        interval under a width narrows the one that lags (:meth:`unknown_scores`); once all are under their
        targets, :meth:`scores`."""
        ratio = self.normalised_widths(level) / np.asarray(target_widths, dtype=np.float64)
        if np.all(ratio <= 1.0):
            return self.scores()
        return self.unknown_scores(int(np.argmax(ratio)))

    def lagging_scores(self, target_widths: npt.ArrayLike, level: float = 0.95, bins: int = 8) -> np.ndarray:
        """The expected information about the unknowns whose width is still above its target (``target_widths``
        (d,), normalised as :meth:`normalised_widths`), summed over them (each :meth:`unknown_scores`: which of
        ``bins`` posterior-quantile bins holds it); once all are under their targets, :meth:`scores`. Unlike
        :meth:`scores` it stops paying for an unknown that has reached its width (a reading that teaches one
        unknown at every launch, the gate's speed, would otherwise keep winning); unlike :meth:`targeted_scores`
        it counts a launch that teaches several lagging unknowns at once. (c,)"""
        widths = self.normalised_widths(level)
        lagging = np.flatnonzero(widths > np.asarray(target_widths, dtype=np.float64))
        if not len(lagging):
            return self.scores()
        return np.sum([self.unknown_scores(int(j), bins) for j in lagging], axis=0)

    def _predicted(self, index):
        p = self.probabilities[:, index]
        w = self.weights
        low, high = weighted_quantiles(p, w, (0.05, 0.95))
        return float(low), float(w @ p), float(high)

    def intervals(self, level: float = 0.95) -> np.ndarray:
        """Equal-tailed credible intervals (d, 2) of the unknowns, own units."""
        tail = (1.0 - level) / 2.0
        return np.array([weighted_quantiles(self.samples[:, j], self.weights, (tail, 1.0 - tail))
                         for j in range(self.samples.shape[1])])

    def normalised_widths(self, level: float = 0.95) -> np.ndarray:
        """Widths (d,) of :meth:`intervals` as fractions of each unknown's range on its search scale."""
        bounds = self.unknowns.to_normalised(self.intervals(level).T).T
        return bounds[:, 1] - bounds[:, 0]


def weighted_quantiles(values: npt.ArrayLike, weights: npt.ArrayLike,
                       quantiles: typing.Sequence[float]) -> np.ndarray:
    """Quantiles (q,) of weighted samples ``values`` (n,) with ``weights`` (n,): the smallest value whose cumulative
    weight reaches each quantile."""
    v = np.asarray(values, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    order = np.argsort(v, kind="stable")
    cumulative = np.cumsum(w[order])
    cumulative /= cumulative[-1]
    picks = np.searchsorted(cumulative, np.asarray(quantiles, dtype=np.float64), side="left")
    return v[order][np.minimum(picks, len(v) - 1)]


# --- predictors ---------------------------------------------------------------------------------------------------


class LogisticToyPredictor:
    """An analytic stand-in for the twin: P(upright) = sigmoid(a_c + b_c . (u - 1/2)), u the normalised unknowns.

    Each grouped condition c gets its own intercept a_c ~ N(0, ``spread``) and sensitivities b_c ~ N(0,
    ``strength``) (d,), drawn from ``seed`` and the condition itself, so some conditions are informative about some
    unknowns and others (saturated near 0 or 1, or insensitive) teach little, as on the rig. Cheap and exact: for
    tests and the plan comparison, never for a physical claim.
    """

    def __init__(self, unknowns: Unknowns, seed: int = 0, spread: float = 2.0, strength: float = 4.0) -> None:
        self.unknowns = unknowns
        self.seed = seed
        self.spread = spread
        self.strength = strength
        self._coefficients: typing.Dict[tuple, typing.Tuple[float, np.ndarray]] = {}

    def coefficients(self, condition: LaunchCondition) -> typing.Tuple[float, np.ndarray]:
        """``(a_c, b_c)`` of a grouped condition (reproducible: seeded by ``seed`` and the condition's text)."""
        import zlib

        if condition.group_key not in self._coefficients:
            key = "|".join(str(v) for v in condition.group_key)
            rng = np.random.default_rng([self.seed, zlib.crc32(key.encode("utf-8"))])
            self._coefficients[condition.group_key] = (float(rng.normal(0.0, self.spread)),
                                                       rng.normal(0.0, self.strength, len(self.unknowns.names)))
        return self._coefficients[condition.group_key]

    def probabilities(self, theta: np.ndarray, conditions: typing.Sequence[LaunchCondition]) -> np.ndarray:
        """P(upright) (s, c); see the class docstring."""
        u = self.unknowns.to_normalised(np.atleast_2d(theta)) - 0.5
        columns = []
        for condition in conditions:
            a, b = self.coefficients(condition)
            columns.append(1.0 / (1.0 + np.exp(-(a + u @ b))))
        return np.stack(columns, axis=1) if columns else np.zeros((len(u), 0))


@dataclasses.dataclass(frozen=True)
class TwinPredictor:
    """The simulation-based likelihood: P(upright) = upright fraction of ``repetitions`` launches of the twin with
    theta's values set (the calibration's :class:`~rollability_ros.core.campaign.calibration.LaunchPool`, common
    random numbers: the same launch seeds for every theta).

    Parameters
    ----------
    twin : LaunchTwinSettings
        The typed twin of its files, parsed once by the command (everything not among the unknowns).
    unknowns : Unknowns
    pool : LaunchPool
    repetitions : int
        Launches per (theta, condition).
    seed : int
        The calibration seed the launch seeds come from.
    """

    twin: "LaunchTwinSettings"
    unknowns: Unknowns
    pool: "LaunchPool"
    repetitions: int
    seed: int = 1

    def __post_init__(self) -> None:
        if self.repetitions < 1:
            raise ValueError(f"repetitions must be >= 1, got {self.repetitions}")

    def probabilities(self, theta: np.ndarray, conditions: typing.Sequence[LaunchCondition]) -> np.ndarray:
        """P(upright) (s, c) from ``repetitions`` twin launches per entry."""
        from rollability_ros.core.campaign.calibration import ConditionResult, simulation_seeds, twin_settings_with

        twins = [twin_settings_with(self.twin, self.unknowns.names, row) for row in np.atleast_2d(theta)]
        grouped = [ConditionResult(*c.group_key, 0, 0) for c in conditions]
        upright = self.pool.predicted_upright(twins, grouped, simulation_seeds(self.seed, 0, self.repetitions))
        return upright / self.repetitions


@typing.runtime_checkable
class PerLaunchPredictor(typing.Protocol):
    """A likelihood that predicts one launch at a time: ``predict_upright_probability(theta (s, d), design,
    (height m, speed m/s, angle deg)) -> (s,)`` (the learnt likelihood of ``core/campaign/likelihood.py``)."""

    def predict_upright_probability(self, theta_samples: npt.ArrayLike, design: str,
                                    condition: typing.Tuple[float, float, float]) -> np.ndarray:
        """P(upright) (s,) of one launch of ``design`` at ``condition`` under each row of ``theta_samples``."""
        ...


@dataclasses.dataclass(frozen=True)
class PerLaunchAdapter:
    """An :class:`UprightPredictor` over a :class:`PerLaunchPredictor` (a learnt likelihood): one column per
    condition. Its unknowns must be the same keys in the same order as the adaptive plan's."""

    likelihood: PerLaunchPredictor

    def probabilities(self, theta: np.ndarray, conditions: typing.Sequence[LaunchCondition]) -> np.ndarray:
        """P(upright) (s, c)."""
        theta = np.atleast_2d(np.asarray(theta, dtype=np.float64))
        columns = [np.asarray(self.likelihood.predict_upright_probability(
            theta, c.configuration, (c.height_m, c.speed_mps, c.angle_deg)), dtype=np.float64).reshape(len(theta))
            for c in conditions]
        return np.stack(columns, axis=1) if columns else np.zeros((len(theta), 0))


def candidate_conditions(configurations: typing.Sequence[str], heights_m: typing.Sequence[float],
                         speeds_mps: typing.Sequence[float],
                         angles_deg: typing.Sequence[float]) -> typing.List[LaunchCondition]:
    """Every grouped condition of a campaign matrix (``campaign.*``), repetition 0: what may be proposed."""
    return [LaunchCondition(c, h, s, a) for c in configurations for h in heights_m for s in speeds_mps
            for a in angles_deg]


def next_repetition(condition: LaunchCondition, stored_trial_ids: typing.Collection[str]) -> LaunchCondition:
    """``condition`` with the first repetition whose trial id is not stored yet (its launch is new)."""
    from rollability_ros.core.records import trial_id_for

    repetition = 0
    while trial_id_for(dataclasses.replace(condition, repetition=repetition)) in stored_trial_ids:
        repetition += 1
    return dataclasses.replace(condition, repetition=repetition)


def proposal_lines(posterior: WeightedPosterior, proposal: Proposal,
                   previous: typing.Optional[LaunchCondition],
                   pressure_psi_by_speed: typing.Optional[typing.Mapping[float, float]] = None,
                   instructions: bool = True) -> typing.List[str]:
    """The proposal as the technician sets it up: what to change on the rig (from ``previous``; left out with
    ``instructions`` False, when the campaign loop says it), why (the expected information), the runners-up, and the
    unknowns' current 95 % intervals."""
    from rollability_ros.core.campaign.plan import changes_between

    c = proposal.condition
    lines = [f"next launch: {c.configuration} at {c.height_m:.2f} m, {c.speed_mps:g} m/s, {c.angle_deg:+g} deg "
             f"(from {posterior.launches} stored launches, {len(posterior.samples)} prior samples of the unknowns, "
             f"effective {posterior.effective_sample_size:.1f})"]
    if instructions:
        changes = changes_between(previous, c, pressure_psi_by_speed)
        lines += [f"  - {instruction}" for instruction in changes] or ["  (nothing to change on the rig)"]
    lines.append(f"why: {proposal.why()}")
    if proposal.runner_up:
        lines.append("then: " + "; ".join(f"{o.configuration} {o.height_m:.2f} m {o.speed_mps:g} m/s "
                                          f"{o.angle_deg:+g} deg ({score:.3f} nats)"
                                          for o, score in proposal.runner_up))
    for name, (low, high) in zip(posterior.unknowns.names, posterior.intervals()):
        lines.append(f"unknown {name}: 95% of the weighted samples in [{low:.4g}, {high:.4g}]")
    if posterior.effective_sample_size < 20:
        lines.append(f"WARNING: only {posterior.effective_sample_size:.1f} effective samples describe the unknowns "
                     "now: the proposal and intervals are coarse; draw more prior samples (--prior-samples)")
    return lines


def adaptive_next_trial(posterior: WeightedPosterior, stored_trial_ids: typing.Collection[str],
                        say: typing.Callable[[str], None] = print,
                        comparison: typing.Optional[typing.Tuple[str, str]] = None
                        ) -> typing.Callable[[typing.Optional[LaunchOutcome]], typing.Optional["PlannedTrial"]]:
    """A campaign's ``next_trial`` (:func:`~rollability_ros.core.campaign.runner.run_campaign`): weighs
    ``posterior`` by each stored outcome, then proposes the next launch (the BALD choice; with ``comparison`` (first,
    second) the launch that tells most about which of the two is better, :meth:`WeightedPosterior.comparison_scores`),
    says why (:func:`proposal_lines`; the campaign loop says what to change) and returns it as a
    :class:`~rollability_ros.core.campaign.plan.PlannedTrial` with a new repetition number. ``posterior`` should
    already hold the outcomes stored before (``observe_outcomes``)."""
    from rollability_ros.core.campaign.plan import PlannedTrial
    from rollability_ros.core.records import trial_id_for

    stored = set(stored_trial_ids)
    state: typing.Dict[str, typing.Any] = {"previous": None, "index": 0}

    def choose(last: typing.Optional[LaunchOutcome]) -> typing.Optional["PlannedTrial"]:
        if last is not None:
            posterior.observe_outcomes([last])
            stored.add(last.trial_id)
            state["previous"] = last.condition
        proposal = posterior.propose(comparison=comparison)
        for line in proposal_lines(posterior, proposal, state["previous"], instructions=False):
            say(line)
        condition = next_repetition(proposal.condition, stored)
        trial = PlannedTrial(state["index"], trial_id_for(condition), condition)
        state["index"] += 1
        return trial
    return choose


#: The unknowns an adaptive plan learns about unless told otherwise (``--fit``): the two of issue 44's five-minute
#: calibration.
DEFAULT_UNKNOWNS = ("robot.com_offset_z_m", "launch_twin.foam.lateral_friction")


def budget_placeholders(budget: int, condition: LaunchCondition) -> typing.List["PlannedTrial"]:
    """The ``plan`` of an adaptive campaign (:func:`~rollability_ros.core.campaign.runner.run_campaign` with
    ``next_trial``): ``budget`` placeholder trials that only count the launches; ``next_trial`` chooses each."""
    from rollability_ros.core.campaign.plan import PlannedTrial as Trial

    return [Trial(i, f"adaptive-{i}", condition) for i in range(budget)]
