"""The analysis report of a run: PNG figures, CSV tables, one self-contained HTML file and a text summary.

A report is built from records only (launch outcomes, candidates, generations, tip events), so the same
campaign gives the same tables and figures whether it is read from the live store, from its bag or from a CSV
of hand-recorded outcomes. Sources:

- a store file (SQLite), a run directory holding ``store.sqlite`` or a ``study`` / ``bringup`` session directory
  holding the outcome logger's ``outcomes.sqlite``;
- a recorded bag (a directory with ``metadata.yaml`` / ``*.mcap``, or one ``.mcap`` file), read through
  ``rollability_ros.core.bags.messages.read_records_from_bag``;
- a CSV of launch outcomes (``docs/outcome-csv.md``).

The per-trial drill-down lists every launch with its twin seed and, for a simulated one, the command that
simulates it again (:func:`resimulate_command`), and its pose trace in a bag next to the source.

Table 3 and the simulated fitness per configuration come from the store's run info (``geometry``,
``sim_fitness``), from ``<run dir>/designs/table3.csv`` of the design selection, or from the command line.
"""
import base64
import csv
import dataclasses
import html
import math
import os
import shlex
import typing

from rollability_ros.core.results import analysis
from rollability_ros.core.results._outcome_csv import read_outcome_csv
from rollability_ros.core.records import INVALID_LAUNCH, NO_SEED, LaunchOutcome
from rollability_ros.core.store import SESSION_STORE_FILENAME, STORE_FILENAME, Store
from rollability_ros.core.stats import newcombe_interval, wilson_interval

#: Order of configurations in figures and tables (others follow alphabetically).
CONFIGURATION_ORDER = ("baseline", "A", "B", "C")
_SQLITE_MAGIC = b"SQLite format 3\x00"
#: Table 3 written by the design selection into a run directory (``selection.write_selection``).
DESIGNS_TABLE = os.path.join("designs", "table3.csv")


@dataclasses.dataclass
class ReportData:
    """Everything a report is made of; ``sim_fitness`` maps configuration -> simulated fitness in [0, 1]."""

    source: str
    outcomes: list = dataclasses.field(default_factory=list)
    candidates: list = dataclasses.field(default_factory=list)
    generations: list = dataclasses.field(default_factory=list)
    tip_events: list = dataclasses.field(default_factory=list)
    sim_fitness: dict = dataclasses.field(default_factory=dict)
    geometry: list = dataclasses.field(default_factory=list)
    design_estimates: list = dataclasses.field(default_factory=list)   # DesignEstimate per configuration
    engine_rows: list = dataclasses.field(default_factory=list)   # engine_agreement.EngineRow, design x engine
    archive_rows: list = dataclasses.field(default_factory=list)  # design_map.read_archive rows (QD runs)
    trait_rows: list = dataclasses.field(default_factory=list)    # design_map.read_traits rows (QD runs)
    design_meshes: dict = dataclasses.field(default_factory=dict)  # label -> mesh file of the chosen designs
    design_folders: list = dataclasses.field(default_factory=list)  # the designs/ folders of this run (design_folders)
    notes: list = dataclasses.field(default_factory=list)         # lines on what the report could not draw


@dataclasses.dataclass(frozen=True)
class DesignEstimate:
    """A configuration's simulated fitness two ways (Table 3 of the selection): the fresh re-evaluation, the
    in-run estimate the optimizer logged, and the selection bias (in-run minus fresh); counts are trials."""

    configuration: str
    fresh_successes: int
    fresh_trials: int
    in_run_successes: int
    in_run_trials: int

    @property
    def fresh(self) -> float:
        """Fresh fitness, NaN when not re-evaluated."""
        return self.fresh_successes / self.fresh_trials if self.fresh_trials else math.nan

    @property
    def in_run(self) -> float:
        """In-run (logged, pooled) fitness, NaN when none was logged (the baseline)."""
        return self.in_run_successes / self.in_run_trials if self.in_run_trials else math.nan

    @property
    def selection_bias(self) -> float:
        """In-run minus fresh fitness (NaN without both)."""
        return self.in_run - self.fresh

    def text(self) -> str:
        """One summary line: fresh with its Wilson 95% interval, in-run with its interval, the bias."""
        def rate(successes: int, trials: int) -> str:
            if not trials:
                return f"{'-':>22}"
            low, high = wilson_interval(successes, trials)
            return f"{successes:>4}/{trials:<4} {successes / trials:4.2f} [{low:.2f}, {high:.2f}]"
        bias = f"{self.selection_bias:+.2f}" if math.isfinite(self.selection_bias) else "-"
        return (f"{self.configuration:<10} {rate(self.fresh_successes, self.fresh_trials)}   "
                f"{rate(self.in_run_successes, self.in_run_trials)}   {bias:>5}")


def design_estimates(rows: typing.Iterable[typing.Mapping[str, typing.Any]],
                     path: typing.Union[str, os.PathLike]) -> typing.List[DesignEstimate]:
    """The :class:`DesignEstimate` s of Table 3 rows (``selection.TABLE_COLUMNS``; a table without the in-run
    columns gives none); ``ValueError`` naming ``path`` and the cell for a count that is not a whole number."""
    estimates = []
    for row in rows:
        if "in_run_trials" not in row:
            return []
        counts: typing.Dict[str, int] = {}
        for column in ("successes", "trials", "in_run_successes", "in_run_trials"):
            try:
                counts[column] = int(float(row[column] or 0))
            except (TypeError, ValueError):
                raise ValueError(f"{path}: {column} of {row['configuration']} is not a count: {row[column]!r}") \
                    from None
        fresh = str(row.get("fitness_source", "")) == "reevaluated"
        estimates.append(DesignEstimate(str(row["configuration"]), counts["successes"] if fresh else 0,
                                        counts["trials"] if fresh else 0, counts["in_run_successes"],
                                        counts["in_run_trials"]))
    return estimates


@dataclasses.dataclass(frozen=True)
class ReportResult:
    """Paths written by :func:`build_report` and the text summary."""

    html_path: str
    figure_paths: typing.List[str]
    table_paths: typing.List[str]
    summary: str


def source_kind(path: typing.Union[str, os.PathLike]) -> str:
    """``"store"``, ``"bag"`` or ``"csv"`` for a report source; ValueError if it is none of them."""
    path = os.fspath(path)
    if os.path.isdir(path):
        if directory_store(path):
            return "store"
        if os.path.isfile(os.path.join(path, "metadata.yaml")) or any(n.endswith(".mcap") for n in os.listdir(path)):
            return "bag"
        raise ValueError(f"{path}: a directory without {STORE_FILENAME} (a run), {SESSION_STORE_FILENAME} (a study "
                         "or bringup session), metadata.yaml or .mcap files (a bag)")
    if not os.path.isfile(path):
        raise FileNotFoundError(f"report source not found: {path}")
    if path.lower().endswith(".csv"):
        return "csv"
    if path.lower().endswith(".mcap"):
        return "bag"
    with open(path, "rb") as stream:
        if stream.read(len(_SQLITE_MAGIC)) == _SQLITE_MAGIC:
            return "store"
    raise ValueError(f"{path}: not a store (SQLite), a bag (.mcap) or a CSV of outcomes")


def directory_store(directory: str) -> str:
    """The store file of a run directory (``store.sqlite``) or of a session directory (``outcomes.sqlite``, what
    ``bringup`` and ``study`` write), or "" when it has neither."""
    for name in (STORE_FILENAME, SESSION_STORE_FILENAME):
        if os.path.isfile(os.path.join(directory, name)):
            return os.path.join(directory, name)
    return ""


def load_report_data(source: typing.Union[str, os.PathLike], run_id: typing.Optional[str] = None) -> ReportData:
    """Read the records of ``source`` (see module docstring) for one campaign run.

    ``run_id`` selects the launch outcomes of one campaign run; it may be omitted when the source holds one.
    Candidates, generations and tip events are all kept (each optimization run is its own convergence line).
    A store's run info for the selected run may carry ``sim_fitness`` ({configuration: fitness}) and
    ``geometry`` (Table 3 rows).
    """
    kind = source_kind(source)
    source = os.fspath(source)
    data = ReportData(source=f"{kind} {source}")
    run_info = None
    if kind == "store":
        with Store(directory_store(source) if os.path.isdir(source) else source) as store:
            data.outcomes = store.launch_outcomes()
            data.candidates = store.candidates()
            data.generations = store.generations()
            data.tip_events = store.tip_events()
            selected = _select_run(data, run_id)
            run_info = store.run_info(selected) if selected else None
    else:
        if kind == "csv":
            data.outcomes = read_outcome_csv(source, run_id=run_id or "csv")
        else:
            from rollability_ros.core.bags import read_records_from_bag

            data.outcomes, data.candidates, data.generations, data.tip_events = (
                list(records) for records in read_records_from_bag(source))
        _select_run(data, run_id)
    info = (run_info or {}).get("info", {})
    data.sim_fitness = {str(k): float(v) for k, v in info.get("sim_fitness", {}).items()}
    data.geometry = analysis.geometry_table(info.get("geometry", []), CONFIGURATION_ORDER)
    data.design_estimates = design_estimates(info.get("table3", []), source)
    data.design_folders = design_folders(source, info)
    table3 = os.path.join(source, DESIGNS_TABLE)
    if kind == "store" and os.path.isdir(source) and os.path.isfile(table3) and not data.geometry:
        use_geometry_csv(data, table3)
    data.engine_rows = _engine_rows(data.design_folders)
    _design_map(data)
    return data


#: Where a run keeps its chosen designs, relative to its folder: an optimization run directory's own
#: ``designs/`` (and ``designs-<n>/`` of later selections), and a study's ``optimization/designs/``
#: (``core/graph/study.py``).
RUN_DESIGN_FOLDERS = ("designs", os.path.join("optimization", "designs"))


def _design_sets(folder):
    """``folder`` (a ``designs/`` path) and its later selections ``designs-<n>/`` beside it, in the order written."""
    import glob

    later = [path for path in glob.glob(folder + "-*") if path.rsplit("-", 1)[1].isdigit()]
    return [folder] + sorted(later, key=lambda path: int(path.rsplit("-", 1)[1]))


def design_folders(source: typing.Union[str, os.PathLike],
                   run_info: typing.Optional[typing.Mapping[str, typing.Any]] = None) -> typing.List[str]:
    """The ``designs/`` folders of the run ``source`` names, never a sibling run's: the folder of the
    ``designs_file`` (and of the ``mesh_files``) recorded in the selected campaign run's info (``run_info``: the
    ``info`` dict), only those when recorded (a later ``select`` writes ``designs-<n>/`` beside the set the
    campaign launched, which it never used); else :data:`RUN_DESIGN_FOLDERS` of the source's own folder (of the
    study or session folder for a bag inside one) with their later sets. Absolute paths, existing folders only."""
    source = os.fspath(source)
    base = os.path.abspath(source if os.path.isdir(source) else os.path.dirname(os.path.abspath(source)))
    roots = [base, os.path.dirname(base)] if _is_bag(base) else [base]
    recorded = (run_info or {}).get("designs", {})
    named = [os.path.dirname(path) for path in [recorded.get("designs_file", "")] +
             list(recorded.get("mesh_files", {}).values()) if path]
    folders = []
    own = [path for root in roots for name in RUN_DESIGN_FOLDERS for path in _design_sets(os.path.join(root, name))]
    for folder in named or own:
        folder = os.path.abspath(folder)
        if os.path.isdir(folder) and folder not in folders:
            folders.append(folder)
    return folders


def _design_map(data):
    """Read the quality-diversity map (``archive.csv``, ``traits.csv``) and the chosen designs' mesh files
    written next to the ``designs.yaml`` of the run's design folders, if any."""
    from rollability_ros.core.results import design_map

    for designs_yaml in [path for path, _ in find_artefacts(data.design_folders)
                         if os.path.basename(path) == "designs.yaml"]:
        folder = os.path.dirname(designs_yaml)
        archive = os.path.join(folder, design_map.ARCHIVE_FILENAME)
        traits = os.path.join(folder, design_map.TRAITS_FILENAME)
        sensitivity = os.path.join(folder, SENSITIVITY_FILENAME)
        if os.path.isfile(sensitivity):
            data.notes.extend(_sensitivity_lines(sensitivity))
        if os.path.isfile(archive):
            data.archive_rows = design_map.read_archive(archive)
            data.trait_rows = design_map.read_traits(traits) if os.path.isfile(traits) else []
        data.design_meshes = {name[len("mesh_"):-len(".stl")]: os.path.join(folder, name)
                              for name in sorted(os.listdir(folder))
                              if name.startswith("mesh_") and name.endswith(".stl")}
        return


#: A sensitivity table (``rollability sensitivity --designs-file .../designs.yaml --out <designs folder>``) next
#: to the designs: the report gives each design minus the bare chassis per unknown factor.
SENSITIVITY_FILENAME = "sensitivity.csv"


def _sensitivity_lines(path):
    """The summary lines of a ``sensitivity.csv`` (:func:`~rollability_ros.core.sim.sensitivity.gain_lines`);
    ``ValueError`` naming the file when it is unusable."""
    from rollability_ros.core.results.sensitivity_table import gain_lines

    try:
        with open(path, newline="", encoding="utf-8") as stream:
            return gain_lines(list(csv.DictReader(stream)))
    except (OSError, KeyError, ValueError, csv.Error) as exc:
        raise ValueError(f"{path}: unusable sensitivity table: {exc!r}") from None


def _engine_rows(folders):
    """The cross-engine table (``rollability evaluate --designs ... --engines ...``) of the designs in the run's
    design ``folders``, if one was written; ``ValueError`` naming the file when it is unusable."""
    from rollability_ros.core.results import engine_agreement

    for designs_yaml in [path for path, _ in find_artefacts(folders) if os.path.basename(path) == "designs.yaml"]:
        path = os.path.join(os.path.dirname(designs_yaml), engine_agreement.TABLE_FILENAME)
        if os.path.isfile(path):
            return engine_agreement.read_table(path)
    return []


def use_geometry_csv(data: ReportData, path: str) -> None:
    """Take Table 3 from a CSV (``designs/table3.csv`` of the selection); its ``simulated_fitness`` column
    fills in the simulated fitness of configurations that have none yet (empty or NaN cells are skipped)."""
    with open(path, newline="", encoding="utf-8-sig") as stream:
        data.geometry = analysis.geometry_table(list(csv.DictReader(stream)), CONFIGURATION_ORDER)
    data.design_estimates = design_estimates(data.geometry, path)
    for row in data.geometry:
        try:
            fitness = float(row.get("simulated_fitness", "nan"))
        except ValueError:
            raise ValueError(f"{path}: simulated_fitness of {row['configuration']} is not a number") from None
        if math.isfinite(fitness):
            data.sim_fitness.setdefault(row["configuration"], fitness)


def _select_run(data, run_id):
    """Keep the outcomes of ``run_id`` (or of the only run); return the run id selected or None."""
    runs = sorted({o.run_id for o in data.outcomes})
    if run_id is None:
        if len(runs) > 1:
            raise ValueError(f"{data.source} holds launch outcomes of several runs ({', '.join(runs)}); "
                             f"choose one with --run")
        return runs[0] if runs else None
    if data.outcomes and run_id not in runs:
        raise ValueError(f"{data.source} has no launch outcomes of run {run_id!r}; runs: {', '.join(runs)}")
    data.outcomes = [o for o in data.outcomes if o.run_id == run_id]
    return run_id


def _write_csv(path, rows):
    columns = []
    for row in rows:
        columns += [c for c in row if c not in columns]
    with open(path, "w", newline="", encoding="utf-8") as stream:
        writer = csv.DictWriter(stream, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    return path


def _format_cell(column, value):
    if isinstance(value, float):
        if math.isnan(value):
            return "–"
        if "rate" in column or column.startswith(("trial_ci", "ci_")) or column == "sim_fitness":
            return f"{value:.0%}"
        return f"{value:.4g}"
    return str(value)


def _html_table(rows):
    if not rows:
        return "<p>(no rows)</p>"
    columns = list(rows[0])
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(_format_cell(c, row.get(c, '')))}</td>" for c in columns)
                   + "</tr>" for row in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _tables(data, views, comparison, points):
    """``{table name: rows}`` of every table the data allows (names are the CSV file stems)."""
    tables = {}
    if views is not None:
        tables["conditions"] = [{**dataclasses.asdict(c), "failures": c.failures, "majority_success": c.success}
                                for c in views.conditions]
        for name in ("by_configuration", "height_angle", "speed_angle", "by_speed", "by_height", "by_angle"):
            tables[name] = [cell.row() for cell in getattr(views, name)]
    if comparison is not None and comparison.rows:
        tables["sim_vs_experiment"] = comparison.rows
    if points:
        tables["convergence"] = [dataclasses.asdict(p) for p in points]
    if data.geometry:
        tables["geometry"] = data.geometry
    if data.tip_events:
        tables["tip_events"] = analysis.tip_event_summary(data.tip_events)
    if data.engine_rows:
        tables["engine_agreement"] = [dataclasses.asdict(row) for row in data.engine_rows]
    if data.archive_rows:
        tables["archive"] = [{k: v for k, v in row.items() if k != "fitness"} for row in data.archive_rows]
    if data.trait_rows:
        tables["traits"] = data.trait_rows
    return tables


_TABLE_TITLES = {
    "by_configuration": "Overall success per configuration (Figure 12d)",
    "sim_vs_experiment": "Simulated fitness vs campaign success (Discussion; the campaign's kind is in the summary)",
    "geometry": "Profile mesh geometry (Table 3), m; printed mass, g (as the twin mounts it)",
    "convergence": "Optimization convergence per generation (Figure 4)",
    "tip_events": "Field tip events per robot",
    "height_angle": "Success by height x angle per configuration (Figure 9)",
    "speed_angle": "Success by speed x angle per configuration (Figures 10, 11)",
    "by_speed": "Success by speed (Figure 12a)",
    "by_height": "Success by height (Figure 12b)",
    "by_angle": "Success by angle (Figure 12c)",
    "conditions": "Grouped conditions (majority rule: successes > failures; a tie is a failure)",
    "engine_agreement": "Cross-engine agreement: each design's simulated fitness in two engines on the same seeds",
    "archive": "Quality-diversity archive: every elite with its traits, in-run and fresh-screen fitness (simulated)",
    "traits": "Every evaluation of the run pooled per bin of maximum height and of sharpness (simulated)",
}


def _trait_edges(trait_rows):
    """``{trait: bin edges}`` of the archive's grid, from the traits table."""
    edges = {}
    for trait in ("max_height_mm", "sharpness_deg"):
        own = [r for r in trait_rows if r["trait"] == trait]
        edges[trait] = [own[0]["bin_low"]] + [r["bin_high"] for r in own] if own else []
    return edges


def _design_figures(out_dir, data, draw):
    """The map, the trait curves and a preview of each chosen design (previews need trimesh, the sim extra)."""
    from rollability_ros.core.results import report_figures as figures

    if data.archive_rows and data.trait_rows:
        edges = _trait_edges(data.trait_rows)
        draw("design_map.png", "Height x sharpness map of the quality-diversity archive (simulated): each cell's "
             "elite coloured by its fitness, the chosen designs boxed", figures.archive_map, data.archive_rows, edges)
        draw("design_traits.png", "How fitness changes with maximum height and with sharpness (simulated): every "
             "evaluation pooled per bin with Wilson 95% bands, archive elites as points", figures.trait_curves,
             data.trait_rows, data.archive_rows)
    if data.design_meshes:
        from rollability_ros.core.optional import MissingDependency
        from rollability_ros.core.profile import load_profile_mesh

        traits = {r["label"]: r for r in data.archive_rows if r["label"]}
        for label, mesh_path in data.design_meshes.items():
            try:
                mesh = load_profile_mesh(mesh_path)
            except MissingDependency as exc:
                data.notes.append(f"design previews not drawn: {exc}")
                return
            trait = traits.get(label)
            title = f"Design {label}" + (f": {trait['max_height_mm']:.0f} mm, {trait['sharpness_deg']:.0f} deg"
                                         if trait else "")
            draw(f"design_{label}.png", f"Preview of design {label} ({os.path.basename(mesh_path)})",
                 lambda path, solid, heading: figures.render_profile_preview(solid, path, heading), mesh, title)


def _figures(out_dir, views, configurations, comparison, points, engine_rows=(), data=None):
    """Draw every figure the data allows; return ``[(path, caption)]``."""
    from rollability_ros.core.results import report_figures as figures

    drawn = []

    def draw(name: str, caption: str, function: typing.Callable[..., str], *args: typing.Any) -> None:
        drawn.append((function(os.path.join(out_dir, name), *args), caption))

    if views is not None:
        draw("fig09_height_angle.png", "Figure 9: success by height and angle", figures.heatmaps,
             views.height_angle, configurations, "height_m", "Success by launch height and angle")
        draw("fig10_speed_angle.png", "Figure 10: success by speed and angle", figures.heatmaps,
             views.speed_angle, configurations, "speed_mps", "Success by launch speed and angle")
        draw("fig11_angle_curves.png", "Figure 11: success by angle per speed", figures.angle_curves,
             views.speed_angle, configurations)
        draw("fig12_overall.png", "Figure 12: overall success by speed, height, angle and configuration "
             "(grouped conditions, the paper's measure)", figures.overall, views, configurations, "condition_rate")
        draw("fig12b_overall_trials.png", "Figure 12 by trials: the same views as the fraction of upright trials, "
             "with Wilson 95% intervals", figures.overall, views, configurations, "trial_rate")
    if comparison is not None and comparison.rows:
        draw("sim_vs_experiment.png", f"Simulated fitness vs {comparison.campaign} campaign success",
             figures.sim_vs_experiment, comparison)
    if points:
        draw("fig04_convergence.png", "Figure 4: optimization convergence", figures.convergence_figure, points)
    if engine_rows:
        draw("engine_agreement.png", "Cross-engine agreement (simulated): each design's fitness in both engines on "
             "the same seeds, with Wilson 95% intervals", figures.engine_fitness, engine_rows)
    if data is not None:
        _design_figures(out_dir, data, draw)
    return drawn


def selection_gain_lines(table3_rows: typing.Sequence[typing.Mapping[str, typing.Any]]) -> typing.List[str]:
    """The summary's lines on each chosen design's gain over the bare robot as the selection measured it (Table 3's
    ``gain*`` columns: fresh robust twin launches, or the fresh re-evaluation), with Newcombe's 95% interval, and
    a plain sentence when no design beats the bare robot. Empty when Table 3 has no gains."""
    from rollability_ros.core.optimization import GAIN_SOURCES

    rows = [r for r in table3_rows if str(r.get("gain_source") or "") in GAIN_SOURCES]
    if not rows:
        return []
    baseline = next((r for r in table3_rows if r.get("configuration") == "baseline"), {})
    source = str(rows[0]["gain_source"])
    count = "launch" if source == "launches" else ""
    base = (f"bare robot {int(float(baseline[count + '_successes' if count else 'successes']))}/"
            f"{int(float(baseline[count + '_trials' if count else 'trials']))}") if baseline else "bare robot"
    lines = [f"gain of each chosen design over the bare robot (simulated; {GAIN_SOURCES[source]}; {base}; "
             f"Newcombe 95%):"]
    for row in rows:
        beats = str(row.get("beats_baseline")).lower() == "true"
        lines.append(f"  {row['configuration']:<8} {float(row['gain']):+.2f} [{float(row['gain_low']):+.2f}, "
                     f"{float(row['gain_high']):+.2f}]  {'beats the bare robot' if beats else 'does NOT beat the bare robot'}")
    if not any(str(r.get("beats_baseline")).lower() == "true" for r in rows):
        lines.append("NO DESIGN BEATS THE BARE ROBOT on this measure: the designs are written for inspection, not "
                     "as improvements")
    return lines


def campaign_gain_lines(by_configuration: typing.Iterable[analysis.CellSummary], label: str) -> typing.List[str]:
    """Each configuration's upright rate over the campaign's trials minus the baseline's, with Newcombe's 95%
    interval, and a plain sentence when no design's interval lies above 0 (empty without a baseline)."""
    cells = {cell.key["configuration"]: cell for cell in by_configuration}
    baseline = cells.get("baseline")
    designs = [c for name, c in cells.items() if name != "baseline"]
    if baseline is None or not designs or not baseline.trials:
        return []
    lines = [f"{label}: trials upright minus the baseline's (Newcombe 95%):"]
    beats = 0
    for cell in designs:
        difference, low, high = newcombe_interval(cell.successes, cell.trials, baseline.successes, baseline.trials)
        beats += low > 0
        lines.append(f"  {cell.key['configuration']:<8} {difference:+.2f} [{low:+.2f}, {high:+.2f}]  "
                     + ("above the baseline" if low > 0 else "below the baseline" if high < 0 else
                        "not distinguishable from the baseline"))
    if not beats:
        lines.append("NO DESIGN BEATS THE BASELINE in this campaign (no interval above 0)")
    return lines


def summary_text(data: ReportData, views: typing.Optional[analysis.Views],
                 comparison: typing.Optional[analysis.SimVsExperiment],
                 points: typing.Sequence[analysis.ConvergencePoint]) -> str:
    """A few lines describing the report's data and headline numbers: the chosen designs' fresh re-evaluations
    first (with the in-run estimates beside them and the selection bias), then the campaign, labelled simulated
    or experimental by where its outcomes came from."""
    lines = [f"source: {data.source}"]
    if data.design_estimates:
        lines.append("simulated fitness of the chosen designs: fresh re-evaluation (headline) vs in-run estimate "
                     "(Wilson 95% CI; selection bias = in-run - fresh)")
        lines.append(f"{'design':<10} {'fresh':<22}   {'in-run':<22}   {'bias':>5}")
        lines.extend(estimate.text() for estimate in data.design_estimates)
    lines.extend(selection_gain_lines(data.geometry))
    if views is not None:
        runs = sorted({o.run_id for o in data.outcomes})
        backends = sorted({o.backend for o in data.outcomes})
        valid = sum(o.valid for o in data.outcomes)
        invalid = len(data.outcomes) - valid
        kind = analysis.campaign_kind(data.outcomes)
        label = {"simulated": "simulated campaign (launch twin)", "experimental": "experimental campaign (rig)",
                 "mixed": "mixed campaign (launch twin and rig)"}[kind]
        lines.append(f"launch outcomes, {label}: {valid} trials, {len(views.conditions)} grouped conditions "
                     f"(run {', '.join(runs)}; backend {', '.join(backends)})"
                     + (f"; {invalid} invalid launch(es) left out" if invalid else ""))
        lines.append(f"{'configuration':<14} {'conditions ok':>13} {'trials upright':>15}  95% CI")
        for cell in views.by_configuration:
            low, high = cell.trial_ci
            lines.append(f"{cell.key['configuration']:<14} {cell.conditions_succeeded:>4}/{cell.conditions:<3} "
                         f"{cell.condition_rate:>4.0%} {cell.successes:>5}/{cell.trials:<4} {cell.trial_rate:>4.0%}"
                         f"  [{low:.0%}, {high:.0%}]")
        lines.extend(campaign_gain_lines(views.by_configuration, label))
    else:
        lines.append("launch outcomes: none")
    if comparison is not None and comparison.rows:
        lines.append(f"simulated fitness vs {comparison.campaign} campaign ({len(comparison.rows)} configurations): "
                     f"{comparison.agreement_text()}")
    if points:
        for run_id in sorted({p.run_id for p in points}):
            own = [p for p in points if p.run_id == run_id]
            lines.append(f"optimization run {run_id!r}: {len(own)} generations, best in-run fitness "
                         f"{own[-1].best_so_far:.3f} (an estimate picked as a maximum: biased upward"
                         + ("; the fresh re-evaluations above are the headline)" if data.design_estimates else ")"))
    if data.tip_events:
        recovered = sum(e.recovered for e in data.tip_events)
        lines.append(f"tip events: {len(data.tip_events)}, recovered {recovered}")
    if data.engine_rows:
        from rollability_ros.core.results.engine_agreement import summary_lines

        lines.extend(summary_lines(data.engine_rows))
    if data.archive_rows:
        from rollability_ros.core.results import design_map

        edges = _trait_edges(data.trait_rows).get("max_height_mm") if data.trait_rows else None
        lines.extend(design_map.summary_lines(data.archive_rows, edges[-1] if edges else None))
    lines.extend(data.notes)
    return "\n".join(lines)


def refuse_all_invalid(data: ReportData) -> None:
    """``ValueError`` (one line) when ``data`` has launch outcomes but every one is an invalid launch: nothing to
    analyse, and the cause is the rig's set-up, not the robot."""
    if not data.outcomes or any(outcome.valid for outcome in data.outcomes):
        return
    reasons = [outcome.note[len(INVALID_LAUNCH):] for outcome in data.outcomes]
    common = max(set(reasons), key=reasons.count)
    raise ValueError(f"{data.source}: all {len(reasons)} launch outcomes are invalid launches (most often: {common})"
                     ", so there is nothing to analyse; fix the launcher (rollability campaign names the setting) "
                     "and run the campaign again")


def check_report_dir(out_dir: typing.Union[str, os.PathLike]) -> None:
    """Raise ValueError unless ``out_dir`` is missing, empty, or holds an earlier report (``report.html``): a report
    never writes into a file's place or among other results (a run or bag folder)."""
    if os.path.lexists(out_dir) and not os.path.isdir(out_dir):
        raise ValueError(f"report output {out_dir} is an existing file, not a folder; choose another --out")
    if os.path.isdir(out_dir) and os.listdir(out_dir) and not os.path.isfile(os.path.join(out_dir, "report.html")):
        raise ValueError(f"report output {out_dir} holds other files (no earlier report.html in it); choose a new "
                         "or empty folder for --out")


def build_report(data: ReportData, out_dir: typing.Union[str, os.PathLike],
                 measure: str = "condition_rate") -> ReportResult:
    """Write figures (PNG), tables (CSV) and ``report.html`` (self-contained) to ``out_dir``.

    Parameters
    ----------
    data : ReportData
    out_dir : str or os.PathLike
        Created if missing; an earlier report in it (a folder with ``report.html``) is overwritten. A file, or a
        folder holding anything but a report, is refused (ValueError) before anything is written.
    measure : str
        Experimental measure compared with simulated fitness: ``"condition_rate"`` (paper) or ``"trial_rate"``.
    """
    out_dir = os.fspath(out_dir)
    check_report_dir(out_dir)
    refuse_all_invalid(data)
    os.makedirs(out_dir, exist_ok=True)
    views = analysis.paper_views(data.outcomes, CONFIGURATION_ORDER) if data.outcomes else None
    configurations = analysis.configurations_in(views.conditions, CONFIGURATION_ORDER) if views else []
    comparison = (analysis.sim_vs_experiment(data.sim_fitness, views.by_configuration, measure,
                                             analysis.campaign_kind(data.outcomes))
                  if views is not None and data.sim_fitness else None)
    points = analysis.convergence(data.generations, data.candidates)
    if views is None and not points and not data.tip_events:
        raise ValueError(f"{data.source}: no launch outcomes, candidates, generations or tip events to report")
    tables = _tables(data, views, comparison, points)
    table_paths = [_write_csv(os.path.join(out_dir, f"{name}.csv"), rows) for name, rows in tables.items()]
    figures = _figures(out_dir, views, configurations, comparison, points, data.engine_rows, data)
    summary = summary_text(data, views, comparison, points)
    html_path = os.path.join(out_dir, "report.html")
    artefacts = find_artefacts(data.design_folders, data.source.split(" ", 1)[-1]) + \
        [(path, "table (CSV)") for path in table_paths]
    trace = _pose_windows(data.outcomes, [p for p, kind in artefacts if kind == "bag"])
    with open(html_path, "w", encoding="utf-8") as stream:
        stream.write(_html(data, summary, figures, tables, artefacts, trace, out_dir))
    return ReportResult(html_path, [path for path, _ in figures], table_paths, summary)


_STYLE = """
body { font-family: sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
img { max-width: 100%; border: 1px solid #ddd; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; font-size: 0.85em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: right; }
th { background: #f0f0f0; }
pre { background: #f7f7f7; padding: 0.8em; }
"""


def find_artefacts(folders: typing.Iterable[str], source: typing.Optional[typing.Union[str, os.PathLike]] = None
                   ) -> typing.List[typing.Tuple[str, str]]:
    """``[(path, kind)]`` of the files a report links: design meshes (STL, 3MF), their Table 3 and ``designs.yaml``
    in the run's design ``folders`` (:func:`design_folders`: never a sibling run's), and recorded bags (folders
    with ``metadata.yaml``, or the source bag itself) in or next to ``source``."""
    import glob

    found = []
    for folder in folders:
        for pattern, kind in (("mesh_*.stl", "design mesh (STL, millimetres unless its header says m)"),
                              ("mesh_*.3mf", "design mesh (3MF)"), ("table3.csv", "Table 3 (CSV)"),
                              ("designs.yaml", "design heights (ROS 2 parameter file)"),
                              ("archive.csv", "quality-diversity archive: every elite (CSV)"),
                              ("traits.csv", "fitness per height and sharpness bin (CSV)")):
            found += [(path, kind) for path in sorted(glob.glob(os.path.join(folder, pattern)))]
    if source is None:
        return found
    source = os.fspath(source)
    base = os.path.abspath(source if os.path.isdir(source) else os.path.dirname(os.path.abspath(source)))
    # a bag inside a study or session folder: the other bags sit next to it
    roots = [base, os.path.dirname(os.path.abspath(base))] if _is_bag(base) else [base]
    bags = {root for root in roots if _is_bag(root)}
    bags |= {os.path.dirname(p) for root in roots for p in glob.glob(os.path.join(root, "*", "metadata.yaml"))}
    found += [(path, "bag") for path in sorted(bags, key=os.path.abspath)]
    return found


def _is_bag(folder):
    return os.path.isfile(os.path.join(folder, "metadata.yaml"))


#: Topic suffix of the chassis pose the per-trial drill-down points into.
POSE_TOPIC_SUFFIX = "rig/pose"


def _pose_windows(outcomes, bags):
    """``{trial_id: (bag, start offset s, poses)}``: for each launch, the rig poses recorded in a bag between the
    previous outcome of its run and this one (the launch's pose trace), and where they start in the bag."""
    if not bags or not outcomes:
        return {}
    from rollability_ros.core.bags import BagReader, bag_info

    windows = {}
    for bag in bags:
        try:
            info = bag_info(bag)
            topics = [t["name"] for t in info["topics"] if t["name"].endswith(POSE_TOPIC_SUFFIX)]
            if not topics or info["start_time_ns"] is None:
                continue
            stamps = sorted(m.log_time_ns for m in BagReader(bag, topics=topics))
        except (ValueError, OSError):
            continue
        previous: typing.Dict[str, int] = {}
        for outcome in sorted(outcomes, key=lambda o: o.stamp_s):
            end_ns = int(outcome.stamp_s * 1e9)
            start_ns = previous.get(outcome.run_id, info["start_time_ns"])
            inside = [t for t in stamps if start_ns <= t <= end_ns]
            if inside and outcome.trial_id not in windows:
                windows[outcome.trial_id] = (bag, (inside[0] - info["start_time_ns"]) / 1e9, len(inside))
            previous[outcome.run_id] = end_ns
    return windows


def _anchor(text):
    return "".join(c if c.isalnum() else "-" for c in text).strip("-").lower()


def resimulate_command(outcome: LaunchOutcome) -> str:
    """The command that runs a simulated launch again from its stored condition and twin seed ("" without a seed):
    ``rollability campaign --resimulate``, which prints the launch's outcome and final orientation."""
    if outcome.seed == NO_SEED or outcome.backend != "sim":
        return ""
    c = outcome.condition
    return (f"rollability campaign --backend sim --resimulate {shlex.quote(c.configuration)} {c.height_m!r} "
            f"{c.speed_mps!r} {c.angle_deg!r} --seed {outcome.seed}")


def _seed_cell(outcome):
    """The seed of a launch and, for a simulated one, the command that simulates it again."""
    if outcome.seed == NO_SEED:
        return "none (physical launch)" if outcome.backend == "physical" else "none recorded"
    command = resimulate_command(outcome)
    return f"{outcome.seed}" + (f": <code>{html.escape(command)}</code>" if command else "")


def _trial_rows(data, trace, out_dir):
    """The per-trial drill-down: one row per launch, with its pose trace in the bag when one was recorded."""
    rows = []
    for outcome in sorted(data.outcomes, key=lambda o: (o.run_id, o.stamp_s, o.trial_id)):
        c = outcome.condition
        cells = [html.escape(outcome.trial_id), html.escape(c.configuration), f"{c.height_m:g}", f"{c.speed_mps:g}",
                 f"{c.angle_deg:g}", str(c.repetition), "upright" if outcome.upright else "not upright",
                 html.escape(outcome.classified_by), html.escape(outcome.backend)]
        cells.append(_seed_cell(outcome))
        if outcome.trial_id in trace:
            bag, offset_s, poses = trace[outcome.trial_id]
            link = html.escape(os.path.relpath(bag, out_dir))
            cells.append(f"{poses} poses from {offset_s:.2f} s in <a href='{link}'>{html.escape(os.path.basename(bag))}"
                         f"</a>: <code>rollability play {html.escape(bag)} --start-offset {offset_s:.2f}</code>")
        else:
            cells.append("no pose trace recorded")
        rows.append(f"<tr id='trial-{_anchor(outcome.trial_id)}'>" + "".join(f"<td>{cell}</td>" for cell in cells)
                    + "</tr>")
    header = "".join(f"<th>{h}</th>" for h in ("trial", "configuration", "height m", "speed m/s", "angle deg",
                                                "repetition", "outcome", "classified by", "backend",
                                                "seed: re-simulate", "pose trace in the bag"))
    return f"<table class='trials'><tr>{header}</tr>{''.join(rows)}</table>"


def _html(data, summary, figures, tables, artefacts=(), trace=None, out_dir="."):
    """The report as one HTML document: a table of contents, the summary, figures as base64 data URIs, links to
    every artefact (relative to ``out_dir``), the tables inline and a per-trial drill-down; no external resources."""
    sections = [("summary", "Summary")]
    sections += [(f"figure-{_anchor(os.path.basename(path))}", caption) for path, caption in figures]
    if artefacts:
        sections.append(("artefacts", "Files: designs, bags, tables"))
    sections += [(f"table-{_anchor(name)}", _TABLE_TITLES.get(name, name)) for name in tables]
    if data.outcomes:
        sections.append(("trials", "Every launch (per-trial drill-down)"))
    toc = "".join(f"<li><a href='#{anchor}'>{html.escape(title)}</a></li>" for anchor, title in sections)
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Rollability report</title>"
             f"<style>{_STYLE}</style></head><body><h1>Rollability report</h1>",
             f"<nav id='contents'><h2>Contents</h2><ol>{toc}</ol></nav>",
             f"<h2 id='summary'>Summary</h2><pre>{html.escape(summary)}</pre>"]
    if figures:
        parts.append("<h2>Figures</h2>")
    for path, caption in figures:
        with open(path, "rb") as stream:
            encoded = base64.b64encode(stream.read()).decode("ascii")
        parts.append(f"<figure id='figure-{_anchor(os.path.basename(path))}'><img alt='{html.escape(caption)}' "
                     f"src='data:image/png;base64,{encoded}'><figcaption>{html.escape(caption)} "
                     f"(<a href='{html.escape(os.path.basename(path))}'>PNG</a>)</figcaption></figure>")
    if artefacts:
        items = "".join(f"<li><a href='{html.escape(os.path.relpath(path, out_dir))}'>"
                        f"{html.escape(os.path.relpath(path, out_dir))}</a> ({html.escape(kind)})</li>"
                        for path, kind in artefacts)
        parts.append(f"<h2 id='artefacts'>Files: designs, bags, tables</h2><ul class='artefacts'>{items}</ul>")
    parts.append("<h2>Tables</h2>")
    for name, rows in tables.items():
        parts.append(f"<h3 id='table-{_anchor(name)}'>{html.escape(_TABLE_TITLES.get(name, name))}</h3>"
                     f"{_html_table(rows)}")
    if data.outcomes:
        parts.append("<h2 id='trials'>Every launch (per-trial drill-down)</h2>"
                     "<p>Each launch with its condition and outcome; its twin seed and, for a simulated launch, the "
                     "command that simulates it again (with the campaign's <code>--rig-config</code> files when "
                     "they were not the shipped ones); where a bag was recorded, the chassis poses of that launch "
                     "and the command that replays them from there.</p>" + _trial_rows(data, trace or {},
                                                                                              out_dir))
    parts.append("</body></html>")
    return "\n".join(parts)
