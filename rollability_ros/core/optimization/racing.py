"""Racing by successive halving: spend expensive trials (launches on the twin) on the candidates that can still win.

Every candidate still in the race gets the round's trials on the round's one seed (common random numbers: in a
round every candidate meets the same launch conditions and the same draws of the unknowns); its estimate is its
successes and trials pooled over the rounds it ran. After every round but the last, a candidate stops when

1. *racing*: it is clearly worse than the leader: the upper bound of its 95% Wilson interval is below the lower
   bound of the leader's (the leader: the highest lower bound). Two 95% Wilson intervals that do not overlap
   differ at well below the 5% level for independent samples, and common random numbers only make the
   difference's variance smaller, so the rule stops few candidates that could still lead; or
2. *halving*: it is not among the best ``max(min_keep, ceil(keep_fraction x survivors))`` by pooled fitness (ties:
   the higher lower bound, then the earlier candidate).

A ``reference`` (the bare robot) runs every round beside the candidates on the same seed and never stops: the
candidates' gain over it is measured on the same draws. The result keeps each round's estimates, so a caller can
use the first round (every candidate, the same trials) as an unbiased comparison of all candidates.
"""
import dataclasses
import math
import typing
from collections.abc import Callable, Hashable, Sequence

import numpy as np

from rollability_ros.core.optional import require
from rollability_ros.core.stats import wilson_interval


@dataclasses.dataclass(frozen=True)
class RaceResult:
    """What a race measured.

    ``totals``: {candidate: (successes, trials)} pooled over the rounds it ran; ``first_round``: {candidate:
    (successes, trials)} of round 1 (every candidate); ``reference``: (successes, trials) of the reference pooled
    over every round (or None); ``survivors``: the candidates that ran the last round, in the input order;
    ``stopped``: {candidate: (round number, reason)}; ``trials_spent``: trials of candidates and reference;
    ``rounds``: one dict per round (``round``, ``trials``, ``seed``, ``running``, ``stopped``).
    """

    totals: dict[Hashable, tuple[int, int]]
    first_round: dict[Hashable, tuple[int, int]]
    reference: tuple[int, int] | None
    survivors: list[Hashable]
    stopped: dict[Hashable, tuple[int, str]]
    trials_spent: int
    rounds: list[dict[str, int]]


def _bounds(pooled):
    successes, trials = pooled
    return wilson_interval(successes, trials)


def stop_after_round(totals: dict[Hashable, tuple[int, int]], running: list[Hashable], keep_fraction: float,
                     min_keep: int) -> dict[Hashable, str]:
    """``{candidate: reason}`` of the ``running`` candidates (in order) that stop after a round given their pooled
    ``totals`` ({candidate: (successes, trials)}); module docstring, rules 1 and 2."""
    lower = {c: _bounds(totals[c])[0] for c in running}
    leader = max(running, key=lambda c: (lower[c], -running.index(c)))
    stops = {}
    for candidate in running:
        upper = _bounds(totals[candidate])[1]
        if candidate != leader and upper < lower[leader]:
            stops[candidate] = (f"clearly worse than the leader: upper 95% bound {upper:.2f} < the leader's lower "
                                f"bound {lower[leader]:.2f}")
    left = [c for c in running if c not in stops]
    keep = max(min_keep, math.ceil(keep_fraction * len(left)))
    ranked = sorted(left, key=lambda c: (-totals[c][0] / totals[c][1], -lower[c], running.index(c)))
    for candidate in ranked[keep:]:
        stops[candidate] = f"halving: not among the best {keep} of {len(left)} by pooled fitness"
    return stops


def race(candidates: Sequence[Hashable],
         evaluate: Callable[[list[Hashable], int, int], Sequence[Sequence[int]]],
         round_trials: Sequence[int], round_seeds: Sequence[int], keep_fraction: float = 0.5, min_keep: int = 1,
         reference: Hashable | None = None) -> RaceResult:
    """Race ``candidates`` (hashable ids) by successive halving (module docstring).

    Parameters
    ----------
    candidates : list
        Ids, in a fixed order (ties go to the earlier one).
    evaluate : callable(ids, seed, trials) -> [(successes, trials), ...]
        Runs ``trials`` trials of each id with one base ``seed`` (the reference is one of the ids when given).
    round_trials, round_seeds : sequences of int, same length
        Trials per candidate and base seed of each round.
    keep_fraction : float in (0, 1]
        Share of the candidates kept after each round (halving: 0.5).
    min_keep : int >= 1
        Never keep fewer than this many after a round.
    reference : hashable, optional
        An id run every round and never stopped (the bare robot).
    """
    if len(round_trials) != len(round_seeds) or not round_trials:
        raise ValueError("a race needs at least one round, with one seed per round")
    if any(int(t) < 1 for t in round_trials):
        raise ValueError(f"every round needs at least one trial, got {list(round_trials)}")
    if not 0 < keep_fraction <= 1 or min_keep < 1:
        raise ValueError(f"need keep_fraction in (0, 1] and min_keep >= 1, got {keep_fraction}, {min_keep}")
    candidates = list(candidates)
    if len(set(candidates)) != len(candidates) or reference in candidates:
        raise ValueError("race candidates must be distinct and not the reference")
    running = list(candidates)
    totals: dict[Hashable, tuple[int, int]] = {}
    first_round: dict[Hashable, tuple[int, int]] = {}
    stopped: dict[Hashable, tuple[int, str]] = {}
    rounds: list[dict[str, int]] = []
    reference_total, spent = (0, 0), 0
    for number, (trials, seed) in enumerate(zip(round_trials, round_seeds), 1):
        ids = running + ([reference] if reference is not None else [])
        results = evaluate(ids, int(seed), int(trials))
        spent += sum(int(r[1]) for r in results)
        for candidate, result in zip(ids, results):
            pooled = (int(result[0]), int(result[1]))
            if candidate == reference and reference is not None:
                reference_total = (reference_total[0] + pooled[0], reference_total[1] + pooled[1])
                continue
            previous = totals.get(candidate, (0, 0))
            totals[candidate] = (previous[0] + pooled[0], previous[1] + pooled[1])
            if number == 1:
                first_round[candidate] = pooled
        stops = stop_after_round(totals, running, keep_fraction, min_keep) if number < len(round_trials) else {}
        rounds.append({"round": number, "trials": int(trials), "seed": int(seed), "running": len(running),
                       "stopped": len(stops)})
        for candidate, reason in stops.items():
            stopped[candidate] = (number, reason)
        running = [c for c in running if c not in stops]
    return RaceResult(totals, first_round, reference_total if reference is not None else None, running, stopped,
                      spent, rounds)


# --- sequential racing inside the optimizer ------------------------------------------------------------------------
# A candidate's ``trials`` are run in stages that end at the cumulative counts ``looks`` (then ``trials``); each stage
# runs every candidate still going on one common seed. At look k (n_k trials, x_k successes) the candidate stops when
#     P(X <= x_k | X ~ Binomial(n_k, b)) <= alpha / K,
# b being the *bar*: the lower end of the 95% Wilson interval of the estimate it must beat (CMA-ES: the incumbent;
# CMA-MAE: the elite of the candidate's archive cell). That is an exact one-sided binomial test of "p >= b" at level
# alpha / K per look; for a candidate at least as good as the bar (p >= b) the chance of being stopped at any of the K
# looks is at most alpha (union bound, and the test's power falls with p), computed exactly by
# :func:`sequential_stop_probability`.

def sequential_stages(looks: Sequence[int], trials: int) -> list[int]:
    """The trials of each stage: the increments of ``looks`` (cumulative counts) and then up to ``trials``.

    ``looks`` strictly increasing in [1, trials); ValueError otherwise. ``[]`` -> ``[trials]`` (one stage)."""
    looks = [int(n) for n in looks]
    if any(b <= a for a, b in zip(looks, looks[1:])) or (looks and not (looks[0] >= 1 and looks[-1] < trials)):
        raise ValueError(f"race_looks must be strictly increasing trial counts in [1, trials = {trials}), got {looks}")
    bounds = [0] + looks + [int(trials)]
    return [b - a for a, b in zip(bounds, bounds[1:])]


def sequential_bar(successes: int, trials: int) -> float:
    """The bar a candidate must not be clearly below: the lower end of the 95% Wilson interval of ``successes`` /
    ``trials`` (the incumbent's pooled estimate, or a cell's elite)."""
    return wilson_interval(int(successes), int(trials))[0]


def stop_count(n: int, bar: float, level: float) -> int:
    """The largest success count x with P(Binomial(n, bar) <= x) <= ``level`` (-1: none; a candidate with at most x
    successes of n stops)."""
    binom = require("scipy.stats", feature="racing's binomial test").binom

    if bar <= 0.0 or n < 1:
        return -1
    x = int(binom.ppf(level, n, bar))       # smallest x with cdf(x) >= level
    while x >= 0 and binom.cdf(x, n, bar) > level:
        x -= 1
    while x + 1 <= n and binom.cdf(x + 1, n, bar) <= level:
        x += 1
    return x


def sequential_stops(successes: int, trials: int, bar: float | None, looks: Sequence[int], alpha: float) -> bool:
    """True when a candidate at cumulative ``successes`` / ``trials`` (``trials`` one of ``looks``) stops against
    ``bar`` (None: nothing to beat, never stops) under level ``alpha`` over the len(looks) looks."""
    if bar is None or not looks:
        return False
    return successes <= stop_count(int(trials), float(bar), alpha / len(looks))


def sequential_stop_probability(looks: Sequence[int], trials: int, bar: float, alpha: float,
                                p: float) -> tuple[float, float]:
    """Exact ``(P(stopped at some look), expected trials)`` of a candidate of true success rate ``p`` raced against
    ``bar`` with ``looks`` of ``trials`` at level ``alpha`` (dynamic programme over the success count)."""
    binom = require("scipy.stats", feature="racing's binomial test").binom

    stages = sequential_stages(looks, trials)
    alive = np.zeros(int(trials) + 1)
    alive[0] = 1.0
    done, stopped, spent = 0, 0.0, 0.0
    for number, stage in enumerate(stages):
        spent += alive.sum() * stage
        step = binom.pmf(np.arange(stage + 1), stage, p)
        alive = np.convolve(alive, step)[:int(trials) + 1]
        done += stage
        if number < len(looks):
            cut = stop_count(done, bar, alpha / len(looks))
            if cut >= 0:
                stopped += alive[:cut + 1].sum()
                alive[:cut + 1] = 0.0
    return float(stopped), float(spent)


# --- successive halving inside the optimizer (``optimizer.race_survivors``) -------------------------------------------
# After a look, of the candidates the bar test left going, at most ``survivors`` go on: the best by their pooled
# estimate's improvement over their own reference (CMA-ES: the incumbent, the same for every candidate, so simply the
# best pooled estimates; CMA-MAE: the elite of the candidate's result-archive cell, an empty cell counting as 0);
# ties go to the earlier candidate (CMA-ES's samples come in random order, so that is a random tie-break). A
# candidate that stops is told its estimate so far. This is a budget rule, not a test: its cost is fixed
# (:func:`halving_trials`), and what it risks is stated by :func:`halving_drop_probability`.

def halving_survivors(totals: dict, references: dict, survivors: int) -> list:
    """The candidates (the keys of ``totals``, in their order) that go on after a look, at most ``survivors`` of them.

    ``totals``: {candidate: (successes, trials)} pooled so far; ``references``: {candidate: (successes, trials) or
    None} (None: nothing to improve on, counts as 0); ``survivors`` >= 1. Ranked by ``successes / trials -
    reference rate``, ties by order."""
    if survivors < 1:
        raise ValueError(f"survivors must be >= 1, got {survivors}")
    order = list(totals)

    def improvement(candidate: Hashable) -> float:
        successes, trials = totals[candidate]
        reference = references.get(candidate)
        base = 0.0 if reference is None else reference[0] / reference[1]
        return successes / trials - base

    ranked = sorted(order, key=lambda c: (-improvement(c), order.index(c)))
    kept = set(ranked[:survivors])
    return [c for c in order if c in kept]


def halving_trials(popsize: int, looks: typing.Sequence[int], trials: int, survivors: int) -> int:
    """The most trials a generation's population can spend under halving (no re-evaluation): every candidate runs
    to the first look, at most ``survivors`` run on to ``trials``."""
    stages = sequential_stages(looks, trials)
    return int(popsize * stages[0] + min(popsize, survivors) * (trials - stages[0]))


def halving_drop_probability(n: int, survivors: int, others: int, p: float, gap: float) -> float:
    """Exact chance that a candidate of rate ``p + gap`` is not among the best ``survivors`` after a first look of
    ``n`` trials, against ``others`` candidates of rate ``p``, every count independent and ties broken at random.

    Independent counts are the case without common random numbers; with them the candidates of a generation meet the
    same trials, their counts are positively correlated and the chance is lower (a conservative figure)."""
    binom = require("scipy.stats", feature="racing's binomial test").binom
    from math import comb

    counts = np.arange(n + 1)
    mine = binom.pmf(counts, n, min(1.0, p + gap))
    theirs = binom.pmf(counts, n, p)
    dropped = 0.0
    for count in counts:
        above = float(theirs[count + 1:].sum())
        equal = float(theirs[count])
        below = max(0.0, 1.0 - above - equal)
        kept = 0.0
        for greater in range(0, min(others, survivors - 1) + 1):
            for tied in range(0, others - greater + 1):
                chance = (comb(others, greater) * comb(others - greater, tied) * above ** greater * equal ** tied
                          * below ** (others - greater - tied))
                kept += chance * min(tied + 1, survivors - greater) / (tied + 1)
        dropped += float(mine[count]) * (1.0 - kept)
    return float(dropped)
