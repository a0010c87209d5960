"""What the analysis report of a run says: the records it reads, its text summary and its lead.

The files (PNG figures, CSV tables, one self-contained HTML file) are written by
:mod:`~rollability_ros.core.results.report_writer`. The summary opens with the lead
(:func:`report_lead`, :mod:`~rollability_ros.core.results.lead`): which design to print first and why, from the
designs' plausible-world check (``world_check.csv`` or the selection's ``selection_world_check.csv`` next to
designs.yaml) and the campaign.

A report is built from records only (launch outcomes, candidates, generations, tip events), so the same
campaign gives the same tables and figures whether it is read from the live store, from its bag or from a CSV
of hand-recorded outcomes. Sources:

- a store file (SQLite), a run directory holding ``store.sqlite`` or a ``study`` / ``bringup`` session directory
  holding the outcome logger's ``outcomes.sqlite``;
- a recorded bag (a directory with ``metadata.yaml`` / ``*.mcap``, or one ``.mcap`` file), read through
  ``rollability_ros.core.bags.messages.read_records_from_bag``;
- a CSV of launch outcomes (``docs/outcome-csv.md``).

The per-trial drill-down lists every launch with its twin seed and, for a simulated one, the command that
simulates it again (:func:`~rollability_ros.core.results.report_writer.resimulate_command`), and its pose trace
in a bag next to the source.

Table 3 and the simulated fitness per configuration come from the store's run info (``geometry``,
``sim_fitness``), from ``<run dir>/designs/table3.csv`` of the design selection, or from the command line.
"""
import csv
import dataclasses
import math
import os
import typing

from rollability_ros.core.optimization import DEFAULT_WORLD_SHARE
from rollability_ros.core.results import analysis
from rollability_ros.core.results._outcome_csv import read_outcome_csv
from rollability_ros.core.records import INVALID_LAUNCH, LaunchOutcome
from rollability_ros.core.store import SESSION_STORE_FILENAME, STORE_FILENAME, Store
from rollability_ros.core.stats import newcombe_interval, wilson_interval

if typing.TYPE_CHECKING:
    from rollability_ros.core.results.lead import Lead

#: Order of configurations in figures and tables (others follow alphabetically).
CONFIGURATION_ORDER = ("baseline", "A", "B", "C")
_SQLITE_MAGIC = b"SQLite format 3\x00"
#: Table 3 written by the design selection into a run directory (``design_set.write_selection``).
DESIGNS_TABLE = os.path.join("designs", "table3.csv")


@dataclasses.dataclass
class ReportData:
    """Everything a report is made of; ``sim_fitness`` maps configuration -> simulated fitness in [0, 1]."""

    source: str
    store: str = ""    # the store the outcomes came from, as given ("" for a bag or CSV): re-simulations read it
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
    world_rows: list = dataclasses.field(default_factory=list)    # the designs' world check (world_check.WORLD_CHECK_COLUMNS)
    world_file: str = ""                                          # the file they came from
    world_share: float = DEFAULT_WORLD_SHARE                     # the recommendation's share of worlds (designs.yaml)


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
    """The :class:`DesignEstimate` s of Table 3 rows (``design_set.TABLE_COLUMNS``; a table without the in-run
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
        data.store = source
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
    roots = [base, os.path.dirname(base)] if is_bag(base) else [base]
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
        _world_check(data, folder, designs_yaml)
        if os.path.isfile(archive):
            data.archive_rows = design_map.read_archive(archive)
            data.trait_rows = design_map.read_traits(traits) if os.path.isfile(traits) else []
        data.design_meshes = {name[len("mesh_"):-len(".stl")]: os.path.join(folder, name)
                              for name in sorted(os.listdir(folder))
                              if name.startswith("mesh_") and name.endswith(".stl")}
        return


#: World checks of the designs next to them, preferred first: the full check (``rollability sensitivity
#: --designs-file .../designs.yaml --worlds N --out <designs folder>``), then the selection's quick one.
WORLD_CHECK_FILENAMES = ("world_check.csv", "selection_world_check.csv")


def _world_check(data, folder, designs_yaml):
    """Read the designs' world check (:data:`WORLD_CHECK_FILENAMES`) and the recommendation's share of worlds
    (``recommendation.min_world_share`` of designs.yaml); ``ValueError`` naming an unusable file."""
    from rollability_ros.core import safe_yaml
    from rollability_ros.core.sim import summarize_worlds

    found = [os.path.join(folder, name) for name in WORLD_CHECK_FILENAMES if os.path.isfile(os.path.join(folder, name))]
    if not found:
        return
    try:
        with open(found[0], newline="", encoding="utf-8") as stream:
            rows = list(csv.DictReader(stream))
        summarize_worlds(rows)   # refuses rows that do not pair
        with open(designs_yaml, encoding="utf-8") as stream:
            document = safe_yaml.load(stream) or {}
    except (OSError, KeyError, TypeError, ValueError, csv.Error) as exc:
        raise ValueError(f"{found[0]}: unusable world check: {exc!r}") from None
    body = ((document.get("/**") or {}).get("ros__parameters") or {}).get("designs") or {}
    share = (body.get("recommendation") or {}).get("min_world_share", DEFAULT_WORLD_SHARE)
    data.world_rows, data.world_file, data.world_share = rows, found[0], float(share)


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


def trait_edges(trait_rows: typing.Sequence[typing.Mapping[str, typing.Union[str, float]]]) -> typing.Dict[str, typing.List[float]]:
    """``{trait: bin edges}`` of the archive's grid, from the traits table's rows (``trait``, ``bin_low``,
    ``bin_high``)."""
    edges: typing.Dict[str, typing.List[float]] = {}
    for trait in ("max_height_mm", "sharpness_deg"):
        own = [r for r in trait_rows if r["trait"] == trait]
        edges[trait] = [float(own[0]["bin_low"])] + [float(r["bin_high"]) for r in own] if own else []
    return edges


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


def campaign_label(outcomes: typing.Sequence[LaunchOutcome]) -> str:
    """What a campaign's outcomes are, by where they came from: simulated, experimental or mixed."""
    return {"simulated": "simulated campaign (launch twin)", "experimental": "experimental campaign (rig)",
            "mixed": "mixed campaign (launch twin and rig)"}[analysis.campaign_kind(outcomes)]


def report_lead(data: ReportData, views: typing.Optional[analysis.Views]) -> typing.Optional["Lead"]:
    """The report's lead (:mod:`~rollability_ros.core.results.lead`) from the designs' world check and the
    campaign, or None when the report has no designs."""
    from rollability_ros.core.results import lead

    counts = lead.campaign_counts(views.by_configuration) if views is not None else {}
    world_label = ""
    if data.world_rows:
        worlds = len({r["world"] for r in data.world_rows})
        kind = "full check" if os.path.basename(data.world_file) == WORLD_CHECK_FILENAMES[0] else \
            "the selection's quick check"
        world_label = (f"{kind} ({os.path.basename(data.world_file)}), {worlds} worlds x "
                       f"{data.world_rows[0]['trials']} paired launches, simulated; a design wins a world when its "
                       f"point gain over the bare robot there is > 0; recommended at >= {data.world_share:.0%} of "
                       f"worlds won with the pooled interval above 0")
    label = campaign_label(data.outcomes) if counts else ""
    return lead.report_lead(data.world_rows, data.world_share, counts, label, world_label)


def summary_text(data: ReportData, views: typing.Optional[analysis.Views],
                 comparison: typing.Optional[analysis.SimVsExperiment],
                 points: typing.Sequence[analysis.ConvergencePoint],
                 lead: typing.Optional["Lead"] = None) -> str:
    """A few lines describing the report's data and headline numbers: the lead first (which design to print
    first and why, :func:`report_lead`, or ``lead`` when given), then the chosen designs' fresh re-evaluations
    (with the in-run estimates beside them and the selection bias), then the campaign, labelled simulated or
    experimental by where its outcomes came from."""
    lead = lead or report_lead(data, views)
    lines = (lead.lines() if lead is not None else []) + [f"source: {data.source}"]
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
        label = campaign_label(data.outcomes)
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

        edges = trait_edges(data.trait_rows).get("max_height_mm") if data.trait_rows else None
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
                              ("traits.csv", "fitness per height and sharpness bin (CSV)"),
                              ("world_check.csv", "plausible-world check: every world x configuration (CSV)"),
                              ("selection_world_check.csv", "the selection's quick world check (CSV)"),
                              ("world_summary.yaml", "plausible-world check per design (YAML)")):
            found += [(path, kind) for path in sorted(glob.glob(os.path.join(folder, pattern)))]
    if source is None:
        return found
    source = os.fspath(source)
    base = os.path.abspath(source if os.path.isdir(source) else os.path.dirname(os.path.abspath(source)))
    # a bag inside a study or session folder: the other bags sit next to it
    roots = [base, os.path.dirname(os.path.abspath(base))] if is_bag(base) else [base]
    bags = {root for root in roots if is_bag(root)}
    bags |= {os.path.dirname(p) for root in roots for p in glob.glob(os.path.join(root, "*", "metadata.yaml"))}
    found += [(path, "bag") for path in sorted(bags, key=os.path.abspath)]
    return found


def is_bag(folder: str) -> bool:
    """True when ``folder`` is a recorded bag (it holds ``metadata.yaml``)."""
    return os.path.isfile(os.path.join(folder, "metadata.yaml"))

