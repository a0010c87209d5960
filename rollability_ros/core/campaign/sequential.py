"""When a design comparison is decided (issue 44.4): an always-valid test on paired launches.

Design B against design A, launched in pairs at the same condition: each pair gives D = y_B - y_A in {-1, 0, 1}.
:class:`PairedSequentialTest` is a betting confidence sequence (Waudby-Smith and Ramdas 2023, "Estimating means
of bounded random variables by betting", hedged capital with a predictable plug-in bet): for each candidate mean
difference m the wealth K_t(m) = prod_i (1 + lambda_i (D_i - m)) is a nonnegative martingale when m is the true
mean, so by Ville's inequality P(sup_t K_t(m) >= 1/alpha) <= alpha. The set {m : K_t(m) < 1/alpha} holds the true
difference at every t at once with probability at least 1 - alpha: the campaign may look after every pair and
stop as soon as 0 leaves it ("decided"), and the chance that a decision was wrong (that it excluded the true
difference) stays at most alpha however long it runs. test/core/test_adaptive.py measures the false decisions
under equal designs by simulation.

numpy only.
"""
import math
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core.records import LaunchOutcome

if typing.TYPE_CHECKING:   # annotations only
    from rollability_ros.core.campaign.plan import PlannedTrial


class PairedSequentialTest:
    """An always-valid (1 - ``alpha``) confidence sequence for the mean paired difference of two designs, and the
    decision it allows (module docstring).

    Parameters
    ----------
    alpha : float
        The error rate: the chance that the sequence ever excludes the true difference, at most this.
    grid : int
        Candidate mean differences in [-1, 1] the confidence sequence is evaluated at.
    """

    def __init__(self, alpha: float = 0.05, grid: int = 401) -> None:
        if not 0 < alpha < 1:
            raise ValueError(f"alpha must be in (0, 1), got {alpha}")
        if grid < 3:
            raise ValueError(f"grid must be >= 3, got {grid}")
        self.alpha = alpha
        self.means = np.linspace(-1.0, 1.0, grid)
        self._log_up = np.zeros(grid)      # log wealth betting that the mean exceeds m
        self._log_down = np.zeros(grid)    # ... that it is below m
        self._sum = 0.0
        self._sum_sq = 0.0
        self.pairs = 0

    def _bet(self) -> float:
        """The predictable plug-in bet, from the pairs before this one (:func:`plug_in_bet`)."""
        return float(plug_in_bet(self._sum, self._sum_sq, self.pairs, self.alpha))

    def update(self, difference: float) -> None:
        """One pair's difference y_B - y_A (in [-1, 1])."""
        if not -1.0 <= difference <= 1.0:
            raise ValueError(f"a paired difference of two upright verdicts is in [-1, 1], got {difference!r}")
        bet = self._bet()
        m = self.means
        with np.errstate(divide="ignore"):
            # bets truncated to half of what keeps the wealth nonnegative (the hedged capital process)
            up = np.minimum(bet, 0.5 / (1.0 + m))
            down = np.minimum(bet, 0.5 / np.maximum(1.0 - m, 1e-12))
            self._log_up += np.log1p(up * (difference - m))
            self._log_down += np.log1p(-down * (difference - m))
        self._sum += difference
        self._sum_sq += difference * difference
        self.pairs += 1

    def wealth(self) -> np.ndarray:
        """The hedged wealth K_t(m) (g,) at every grid mean (g,) (half on each side)."""
        return 0.5 * np.exp(self._log_up) + 0.5 * np.exp(self._log_down)

    def confidence_sequence(self) -> typing.Tuple[float, float]:
        """The smallest and largest grid mean still plausible: ``(low, high)`` (the set is an interval up to the
        grid's resolution)."""
        plausible = self.means[self.wealth() < 1.0 / self.alpha]
        if not len(plausible):   # cannot happen for the true mean but for probability alpha; keep the estimate
            estimate = self._sum / max(self.pairs, 1)
            return estimate, estimate
        return float(plausible.min()), float(plausible.max())

    @property
    def decided(self) -> int:
        """+1 when B is decided better (the whole sequence above 0), -1 when A is, 0 while undecided."""
        low, high = self.confidence_sequence()
        return 1 if low > 0 else -1 if high < 0 else 0


def plug_in_bet(total: npt.ArrayLike, total_sq: npt.ArrayLike, pairs: int, alpha: float) -> np.ndarray:
    """The predictable plug-in bets (r,) of Waudby-Smith and Ramdas (eq. 26) for differences in [-1, 1], one per
    sequence from the sums ``total`` (r,) and ``total_sq`` (r,):
    sqrt(2 log(2 / alpha) / (variance t log(t + 1))), t = pairs + 1, from the sum and the sum of squares of the
    ``pairs`` differences before (arrays: one bet per sequence); the variance estimate starts at a pseudo-variance
    of 1/4 so the first bets are moderate."""
    t = pairs + 1
    s = np.asarray(total, dtype=np.float64)
    mean = s / t
    variance = (0.25 + np.asarray(total_sq, dtype=np.float64) - 2.0 * mean * s + pairs * mean * mean) / t
    return np.sqrt(2.0 * math.log(2.0 / alpha) / (np.maximum(variance, 1e-6) * t * math.log(t + 1.0)))


def first_decisions(differences: npt.ArrayLike, alpha: float = 0.05) -> np.ndarray:
    """For many sequences of paired differences (runs, pairs) at once: the number of pairs after which each
    sequence's :class:`PairedSequentialTest` first decided (0 leaves its confidence sequence), 0 where it never did.
    The same bets and wealth as the class (at m = 0), vectorised over runs for simulations."""
    d = np.asarray(differences, dtype=np.float64)
    runs, pairs = d.shape
    log_up, log_down = np.zeros(runs), np.zeros(runs)
    total, total_sq = np.zeros(runs), np.zeros(runs)
    first = np.zeros(runs, dtype=np.int64)
    for i in range(pairs):
        bet = np.minimum(plug_in_bet(total, total_sq, i, alpha), 0.5)   # at m = 0 both sides are capped at 1/2
        log_up += np.log1p(bet * d[:, i])
        log_down += np.log1p(-bet * d[:, i])
        total += d[:, i]
        total_sq += d[:, i] ** 2
        wealth = 0.5 * np.exp(log_up) + 0.5 * np.exp(log_down)
        first[(first == 0) & (wealth >= 1.0 / alpha)] = i + 1
    return first


def paired_differences(outcomes: typing.Iterable[LaunchOutcome], first: str, second: str
                       ) -> typing.List[float]:
    """The paired differences y_second - y_first of valid launches of configurations ``first`` and ``second`` at the
    same (height, speed, angle, repetition), in the order the pair was completed."""
    seen: typing.Dict[tuple, typing.Dict[str, bool]] = {}
    differences = []
    for outcome in outcomes:
        c = outcome.condition
        if not outcome.valid or c.configuration not in (first, second):
            continue
        key = (c.height_m, c.speed_mps, c.angle_deg, c.repetition)
        pair = seen.setdefault(key, {})
        if c.configuration in pair:
            continue
        pair[c.configuration] = outcome.upright
        if len(pair) == 2:
            differences.append(float(pair[second]) - float(pair[first]))
    return differences


def comparison_decision(outcomes: typing.Iterable[LaunchOutcome], first: str, second: str,
                        alpha: float = 0.05) -> typing.Tuple[int, PairedSequentialTest]:
    """The :class:`PairedSequentialTest` of ``second`` against ``first`` over the stored ``outcomes``, and its
    decision (+1 ``second`` better, -1 ``first`` better, 0 undecided)."""
    test = PairedSequentialTest(alpha)
    for difference in paired_differences(outcomes, first, second):
        test.update(difference)
    return test.decided, test


def comparison_stop_rule(outcomes: typing.Iterable[LaunchOutcome], first: str, second: str,
                         alpha: float = 0.05) -> typing.Callable[[LaunchOutcome], str]:
    """A campaign's ``stop_rule`` (:func:`~rollability_ros.core.campaign.runner.run_campaign`): fed every newly stored
    outcome after the ``outcomes`` stored before, it answers why the comparison of ``second`` against ``first`` is
    decided ("" while it is not): the always-valid test of :class:`PairedSequentialTest` at error rate ``alpha``."""
    seen = [o for o in outcomes]

    def rule(outcome: LaunchOutcome) -> str:
        seen.append(outcome)
        decision, test = comparison_decision(seen, first, second, alpha)
        if not decision:
            return ""
        low, high = test.confidence_sequence()
        better, worse = (second, first) if decision > 0 else (first, second)
        return (f"{better} rights the robot more often than {worse} after {test.pairs} paired launches: the "
                f"difference P({second}) - P({first}) lies in [{low:+.2f}, {high:+.2f}] (always-valid "
                f"{1 - alpha:.0%} confidence sequence; the chance this decision is wrong is at most {alpha:.0%})")
    return rule



def paired_order(plan: typing.Sequence["PlannedTrial"], first: str, second: str) -> typing.List["PlannedTrial"]:
    """``plan`` (PlannedTrials) reordered for a comparison of ``first`` and ``second``: their trials in pairs (the
    same height, speed, angle and repetition, ``first`` then ``second``), pair after pair in plan order, so every
    second launch completes a pair the stop rule can use; other configurations' trials follow in plan order."""
    pairs: typing.Dict[tuple, typing.Dict[str, "PlannedTrial"]] = {}
    rest = []
    for trial in plan:
        c = trial.condition
        if c.configuration in (first, second):
            pairs.setdefault((c.height_m, c.speed_mps, c.angle_deg, c.repetition), {})[c.configuration] = trial
        else:
            rest.append(trial)
    ordered = [pair[name] for pair in pairs.values() for name in (first, second) if name in pair]
    return ordered + rest
