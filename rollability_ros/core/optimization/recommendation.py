"""The recommendation rule: which chosen design to print first, from the plausible-world check.

A design is *recommended* only where, in the world check (:mod:`~rollability_ros.core.sim.world_check`), it wins
(point gain over the bare robot > 0) in at least ``min_share`` of the worlds (``selection.recommend_world_share``,
0.9 by default) **and** its pooled gain's Newcombe 95% interval lies above 0: it beats the bare robot across what
the lab has not measured, not only on average. Recommended designs are ordered by the pooled gain's lower bound,
then the share of worlds won, then the worst world's gain; the first is the design to print first.

Later evidence can only take a recommendation away: with a campaign (:func:`with_campaign`), a recommended design whose
campaign gain's interval does not lie above 0 is not listed first, and when none is left the lead says plainly that
no design is to be printed first. Nothing here ever lists first a design that does not beat the bare robot.
"""
import dataclasses
import typing

if typing.TYPE_CHECKING:
    from rollability_ros.core.sim import WorldSummary

#: The default of ``selection.recommend_world_share``: the share of worlds a recommended design must win.
DEFAULT_WORLD_SHARE = 0.9


@dataclasses.dataclass(frozen=True)
class Recommendation:
    """The rule's verdict: the recommended designs in order (the first is to be printed first) and, for every
    design checked, the sentence saying why it is or is not recommended."""

    recommended: typing.Tuple[str, ...]
    reasons: typing.Mapping[str, str]
    min_share: float
    worlds: int
    vetoed: typing.Tuple[str, ...] = ()   # recommended by the worlds, not shown beating the bare robot by the campaign

    @property
    def first(self) -> typing.Optional[str]:
        """The design to print first, or None when no design is recommended."""
        return self.recommended[0] if self.recommended else None

    def headline(self) -> str:
        """One plain sentence: which design to print first and why, or that none is recommended."""
        if self.first is None and self.vetoed:
            return (f"NO DESIGN TO PRINT FIRST: the world check recommended {', '.join(self.vetoed)}, but the "
                    f"campaign does not show it beating the bare robot (interval not above 0)")
        if self.first is None:
            return (f"NO DESIGN IS RECOMMENDED: none beats the bare robot in at least {self.min_share:.0%} of the "
                    f"{self.worlds} plausible worlds with its pooled gain's interval above 0 (simulated)")
        return f"print design {self.first} first: {self.reasons[self.first]}"

    def as_dict(self) -> typing.Dict[str, object]:
        """Plain values for designs.yaml (a ROS 2 parameter file: no empty lists) and the run's record."""
        return {"first": self.first or "", "recommended": ", ".join(self.recommended), "min_world_share": self.min_share,
                "worlds": self.worlds, "headline": self.headline(), "why": dict(self.reasons)}


def _reason(summary: "WorldSummary", recommended: bool, min_share: float) -> str:
    gain, low, high = summary.pooled
    worst_gain, worst_low, worst_high = summary.worst.interval
    evidence = (f"wins {summary.wins}/{summary.worlds} plausible worlds ({summary.share_won:.0%}; rule >= "
                f"{min_share:.0%}), pooled gain {gain:+.2f} [{low:+.2f}, {high:+.2f}], worst world "
                f"{worst_gain:+.2f} [{worst_low:+.2f}, {worst_high:+.2f}] (simulated, Newcombe 95%)")
    if recommended:
        return f"it beats the bare robot across the plausible worlds: {evidence}"
    why = "wins too few worlds" if summary.share_won < min_share else "its pooled gain's interval is not above 0"
    return f"not recommended, {why}: {evidence}"


def recommend(summaries: typing.Sequence["WorldSummary"], min_share: float = DEFAULT_WORLD_SHARE) -> Recommendation:
    """Apply the rule (module docstring) to the world check's :class:`WorldSummary` s."""
    if not 0 <= min_share <= 1:
        raise ValueError(f"the recommendation's world share must be in [0, 1], got {min_share}")
    passing = [s for s in summaries if s.share_won >= min_share and s.pooled[1] > 0]
    ordered = sorted(passing, key=lambda s: (-s.pooled[1], -s.share_won, -s.worst.interval[0]))
    reasons = {s.configuration: _reason(s, s in passing, min_share) for s in summaries}
    return Recommendation(tuple(s.configuration for s in ordered), reasons, min_share,
                          max((s.worlds for s in summaries), default=0))


def evidence_ranking(summaries: typing.Sequence["WorldSummary"],
                     min_share: float = DEFAULT_WORLD_SHARE) -> typing.Tuple[str, ...]:
    """Every design of the world check in the order its evidence ranks them: the recommended designs first, in the
    rule's order (:func:`recommend`), then the others by the same keys (the pooled gain's lower bound, the share of
    worlds won, the worst world's gain). The selection labels its designs A, B, C in this order."""
    recommended = recommend(summaries, min_share).recommended
    return tuple(s.configuration for s in sorted(summaries, key=lambda s: (
        recommended.index(s.configuration) if s.configuration in recommended else len(recommended),
        -s.pooled[1], -s.share_won, -s.worst.interval[0])))


def with_campaign(recommendation: Recommendation,
         campaign: typing.Optional[typing.Mapping[str, typing.Tuple[float, float, float]]] = None) -> Recommendation:
    """``recommendation`` with the campaign's evidence: ``campaign`` ``{design: (gain, low, high)}`` (upright rate
    minus the bare robot's on the campaign, Newcombe 95%); a recommended design the campaign ran whose interval is
    not above 0 is no longer recommended (its reason says so). Without a campaign, unchanged."""
    if not campaign:
        return recommendation
    reasons = dict(recommendation.reasons)
    kept = []
    for label in recommendation.recommended:
        if label in campaign and not campaign[label][1] > 0:
            gain, low, high = campaign[label]
            reasons[label] = (f"not listed first: the campaign does not show it beating the bare robot ({gain:+.2f} "
                              f"[{low:+.2f}, {high:+.2f}]), though the world check recommended it: "
                              f"{recommendation.reasons[label]}")
        else:
            kept.append(label)
    vetoed = tuple(label for label in recommendation.recommended if label not in kept)
    return dataclasses.replace(recommendation, recommended=tuple(kept), reasons=reasons, vetoed=vetoed)
