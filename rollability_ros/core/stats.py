"""Binomial statistics for success rates (fitness = successes / trials), and rank correlation."""
import math
import typing

import numpy as np
import numpy.typing as npt


def wilson_interval(successes: int, trials: int, z: float = 1.959963984540054) -> typing.Tuple[float, float]:
    """Wilson score interval of a binomial proportion.

    Parameters
    ----------
    successes, trials : int
        Observed successes out of ``trials`` (``0 <= successes <= trials``).
    z : float
        Standard-normal quantile; the default gives a 95% interval.

    Returns
    -------
    (low, high) : tuple of float
        Bounds in [0, 1]; ``(nan, nan)`` when ``trials == 0``.
    """
    if trials < 0 or successes < 0 or successes > trials:
        raise ValueError(f"need 0 <= successes <= trials, got {successes} of {trials}")
    if trials == 0:
        return (math.nan, math.nan)
    p = successes / trials
    z2 = z * z
    denominator = 1.0 + z2 / trials
    centre = (p + z2 / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z2 / (4 * trials * trials)) / denominator
    # at p = 0 or 1 the bound is exact; clamp rounding noise
    return (max(0.0, centre - half) if successes else 0.0, min(1.0, centre + half) if successes < trials else 1.0)


def newcombe_interval(successes_a: int, trials_a: int, successes_b: int, trials_b: int,
                      z: float = 1.959963984540054) -> typing.Tuple[float, float, float]:
    """Newcombe's hybrid score interval of the difference of two independent proportions, ``p_a - p_b``.

    Method 10 of Newcombe (1998), "Interval estimation for the difference between independent proportions:
    comparison of eleven methods", Statistics in Medicine 17, 873-890: from the Wilson intervals ``(l_a, u_a)``
    and ``(l_b, u_b)`` of the two proportions, ``low = d - sqrt((p_a - l_a)^2 + (u_b - p_b)^2)`` and
    ``high = d + sqrt((u_a - p_a)^2 + (p_b - l_b)^2)`` with ``d = p_a - p_b``. Its worked example 56/70 - 48/80
    gives [0.0524, 0.3339] (test/core/test_stats.py).

    Returns ``(difference, low, high)``; all nan when either sample is empty.
    """
    if trials_a == 0 or trials_b == 0:
        return (math.nan, math.nan, math.nan)
    p_a, p_b = successes_a / trials_a, successes_b / trials_b
    (low_a, high_a), (low_b, high_b) = wilson_interval(successes_a, trials_a, z), wilson_interval(successes_b, trials_b, z)
    difference = p_a - p_b
    return (difference, difference - math.sqrt((p_a - low_a) ** 2 + (high_b - p_b) ** 2),
            difference + math.sqrt((high_a - p_a) ** 2 + (p_b - low_b) ** 2))


def average_ranks(values: npt.ArrayLike) -> np.ndarray:
    """Ranks 1..n of ``values`` (n,), ties sharing their average rank."""
    array = np.asarray(values, dtype=np.float64)
    order = np.argsort(array, kind="mergesort")
    ranks = np.empty(len(array))
    ranks[order] = np.arange(1, len(array) + 1)
    for value in np.unique(array):
        tied = array == value
        ranks[tied] = ranks[tied].mean()
    return ranks


def spearman(x: npt.ArrayLike, y: npt.ArrayLike) -> float:
    """Spearman rank correlation of paired samples ``x`` and ``y`` (n,) (ties: average ranks); nan when either is
    constant."""
    rx, ry = average_ranks(x), average_ranks(y)
    if len(rx) < 2 or np.std(rx) == 0 or np.std(ry) == 0:
        return math.nan
    return float(np.corrcoef(rx, ry)[0, 1])


def spearman_permutation_test(x: npt.ArrayLike, y: npt.ArrayLike, permutations: int = 10000,
                              seed: int = 0) -> typing.Tuple[float, float]:
    """``(rho, p)``: Spearman's rho of ``x`` and ``y`` and its two-sided permutation p-value (the share of
    ``permutations`` random pairings, plus the observed one, with ``|rho|`` at least the observed; seeded, so the
    same data give the same p). Needs at least 3 pairs; nan, nan when rho is undefined."""
    xs, ys = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    if len(xs) != len(ys) or len(xs) < 3:
        raise ValueError(f"a rank test needs at least 3 pairs of equal length, got {len(xs)} and {len(ys)}")
    observed = spearman(xs, ys)
    if not math.isfinite(observed):
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    rx, ry = average_ranks(xs), average_ranks(ys)
    shuffled = np.array([rng.permutation(ry) for _ in range(permutations)])
    rx_c = rx - rx.mean()
    rhos = (shuffled - shuffled.mean(axis=1, keepdims=True)) @ rx_c / (
        np.linalg.norm(rx_c) * np.linalg.norm(shuffled - shuffled.mean(axis=1, keepdims=True), axis=1))
    at_least = int(np.sum(np.abs(rhos) >= abs(observed) - 1e-12))
    return observed, (at_least + 1) / (permutations + 1)
