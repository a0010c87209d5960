"""Binomial statistics for success rates (fitness = successes / trials), and rank correlation."""
import math

import numpy as np


def wilson_interval(successes, trials, z=1.959963984540054):
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


def average_ranks(values):
    """Ranks 1..n of ``values`` (n,), ties sharing their average rank."""
    values = np.asarray(values, dtype=np.float64)
    order = np.argsort(values, kind="mergesort")
    ranks = np.empty(len(values))
    ranks[order] = np.arange(1, len(values) + 1)
    for value in np.unique(values):
        tied = values == value
        ranks[tied] = ranks[tied].mean()
    return ranks


def spearman(x, y):
    """Spearman rank correlation of paired samples (ties: average ranks); nan when either is constant."""
    rx, ry = average_ranks(x), average_ranks(y)
    if len(rx) < 2 or np.std(rx) == 0 or np.std(ry) == 0:
        return math.nan
    return float(np.corrcoef(rx, ry)[0, 1])


def spearman_permutation_test(x, y, permutations=10000, seed=0):
    """``(rho, p)``: Spearman's rho of ``x`` and ``y`` and its two-sided permutation p-value (the share of
    ``permutations`` random pairings, plus the observed one, with ``|rho|`` at least the observed; seeded, so the
    same data give the same p). Needs at least 3 pairs; nan, nan when rho is undefined."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    if len(x) != len(y) or len(x) < 3:
        raise ValueError(f"a rank test needs at least 3 pairs of equal length, got {len(x)} and {len(y)}")
    observed = spearman(x, y)
    if not math.isfinite(observed):
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    rx, ry = average_ranks(x), average_ranks(y)
    shuffled = np.array([rng.permutation(ry) for _ in range(permutations)])
    rx_c = rx - rx.mean()
    rhos = (shuffled - shuffled.mean(axis=1, keepdims=True)) @ rx_c / (
        np.linalg.norm(rx_c) * np.linalg.norm(shuffled - shuffled.mean(axis=1, keepdims=True), axis=1))
    at_least = int(np.sum(np.abs(rhos) >= abs(observed) - 1e-12))
    return observed, (at_least + 1) / (permutations + 1)
