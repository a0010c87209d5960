"""Binomial statistics: Newcombe's interval of a difference of proportions against the published worked examples."""
import math

import pytest

from rollability_ros.core.stats import newcombe_interval


@pytest.mark.parametrize("a, b, expected", [
    # Newcombe (1998), Statistics in Medicine 17:873-890, Table II, method 10 (hybrid score, no continuity correction)
    ((56, 70), (48, 80), (0.0524, 0.3339)),
    ((9, 10), (3, 10), (0.1705, 0.8090)),
    ((0, 10), (0, 20), (-0.1611, 0.2775)),
    ((0, 10), (0, 10), (-0.2775, 0.2775)),
])
def test_newcombe_matches_the_published_worked_examples(a, b, expected):
    difference, low, high = newcombe_interval(*a, *b)
    assert difference == pytest.approx(a[0] / a[1] - b[0] / b[1])
    assert (low, high) == pytest.approx(expected, abs=6e-5)


def test_newcombe_is_antisymmetric_and_nan_without_trials():
    _, low, high = newcombe_interval(30, 100, 22, 100)
    _, low_swapped, high_swapped = newcombe_interval(22, 100, 30, 100)
    assert (low, high) == pytest.approx((-high_swapped, -low_swapped))
    assert all(math.isnan(v) for v in newcombe_interval(1, 0, 3, 10))
