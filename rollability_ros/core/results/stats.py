"""Binomial statistics for success rates (fitness = successes / trials)."""
import math


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
