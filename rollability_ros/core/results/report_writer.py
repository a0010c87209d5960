"""Writing the analysis report: CSV tables, PNG figures and one self-contained HTML file (:func:`build_report`).

What the report says is decided in :mod:`~rollability_ros.core.results.report` (the records read, the summary
text, the lead: :mod:`~rollability_ros.core.results.lead`); this module only writes it. The HTML opens with the
lead table (which design to print first, its gains over the bare robot on the campaign and across the plausible
worlds, and why), then the summary, figures, links to every artefact, the tables and a per-trial drill-down.
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
from rollability_ros.core.results.lead import Lead
from rollability_ros.core.results.report import (CONFIGURATION_ORDER, ReportData, find_artefacts, is_bag,
                                                  refuse_all_invalid, report_lead, summary_text, trait_edges)
from rollability_ros.core.records import NO_SEED, LaunchOutcome


@dataclasses.dataclass(frozen=True)
class ReportResult:
    """Paths written by :func:`build_report` and the text summary."""

    html_path: str
    figure_paths: typing.List[str]
    table_paths: typing.List[str]
    summary: str


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


def _design_figures(out_dir, data, draw):
    """The map, the trait curves and a preview of each chosen design (previews need trimesh, the sim extra)."""
    from rollability_ros.core.results import report_figures as figures

    if data.archive_rows and data.trait_rows:
        edges = trait_edges(data.trait_rows)
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
    lead = report_lead(data, views)
    summary = summary_text(data, views, comparison, points, lead)
    html_path = os.path.join(out_dir, "report.html")
    artefacts = find_artefacts(data.design_folders, data.source.split(" ", 1)[-1]) + \
        [(path, "table (CSV)") for path in table_paths]
    trace = _pose_windows(data.outcomes, [p for p, kind in artefacts if kind == "bag"])
    with open(html_path, "w", encoding="utf-8") as stream:
        stream.write(_html(data, summary, figures, tables, artefacts, trace, out_dir, lead))
    return ReportResult(html_path, [path for path, _ in figures], table_paths, summary)


_STYLE = """
body { font-family: sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
img { max-width: 100%; border: 1px solid #ddd; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; font-size: 0.85em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: right; }
th { background: #f0f0f0; }
pre { background: #f7f7f7; padding: 0.8em; white-space: pre-wrap; overflow-wrap: anywhere; }
table.lead td, table.lead th { text-align: left; vertical-align: top; }
table.lead tr.first { background: #e8f5e9; font-weight: bold; }
p.headline { font-size: 1.1em; }
"""


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


def resimulate_command(outcome: LaunchOutcome, store: str = "") -> str:
    """The command that runs a simulated launch again from its stored condition and twin seed ("" without a seed):
    ``rollability campaign --resimulate``, which prints the launch's outcome and final orientation; with the
    ``store`` it came from, on the twin files recorded for its run (``--store``, ``--run-id``)."""
    if outcome.seed == NO_SEED or outcome.backend != "sim":
        return ""
    c = outcome.condition
    command = (f"rollability campaign --backend sim --resimulate {shlex.quote(c.configuration)} {c.height_m!r} "
               f"{c.speed_mps!r} {c.angle_deg!r} --seed {outcome.seed}")
    if store:
        command += f" --store {shlex.quote(store)} --run-id {shlex.quote(outcome.run_id)}"
    return command


def _seed_cell(outcome, store):
    """The seed of a launch and, for a simulated one, the command that simulates it again."""
    if outcome.seed == NO_SEED:
        return "none (physical launch)" if outcome.backend == "physical" else "none recorded"
    command = resimulate_command(outcome, store)
    return f"{outcome.seed}" + (f": <code>{html.escape(command)}</code>" if command else "")


def _trial_rows(data, trace, out_dir):
    """The per-trial drill-down: one row per launch, with its pose trace in the bag when one was recorded."""
    rows = []
    for outcome in sorted(data.outcomes, key=lambda o: (o.run_id, o.stamp_s, o.trial_id)):
        c = outcome.condition
        cells = [html.escape(outcome.trial_id), html.escape(c.configuration), f"{c.height_m:g}", f"{c.speed_mps:g}",
                 f"{c.angle_deg:g}", str(c.repetition), "upright" if outcome.upright else "not upright",
                 html.escape(outcome.classified_by), html.escape(outcome.backend)]
        cells.append(_seed_cell(outcome, data.store))
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


def lead_html(lead: typing.Optional[Lead]) -> str:
    """The lead as HTML: the headline in plain words, then a table with one row per design (best first): its
    verdict, gain over the bare robot on the campaign and across the plausible worlds with intervals, and why."""
    if lead is None:
        return ""
    campaign = html.escape(lead.campaign_label or "no campaign")
    header = "".join(f"<th>{html.escape(h)}</th>" for h in (
        "design", "verdict", f"gain on the campaign ({lead.campaign_label or 'none'}), Newcombe 95%",
        "worlds won (point gain > 0)", "worlds with the interval above 0", "worst world's gain, 95%",
        "pooled gain across worlds (simulated), 95%", "why"))
    rows = []
    for row in lead.rows:
        worlds = row.worlds
        cells = [row.design, row.verdict, _gain_cell(row.campaign_gain),
                 f"{worlds.wins}/{worlds.worlds} ({worlds.share_won:.0%})" if worlds else "not checked",
                 f"{worlds.clear_wins}/{worlds.worlds} ({worlds.share_clear:.0%})" if worlds else "-",
                 (_gain_cell(worlds.worst.interval) + f" (world {worlds.worst.world}"
                  + (f": {worlds.worst.draws_text()})" if worlds.worst.draws_text() else ")")) if worlds else "-",
                 _gain_cell(worlds.pooled) if worlds else "-", row.reason]
        css = " class='first'" if row.verdict == "print first" else ""
        rows.append(f"<tr{css}>" + "".join(f"<td>{html.escape(cell)}</td>" for cell in cells) + "</tr>")
    world = f"<p>World check: {html.escape(lead.world_label)}.</p>" if lead.world_label else ""
    return (f"<p class='headline'><strong>{html.escape(lead.headline)}</strong></p>{world}"
            f"<p>Campaign: {campaign}.</p><table class='lead'><thead><tr>{header}</tr></thead>"
            f"<tbody>{''.join(rows)}</tbody></table>")


def _gain_cell(gain):
    return "-" if gain is None else f"{gain[0]:+.2f} [{gain[1]:+.2f}, {gain[2]:+.2f}]"


def _html(data, summary, figures, tables, artefacts=(), trace=None, out_dir=".", lead=None):
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
             (f"<h2 id='recommendation'>Recommendation: which design to print first</h2>{lead_html(lead)}"
              if lead is not None else ""),
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
