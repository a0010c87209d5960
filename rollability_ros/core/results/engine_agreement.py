"""Cross-engine agreement: the same trials (same seeds) simulated in two physics engines, compared.

Trial by trial (same index and seed: same start state and disturbance) and across designs (fitness ranks);
a design whose advantage over the reference (e.g. the baseline) holds in every engine is *robust to the
engine*: its Wilson 95% interval lies above the reference's in each.
"""
import dataclasses

import numpy as np

from rollability_ros.core.results.stats import wilson_interval


@dataclasses.dataclass(frozen=True)
class TrialAgreement:
    """How often two engines agree on the outcome of the same trials, with the Wilson 95% interval."""

    trials: int
    agreed: int
    both_upright: int
    only_first_upright: int
    only_second_upright: int
    ci_low: float
    ci_high: float

    @property
    def fraction(self):
        """Share of trials with the same outcome, [0, 1]."""
        return self.agreed / self.trials


def trial_agreement(first_outcomes, second_outcomes):
    """Compare two lists of trial outcomes (objects with ``index``, ``seed``, ``upright``) trial by trial.

    Raises ``ValueError`` unless both hold the same trials (indices and seeds).
    """
    first = sorted(first_outcomes, key=lambda outcome: outcome.index)
    second = sorted(second_outcomes, key=lambda outcome: outcome.index)
    if [(o.index, o.seed) for o in first] != [(o.index, o.seed) for o in second] or not first:
        raise ValueError("trial agreement needs the same, non-empty trials (indices and seeds) from both engines")
    pairs = [(bool(a.upright), bool(b.upright)) for a, b in zip(first, second)]
    agreed = sum(a == b for a, b in pairs)
    low, high = wilson_interval(agreed, len(pairs))
    return TrialAgreement(trials=len(pairs), agreed=agreed, both_upright=sum(a and b for a, b in pairs),
                          only_first_upright=sum(a and not b for a, b in pairs),
                          only_second_upright=sum(b and not a for a, b in pairs), ci_low=low, ci_high=high)


def rank_agreement(fitness_by_engine):
    """Spearman rank correlation of design fitnesses between two engines.

    ``fitness_by_engine``: {engine: {design: fitness}} with exactly two engines and the same designs (>= 2);
    ties get average ranks. Returns rho in [-1, 1] (nan if one engine ranks every design equal).
    """
    if len(fitness_by_engine) != 2:
        raise ValueError(f"rank agreement compares two engines, got {len(fitness_by_engine)}")
    first, second = fitness_by_engine.values()
    if set(first) != set(second) or len(first) < 2:
        raise ValueError("rank agreement needs the same two or more designs in both engines")
    designs = sorted(first)
    ranks = [_average_ranks([table[d] for d in designs]) for table in (first, second)]
    if np.std(ranks[0]) == 0 or np.std(ranks[1]) == 0:
        return float("nan")
    return float(np.corrcoef(ranks[0], ranks[1])[0, 1])


def _average_ranks(values):
    values = np.asarray(values, dtype=np.float64)
    order = np.argsort(values, kind="mergesort")
    ranks = np.empty(len(values))
    ranks[order] = np.arange(1, len(values) + 1)
    for value in np.unique(values):
        tied = values == value
        ranks[tied] = ranks[tied].mean()
    return ranks


def robust_to_engine(results_by_engine, reference):
    """Designs whose advantage over ``reference`` holds in every engine.

    ``results_by_engine``: {engine: {design: result with ci_low, ci_high}}; a design is robust when its
    ``ci_low`` exceeds the reference's ``ci_high`` in each engine. Returns the sorted design names.
    """
    designs = set.intersection(*(set(table) for table in results_by_engine.values())) - {reference}
    return sorted(d for d in designs
                  if all(table[d].ci_low > table[reference].ci_high for table in results_by_engine.values()))
