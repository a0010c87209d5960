"""Labels follow the evidence: the design labelled A is the one the evidence after the pick ranks first.

The race decides *which* designs are chosen; the labels come from the evidence gathered afterwards on all of them
alike (:func:`label_by_evidence`, :func:`evidence_order`): with the world check, A is the design the
recommendation puts first (the recommended designs in its order, then the others by their pooled gain's lower
bound); without it, the fresh robust launches rank them (designs whose gain's interval lies above 0 first). A
design picked first for a lucky race is then labelled by what its fresh launches show, and a design that does not
beat the bare robot is never labelled ahead of one that does. A campaign that runs later cannot relabel (design
sets are append-only and its outcomes are stored under these labels); it can only take the recommendation away.
"""
import dataclasses
import string
import typing

from rollability_ros.core.optimization.recommendation import evidence_ranking, recommend
from rollability_ros.core.optimization.selection import Gain, SelectionResult


def evidence_order(result: SelectionResult) -> typing.Tuple[typing.List[int], str]:
    """``(order, measure)``: the indices of ``result.designs`` as the fresh evidence after the pick ranks them, and
    what ranked them (a phrase). The race picks *which* designs are chosen, and a pick by the maximum of noisy
    launches is biased upward; the evidence gathered afterwards on every chosen design alike ranks them:

    - with the plausible-world check: the recommended designs first, in the recommendation's order (the pooled
      gain's lower bound, then the share of worlds won, then the worst world), then the others by the same keys;
    - else with fresh robust launches: the designs whose gain's interval lies above 0 first, then by the gain's
      lower bound, then the gain;
    - else the pick order.
    A design that does not beat the bare robot on that evidence is never ranked before one that does."""
    count = len(result.designs)
    if result.world_rows and result.recommendation is not None:
        from rollability_ros.core.sim import summarize_worlds

        ranking = evidence_ranking(summarize_worlds(result.world_rows), result.recommendation.min_share)
        return sorted(range(count), key=lambda i: ranking.index(result.designs[i].label)), "the plausible-world check"
    gains = result.gains()
    if gains and all(g is not None and g.source == "launches" for g in gains):
        def launch_key(i: int) -> tuple:
            gain = typing.cast(Gain, gains[i])
            return not gain.beats, -gain.interval[1], -gain.interval[0], i
        return sorted(range(count), key=launch_key), "the fresh robust launches"
    return list(range(count)), "the pick"


def label_by_evidence(result: SelectionResult, min_share: float) -> SelectionResult:
    """``result`` with its designs relabelled A, B, C, ... in :func:`evidence_order`: "A" is the design the fresh
    evidence ranks first (with the world check, the design to print first whenever one is recommended), never one
    that does not beat the bare robot while another does. Each design's reason says what ranked it and which pick
    it was; the world check's rows, the recommendation and the archive rows follow the new labels. Unchanged
    without designs."""
    if not result.designs:
        return result
    from rollability_ros.core.sim import summarize_worlds

    order, measure = evidence_order(result)
    labels = {result.designs[i].label: string.ascii_uppercase[rank] for rank, i in enumerate(order)}
    designs = []
    for rank, i in enumerate(order):
        design = result.designs[i]
        why = (f"labelled {labels[design.label]}: rank {rank + 1} of {len(order)} by {measure} (the evidence after "
               f"the pick, on every chosen design alike); pick {i + 1}: {design.reason}")
        designs.append(dataclasses.replace(design, label=labels[design.label], reason=why))
    changes: typing.Dict[str, typing.Any] = {"designs": designs}
    if result.world_rows is not None:
        rows = [{**row, "configuration": labels.get(str(row["configuration"]), row["configuration"])}
                for row in result.world_rows]
        changes["world_rows"] = rows
        changes["recommendation"] = recommend(summarize_worlds(rows), min_share)
    if result.archive is not None:
        changes["archive"] = [{**row, "label": labels.get(row["label"], row["label"])} for row in result.archive]
    return dataclasses.replace(result, **changes)
