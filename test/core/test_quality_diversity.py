"""Quality diversity: the descriptors against analytic hulls, the CMA-MAE optimizer's protocol, archive, checkpoint
and spread, and selection from the archive."""
import json
import math
import os

import numpy as np
import pytest

pytest.importorskip("trimesh")
pytest.importorskip("cma")
ribs = pytest.importorskip("ribs")

from doubles import SyntheticEvaluator  # noqa: E402
from rollability_ros.core.optimization import design_set, selection  # noqa: E402
from rollability_ros.core.optimization.optimizer_contract import OptimizerSettings  # noqa: E402
from rollability_ros.core.optimization.optimization_run import (OptimizationRun, run_config, make_optimizer,  # noqa: E402
                                                                run_settings)
from rollability_ros.core.optimization.quality_diversity import (QualityDiversityOptimizer, emitter_batch_sizes,
                                                                 emitter_ceilings)
from rollability_ros.core.optimization.optimizer_contract import QualityDiversitySettings  # noqa: E402
from rollability_ros.core.profile import descriptors  # noqa: E402
from rollability_ros.core.profile.geometry import PrinterSpec, ProfileGrid, grid_xy  # noqa: E402
from rollability_ros.core.store import Store  # noqa: E402

GRID = ProfileGrid(rows=4, cols=4)


# --- descriptors -------------------------------------------------------------------------------------------------
def test_a_box_is_as_tall_as_its_heights_and_all_its_ridges_are_right_angles():
    for height in (0.05, 0.2, 0.45):
        measured = descriptors.profile_descriptors(np.full(GRID.n_variables, height), GRID)
        assert measured.max_height_mm == pytest.approx(height * GRID.unit_m * 1000, rel=1e-9)
        assert measured.sharpness_deg == pytest.approx(90.0, abs=1e-6)


def test_a_gable_roof_matches_its_analytic_length_weighted_ridge_angle():
    # 2 x 2 half grid: inner column (y = W/6) at height h, outer column (y = W/2) at 0. The hull is a flat strip
    # |y| <= W/6 at z = h, two roof planes down to the long footprint edges, vertical gable ends at x = +-L/2.
    grid = ProfileGrid(rows=2, cols=2)
    height_units = 0.3
    h, length, width = height_units * grid.unit_m, grid.length_m, grid.width_m
    run = width / 3                        # from y = W/6 to y = W/2
    slope_deg = math.degrees(math.atan2(h, run))
    slant = math.hypot(run, h)
    # ridges: 2 strip-to-roof edges (length L, angle = roof slope); gable edges at 90 deg: 2 strip ends (W/3) and
    # 4 roof ends (slant). Roof planes meet the base along the footprint edges: base edges do not count.
    expected = (2 * length * slope_deg + 90.0 * (2 * width / 3 + 4 * slant)) / (2 * length + 2 * width / 3 + 4 * slant)
    heights = np.array([height_units, 0.0, height_units, 0.0])   # row-major: (row 0: inner, outer), (row 1: ...)
    measured = descriptors.profile_descriptors(heights, grid)
    assert measured.max_height_mm == pytest.approx(h * 1000)
    assert measured.sharpness_deg == pytest.approx(expected, rel=1e-6)


def test_a_smooth_dome_is_less_sharp_than_a_box_and_the_baseline_is_zero():
    xy = grid_xy(GRID)
    radius = np.hypot(xy[:, 0] / (GRID.length_m / 2), xy[:, 1] / (GRID.width_m / 2))
    dome = descriptors.profile_descriptors(np.clip(0.45 * (1 - radius ** 2 / 2), 0.01, 0.45), GRID)
    box = descriptors.profile_descriptors(np.full(GRID.n_variables, 0.45), GRID)
    assert dome.sharpness_deg < 40 < box.sharpness_deg
    assert descriptors.profile_descriptors(np.zeros(GRID.n_variables), GRID) == descriptors.ProfileDescriptors(0, 0)
    flat = np.full(GRID.n_variables, GRID.flat_tolerance / 2)
    assert descriptors.profile_descriptors(flat, GRID) == descriptors.ProfileDescriptors(0, 0)
    with pytest.raises(ValueError):
        descriptors.profile_descriptors(np.full(GRID.n_variables, np.nan), GRID)


# --- the optimizer -------------------------------------------------------------------------------------------------
OPTIMUM = np.linspace(0.05, 0.4, GRID.n_variables)


def settings(**overrides):
    values = dict(method="cma_mae", popsize=12, sigma0=0.02, seed=3, trials=30, max_generations=0,
                  reevaluate_incumbent=True)
    values.update(overrides)
    return OptimizerSettings(**values)


def drive(optimizer, evaluator, generations):
    """Run ``generations`` generations of ask / tell / re-evaluation with the synthetic evaluator."""
    for generation in range(generations):
        population = optimizer.ask()
        results = evaluator(population, 1000 + generation)
        optimizer.tell(population, [s / t for s, t, _, _ in results], [t for _, t, _, _ in results])
        request = optimizer.reevaluation_request()
        if request is not None:
            (again,) = evaluator([request], 5000 + generation)
            optimizer.tell_reevaluation(again[0] / again[1], again[1])


def test_batches_split_the_population_and_too_many_emitters_are_refused():
    assert emitter_batch_sizes(12, 3) == [4, 4, 4]
    assert emitter_batch_sizes(13, 3) == [5, 4, 4]
    with pytest.raises(ValueError, match="emitters"):
        QualityDiversityOptimizer(settings(popsize=6), QualityDiversitySettings(emitters=4), GRID)
    with pytest.raises(ValueError, match="learning_rate"):
        QualityDiversityOptimizer(settings(), QualityDiversitySettings(learning_rate=0.0), GRID)


def test_each_emitter_searches_under_its_own_height_ceiling():
    qd = QualityDiversitySettings(emitters=3, lowest_ceiling=0.5)
    assert emitter_ceilings(3, 0.5) == [1.0, 0.75, 0.5] and emitter_ceilings(1, 0.5) == [1.0]
    optimizer = QualityDiversityOptimizer(settings(), qd, GRID)
    ceilings = [GRID.height_max * f for f in (1.0, 0.75, 0.5)]
    evaluator = SyntheticEvaluator(np.full(GRID.n_variables, 0.45), trials=30)   # pulls every emitter upward
    tallest = [0.0, 0.0, 0.0]
    for generation in range(15):
        population = optimizer.ask()
        for index, heights in enumerate(population):
            tallest[index // 4] = max(tallest[index // 4], heights.max())
        results = evaluator(population, generation)
        optimizer.tell(population, [r[0] / r[1] for r in results], [30] * 12)
        optimizer.tell_reevaluation(0.5, 30)
    for reached, ceiling in zip(tallest, ceilings):
        assert reached <= ceiling + 1e-12
        assert reached > 0.9 * ceiling, "pulled upward, each emitter climbs to its ceiling"


def test_candidates_are_within_bounds_and_the_archive_holds_what_was_told():
    optimizer = QualityDiversityOptimizer(settings(), QualityDiversitySettings(emitters=3), GRID)
    evaluator = SyntheticEvaluator(OPTIMUM, trials=30)
    told = {}
    for generation in range(6):
        population = optimizer.ask()
        assert len(population) == 12
        for heights in population:
            assert heights.shape == (GRID.n_variables,)
            assert heights.min() >= GRID.height_min and heights.max() <= GRID.height_max
        results = evaluator(population, generation)
        fitness = [s / t for s, t, _, _ in results]
        told.update({tuple(h): f for h, f in zip(population, fitness)})
        optimizer.tell(population, fitness, [30] * 12)
        optimizer.tell_reevaluation(*[(r[0] / r[1], r[1]) for r in evaluator([optimizer.reevaluation_request()],
                                                                             99)][0])
    rows = optimizer.archive_rows()
    assert len(rows) == optimizer.archive_summary()["filled_cells"] >= 2
    assert optimizer.archive_summary()["qd_score"] == pytest.approx(sum(r["fitness"] for r in rows))
    cells = set()
    for row in rows:
        key = tuple(row["heights"])
        assert key in told, "every elite is a design that was evaluated, with the heights evaluated"
        assert row["fitness"] == told[key]
        measured = descriptors.profile_descriptors(np.array(row["heights"]), GRID)
        assert (row["max_height_mm"], row["sharpness_deg"]) == pytest.approx(measured.as_tuple())
        cells.add(tuple(row["cell"]))
        # each elite is the best told design of its cell
        same_cell = [f for h, f in told.items() if optimizer.result_archive.index_of_single(
            descriptors.profile_descriptors(np.array(h), GRID).as_tuple()) == optimizer.result_archive.
            grid_to_int_index([row["cell"]])[0]]
        assert row["fitness"] == max(same_cell)
    assert len(cells) == len(rows)


def test_generations_where_every_candidate_fails_keep_the_search_going():
    # a hard objective (launches on a pessimistic twin) can score whole generations 0: nothing enters the archive
    # (threshold_min 0), the emitters converge and restart; with no elite to restart from they go back to their
    # start (pyribs' own restart raised IndexError on the empty archive)
    optimizer = QualityDiversityOptimizer(settings(), QualityDiversitySettings(emitters=3), GRID)
    for generation in range(8):
        population = optimizer.ask()
        assert all(GRID.height_min <= h.min() and h.max() <= GRID.height_max for h in population)
        optimizer.tell(population, [0.0] * len(population), [30] * len(population))
        optimizer.tell_reevaluation(0.0, 30)
    assert optimizer.archive_summary()["qd_score"] == 0.0
    assert sum(emitter.restarts for emitter in optimizer.emitters) >= 1
    population = optimizer.ask()  # the first success fills a cell and the search goes on from the archive
    optimizer.tell(population, [0.5] + [0.0] * (len(population) - 1), [30] * len(population))
    assert optimizer.archive.stats.num_elites >= 1


def test_an_empty_archive_at_the_start_of_a_search_warns_nothing_and_other_warnings_pass(monkeypatch):
    """pyribs warned on every tell that left the CMA-MAE archive empty (printed each generation of a search whose
    candidates all score 0), which a search expects while no design has scored yet: silenced for exactly those
    tells, not globally. Every warning is shown here (filter "always", as a fresh interpreter shows each first
    one): none is pyribs's, and another warning raised inside the same tells still comes through."""
    import warnings

    add = ribs.archives.GridArchive.add

    def add_and_warn(archive, *args, **kwargs):
        warnings.warn("a warning of another kind", UserWarning)
        return add(archive, *args, **kwargs)

    monkeypatch.setattr(ribs.archives.GridArchive, "add", add_and_warn)
    optimizer = QualityDiversityOptimizer(settings(), QualityDiversitySettings(emitters=3), GRID)
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        for fitness in (0.0, 0.0, 0.5):
            population = optimizer.ask()
            optimizer.tell(population, [fitness] + [0.0] * (len(population) - 1), [30] * len(population))
            optimizer.tell_reevaluation(fitness, 30)
    assert optimizer.archive.stats.num_elites >= 1                       # the first success filled a cell
    messages = [str(warning.message) for warning in shown]
    assert not [m for m in messages if "was empty before adding solutions" in m], messages
    assert messages.count("a warning of another kind") == 2 * 3          # archive and result archive, each tell


def test_state_round_trips_through_json_and_continues_exactly():
    qd = QualityDiversitySettings(emitters=2)
    evaluator = SyntheticEvaluator(OPTIMUM, trials=30)
    straight = QualityDiversityOptimizer(settings(), qd, GRID)
    drive(straight, evaluator, 5)
    state = json.loads(json.dumps(straight.state_dict()))
    restored = QualityDiversityOptimizer.from_state_dict(state, settings(), qd, GRID)
    assert restored.archive_rows() == straight.archive_rows()
    for optimizer in (straight, restored):
        population = optimizer.ask()
        optimizer.tell(population, [0.5] * len(population), [30] * len(population))
    assert restored.archive_rows() == straight.archive_rows()
    assert restored.sigma == straight.sigma


def test_a_state_from_other_settings_or_method_is_refused():
    qd = QualityDiversitySettings(emitters=2)
    optimizer = QualityDiversityOptimizer(settings(), qd, GRID)
    drive(optimizer, SyntheticEvaluator(OPTIMUM, trials=30), 3)
    state = optimizer.state_dict()
    with pytest.raises(ValueError, match="archive|initial mean"):
        QualityDiversityOptimizer.from_state_dict(state, settings(), QualityDiversitySettings(emitters=3), GRID)
    tampered = dict(state, archive_sha256="0" * 64)
    with pytest.raises(ValueError, match="archive"):
        QualityDiversityOptimizer.from_state_dict(tampered, settings(), qd, GRID)
    with pytest.raises(ValueError, match="cmaes"):
        make_optimizer(GRID, run_settings({"optimizer.method": "cmaes", "optimizer.seed": 3}), clock=lambda: 0.0, state=state)


def test_at_equal_budget_the_archive_spans_more_heights_than_one_cma_es():
    """The point of the method: on the same evaluator and budget, CMA-MAE's designs cover more of the height x
    sharpness map and a wider height range than CMA-ES's, whose population stays in one basin. Summed over three
    seeds: one trajectory is chaotic (a different BLAS kernel moves a single seed's cell count by 15%)."""
    evaluator = SyntheticEvaluator(OPTIMUM, trials=30, width=0.2)
    spans = {"cmaes": [0.0, 0], "cma_mae": [0.0, 0]}
    for seed in (3, 4, 5):
        for method in spans:
            optimizer = make_optimizer(GRID, run_settings({f"optimizer.{k}": v for k, v in dict(
                method=method, popsize=12, seed=seed, max_generations=0).items()}), clock=lambda: 0.0)
            heights_mm, cells = [], set()
            for generation in range(20):
                population = optimizer.ask()
                results = evaluator(population, generation)
                optimizer.tell(population, [s / t for s, t, _, _ in results], [t for _, t, _, _ in results])
                if optimizer.reevaluation_request() is not None:
                    optimizer.tell_reevaluation(0.0, 30)
                for heights in population:
                    measured = descriptors.profile_descriptors(heights, GRID)
                    heights_mm.append(measured.max_height_mm)
                    cells.add((int(measured.max_height_mm // 9), int(measured.sharpness_deg // 15)))
            spans[method][0] += np.ptp(heights_mm)
            spans[method][1] += len(cells)
    assert spans["cma_mae"][0] > 2 * spans["cmaes"][0]
    assert spans["cma_mae"][1] > 2 * spans["cmaes"][1]


def test_a_run_stores_its_archive_every_generation(tmp_path):
    parameters = {"optimizer.method": "cma_mae", "optimizer.max_generations": 4, "optimizer.seed": 2,
                  "optimizer.trials": 30, "optimizer.popsize": 6, "quality_diversity.emitters": 2}
    run_dir = os.path.join(tmp_path, "run")
    run = OptimizationRun(run_dir, run_config(parameters), GRID, SyntheticEvaluator(OPTIMUM, trials=30))
    run.run()
    run.close()
    with Store(run_dir) as store:
        archive = store.run_info("run")["info"]["archive"]
        generations = {c.generation for c in store.candidates()}
    assert archive["descriptors"] == ["max_height_mm", "sharpness_deg"]
    assert archive["filled_cells"] == len(archive["elites"]) >= 1
    assert {e["generation"] for e in archive["elites"]} <= generations == {1, 2, 3, 4}


# --- selection from the archive --------------------------------------------------------------------------------------
def elite(cell, height_mm, sharpness_deg, fitness, trials=20):
    """A synthetic archive elite: a box-ish profile of the given height (sharpness is what the archive says)."""
    heights = np.full(GRID.n_variables, height_mm / 1000 / GRID.unit_m)
    heights[0] *= 0.5 + cell[1] / 10      # distinct designs per cell
    return {"cell": list(cell), "heights": heights.tolist(), "fitness": fitness, "trials": trials, "generation": 1,
            "max_height_mm": height_mm, "sharpness_deg": sharpness_deg}


def test_archive_selection_takes_the_best_then_the_farthest_fit_elites():
    elites = [elite((9, 2), 88, 40, 0.80), elite((8, 2), 80, 40, 0.75), elite((5, 1), 50, 25, 0.75),
              elite((6, 4), 65, 65, 0.75), elite((2, 2), 25, 40, 0.20)] + \
        [elite((i, 5), 10 * i + 5, 80, 0.1) for i in range(1, 9)]
    archive = {"ranges": [[0, 90], [0, 90]], "elites": elites}
    chosen = selection.select_from_archive(archive, [], GRID, PrinterSpec(),
                                           selection.SelectionSettings(count=3, top_fraction=0.3))
    assert [d.label for d in chosen.designs] == ["A", "B", "C"]
    assert chosen.designs[0].cell == (9, 2)
    # from A (88 mm, 40 deg) the farthest fit elite is (50 mm, 25 deg), then (65 mm, 65 deg); never the unfit one
    assert [d.cell for d in chosen.designs[1:]] == [(5, 1), (6, 4)]
    assert chosen.top_threshold == pytest.approx(np.quantile([e["fitness"] for e in elites], 0.7))
    assert "highest lower Wilson bound" in chosen.designs[0].reason
    assert "farthest from pick 1 " in chosen.designs[1].reason
    assert "farthest from picks 1, 2 " in chosen.designs[2].reason


def test_archive_selection_screens_every_elite_on_fresh_trials():
    # in the run the tall elite looked best; the screen shows it was luck, so it is not in the top pool
    elites = [elite((9, 2), 88, 40, 0.95), elite((5, 1), 50, 25, 0.60), elite((6, 4), 60, 70, 0.55),
              elite((3, 3), 30, 55, 0.50)]
    truth = {tuple(e["heights"]): p for e, p in zip(elites, (0.1, 0.7, 0.6, 0.5))}
    calls = []

    def evaluate_batch(heights_list, seed):
        calls.append(len(heights_list))
        return [(int(round(truth.get(tuple(h), 0.0) * 60)), 60, 0.0, "fake") for h in heights_list]

    chosen = selection.select_from_archive({"ranges": [[0, 90], [0, 90]], "elites": elites}, [], GRID,
                                           PrinterSpec(), selection.SelectionSettings(count=2, top_fraction=0.5,
                                                                                      reevaluate_trials=60),
                                           evaluate_batch)
    assert calls == [4, 3]      # the screen of all elites, then the chosen two and the baseline
    assert [d.cell for d in chosen.designs] == [(5, 1), (6, 4)]
    assert "screen" in chosen.designs[0].reason
    assert chosen.designs[0].reevaluation[:2] == (42, 60)


# --- the whole chain: run -> select -> report ------------------------------------------------------------------------
def test_a_run_selects_from_its_archive_and_the_report_shows_the_map(tmp_path):
    pytest.importorskip("matplotlib")
    from rollability_ros.core.results import design_map, report, report_writer

    parameters = {"optimizer.method": "cma_mae", "optimizer.max_generations": 8, "optimizer.seed": 4,
                  "optimizer.trials": 30, "optimizer.popsize": 12, "quality_diversity.emitters": 3}
    run_dir = os.path.join(tmp_path, "run")
    evaluator = SyntheticEvaluator(OPTIMUM, trials=30, width=0.2)
    run = OptimizationRun(run_dir, run_config(parameters), GRID, evaluator)
    run.run()
    settings = selection.SelectionSettings(count=3, top_fraction=0.5, reevaluate_trials=60)
    picked, folder = design_set.select_run(run.store, "run", run_dir, GRID, PrinterSpec(), settings,
                                          SyntheticEvaluator(OPTIMUM, trials=60, width=0.2))
    run.close()
    assert picked.archive and picked.top_threshold is not None and len(picked.designs) >= 2
    archive = design_map.read_archive(os.path.join(folder, design_map.ARCHIVE_FILENAME))
    assert sorted(r["label"] for r in archive if r["label"]) == [d.label for d in picked.designs]
    assert all(r["top_pool"] == 1 for r in archive if r["label"])
    traits = design_map.read_traits(os.path.join(folder, design_map.TRAITS_FILENAME))
    evaluated = sum(r["trials"] for r in traits if r["trait"] == "max_height_mm")
    with Store(run_dir) as store:
        assert evaluated == sum(c.trials for c in store.candidates())   # every evaluation lands in one height bin

    built = report_writer.build_report(report.load_report_data(os.path.join(run_dir, "store.sqlite")), tmp_path / "report")
    names = {os.path.basename(path) for path in built.figure_paths}
    assert {"design_map.png", "design_traits.png"} <= names
    assert {f"design_{d.label}.png" for d in picked.designs} <= names
    assert "quality-diversity map (simulated)" in built.summary and "Spearman rho" in built.summary


def test_a_damaged_archive_table_is_refused_with_its_name(tmp_path):
    from rollability_ros.core.results import design_map

    path = tmp_path / "archive.csv"
    path.write_text(",".join(selection.ARCHIVE_COLUMNS) + "\n0,1,50,40,nan-ish,20,1,60,0.1,0,\n")
    with pytest.raises(ValueError, match="archive.csv.*in_run_fitness"):
        design_map.read_archive(str(path))
    path.write_text(",".join(selection.ARCHIVE_COLUMNS) + "\n0,1,50,40,1.5,20,,,,0,\n")
    with pytest.raises(ValueError, match="outside"):
        design_map.read_archive(str(path))


def test_a_top_pool_smaller_than_the_count_is_a_shortfall_that_says_what_to_change():
    elites = [elite((9, 2), 88, 40, 0.8), elite((5, 1), 50, 25, 0.3), elite((3, 3), 30, 55, 0.2)]
    picked = selection.select_from_archive({"ranges": [[0, 90], [0, 90]], "elites": elites}, [], GRID, PrinterSpec(),
                                           selection.SelectionSettings(count=3, top_fraction=0.1))
    assert [d.cell for d in picked.designs] == [(9, 2)]
    assert "top pool" in picked.shortfall and "top_fraction" in picked.shortfall


def test_the_result_mean_is_heights_within_the_bounds():
    optimizer = QualityDiversityOptimizer(settings(), QualityDiversitySettings(), GRID)
    drive(optimizer, SyntheticEvaluator(np.zeros(GRID.n_variables), trials=30), 5)   # pulls toward the lower bound
    mean = optimizer.result.mean
    assert mean.shape == (GRID.n_variables,) and mean.min() >= GRID.height_min and mean.max() <= GRID.height_max


def test_settings_the_method_cannot_run_are_refused_before_a_run_starts():
    from rollability_ros.core.optimization.optimization_run import check_method_settings

    check_method_settings(run_settings({"optimizer.method": "cma_mae", "optimizer.popsize": 12}))
    check_method_settings(run_settings({"optimizer.method": "cmaes", "optimizer.popsize": 4}))   # no archive used
    with pytest.raises(ValueError, match="popsize 4 cannot give 3 emitters"):
        check_method_settings(run_settings({"optimizer.method": "cma_mae", "optimizer.popsize": 4}))
    with pytest.raises(ValueError, match="method must be one of"):
        run_settings({"optimizer.method": "cma-mae"})
