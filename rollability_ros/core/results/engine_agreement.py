"""Cross-engine agreement: the same trials (same seeds) simulated in two physics engines, compared.

Trial by trial (same index and seed: same start state and disturbance) and across designs (fitness ranks);
a design whose advantage over the reference (e.g. the baseline) holds in every engine is *robust to the
engine*: its Wilson 95% interval lies above the reference's in each.
"""
import dataclasses
import os
import typing

import numpy as np

from rollability_ros.core.stats import average_ranks, wilson_interval

if typing.TYPE_CHECKING:  # annotations only: the results read what the simulation returned
    from rollability_ros.core.sim import EvaluationResult, TrialOutcome


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
    def fraction(self) -> float:
        """Share of trials with the same outcome, [0, 1]."""
        return self.agreed / self.trials


def trial_agreement(first_outcomes: typing.Sequence["TrialOutcome"],
                    second_outcomes: typing.Sequence["TrialOutcome"]) -> TrialAgreement:
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


def rank_agreement(fitness_by_engine: typing.Mapping[str, typing.Mapping[str, float]]) -> float:
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
    ranks = [average_ranks([table[d] for d in designs]) for table in (first, second)]
    if np.std(ranks[0]) == 0 or np.std(ranks[1]) == 0:
        return float("nan")
    return float(np.corrcoef(ranks[0], ranks[1])[0, 1])


class WithInterval(typing.Protocol):
    """A fitness with its 95% interval: an evaluation result or an :class:`EngineRow`'s cell."""

    @property
    def ci_low(self) -> float: ...

    @property
    def ci_high(self) -> float: ...


def robust_to_engine(results_by_engine: typing.Mapping[str, typing.Mapping[str, "WithInterval"]],
                     reference: str) -> typing.List[str]:
    """Designs whose advantage over ``reference`` holds in every engine.

    ``results_by_engine``: {engine: {design: result with ci_low, ci_high}}; a design is robust when its
    ``ci_low`` exceeds the reference's ``ci_high`` in each engine. Returns the sorted design names.
    """
    designs = set.intersection(*(set(table) for table in results_by_engine.values())) - {reference}
    return sorted(d for d in designs
                  if all(table[d].ci_low > table[reference].ci_high for table in results_by_engine.values()))


def rank_agreement_p_value(fitness_by_engine: typing.Mapping[str, typing.Mapping[str, float]]) -> float:
    """One-sided exact permutation p-value of :func:`rank_agreement`: the share of the orderings of the second
    engine's fitnesses whose rank correlation with the first is at least the observed one (every ordering
    equally likely when the engines' rankings are unrelated). Needs >= 3 designs (with 2, rho can only be +-1
    and p is at least 0.5); at most 8 designs (8! orderings)."""
    import itertools

    first, second = fitness_by_engine.values()
    designs = sorted(first)
    if not 3 <= len(designs) <= 8:
        raise ValueError(f"an exact rank p-value needs 3 to 8 designs, got {len(designs)}")
    observed = rank_agreement(fitness_by_engine)
    if not np.isfinite(observed):
        return float("nan")
    values = [second[d] for d in designs]
    at_least = total = 0
    for order in itertools.permutations(values):
        rho = rank_agreement({"a": first, "b": dict(zip(designs, order))})
        total += 1
        at_least += bool(np.isfinite(rho) and rho >= observed - 1e-12)
    return at_least / total


#: Columns of ``engine_agreement.csv``: one row per design and engine.
TABLE_COLUMNS = ("design", "engine", "trials", "successes", "fitness", "ci_low", "ci_high", "seed",
                 "agreed_trials", "agreement_ci_low", "agreement_ci_high")

#: File name of the table, written next to the ``designs.yaml`` it evaluates.
TABLE_FILENAME = "engine_agreement.csv"


@dataclasses.dataclass(frozen=True)
class EngineRow:
    """One design's fitness in one engine, and how often its trials agreed with the other engine's."""

    design: str
    engine: str
    trials: int
    successes: int
    fitness: float
    ci_low: float
    ci_high: float
    seed: int
    agreed_trials: int
    agreement_ci_low: float
    agreement_ci_high: float


def table_rows(results_by_design: typing.Mapping[str, typing.Mapping[str, "EvaluationResult"]],
               seed: int) -> typing.List["EngineRow"]:
    """``[EngineRow]`` from ``{design: {engine: EvaluationResult}}`` (two engines, the same seeds)."""
    rows = []
    for design, by_engine in results_by_design.items():
        agreement = trial_agreement(*(result.trial_results for result in by_engine.values()))
        for engine, result in by_engine.items():
            rows.append(EngineRow(design, engine, result.trials, result.successes, result.fitness, result.ci_low,
                                  result.ci_high, int(seed), agreement.agreed, agreement.ci_low, agreement.ci_high))
    return rows


_Path = typing.TypeVar("_Path", str, os.PathLike)


def write_table(path: _Path, rows: typing.Iterable["EngineRow"]) -> _Path:
    """Write ``rows`` to ``path`` (CSV, :data:`TABLE_COLUMNS`); return ``path``."""
    import csv

    with open(path, "w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(TABLE_COLUMNS)
        for row in rows:
            writer.writerow([getattr(row, column) for column in TABLE_COLUMNS])
    return path


def read_table(path: typing.Union[str, os.PathLike]) -> typing.List["EngineRow"]:
    """The rows of an ``engine_agreement.csv``; ``ValueError`` naming the file and the problem otherwise."""
    import csv

    types = {field.name: field.type for field in dataclasses.fields(EngineRow)}
    rows = []
    try:
        with open(path, newline="", encoding="utf-8") as stream:
            reader = csv.DictReader(stream)
            if tuple(reader.fieldnames or ()) != TABLE_COLUMNS:
                raise ValueError(f"columns {reader.fieldnames} are not {list(TABLE_COLUMNS)}")
            for line, record in enumerate(reader, start=2):
                try:
                    values: typing.Dict[str, typing.Any] = {
                        k: (int(v) if types[k] in (int, "int") else float(v) if types[k] in (float, "float") else v)
                        for k, v in record.items()}
                except (TypeError, ValueError):
                    raise ValueError(f"line {line}: not numbers where numbers belong") from None
                row = EngineRow(**values)
                if not (0 <= row.successes <= row.trials and 0 <= row.agreed_trials <= row.trials and row.trials > 0
                        and all(np.isfinite([row.fitness, row.ci_low, row.ci_high]))):
                    raise ValueError(f"line {line}: counts or rates out of range")
                rows.append(row)
    except (OSError, UnicodeDecodeError, csv.Error, ValueError) as exc:
        raise ValueError(f"{path}: unusable engine agreement table: {exc}") from None
    engines = sorted({row.engine for row in rows})
    if len(engines) != 2 or any(sum(r.design == d for r in rows) != 2 for d in {r.design for r in rows}):
        raise ValueError(f"{path}: unusable engine agreement table: it needs every design in exactly two engines")
    return rows


def summary_lines(rows: typing.Sequence["EngineRow"], reference: str = "baseline") -> typing.List[str]:
    """Lines for the report: per design the fitness in each engine and the trial agreement, the rank agreement
    across designs (with its exact p-value, or why there is none) and the designs robust to the engine."""
    engines = sorted({row.engine for row in rows}, key=[r.engine for r in rows].index)
    table = {engine: {row.design: row for row in rows if row.engine == engine} for engine in engines}
    designs = list(table[engines[0]])
    lines = [f"cross-engine agreement (simulated; same seeds in {' and '.join(engines)}, {rows[0].trials} trials "
             f"per design, base seed {rows[0].seed}):"]
    for design in designs:
        cells = "   ".join(f"{engine} {table[engine][design].fitness:.2f} [{table[engine][design].ci_low:.2f}, "
                           f"{table[engine][design].ci_high:.2f}]" for engine in engines)
        first = table[engines[0]][design]
        lines.append(f"  {design:<10} {cells}   same outcome {first.agreed_trials}/{first.trials} trials "
                     f"[{first.agreement_ci_low:.2f}, {first.agreement_ci_high:.2f}]")
    fitness = {engine: {d: table[engine][d].fitness for d in designs} for engine in engines}
    if len(designs) >= 3:
        rho = rank_agreement(fitness)
        p = rank_agreement_p_value(fitness) if len(designs) <= 8 else float("nan")
        lines.append(f"  rank agreement across {len(designs)} designs: Spearman rho {rho:+.2f} "
                     f"(exact one-sided permutation p = {p:.3f})")
    else:
        lines.append(f"  rank agreement: not computed ({len(designs)} designs; a rank statistic needs at least 3)")
    if reference in designs:
        robust = robust_to_engine(table, reference)
        lines.append(f"  robust to the engine (Wilson interval above the {reference}'s in both): "
                     + (", ".join(robust) if robust else "none"))
    return lines
