"""Writing a selection: the design set folder (STL, 3MF, Table 3, designs.yaml, the world check) and the run's record.

The deciding is :mod:`~rollability_ros.core.optimization.selection`; :func:`select_run` is the one flow of
``rollability select`` and the optimizer node: decide, then write here.

Outputs (``<run_dir>/designs/``, or ``designs-<n>/`` for a later selection of the same run: design sets are
append-only, see :func:`write_selection`): ``mesh_<label>.stl`` (millimetres by default, ``mesh_units``; the unit is
written in the STL header), ``mesh_<label>.3mf`` (millimetres, the 3MF unit attribute), ``table3.csv`` (the paper's Table 3 with the
simulated fitness and its Wilson interval, baseline row first; beside it the in-run estimate with its interval
and the selection bias, in-run minus fresh) and ``designs.yaml``, a ROS 2 parameter file
with the heights of each design and its grid, for the rig's simulation twin. ``selection_world_check.csv``
(:data:`~rollability_ros.core.sim.world_check.WORLD_CHECK_COLUMNS`) holds the selection's plausible-world check, and designs.yaml its ``recommendation``: the design to print first
and why (:mod:`~rollability_ros.core.optimization.recommendation`).
"""
import csv
import dataclasses
import io
import math
import os
import re
import shutil
import typing

import numpy as np
import yaml

from rollability_ros.core.profile import DESIGN_GRID_KEYS, Mesh, PrinterSpec, ProfileGrid, export_mesh, is_baseline
from rollability_ros.core.optimization.checkpoint import atomic_write_bytes
from rollability_ros.core.optimization.labelling import label_by_evidence
from rollability_ros.core.optimization.selection import (ARCHIVE_COLUMNS, GAIN_SOURCES, BatchEvaluator,
                                                          LaunchEvaluator, SelectionResult, SelectionSettings,
                                                          WorldDescriber, WorldLaunch, pool_candidates,
                                                          select_designs, select_from_archive, with_world_check)
from rollability_ros.core.stats import wilson_interval

if typing.TYPE_CHECKING:
    from rollability_ros.core.records import CandidateRecord
    from rollability_ros.core.store import Store

#: Columns of ``traits.csv``: every evaluation of the run pooled per bin of one descriptor.
TRAIT_COLUMNS = ("trait", "bin_low", "bin_high", "designs", "successes", "trials", "fitness", "ci_low", "ci_high")
#: Sub-directory of the run directory that receives the selected designs.
DESIGNS_DIRNAME = "designs"
#: Columns of ``table3.csv`` (configuration and dimensions as in ``analysis.GEOMETRY_COLUMNS``).
TABLE_COLUMNS = ("configuration", "length_m", "width_m", "max_height_m", "printed_mass_g", "simulated_fitness",
                 "ci_low", "ci_high",
                 "successes", "trials", "fitness_source", "in_run_fitness", "in_run_ci_low", "in_run_ci_high",
                 "in_run_successes", "in_run_trials", "selection_bias", "launch_successes", "launch_trials",
                 "launch_fitness", "gain_source", "gain", "gain_low", "gain_high", "beats_baseline")


def trait_rows(candidates: typing.Iterable["CandidateRecord"], grid: ProfileGrid,
               ranges: typing.Sequence[typing.Sequence[float]], bins: typing.Sequence[int]
               ) -> typing.List[typing.Dict[str, typing.Any]]:
    """Every evaluation of a run pooled per bin of each descriptor: rows with :data:`TRAIT_COLUMNS`.

    ``ranges`` ``[[0, height mm], [low, high deg]]`` and ``bins`` ``[height bins, sharpness bins]`` (the archive's
    grid). A design's evaluations all fall in its bins; the fitness of a bin is its pooled successes / trials with a
    Wilson 95% interval: how well the designs the optimizer tried with that trait did (not a random sample of
    designs).
    """
    from rollability_ros.core.profile import profile_descriptors

    pooled = [d for d in pool_candidates(candidates) if not is_baseline(d.heights)]
    measured = [profile_descriptors(d.heights, grid).as_tuple() for d in pooled]
    rows = []
    for axis, trait in enumerate(("max_height_mm", "sharpness_deg")):
        edges = np.linspace(ranges[axis][0], ranges[axis][1], int(bins[axis]) + 1)
        # the bin of each design; values below the first edge or above the last fall in the end bins
        where = [int(np.clip(np.searchsorted(edges, m[axis], side="right") - 1, 0, len(edges) - 2))
                 if math.isfinite(m[axis]) else None for m in measured]
        for number, (low, high) in enumerate(zip(edges[:-1], edges[1:])):
            members = [d for d, b in zip(pooled, where) if b == number]
            successes, trials = sum(d.successes for d in members), sum(d.trials for d in members)
            ci_low, ci_high = wilson_interval(successes, trials)
            rows.append({"trait": trait, "bin_low": float(low), "bin_high": float(high), "designs": len(members),
                         "successes": successes, "trials": trials,
                         "fitness": successes / trials if trials else math.nan, "ci_low": ci_low, "ci_high": ci_high})
    return rows


def table_rows(result: SelectionResult) -> typing.List[typing.Dict[str, typing.Any]]:
    """Rows of Table 3 as dicts with :data:`TABLE_COLUMNS` keys: the baseline first, then the designs.

    The baseline has no profile, so its dimensions are 0 m; its fitness is given only when re-evaluated. Each
    design's gain over the baseline (``gain``, Newcombe 95% ``gain_low`` .. ``gain_high``, ``beats_baseline`` when
    the interval lies above 0) is on fresh robust twin launches when there are any (``gain_source``), else on
    the fresh re-evaluation, else empty.
    """
    rows: typing.List[typing.Dict[str, typing.Any]] = []
    baseline_fitness = _fitness_columns(*result.baseline[:2], "reevaluated") if result.baseline else \
        _fitness_columns(0, 0, "not evaluated")
    rows.append({"configuration": "baseline", "length_m": 0.0, "width_m": 0.0, "max_height_m": 0.0,
                 "printed_mass_g": 0.0,
                 **baseline_fitness, **_in_run_columns(0, 0, math.nan),
                 **_launch_columns(result.baseline_launches), **_gain_columns(None)})
    for design, gain in zip(result.designs, result.gains()):
        reported = _fitness_columns(*design.reported)
        fresh = reported["simulated_fitness"] if design.reevaluation is not None else math.nan
        rows.append({"configuration": design.label, "length_m": design.metrics.length_m,
                     "width_m": design.metrics.width_m, "max_height_m": design.metrics.max_height_m,
                     "printed_mass_g": "" if design.printed_mass_kg is None else design.printed_mass_kg * 1000.0,
                     **reported, **_in_run_columns(design.design.successes, design.design.trials, fresh),
                     **_launch_columns(design.launches), **_gain_columns(gain)})
    return rows


def _launch_columns(launches):
    if launches is None:
        return {"launch_successes": "", "launch_trials": "", "launch_fitness": ""}
    return {"launch_successes": launches[0], "launch_trials": launches[1],
            "launch_fitness": launches[0] / launches[1] if launches[1] else math.nan}


def _gain_columns(gain):
    if gain is None:
        return {"gain_source": "", "gain": "", "gain_low": "", "gain_high": "", "beats_baseline": ""}
    difference, low, high = gain.interval
    return {"gain_source": gain.source, "gain": difference, "gain_low": low, "gain_high": high,
            "beats_baseline": str(bool(gain.beats)).lower()}


def _in_run_columns(successes, trials, fresh_fitness):
    """The in-run (pooled log) estimate of a design, its Wilson interval and the selection bias: in-run minus
    fresh fitness (NaN without a fresh re-evaluation). A design picked for its high logged fitness is picked
    partly for its luck, so the bias is expected to be positive."""
    low, high = wilson_interval(successes, trials)
    in_run = successes / trials if trials else math.nan
    return {"in_run_fitness": in_run, "in_run_ci_low": low, "in_run_ci_high": high, "in_run_successes": successes,
            "in_run_trials": trials, "selection_bias": in_run - fresh_fitness}


def _fitness_columns(successes, trials, source):
    low, high = wilson_interval(successes, trials)
    return {"simulated_fitness": successes / trials if trials else math.nan, "ci_low": low, "ci_high": high,
            "successes": successes, "trials": trials, "fitness_source": source}


def designs_document(result: SelectionResult, grid: ProfileGrid, run_id: str,
                     mesh_units: str = "mm") -> typing.Dict[str, typing.Any]:
    """The ``designs.yaml`` content: a ROS 2 parameter file with namespace ``designs`` (heights per label).

    Each design carries its gain over the bare robot (``gain_over_baseline``: what it was measured on, the
    difference, Newcombe's 95% interval) and ``beats_baseline`` (the interval lies above 0) when a fresh
    comparison was made; a design that does not beat the bare robot is exported for inspection, marked so."""
    body: typing.Dict[str, typing.Any] = {
        "run_id": run_id, "labels": [d.label for d in result.designs],
        "grid": {key: getattr(grid, key) for key in DESIGN_GRID_KEYS}}
    if result.baseline_launches is not None:
        body["baseline_launches"] = {"successes": result.baseline_launches[0], "trials": result.baseline_launches[1]}
    race = result.race
    if race is not None:
        body["launch_race"] = {"rounds": [r["trials"] for r in race.rounds], "designs_raced": len(race.totals),
                               "survivors": len(race.survivors), "launches_spent": race.trials_spent}
        if race.reference is not None:   # the bare robot runs every round of a selection's race
            body["launch_race"]["baseline"] = {"successes": race.reference[0], "trials": race.reference[1]}
    for design, gain in zip(result.designs, result.gains()):
        successes, trials, source = design.reported
        body[design.label] = {"heights": [float(h) for h in design.design.heights],
                              "mesh_file": f"mesh_{design.label}.stl", "mesh_units": mesh_units,
                              "fitness": successes / trials,
                              "successes": successes, "trials": trials, "fitness_source": source,
                              "why": design.reason}
        if design.descriptors is not None:
            body[design.label].update(max_height_mm=float(design.descriptors[0]),
                                      sharpness_deg=float(design.descriptors[1]),
                                      archive_cell=[int(i) for i in design.cell])
        if design.launches is not None:
            body[design.label]["launches"] = {"successes": design.launches[0], "trials": design.launches[1]}
        if gain is not None:
            difference, low, high = gain.interval
            body[design.label]["gain_over_baseline"] = {"measured_on": GAIN_SOURCES[gain.source],
                                                        "difference": float(difference),
                                                        "newcombe_95": [float(low), float(high)]}
            body[design.label]["beats_baseline"] = bool(gain.beats)
    if result.printed_with is not None:   # the lab's print instructions: the masses above assume them
        body["print"] = dict(result.printed_with)
    if result.recommendation is not None:
        body["recommendation"] = result.recommendation.as_dict()
        body["world_check"] = {"worlds": result.recommendation.worlds,
                               "launches_per_world": int((result.world_rows or [{}])[0].get("trials", 0)),
                               "file": WORLD_CHECK_FILENAME}
    return {"/**": {"ros__parameters": {"designs": body}}}


def record_selection(store: "Store", run_id: str, result: SelectionResult, folder: str = "") -> None:
    """Add ``sim_fitness`` ({configuration: fitness}) and ``geometry`` (Table 3 rows of the designs) to the run's
    info in ``store``, the keys ``rollability report`` reads; the baseline has no geometry row (no profile).
    ``folder`` is the design set written; an earlier selection's entries move to ``earlier_selections``."""
    rows = table_rows(result)
    described = store.run_info(run_id) or {"kind": "optimization", "info": {}}
    info = dict(described["info"])
    if "selection" in info:   # append-only: the earlier design set's numbers stay in the run's record
        earlier = {key: info[key] for key in ("sim_fitness", "geometry", "table3", "selection") if key in info}
        info["earlier_selections"] = [*info.get("earlier_selections", []), earlier]
    info["sim_fitness"] = {r["configuration"]: r["simulated_fitness"] for r in rows if r["trials"]}
    info["geometry"] = [{k: r[k] for k in TABLE_COLUMNS[:5]} for r in rows if r["configuration"] != "baseline"]
    info["table3"] = rows   # fresh and in-run fitness side by side, for the report's headline
    info["selection"] = {"why": {d.label: d.reason for d in result.designs},
                         "no_design_helps": result.no_design_helps(),
                         "archive_cells": {d.label: list(d.cell) for d in result.designs if d.cell is not None},
                         "top_threshold": result.top_threshold, "folder": os.path.basename(folder),
                         "recommendation": result.recommendation.as_dict() if result.recommendation else None}
    store.set_run_info(run_id, described["kind"], info)


#: The selection's quick world check in a design set (``rollability sensitivity --worlds`` writes the full check,
#: same columns, as ``world_check.csv``; the report prefers that one).
WORLD_CHECK_FILENAME = "selection_world_check.csv"


def _world_columns():
    from rollability_ros.core.sim import WORLD_CHECK_COLUMNS

    return WORLD_CHECK_COLUMNS


def _write_csv(path, columns, rows):
    table = io.StringIO()
    writer = csv.DictWriter(table, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})
    atomic_write_bytes(path, table.getvalue().encode("utf-8"))


def design_set_folders(run_dir: str) -> typing.List[str]:
    """The run's design sets in the order they were written: ``designs/``, then ``designs-2/``, ``designs-3/``, ..."""
    if not os.path.isdir(run_dir):
        return []
    pattern = re.compile(re.escape(DESIGNS_DIRNAME) + r"(-[1-9]\d*)?")
    found = [name for name in os.listdir(run_dir)
             if pattern.fullmatch(name) and os.path.isdir(os.path.join(run_dir, name))]
    return [os.path.join(run_dir, name) for name in sorted(found, key=lambda n: (len(n), n))]


def next_design_folder(run_dir: str) -> str:
    """The folder a new selection of the run writes: ``designs/`` for the first, else the next free
    ``designs-<n>/``. A written design set is never rewritten (docs/optimization.md, "Design sets are append-only")."""
    existing = design_set_folders(run_dir)
    if not existing:
        return os.path.join(run_dir, DESIGNS_DIRNAME)
    number = len(existing) + 1
    while os.path.exists(os.path.join(run_dir, f"{DESIGNS_DIRNAME}-{number}")):
        number += 1
    return os.path.join(run_dir, f"{DESIGNS_DIRNAME}-{number}")


def write_selection(run_dir: str, result: SelectionResult, grid: ProfileGrid, run_id: str,
                    mesh_units: str = "mm", traits: typing.Optional[typing.List[typing.Dict[str, typing.Any]]] = None
                    ) -> str:
    """Write the STL (in ``mesh_units``) and 3MF files, ``table3.csv`` and ``designs.yaml`` into a new design set
    folder (:func:`next_design_folder`: ``<run_dir>/designs/``, or ``designs-<n>/`` when the run has one), for a
    quality-diversity run ``archive.csv`` and the ``traits`` rows as ``traits.csv``, and the world check's rows as
    ``selection_world_check.csv``; return that folder.

    Append-only: an earlier design set (which a campaign's stored outcomes may refer to by label, and whose meshes
    may have been printed) is never touched. The set is written into a hidden temporary folder and renamed into
    place only when complete, so a killed selection leaves no half-written set.
    """
    folder = next_design_folder(run_dir)
    partial = os.path.join(run_dir, f".{os.path.basename(folder)}.partial")
    if os.path.isdir(partial):   # left by a selection killed before its rename: never referenced by anything
        shutil.rmtree(partial)
    os.makedirs(partial)
    for design in result.designs:
        export_mesh(design.mesh, os.path.join(partial, f"mesh_{design.label}.stl"), mesh_units)
        export_mesh(design.mesh, os.path.join(partial, f"mesh_{design.label}.3mf"))
    _write_csv(os.path.join(partial, "table3.csv"), TABLE_COLUMNS, table_rows(result))
    for name, columns, rows in (("archive.csv", ARCHIVE_COLUMNS, result.archive),
                                ("traits.csv", TRAIT_COLUMNS, traits),
                                (WORLD_CHECK_FILENAME, _world_columns(), result.world_rows)):
        if rows is not None:
            _write_csv(os.path.join(partial, name), columns, rows)
    text = yaml.safe_dump(designs_document(result, grid, run_id, mesh_units), sort_keys=False)
    atomic_write_bytes(os.path.join(partial, "designs.yaml"), text.encode("utf-8"))
    os.rename(partial, folder)   # fails rather than replace: a folder that appeared meanwhile is kept
    return folder


def select_run(store: "Store", run_id: str, run_dir: str, grid: ProfileGrid, printer: PrinterSpec,
               settings: SelectionSettings, evaluate_batch: typing.Optional[BatchEvaluator] = None, run_seed: int = 1,
               launch_batch: typing.Optional[LaunchEvaluator] = None,
               weigh: typing.Optional[typing.Callable[[Mesh], float]] = None,
               world_launch: typing.Optional[WorldLaunch] = None,
               describe_world: typing.Optional[WorldDescriber] = None,
               printed_with: typing.Optional[typing.Mapping[str, typing.Union[str, float]]] = None
               ) -> typing.Tuple[SelectionResult, str]:
    """Select the designs of run ``run_id`` from its logged candidates, record them in ``store`` (run info:
    simulated fitness and geometry) and write a new design set (``<run_dir>/designs/`` or ``designs-<n>/``);
    return ``(SelectionResult, folder)``. ``weigh(mesh) -> kg`` gives each design's printed mass for Table 3 (the
    robot's ``profile_body(mesh).mass_kg``: what the twin mounts); without it the column is empty.
    ``printed_with`` (the robot's ``print_instructions()``: its ``profile_print`` and ``profile_mass_scale``) goes
    into designs.yaml as ``print``: how the lab prints the designs, and what their masses assume. With
    ``settings.world_count`` the chosen designs then go through the plausible-world check on ``world_launch``
    (``describe_world(seed)`` names each world's draws) and the result carries the recommendation
    (:func:`~rollability_ros.core.optimization.selection.with_world_check`). Last the designs are labelled by the
    evidence gathered after the pick (:func:`~rollability_ros.core.optimization.labelling.label_by_evidence`): A is
    the design the world check (or, without one, the fresh launches) ranks first.

    The one selection flow of ``rollability select`` and the optimizer node: from the archive when the run has one
    (a quality-diversity run), else from the ranked log. Raises ``ValueError`` when the run
    has no evaluated candidates.
    """
    if settings.world_count and world_launch is None:   # refused before anything is launched
        raise ValueError("world_count > 0 needs a world launch evaluator (fidelity world:<seed>)")
    candidates = store.candidates(run_id=run_id)
    if not candidates:
        raise ValueError(f"run {run_id} in {run_dir} has no evaluated candidates yet")
    archive = ((store.run_info(run_id) or {}).get("info") or {}).get("archive")
    traits = None
    if archive:
        result = select_from_archive(archive, candidates, grid, printer, settings, evaluate_batch, run_seed,
                                     launch_batch)
        traits = trait_rows(candidates, grid, archive["ranges"], archive["dims"])
    else:
        result = select_designs(candidates, grid, printer, settings, evaluate_batch, run_seed, launch_batch)
    if weigh is not None:
        result = dataclasses.replace(result, designs=[dataclasses.replace(design, printed_mass_kg=weigh(design.mesh))
                                                      for design in result.designs])
    if printed_with is not None:
        result = dataclasses.replace(result, printed_with=dict(printed_with))
    result = with_world_check(result, grid, settings, world_launch, run_seed, describe_world)
    result = label_by_evidence(result, settings.recommend_world_share)
    folder = write_selection(run_dir, result, grid, run_id, settings.mesh_units, traits)
    record_selection(store, run_id, result, folder)
    return result, folder
