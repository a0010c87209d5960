"""The report's lead: which design to print first, its gains over the bare robot, and the reason in plain words.

The evidence is the plausible-world check of the run's designs (:mod:`~rollability_ros.core.sim.world_check`:
``world_check.csv``, the full check ``rollability sensitivity --worlds N --out <designs folder>`` writes, else the
selection's quick check ``selection_world_check.csv``) and the campaign's upright launches. The rule is the
selection's (:mod:`~rollability_ros.core.optimization.recommendation`): a design is recommended only where it wins
(point gain > 0) in at least ``min_world_share`` of the worlds with its pooled gain's interval above 0; then the
campaign can only take the lead away: a design whose campaign gain's interval is not above 0 is never listed first.
When no design qualifies, or no world check was run, the lead says so first, plainly. Numbers from the twin are
labelled simulated; the campaign is labelled by where its outcomes came from.
"""
import dataclasses
import textwrap
import typing

from rollability_ros.core.optimization import recommend, with_campaign
from rollability_ros.core.sim import WorldSummary, summarize_worlds
from rollability_ros.core.stats import newcombe_interval

if typing.TYPE_CHECKING:
    from rollability_ros.core.results.analysis import CellSummary

#: Width of the lead's wrapped terminal lines, characters.
_WIDTH = 110
#: Verdicts of a lead row, in the order rows are listed.
VERDICTS = ("print first", "recommended", "not listed first", "not recommended", "not checked across worlds")


@dataclasses.dataclass(frozen=True)
class LeadRow:
    """One design in the lead table: its verdict, campaign counts against the bare robot, world check, reason."""

    design: str
    verdict: str                                   # one of VERDICTS
    campaign: typing.Optional[typing.Tuple[int, int, int, int]]   # (successes, trials, bare successes, bare trials)
    worlds: typing.Optional[WorldSummary]
    reason: str

    @property
    def campaign_gain(self) -> typing.Optional[typing.Tuple[float, float, float]]:
        """``(gain, low, high)`` on the campaign (upright rate minus the bare robot's, Newcombe 95%), or None."""
        return newcombe_interval(*self.campaign) if self.campaign is not None else None


@dataclasses.dataclass(frozen=True)
class Lead:
    """The lead: a plain headline (first in the summary and the HTML) and one row per design, best first."""

    headline: str
    rows: typing.Tuple[LeadRow, ...]
    campaign_label: str       # "simulated campaign (launch twin)", ... or "" without a campaign
    world_label: str          # what the world check was, or "" without one

    def lines(self) -> typing.List[str]:
        """The lead as terminal lines: the headline, then one line per design (each under 120 characters)."""
        lines = textwrap.wrap(f"RECOMMENDATION: {self.headline}", _WIDTH, subsequent_indent="    ")
        if self.world_label:
            lines += textwrap.wrap(f"world check: {self.world_label}", _WIDTH, initial_indent="  ",
                                   subsequent_indent="    ")
        if self.campaign_label:
            lines.append(f"  campaign: {self.campaign_label}")
        for row in self.rows:
            lines.append(f"  {row.design:<6} {row.verdict}: campaign gain {_gain_text(row.campaign_gain)}")
            lines.append(f"  {'':<6} worlds {_worlds_text(row.worlds)}")
        return lines


def _gain_text(gain: typing.Optional[typing.Tuple[float, float, float]]) -> str:
    if gain is None:
        return "-"
    return f"{gain[0]:+.2f} [{gain[1]:+.2f}, {gain[2]:+.2f}]"


def _worlds_text(summary: typing.Optional[WorldSummary]) -> str:
    if summary is None:
        return "not checked"
    return (f"won {summary.wins}/{summary.worlds} ({summary.share_won:.0%}), worst world "
            f"{_gain_text(summary.worst.interval)}, pooled {_gain_text(summary.pooled)} (simulated)")


def campaign_counts(by_configuration: typing.Iterable["CellSummary"], baseline: str = "baseline"
                    ) -> typing.Dict[str, typing.Tuple[int, int, int, int]]:
    """``{design: (successes, trials, bare successes, bare trials)}`` of the campaign's per-configuration cells
    (``analysis.CellSummary``); empty without a bare robot."""
    cells = {cell.key["configuration"]: cell for cell in by_configuration}
    bare = cells.get(baseline)
    if bare is None or not bare.trials:
        return {}
    return {name: (cell.successes, cell.trials, bare.successes, bare.trials)
            for name, cell in cells.items() if name != baseline and cell.trials}


def report_lead(world_rows: typing.Sequence[typing.Mapping[str, typing.Union[str, int, float]]], min_share: float,
                campaign: typing.Mapping[str, typing.Tuple[int, int, int, int]], campaign_label: str = "",
                world_label: str = "") -> typing.Optional[Lead]:
    """The :class:`Lead` from the world check's rows (``world_check.csv``), the recommendation's world share and
    the campaign's counts (:func:`campaign_counts`); None when there is no design to speak of."""
    summaries = {s.configuration: s for s in summarize_worlds(world_rows)}
    designs = list(summaries) + [name for name in campaign if name not in summaries]
    if not designs:
        return None
    if not summaries:
        headline = ("NO DESIGN IS RECOMMENDED: no plausible-world check of these designs was found; a design is "
                    f"recommended only where it beats the bare robot in at least {min_share:.0%} of the worlds "
                    "(rollability sensitivity --designs-file <designs.yaml> --worlds 20 --out <designs folder>)")
        rows = tuple(LeadRow(name, VERDICTS[4], campaign[name], None, "no world check")
                     for name in sorted(designs, key=lambda n: -newcombe_interval(*campaign[n])[1]))
        return Lead(headline, rows, campaign_label, world_label)
    gains = {name: newcombe_interval(*counts) for name, counts in campaign.items()}
    verdict = with_campaign(recommend(list(summaries.values()), min_share), gains)

    def status(name: str) -> str:
        if name == verdict.first:
            return VERDICTS[0]
        if name in verdict.recommended:
            return VERDICTS[1]
        return VERDICTS[2] if name in verdict.vetoed else VERDICTS[3] if name in summaries else VERDICTS[4]

    def order(name: str) -> tuple:
        rank = verdict.recommended.index(name) if name in verdict.recommended else len(designs)
        pooled_low = summaries[name].pooled[1] if name in summaries else -2.0
        return VERDICTS.index(status(name)), rank, -pooled_low
    rows = tuple(LeadRow(name, status(name), campaign.get(name), summaries.get(name),
                         verdict.reasons.get(name, "no world check"))
                 for name in sorted(designs, key=order))
    return Lead(verdict.headline(), rows, campaign_label, world_label)
