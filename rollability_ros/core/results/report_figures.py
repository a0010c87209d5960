"""PNG figures of the report (matplotlib, Agg backend): Figures 4, 9, 10, 11, 12 and the sim-vs-experiment plot.

Bars and heat-map colours show the paper's measure (fraction of grouped conditions successful by the majority
rule); black points with whiskers show the per-trial success rate with its Wilson 95 % interval.
Heights are drawn in cm and speeds in m/s, as in the paper.
"""
import math
import typing

from rollability_ros.core.results.analysis import (CellSummary, ConvergencePoint, SimVsExperiment, Views, cells_of,
                                                   grid)
from rollability_ros.core.optional import require

if typing.TYPE_CHECKING:  # annotations only
    from rollability_ros.core.profile import Mesh
    from rollability_ros.core.results.engine_agreement import EngineRow

_FACTOR_LABELS = {"height_m": "height (cm)", "speed_mps": "speed (m/s)", "angle_deg": "angle (deg)",
                  "configuration": "configuration"}


def _pyplot():
    matplotlib = require("matplotlib", feature="the report figures")
    matplotlib.use("Agg")
    return require("matplotlib.pyplot", feature="the report figures")


def _level_label(factor, value):
    if factor == "height_m":
        return f"{value * 100:g}"
    if factor == "angle_deg":
        return f"{value:+g}" if value else "0"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _save(figure, path):
    figure.savefig(path, dpi=110, bbox_inches="tight")
    _pyplot().close(figure)
    return path


def _panels(count, columns=2, size=(4.8, 3.4)):
    plt = _pyplot()
    rows = math.ceil(count / columns)
    columns = min(columns, count)
    figure, axes = plt.subplots(rows, columns, figsize=(size[0] * columns, size[1] * rows), squeeze=False,
                                layout="constrained")
    flat = [ax for row in axes for ax in row]
    for ax in flat[count:]:
        ax.set_visible(False)
    return figure, flat[:count]


def heatmaps(path: str, cells: typing.Sequence[CellSummary], configurations: typing.Sequence[str], row_factor: str,
             title: str) -> str:
    """One heat map per configuration: ``row_factor`` x angle, colour = condition rate, text = both rates."""
    figure, axes = _panels(len(configurations))
    image = None
    for letter, (ax, configuration) in zip("abcdefghijklmnop", zip(axes, configurations)):
        own = cells_of(cells, configuration=configuration)
        rows, columns, rates = grid(own, row_factor, "angle_deg")
        image = ax.imshow(rates, vmin=0.0, vmax=1.0, cmap="RdYlGn", aspect="auto", origin="lower")
        for cell in own:
            i, j = rows.index(cell.key[row_factor]), columns.index(cell.key["angle_deg"])
            ax.text(j, i, f"{cell.condition_rate:.0%}\n{cell.successes}/{cell.trials}", ha="center", va="center",
                    fontsize=9, weight="bold", color=_text_colour(cell.condition_rate))
        ax.set_xticks(range(len(columns)), [_level_label("angle_deg", c) for c in columns])
        ax.set_yticks(range(len(rows)), [_level_label(row_factor, r) for r in rows])
        ax.set_xlabel(_FACTOR_LABELS["angle_deg"])
        ax.set_ylabel(_FACTOR_LABELS[row_factor])
        ax.set_title(f"({letter}) {configuration}")
    figure.suptitle(f"{title}\ncolour and %: grouped conditions successful (majority); n/N: upright trials")
    figure.colorbar(image, ax=axes, shrink=0.8, label="success rate")
    return _save(figure, path)


def _text_colour(rate):
    """Black or white, whichever reads better on the RdYlGn colour of ``rate`` (dark red / dark green ends)."""
    return "white" if rate < 0.2 or rate > 0.85 else "black"


def angle_curves(path: str, speed_angle_cells: typing.Sequence[CellSummary],
                 configurations: typing.Sequence[str]) -> str:
    """Figure 11: success against angle, one line per speed, one panel per configuration."""
    figure, axes = _panels(len(configurations))
    for letter, (ax, configuration) in zip("abcdefghijklmnop", zip(axes, configurations)):
        own = cells_of(speed_angle_cells, configuration=configuration)
        for speed in sorted({c.key["speed_mps"] for c in own}):
            line = sorted(cells_of(own, speed_mps=speed), key=lambda c: c.key["angle_deg"])
            angles = [c.key["angle_deg"] for c in line]
            drawn = ax.plot(angles, [c.condition_rate for c in line], marker="o", label=f"{speed:g} m/s")
            _trial_whiskers(ax, angles, line, drawn[0].get_color())
        ax.set_ylim(-0.05, 1.05)
        ax.set_xticks(sorted({c.key["angle_deg"] for c in own}))
        ax.set_xlabel(_FACTOR_LABELS["angle_deg"])
        ax.set_ylabel("success rate")
        ax.set_title(f"({letter}) {configuration}")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    figure.suptitle("Success by launch angle per speed (lines: grouped conditions; whiskers: trials, Wilson 95%)")
    return _save(figure, path)


def _trial_whiskers(ax, positions, cells, color):
    rates = [c.trial_rate for c in cells]
    lows = [r - c.trial_ci[0] for r, c in zip(rates, cells)]
    highs = [c.trial_ci[1] - r for r, c in zip(rates, cells)]
    ax.errorbar(positions, rates, yerr=[lows, highs], fmt="o", markersize=3, color=color, ecolor=color, alpha=0.55,
                capsize=3)


#: The two measures of Figure 12, each on its own axes: (cell attribute, axis label, with Wilson whiskers).
OVERALL_MEASURES = {
    "condition_rate": ("grouped conditions successful (majority)", False),
    "trial_rate": ("upright trials (whiskers: Wilson 95%)", True),
}


def overall(path: str, views: Views, configurations: typing.Sequence[str], measure: str = "condition_rate") -> str:
    """Figure 12: grouped bars by speed, height and angle per configuration, and overall per configuration, of one
    ``measure`` (:data:`OVERALL_MEASURES`): the paper's condition rate, or the trial rate with its interval."""
    label, whiskers = OVERALL_MEASURES[measure]
    figure, axes = _panels(4, columns=2, size=(5.6, 3.6))
    panels = (("a", views.by_speed, "speed_mps"), ("b", views.by_height, "height_m"), ("c", views.by_angle,
                                                                                        "angle_deg"))
    for ax, (letter, cells, factor) in zip(axes, panels):
        levels = sorted({c.key[factor] for c in cells})
        width = 0.8 / max(1, len(levels))
        for k, level in enumerate(levels):
            positions, bars = [], []
            for i, configuration in enumerate(configurations):
                match = cells_of(cells, configuration=configuration, **{factor: level})
                if match:
                    positions.append(i - 0.4 + width * (k + 0.5))
                    bars.append(match[0])
            ax.bar(positions, [getattr(c, measure) for c in bars], width, label=_level_label(factor, level))
            if whiskers:
                _trial_whiskers(ax, positions, bars, "black")
        _configuration_axis(ax, configurations, label)
        ax.set_title(f"({letter}) by {_FACTOR_LABELS[factor]}")
        ax.set_ylim(0.0, 1.3)  # room for the legend above the bars
        ax.legend(fontsize=7, title=_FACTOR_LABELS[factor], title_fontsize=7, ncol=min(5, len(levels)),
                  loc="upper center")
    ax = axes[3]
    cells = [cells_of(views.by_configuration, configuration=c)[0] for c in configurations]
    ax.bar(range(len(cells)), [getattr(c, measure) for c in cells], 0.6, color="tab:gray")
    if whiskers:
        _trial_whiskers(ax, list(range(len(cells))), cells, "black")
    for i, cell in enumerate(cells):
        ax.text(i, 0.03, f"{getattr(cell, measure):.0%}", ha="center", fontsize=9, color="white", weight="bold")
    _configuration_axis(ax, configurations, label)
    ax.set_title("(d) overall")
    figure.suptitle(f"Overall success: {label}")
    return _save(figure, path)


def _configuration_axis(ax, configurations, label="success rate"):
    ax.set_xticks(range(len(configurations)), configurations)
    ax.set_ylim(0.0, 1.05)
    ax.set_yticks([0.0, 0.2, 0.4, 0.6, 0.8, 1.0])
    ax.set_ylabel(label, fontsize=8)
    ax.grid(axis="y", alpha=0.3)


def convergence_figure(path: str, points: typing.Sequence[ConvergencePoint]) -> str:
    """Figure 4: best-so-far fitness per generation (solid), generation best and mean (faint), per run."""
    plt = _pyplot()
    figure, ax = plt.subplots(figsize=(6.4, 3.8), layout="constrained")
    for run_id in sorted({p.run_id for p in points}):
        own = [p for p in points if p.run_id == run_id]
        generations = [p.generation for p in own]
        drawn = ax.plot(generations, [p.best_so_far for p in own], marker=".",
                        label=f"{run_id}: best so far (incumbent, re-evaluated and pooled)")
        ax.plot(generations, [p.best_fitness for p in own], color=drawn[0].get_color(), alpha=0.35, lw=0.8)
        ax.plot(generations, [p.mean_fitness for p in own], color=drawn[0].get_color(), alpha=0.35, ls="--",
                lw=0.8)
    ax.set_xlabel("generation")
    ax.set_ylabel("fitness (upright trials / trials)")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Optimization convergence (faint: generation best, dashed: generation mean)")
    return _save(figure, path)


def sim_vs_experiment(path: str, comparison: SimVsExperiment) -> str:
    """Simulated fitness against campaign success per configuration (the campaign labelled experimental or
    simulated), with the rank agreement."""
    plt = _pyplot()
    figure, ax = plt.subplots(figsize=(4.8, 4.2), layout="constrained")
    for row in comparison.rows:
        ax.scatter(row["sim_fitness"], row["experimental_rate"], s=40)
        ax.annotate(row["configuration"], (row["sim_fitness"], row["experimental_rate"]),
                    textcoords="offset points", xytext=(6, 4))
    ax.plot([0, 1], [0, 1], color="gray", lw=0.8, ls=":")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_xlabel("simulated fitness")
    ax.set_ylabel(f"{comparison.campaign} campaign success ({comparison.measure.replace('_', ' ')})")
    ax.set_title(comparison.agreement_text(), fontsize=9)
    ax.grid(alpha=0.3)
    return _save(figure, path)


def engine_fitness(path: str, rows: typing.Sequence["EngineRow"]) -> str:
    """Each design's simulated fitness per engine (bars) with its Wilson 95% interval (whiskers)."""
    plt = _pyplot()
    engines = sorted({row.engine for row in rows}, key=[row.engine for row in rows].index)
    designs = list(dict.fromkeys(row.design for row in rows))
    by_key = {(row.design, row.engine): row for row in rows}
    figure, ax = plt.subplots(figsize=(1.2 + 1.3 * len(designs), 3.6))
    width = 0.8 / len(engines)
    for index, engine in enumerate(engines):
        positions = [i + (index - (len(engines) - 1) / 2) * width for i in range(len(designs))]
        cells = [by_key[(design, engine)] for design in designs]
        ax.bar(positions, [c.fitness for c in cells], width, label=engine, color=f"C{index}")
        ax.errorbar(positions, [c.fitness for c in cells],
                    yerr=[[c.fitness - c.ci_low for c in cells], [c.ci_high - c.fitness for c in cells]],
                    fmt="none", ecolor="black", capsize=3)
    ax.set_xticks(range(len(designs)), designs)
    ax.set_ylim(0, 1)
    ax.set_ylabel("simulated fitness (upright trials / trials)")
    ax.set_title("Fitness per engine, same seeds (simulated)")
    ax.legend(frameon=False)
    return _save(figure, path)


def render_profile_preview(mesh: "Mesh", path: str, title: typing.Optional[str] = None) -> str:
    """Render a profile solid (a trimesh in metres, profile frame) to a shaded 3D PNG at ``path``; returns ``path``.

    Axes are in millimetres, equal scale, seen from the front-left above; ``mesh`` None (the baseline) draws the
    empty footprint note instead. Shared by every report section that shows a design.
    """
    plt = _pyplot()
    art3d = require("mpl_toolkits.mplot3d.art3d", feature="the report figures")
    import numpy as np

    figure = plt.figure(figsize=(3.6, 3.0), layout="constrained")
    ax = figure.add_subplot(projection="3d")
    if mesh is None:
        ax.text2D(0.5, 0.5, "baseline: no profile", ha="center", va="center", transform=ax.transAxes)
        ax.set_axis_off()
    else:
        vertices_mm = np.asarray(mesh.vertices, dtype=np.float64) * 1000.0
        triangles = vertices_mm[np.asarray(mesh.faces)]
        normals = np.asarray(mesh.face_normals, dtype=np.float64)
        light = np.array([-0.4, -0.5, 0.77])
        shade = 0.35 + 0.65 * np.clip(normals @ (light / np.linalg.norm(light)), 0.0, 1.0)
        colors = np.column_stack([0.20 * shade, 0.45 * shade, 0.85 * shade, np.ones_like(shade)])
        ax.add_collection3d(art3d.Poly3DCollection(triangles, facecolors=colors, edgecolors=(0, 0, 0, 0.15),
                                                   linewidths=0.2))
        low, high = vertices_mm.min(axis=0), vertices_mm.max(axis=0)
        ax.set_xlim(low[0], high[0])
        ax.set_ylim(low[1], high[1])
        ax.set_zlim(0.0, max(high[2], 1e-3))
        ax.set_box_aspect(np.maximum(high - np.array([low[0], low[1], 0.0]), 1e-3))
        ax.view_init(elev=28, azim=-60)
        ax.set_xlabel("x (mm)", fontsize=7, labelpad=-2)
        ax.set_ylabel("y (mm)", fontsize=7, labelpad=-2)
        ax.set_zlabel("z (mm)", fontsize=7, labelpad=-4)
        ax.tick_params(labelsize=6, pad=-1)
    if title:
        ax.set_title(title, fontsize=9)
    return _save(figure, path)


def sensitivity_figure(path: str, rows: typing.Sequence[typing.Mapping[str, typing.Any]]) -> str:
    """The sensitivity study (:mod:`rollability_ros.core.sim.sensitivity`): one panel per factor, fitness of each
    configuration against the factor's levels with Wilson 95% intervals; the robust fitness as its own panel."""
    plt = _pyplot()
    factors = list(dict.fromkeys(row["factor"] for row in rows))
    configurations = list(dict.fromkeys(row["configuration"] for row in rows))
    figure, axes = plt.subplots(1, len(factors), figsize=(3.2 * len(factors), 3.4), layout="constrained",
                                squeeze=False)
    for ax, factor in zip(axes[0], factors):
        own = [row for row in rows if row["factor"] == factor]
        levels = list(dict.fromkeys(str(row["level"]) for row in own))
        for number, configuration in enumerate(configurations):
            points = [row for row in own if row["configuration"] == configuration]
            x = [levels.index(str(row["level"])) + 0.08 * (number - (len(configurations) - 1) / 2) for row in points]
            y = [row["fitness"] for row in points]
            errors = [[row["fitness"] - row["ci_low"] for row in points], [row["ci_high"] - row["fitness"]
                                                                           for row in points]]
            ax.errorbar(x, y, yerr=errors, marker="o", capsize=3, label=configuration,
                        ls="-" if factor != "robust" else "none")
        ax.set_xticks(range(len(levels)))
        ax.set_xticklabels(levels, fontsize=8)
        ax.set_ylim(-0.02, 1.02)
        ax.set_title(factor.replace("_", " "), fontsize=10)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("simulated fitness (95% CI)")
    axes[0][-1].legend(fontsize=8)
    return _save(figure, path)


def archive_map(path: str, archive_rows: typing.Sequence[typing.Mapping[str, typing.Any]],
                edges: typing.Mapping[str, typing.Sequence[float]]) -> str:
    """The quality-diversity map: one square per filled cell of maximum height (x) x sharpness (y), coloured by the
    elite's fitness (the fresh screen's when there is one), the chosen designs' labels written in their cells.

    ``edges``: ``{"max_height_mm": [...], "sharpness_deg": [...]}`` bin edges of the archive's grid.
    """
    plt = _pyplot()
    import numpy as np

    heights, sharpness = edges["max_height_mm"], edges["sharpness_deg"]
    rates = np.full((len(sharpness) - 1, len(heights) - 1), np.nan)
    for row in archive_rows:
        rates[int(row["cell_sharpness"]), int(row["cell_height"])] = row["fitness"]
    figure, ax = plt.subplots(figsize=(6.4, 3.8), layout="constrained")
    image = ax.pcolormesh(heights, sharpness, np.ma.masked_invalid(rates), vmin=0.0, vmax=1.0, cmap="RdYlGn",
                          edgecolors="white", linewidth=0.5)
    for row in archive_rows:
        x = (heights[int(row["cell_height"])] + heights[int(row["cell_height"]) + 1]) / 2
        y = (sharpness[int(row["cell_sharpness"])] + sharpness[int(row["cell_sharpness"]) + 1]) / 2
        text = f"{row['label']}\n{row['fitness']:.2f}" if row["label"] else f"{row['fitness']:.2f}"
        ax.text(x, y, text, ha="center", va="center", fontsize=7 if not row["label"] else 9,
                weight="bold" if row["label"] else "normal", color=_text_colour(row["fitness"]))
        if row["label"]:
            ax.add_patch(plt.Rectangle((heights[int(row["cell_height"])], sharpness[int(row["cell_sharpness"])]),
                                       heights[1] - heights[0], sharpness[1] - sharpness[0], fill=False,
                                       edgecolor="black", linewidth=2))
    ax.set_xlabel("maximum height (mm)")
    ax.set_ylabel("sharpness (deg, mean ridge angle)")
    ax.set_title("Archive of elites (simulated): fitness per height x sharpness cell; chosen designs boxed")
    figure.colorbar(image, ax=ax, label="fitness (upright trials / trials)")
    return _save(figure, path)


def trait_curves(path: str, trait_rows: typing.Sequence[typing.Mapping[str, typing.Any]],
                 archive_rows: typing.Sequence[typing.Mapping[str, typing.Any]]) -> str:
    """Fitness against each trait: every evaluation of the run pooled per bin (line, Wilson 95% band) and each
    elite's fitness (points; the fresh screen's when there is one)."""
    plt = _pyplot()
    labels = {"max_height_mm": "maximum height (mm)", "sharpness_deg": "sharpness (deg, mean ridge angle)"}
    figure, axes = plt.subplots(1, 2, figsize=(9.6, 3.4), layout="constrained")
    for ax, trait in zip(axes, labels):
        own = [r for r in trait_rows if r["trait"] == trait and r["trials"] > 0]
        centres = [(r["bin_low"] + r["bin_high"]) / 2 for r in own]
        ax.fill_between(centres, [r["ci_low"] for r in own], [r["ci_high"] for r in own], alpha=0.25, color="C0",
                        label="all evaluations per bin (95% CI)")
        ax.plot(centres, [r["fitness"] for r in own], "o-", color="C0")
        ax.scatter([r[trait] for r in archive_rows], [r["fitness"] for r in archive_rows], s=14, color="C1",
                   label="archive elites")
        for row in archive_rows:
            if row["label"]:
                ax.annotate(row["label"], (row[trait], row["fitness"]), fontsize=9, weight="bold",
                            xytext=(3, 3), textcoords="offset points")
        ax.set_xlabel(labels[trait])
        ax.set_ylim(-0.02, 1.02)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("simulated fitness")
    axes[0].legend(fontsize=7, loc="upper left")
    figure.suptitle("How fitness changes with height and with sharpness (simulated)")
    return _save(figure, path)
