"""Design selection from a real run's store: ranking, printability, diversity, shortfall, STL/CSV/YAML output."""
import csv
import itertools
import os

import numpy as np
import pytest

pytest.importorskip("cma")
pytest.importorskip("trimesh")

from rollability_ros.core.profile import geometry  # noqa: E402
from rollability_ros.core.config import load_parameters  # noqa: E402
from doubles import SyntheticEvaluator, tree_checksums  # noqa: E402
from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config  # noqa: E402
from rollability_ros.core.records import CandidateRecord  # noqa: E402
from rollability_ros.core.optimization.design_set import design_set_folders, write_selection  # noqa: E402
from rollability_ros.core.optimization.selection import (  # noqa: E402
    SelectionSettings,
    pool_candidates,
    rms_distance,
    select_designs,
)
from rollability_ros.core.store import Store  # noqa: E402

GRID = geometry.ProfileGrid(rows=3, cols=3)
OPTIMUM = np.linspace(0.1, 0.4, GRID.n_variables)


@pytest.fixture(scope="module")
def run_candidates(tmp_path_factory):
    """Candidates of a real 25-generation run on the synthetic fitness (sigma 0.1 for a spread-out log)."""
    run_dir = os.path.join(tmp_path_factory.mktemp("selection"), "run")
    parameters = {"optimizer.max_generations": 25, "optimizer.seed": 3, "optimizer.trials": 30,
                  "optimizer.sigma0": 0.1, "profile.rows": GRID.rows, "profile.cols": GRID.cols}
    run = OptimizationRun(run_dir, run_config(parameters), GRID, SyntheticEvaluator(OPTIMUM, trials=30))
    run.run()
    run.close()
    with Store(run_dir) as store:
        return run_dir, store.candidates()


def test_picks_high_fitness_diverse_printable_designs_in_rank_order(run_candidates):
    _, candidates = run_candidates
    settings = SelectionSettings(count=3, min_distance=0.05)
    result = select_designs(candidates, GRID, geometry.PrinterSpec(), settings)
    assert [d.label for d in result.designs] == ["A", "B", "C"] and result.shortfall == ""
    for a, b in itertools.combinations(result.designs, 2):
        assert rms_distance(a.design.heights, b.design.heights) >= 0.05
    lows = [d.design.wilson_low for d in result.designs]
    assert lows == sorted(lows, reverse=True)
    best = max(pool_candidates(candidates), key=lambda d: d.wilson_low)
    np.testing.assert_array_equal(result.designs[0].design.heights, best.heights)
    assert result.rejected.get("too close", 0) > 0     # the converged population is dense near the top
    for design in result.designs:
        assert geometry.check_printability(design.mesh, geometry.PrinterSpec()).printable
        assert design.metrics.max_height_m == pytest.approx(design.design.heights.max() * GRID.unit_m)


def test_shortfall_is_reported_not_padded(run_candidates):
    _, candidates = run_candidates
    result = select_designs(candidates, GRID, geometry.PrinterSpec(), SelectionSettings(count=3, min_distance=1.0))
    assert len(result.designs) == 1
    assert "only 1 of 3 requested designs" in result.shortfall and "too close" in result.shortfall
    tiny_printer = geometry.PrinterSpec(bed_z_m=0.001)
    result = select_designs(candidates, GRID, tiny_printer, SelectionSettings(count=3, min_distance=0.0))
    assert result.designs == [] and result.rejected == {"not printable: printer.bed_z_m": result.considered}
    assert "printer.bed_z_m" in result.shortfall and "select --config" in result.shortfall


def test_a_footprint_wider_than_the_bed_stops_the_run_before_it_starts(tmp_path):
    run_dir = tmp_path / "wide"
    parameters = {"optimizer.max_generations": 1, "printer.bed_x_m": 0.1, "printer.bed_y_m": 0.1}
    with pytest.raises(ValueError, match=r"cannot optimize: the profile footprint 180 x 140 mm does not fit the "
                                         r"printer bed 100 x 100 mm \(printer.bed_x_m / printer.bed_y_m\)"):
        OptimizationRun(str(run_dir), run_config(parameters), GRID, SyntheticEvaluator(OPTIMUM, trials=30))
    assert not run_dir.exists()   # nothing written: the run can start again once the printer is fixed
    with pytest.raises(ValueError, match="printer.nozzle_m"):
        geometry.PrinterSpec(nozzle_m=0.001, min_wall_m=0.0008).validate()
    fine = geometry.ProfileGrid(rows=1000, cols=3)  # 0.18 mm spacing
    assert "grid spacing" in geometry.design_space_printability(fine, geometry.PrinterSpec())[0]


def test_identical_heights_are_pooled():
    heights = (0.1,) * GRID.n_variables
    records = [CandidateRecord("r", g, 0, heights, s / 60, s, 60, 1, 0.0) for g, s in ((0, 60), (1, 30))]
    records.append(CandidateRecord("r", 1, 1, (0.2,) * GRID.n_variables, 0.9, 54, 60, 1, 0.0))
    pooled = pool_candidates(records)
    assert [(p.successes, p.trials, p.evaluations) for p in pooled] == [(90, 120, 2), (54, 60, 1)]
    result = select_designs(records, GRID, geometry.PrinterSpec(), SelectionSettings(count=2, min_distance=0.0))
    # 54/60 once ranks above 90/120 pooled (Wilson low 0.80 vs 0.67)
    assert [d.design.trials for d in result.designs] == [60, 120]


def test_outputs_with_reevaluation(run_candidates):
    run_dir, candidates = run_candidates
    evaluator = SyntheticEvaluator(OPTIMUM, trials=200)
    settings = SelectionSettings(count=3, min_distance=0.05, reevaluate_trials=200)
    result = select_designs(candidates, GRID, geometry.PrinterSpec(), settings, evaluator, run_seed=3)
    folder = write_selection(run_dir, result, GRID, "run")

    with open(os.path.join(folder, "table3.csv"), newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert [r["configuration"] for r in rows] == ["baseline", "A", "B", "C"]
    assert all(r["trials"] == "200" and r["fitness_source"] == "reevaluated" for r in rows)
    for row, design in zip(rows[1:], result.designs):
        assert float(row["max_height_m"]) == pytest.approx(design.metrics.max_height_m, rel=1e-5)
        assert float(row["length_m"]) == pytest.approx(GRID.length_m, rel=1e-5)
        assert float(row["ci_low"]) <= float(row["simulated_fitness"]) <= float(row["ci_high"])
        assert float(row["simulated_fitness"]) == pytest.approx(
            evaluator.success_probability(design.design.heights), abs=0.12)

    parameters = load_parameters(os.path.join(folder, "designs.yaml"))
    assert parameters["designs.labels"] == ["A", "B", "C"]
    assert parameters["designs.grid.rows"] == 3
    for design in result.designs:
        np.testing.assert_array_equal(parameters[f"designs.{design.label}.heights"], design.design.heights)
        assert parameters[f"designs.{design.label}.mesh_units"] == "mm"
        for extension in (".stl", ".3mf"):  # both in millimetres, read back into metres
            mesh = geometry.load_profile_mesh(os.path.join(folder, f"mesh_{design.label}{extension}"))
            assert mesh.volume == pytest.approx(design.mesh.volume, rel=1e-5)

    # a second selection of the run writes a new design set beside the first, which stays byte for byte
    before = tree_checksums(run_dir)
    fewer = select_designs(candidates, GRID, geometry.PrinterSpec(), SelectionSettings(count=1))
    second = write_selection(run_dir, fewer, GRID, "run")
    assert os.path.basename(second) == "designs-2" and os.path.basename(folder) == "designs"
    assert sorted(n for n in os.listdir(second) if n.startswith("mesh_")) == ["mesh_A.3mf", "mesh_A.stl"]
    after = tree_checksums(run_dir)
    assert {path: after[path] for path in before} == before
    assert os.path.basename(write_selection(run_dir, fewer, GRID, "run")) == "designs-3"


def test_settings_are_checked():
    with pytest.raises(ValueError, match=r"^selection.count out of range: 0 is not in \[1, 26\]$"):
        select_designs([], GRID, geometry.PrinterSpec(), SelectionSettings(count=0))
    with pytest.raises(ValueError, match="needs an evaluator"):
        select_designs([], GRID, geometry.PrinterSpec(), SelectionSettings(reevaluate_trials=10))


def test_select_cli_takes_another_printer_from_config(run_candidates, tmp_path, capsys):
    from rollability_ros.cli import main as cli_main

    run_dir, _ = run_candidates
    printer_file = tmp_path / "small_printer.yaml"
    printer_file.write_text("/**:\n  ros__parameters:\n    printer:\n      bed_x_m: 0.1\n      bed_y_m: 0.1\n")
    assert cli_main(["select", run_dir, "--count", "1", "--config", str(printer_file)]) == 1
    assert "printer.bed_x_m / bed_y_m" in capsys.readouterr().err
    assert cli_main(["select", run_dir, "--count", "1", "--mesh-units", "m"]) == 0
    latest = design_set_folders(run_dir)[-1]     # each selection of the run is its own design set
    assert f"wrote {latest}/" in capsys.readouterr().out
    header = open(os.path.join(latest, "mesh_A.stl"), "rb").read(80)
    assert header.startswith(b"rollability_ros profile mesh; units=m;")


def test_table3_gives_each_design_its_printed_mass_beside_its_height(run_candidates, tmp_path):
    """The mass column is the robot's print of each design (what the twin mounts), and the report keeps it;
    designs.yaml tells the lab the print those masses assume (here 10 % infill, config/light_print.yaml's)."""
    import dataclasses
    import shutil

    from rollability_ros.core.optimization.design_set import select_run
    from rollability_ros.core.profile.print_mass import ProfilePrintSpec
    from rollability_ros.core.results import report
    from rollability_ros.core.robots.robot import ChassisModel, ChassisSpec
    from rollability_ros.core.sim import EvaluatorSettings

    run_dir = str(tmp_path / "run")
    shutil.copytree(run_candidates[0], run_dir)
    spec = ChassisSpec(profile_print=ProfilePrintSpec(infill_fraction=0.1))
    chassis = ChassisModel(spec)
    with Store(run_dir) as store:
        result, folder = select_run(store, "run", run_dir, GRID, geometry.PrinterSpec(),
                                    SelectionSettings(count=3, min_distance=0.05),
                                    weigh=lambda mesh: chassis.profile_body(mesh).mass_kg,
                                    printed_with=EvaluatorSettings(robot=spec).print_instructions())
    printed = load_parameters([os.path.join(folder, "designs.yaml")])
    assert printed["designs.print.infill_fraction"] == 0.1 and printed["designs.print.profile_mass_scale"] == 1.0
    assert printed["designs.print.wall_thickness_m"] == spec.profile_print.wall_thickness_m
    heavier = ChassisModel(dataclasses.replace(spec, profile_print=ProfilePrintSpec()))   # the default 20 %
    assert heavier.profile_body(result.designs[0].mesh).mass_kg > 1.05 * result.designs[0].printed_mass_kg
    with open(os.path.join(folder, "table3.csv"), newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert list(rows[0])[3:5] == ["max_height_m", "printed_mass_g"] and float(rows[0]["printed_mass_g"]) == 0.0
    for row, design in zip(rows[1:], result.designs):
        grams = chassis.profile_body(geometry.profile_mesh(design.design.heights, GRID)).mass_kg * 1000
        assert float(row["printed_mass_g"]) == pytest.approx(grams, rel=1e-5) and grams > 10
    shown = report.load_report_data(run_dir, "run").geometry
    assert [float(r["printed_mass_g"]) for r in shown] == pytest.approx([float(r["printed_mass_g"]) for r in rows[1:]],
                                                                     rel=1e-5)
