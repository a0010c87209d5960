"""Designs ranked by the rig's measure: a launch race over the archive's elites, the gain over the bare robot with
Newcombe's interval, and the plain "no design helps" outcome in designs.yaml, Table 3, select and the report."""
import csv
import os

import numpy as np
import pytest

pytest.importorskip("trimesh")

from rollability_ros.core.config import load_parameters  # noqa: E402
from rollability_ros.core.optimization import design_set, selection  # noqa: E402
from rollability_ros.core.profile.geometry import PrinterSpec, ProfileGrid  # noqa: E402
from rollability_ros.core.results import design_map, report  # noqa: E402

GRID = ProfileGrid(rows=3, cols=3)


def elite(cell, height_mm, sharpness_deg, fitness=0.5, trials=20):
    heights = np.full(GRID.n_variables, height_mm / 1000 / GRID.unit_m)
    heights[0] *= 0.5 + cell[1] / 10
    return {"cell": list(cell), "heights": heights.tolist(), "fitness": fitness, "trials": trials, "generation": 1,
            "max_height_mm": height_mm, "sharpness_deg": sharpness_deg}


# (cell, height mm, sharpness deg, screen success, launch success)
ELITES = [((9, 2), 88, 40, 0.90, 0.20), ((8, 2), 80, 40, 0.85, 0.25), ((5, 1), 50, 25, 0.60, 0.70),
          ((6, 4), 65, 65, 0.55, 0.65), ((3, 3), 30, 55, 0.50, 0.60), ((2, 5), 25, 80, 0.45, 0.05),
          ((7, 0), 70, 10, 0.40, 0.55), ((1, 1), 15, 20, 0.10, 0.02)]
ARCHIVE = {"ranges": [[0, 90], [0, 90]], "elites": [elite(c, h, s) for c, h, s, _, _ in ELITES]}


class Truth:
    """Seeded trials with known success rates per design: screen (disturbance) and launch (the rig's measure)."""

    def __init__(self, baseline_launch, launch_scale=1.0):
        self.screen = {tuple(e["heights"]): p for e, (_, _, _, p, _) in zip(ARCHIVE["elites"], ELITES)}
        self.launch = {tuple(e["heights"]): q * launch_scale for e, (*_, q) in zip(ARCHIVE["elites"], ELITES)}
        self.baseline_launch = baseline_launch
        self.launch_calls = []

    def evaluate_batch(self, heights_list, seed, trials=60):
        draws = np.random.default_rng(seed).random(trials)
        return [(int(np.sum(draws < self.screen.get(tuple(h), 0.0))), trials, 0.0, "fake") for h in heights_list]

    def launch_batch(self, heights_list, seed, trials):
        self.launch_calls.append((len(heights_list), seed, trials))
        draws = np.random.default_rng(seed).random(trials)
        rates = [self.launch.get(tuple(h), self.baseline_launch) if np.any(h) else self.baseline_launch
                 for h in heights_list]
        return [(int(np.sum(draws < q)), trials, 0.0, "fake") for q in rates]


SETTINGS = selection.SelectionSettings(count=3, top_fraction=0.5, reevaluate_trials=60, race_launches=[20, 20],
                                       race_elites=6, race_keep=3, launch_trials=100)


def test_designs_are_ranked_by_the_race_on_launches_not_by_the_screen():
    truth = Truth(baseline_launch=0.25)
    result = selection.select_from_archive(ARCHIVE, [], GRID, PrinterSpec(), SETTINGS, truth.evaluate_batch, 5,
                                           truth.launch_batch)
    # the screen's two best (88 and 80 mm) launch poorly: the race drops them; A is the best launcher
    assert result.designs[0].cell == (5, 1)
    assert {d.cell for d in result.designs} <= {(5, 1), (6, 4), (3, 3)}
    assert len(result.designs) == 3 and result.shortfall == ""
    # the race: the 6 best by the screen entered (never the screen's worst), round 2 with at most half of them
    assert [c[0] for c in truth.launch_calls[:2]] == [6 + 1, 3 + 1]           # + the bare robot every round
    assert truth.launch_calls[0][1] != truth.launch_calls[1][1]                # a fresh seed per round ...
    assert truth.launch_calls[-1] == (3 + 1, selection.derive_seed(5, selection.LAUNCH_SEED_KEY, 2), 100)
    assert "robust twin launches in the race" in result.designs[0].reason
    assert "highest lower Wilson bound of any race survivor of 6 elites raced on 20+20 launches: " in \
        result.designs[0].reason                                                 # not "... launchess"
    for design, gain in zip(result.designs, result.gains()):
        assert gain.source == "launches" and gain.beats and design.launches[1] == 100
        difference, low, high = gain.interval
        assert low < difference < high and low > 0
    assert result.no_design_helps() == ""
    rows = {r["cell_height"]: r for r in result.archive}
    assert rows[1]["race_round1_trials"] == ""                                 # not among the 6 best screened
    assert rows[9]["race_round1_trials"] == 20 and rows[9]["race_stopped"] == 1


def test_when_no_design_beats_the_bare_robot_every_output_says_so(tmp_path, capsys):
    truth = Truth(baseline_launch=0.7, launch_scale=0.6)     # every design launches worse than the bare robot
    result = selection.select_from_archive(ARCHIVE, [], GRID, PrinterSpec(), SETTINGS, truth.evaluate_batch, 5,
                                           truth.launch_batch)
    assert result.designs, "designs are still written, for inspection"
    assert all(not g.beats for g in result.gains())
    assert result.no_design_helps().startswith("no design beats the bare robot on fresh robust launches")
    assert "(none above the bare robot)" in result.designs[0].reason

    folder = design_set.write_selection(str(tmp_path), result, GRID, "run")
    parameters = load_parameters(os.path.join(folder, "designs.yaml"))
    assert parameters["designs.launch_race.rounds"] == [20, 20] and parameters["designs.launch_race.designs_raced"] == 6
    assert parameters["designs.launch_race.baseline.trials"] == 40
    for design in result.designs:
        assert parameters[f"designs.{design.label}.beats_baseline"] is False
        low, high = parameters[f"designs.{design.label}.gain_over_baseline.newcombe_95"]
        assert low < 0
    with open(os.path.join(folder, "table3.csv"), newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert [r["beats_baseline"] for r in rows] == ["", "false", "false", "false"]
    assert rows[0]["launch_trials"] == "100" and rows[1]["gain_source"] == "launches"

    data = report.ReportData(source="test")
    report.use_geometry_csv(data, os.path.join(folder, "table3.csv"))
    lines = report.selection_gain_lines(data.geometry)
    assert "bare robot 70/100" in lines[0] or "bare robot" in lines[0]
    assert sum("does NOT beat the bare robot" in line for line in lines) == 3
    assert lines[-1].startswith("NO DESIGN BEATS THE BARE ROBOT")

    archive = design_map.read_archive(os.path.join(folder, design_map.ARCHIVE_FILENAME))
    rho, p, n = design_map.transfer(archive)
    assert n == 6 and -1 <= rho <= 1 and 0 < p <= 1
    assert any(line.startswith("transfer (simulated)") for line in design_map.summary_lines(archive))


def test_a_race_without_a_launch_evaluator_is_refused():
    with pytest.raises(ValueError, match="launch evaluator"):
        selection.select_from_archive(ARCHIVE, [], GRID, PrinterSpec(), SETTINGS, Truth(0.2).evaluate_batch, 5)
    with pytest.raises(ValueError, match="race_launches"):
        selection.SelectionSettings(race_launches=[20, 0]).validate()


def test_the_campaign_summary_gives_each_design_minus_the_baseline_and_says_when_none_is_above():
    class Cell:
        def __init__(self, name, successes, trials):
            self.key, self.successes, self.trials = {"configuration": name}, successes, trials

    lines = report.campaign_gain_lines([Cell("baseline", 22, 100), Cell("A", 30, 100), Cell("B", 41, 100)],
                                       "simulated campaign (launch twin)")
    assert "A        +0.08 [-0.04, +0.20]  not distinguishable from the baseline" in lines[1]
    assert "B        +0.19 [+0.06, +0.31]  above the baseline" in lines[2]     # the issue's own numbers
    assert not any("NO DESIGN" in line for line in lines)
    lines = report.campaign_gain_lines([Cell("baseline", 22, 100), Cell("A", 30, 100)], "campaign")
    assert lines[-1].startswith("NO DESIGN BEATS THE BASELINE")


def test_the_sensitivity_table_gives_each_design_minus_the_bare_chassis_per_factor(tmp_path):
    from rollability_ros.core.results.sensitivity_table import gain_lines, gain_rows

    rows = [{"configuration": c, "factor": f, "level": lv, "successes": s, "trials": 60}
            for c, f, lv, s in (("baseline", "disturbance_scale", 2.0, 38), ("A", "disturbance_scale", 2.0, 32),
                                ("baseline", "robust", "all factors drawn", 12),
                                ("A", "robust", "all factors drawn", 25))]
    gains = {(g["factor"], g["configuration"]): g for g in gain_rows(rows)}
    assert gains[("disturbance_scale", "A")]["gain"] == pytest.approx(-0.1)
    robust = gains[("robust", "A")]
    assert robust["gain"] == pytest.approx(13 / 60) and robust["gain_low"] > 0     # the 25/60 vs 12/60
    lines = gain_lines(rows)
    assert lines[-1].startswith("**robust") and "+0.22 [+0.05, +0.37]" in lines[-1]
    folder = tmp_path / "designs"
    folder.mkdir()
    (folder / "sensitivity.csv").write_text("configuration,factor,level,successes,trials\n"
                                            + "".join(f"{r['configuration']},{r['factor']},{r['level']},"
                                                      f"{r['successes']},60\n" for r in rows))
    assert report._sensitivity_lines(str(folder / "sensitivity.csv")) == lines


def test_select_warns_in_one_line_and_exits_0_when_no_design_beats_the_bare_robot(tmp_path, monkeypatch, capsys):
    pytest.importorskip("ribs")
    from doubles import SyntheticEvaluator
    from rollability_ros.cli import main
    from rollability_ros.core.optimization import optimization_run

    optimum = np.linspace(0.1, 0.4, GRID.n_variables)
    parameters = {"optimizer.method": "cma_mae", "optimizer.max_generations": 4, "optimizer.seed": 2,
                  "optimizer.trials": 30, "optimizer.popsize": 6, "optimizer.initial_mean_screen": 0,
                  "quality_diversity.emitters": 2, "profile.rows": GRID.rows, "profile.cols": GRID.cols,
                  "selection.reevaluate_trials": 0, "selection.race_launches": [4], "selection.race_elites": 4,
                  "selection.launch_trials": 30, "selection.top_fraction": 1.0}
    run_dir = str(tmp_path / "run")
    run = optimization_run.OptimizationRun(run_dir, optimization_run.run_config(parameters), GRID, SyntheticEvaluator(optimum, trials=30))
    run.run()
    run.close()

    def launches(settings, executor, fidelity="screen", name="local"):
        assert fidelity == "launch"      # the race and the gain are measured on robust twin launches
        return lambda heights_list, seed, trials: [(trials if not np.any(h) else trials // 3, trials, 0.0, name)
                                                   for h in heights_list]

    # the face caches a name once resolved (lazy_loader): the command reads it there
    monkeypatch.setattr("rollability_ros.core.optimization.fidelity_batch_evaluator", launches)
    assert main(["select", run_dir, "--workers", "1"]) == 0
    captured = capsys.readouterr()
    warnings = captured.err.strip().splitlines()
    assert len(warnings) == 1 and warnings[0].startswith("rollability select: warning: no design beats the bare "
                                                         "robot on fresh robust launches")
    assert "does NOT beat the bare robot" in captured.out and "race of" in captured.out
    parameters = load_parameters(os.path.join(run_dir, "designs", "designs.yaml"))
    labels = parameters["designs.labels"]
    assert labels and all(parameters[f"designs.{label}.beats_baseline"] is False for label in labels)
