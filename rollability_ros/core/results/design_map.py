"""The height x sharpness map of a quality-diversity run, for the report: its files, checks and headline lines.

``rollability select`` on a quality-diversity run writes, beside ``designs.yaml``:

* ``archive.csv``: one row per archive elite (``selection.ARCHIVE_COLUMNS``): its cell, maximum height (mm),
  sharpness (deg), in-run fitness and trials, the fresh screen's successes and trials, whether it made the top pool,
  and its label when chosen;
* ``traits.csv``: every evaluation of the run pooled per bin of each trait (``design_set.TRAIT_COLUMNS``).

This module reads them back (numbers only; a malformed file is a ``ValueError`` naming it) and answers the paper's
question from the data: how fitness changes with height and with sharpness (Spearman's rho over the elites'
screened fitness, with a permutation p-value; the binned curves with Wilson intervals are in the figure).
"""
import csv
import math
import typing

from rollability_ros.core.stats import spearman_permutation_test

#: File names written next to ``designs.yaml``.
ARCHIVE_FILENAME = "archive.csv"
TRAITS_FILENAME = "traits.csv"
#: The traits, their axis labels.
TRAIT_LABELS = {"max_height_mm": "maximum height (mm)", "sharpness_deg": "sharpness (deg, mean ridge angle)"}
_ARCHIVE_NUMBERS = ("cell_height", "cell_sharpness", "max_height_mm", "sharpness_deg", "in_run_fitness",
                    "in_run_trials", "screen_successes", "screen_trials", "screen_fitness", "top_pool")
#: Columns of the launch race (selection.race_launches), absent or empty in tables without one.
_RACE_NUMBERS = ("race_round1_successes", "race_round1_trials", "race_successes", "race_trials")
_TRAIT_NUMBERS = ("bin_low", "bin_high", "designs", "successes", "trials", "fitness", "ci_low", "ci_high")


def _read(path, numbers, optional=(), absent_ok=()):
    rows = []
    try:
        with open(path, newline="", encoding="utf-8") as stream:
            reader = csv.DictReader(stream)
            missing = [c for c in numbers if c not in (reader.fieldnames or ()) and c not in absent_ok]
            if missing:
                raise ValueError(f"missing column(s) {', '.join(missing)}")
            for line, record in enumerate(reader, start=2):
                row = dict(record)
                for column in numbers:
                    text = (record.get(column) or "").strip()
                    if text == "" and column in optional:
                        row[column] = math.nan
                        continue
                    try:
                        row[column] = float(text)
                    except ValueError:
                        raise ValueError(f"line {line}: {column} {text!r} is not a number") from None
                rows.append(row)
    except (OSError, UnicodeDecodeError, csv.Error, ValueError) as exc:
        raise ValueError(f"{path}: unusable design map table: {exc}") from None
    return rows


def read_archive(path: str) -> typing.List[typing.Dict[str, typing.Any]]:
    """The rows of an ``archive.csv`` (numbers as floats; no screen -> NaN screen columns)."""
    rows = _read(path, _ARCHIVE_NUMBERS + _RACE_NUMBERS,
                 optional=("screen_successes", "screen_trials", "screen_fitness") + _RACE_NUMBERS,
                 absent_ok=_RACE_NUMBERS)
    for row in rows:
        fitness = row["screen_fitness"] if math.isfinite(row["screen_fitness"]) else row["in_run_fitness"]
        if not 0 <= fitness <= 1:
            raise ValueError(f"{path}: unusable design map table: fitness {fitness} outside [0, 1]")
        row["fitness"] = fitness      # the estimate the map shows: the fresh screen when there is one
        row["label"] = (row.get("label") or "").strip()
    return rows


def read_traits(path: str) -> typing.List[typing.Dict[str, typing.Any]]:
    """The rows of a ``traits.csv`` (numbers as floats; empty bins have NaN fitness)."""
    return _read(path, _TRAIT_NUMBERS, optional=("fitness", "ci_low", "ci_high"))


def trait_trends(archive_rows: typing.Sequence[typing.Mapping[str, typing.Any]]
                 ) -> typing.Dict[str, typing.Optional[typing.Tuple[float, float, int]]]:
    """``{trait: (rho, p, n)}``: Spearman's rho between each trait and the elites' fitness (the screen's when
    there is one) with its two-sided permutation p-value; None for a trait with fewer than 3 elites."""
    trends: typing.Dict[str, typing.Optional[typing.Tuple[float, float, int]]] = {}
    for trait in TRAIT_LABELS:
        if len(archive_rows) < 3:
            trends[trait] = None
            continue
        rho, p = spearman_permutation_test([r[trait] for r in archive_rows], [r["fitness"] for r in archive_rows])
        trends[trait] = (rho, p, len(archive_rows))
    return trends


def transfer(archive_rows: typing.Sequence[typing.Mapping[str, typing.Any]]
             ) -> typing.Optional[typing.Tuple[float, float, int]]:
    """``(rho, p, n)``: Spearman's rho between the elites' screen fitness and their success on the launch race's
    first round (every raced elite, the same robust twin launches), with its two-sided permutation p-value; None
    without a race (or a screen) over at least 3 elites. It says how well the cheap trials predict what the rig
    measures."""
    raced = [r for r in archive_rows if math.isfinite(r.get("race_round1_trials", math.nan))
             and r["race_round1_trials"] > 0 and math.isfinite(r["screen_fitness"])]
    if len(raced) < 3:
        return None
    rho, p = spearman_permutation_test([r["screen_fitness"] for r in raced],
                                       [r["race_round1_successes"] / r["race_round1_trials"] for r in raced])
    return rho, p, len(raced)


def summary_lines(archive_rows: typing.Sequence[typing.Mapping[str, typing.Any]],
                  height_bound_mm: typing.Optional[float] = None) -> typing.List[str]:
    """The report's lines on the map: elites, the chosen designs' traits and height spread, and the trends."""
    if not archive_rows:
        return []
    screened = all(math.isfinite(r["screen_fitness"]) for r in archive_rows)
    source = "fresh screen of every elite" if screened else "in-run estimates (no screen: biased upward)"
    lines = [f"quality-diversity map (simulated): {len(archive_rows)} elites over maximum height x sharpness; "
             f"fitness from the {source}"]
    chosen = sorted((r for r in archive_rows if r["label"]), key=lambda r: r["label"])
    if chosen:
        heights = [r["max_height_mm"] for r in chosen]
        spread = max(heights) - min(heights)
        lines.append(f"chosen ({'screen' if screened else 'in-run'} fitness): "
                     + "; ".join(f"{r['label']} {r['max_height_mm']:.0f} mm, {r['sharpness_deg']:.0f} deg, "
                                 f"fitness {r['fitness']:.2f}" for r in chosen)
                     + f"; height spread {spread:.0f} mm"
                     + (f" = {spread / height_bound_mm:.0%} of the height bound" if height_bound_mm else ""))
    for trait, trend in trait_trends(archive_rows).items():
        name = TRAIT_LABELS[trait]
        if trend is None:
            lines.append(f"fitness vs {name}: fewer than 3 elites, no trend")
        elif not math.isfinite(trend[0]):
            lines.append(f"fitness vs {name}: undefined (constant over the elites)")
        else:
            lines.append(f"fitness vs {name} over the {trend[2]} elites: Spearman rho {trend[0]:+.2f}, two-sided "
                         f"permutation p = {trend[1]:.3f}")
    evidence = transfer(archive_rows)
    if evidence is not None:
        rho, p, n = evidence
        launches = int(next(r["race_round1_trials"] for r in archive_rows
                            if math.isfinite(r.get("race_round1_trials", math.nan))))
        lines.append(f"transfer (simulated): screen fitness vs robust twin launches ({launches} each, the launch "
                     f"race's first round) over the {n} raced elites: Spearman rho "
                     + ("undefined (constant)" if not math.isfinite(rho) else f"{rho:+.2f}, two-sided permutation "
                                                                             f"p = {p:.3f}"))
    return lines
