"""Calibration of the launch twin: parameter mapping, likelihood, the calibrated parameter file, the CLI, and
recovery of hidden parameter values from synthetic "physical" outcomes."""
import math

import numpy as np
import pytest
import yaml

from doubles import synthetic_outcomes
from rollability_ros.core.campaign import calibration, local_rig_settings_from_files
from rollability_ros.core.results.analysis import ConditionResult
from rollability_ros.core.config import ConfigError, load_parameters, section
from rollability_ros.core.sim.evaluation import load_settings
from rollability_ros.core.sim.launch.settings import (TWIN_SECTIONS, launch_twin_settings_from_parameters,
                                                      load_launch_twin_settings)
from rollability_ros.core.results import write_outcome_csv
from rollability_ros.core.records import LaunchCondition


def twin_parameters():
    return load_parameters(list(calibration.TWIN_CONFIGS))


def test_normalised_coordinates_map_to_bounds_on_linear_and_log_scales():
    settings = calibration.CalibrationSettings(parameters=["a", "b"], lower=[1000.0, -0.02], upper=[100000.0, 0.02],
                                               log_scale=[True, False])
    assert settings.to_values([0.0, 0.0]) == pytest.approx([1000.0, -0.02])
    assert settings.to_values([0.5, 0.5]) == pytest.approx([10000.0, 0.0])
    assert settings.to_values([1.5, -1.0]) == pytest.approx([100000.0, -0.02])   # clipped to [0, 1]
    assert settings.to_normalised([20000.0, 0.01]) == pytest.approx(
        [math.log(20) / math.log(100), 0.75])
    with pytest.raises(ValueError, match="b = 0.03 lies outside"):
        settings.to_normalised([20000.0, 0.03])


def test_settings_are_checked():
    with pytest.raises(ValueError, match="one entry per parameter"):
        calibration.CalibrationSettings(parameters=["a"], lower=[0.0, 1.0], upper=[1.0], log_scale=[False]).validate()
    with pytest.raises(ValueError, match="lower > 0"):
        calibration.CalibrationSettings(parameters=["a"], lower=[0.0], upper=[1.0], log_scale=[True]).validate()
    parameters = {**twin_parameters(), "calibration.parameters": ["launch_twin.foam.stiffness"],
                  "calibration.lower": [1.0], "calibration.upper": [2.0], "calibration.log_scale": [False]}
    with pytest.raises(ConfigError, match="launch_twin.foam.stiffness not set"):
        calibration.calibration_settings(parameters)


def test_shipped_config_starts_inside_its_bounds():
    parameters = load_parameters([*calibration.TWIN_CONFIGS, "calibration"])
    settings = calibration.calibration_settings(parameters)
    start = settings.to_normalised([parameters[name] for name in settings.parameters])
    assert np.all((start >= 0) & (start <= 1))


def test_binomial_log_likelihood_matches_scipy_and_clips():
    stats = pytest.importorskip("scipy.stats")
    k, n, p = np.array([3, 0, 10]), np.array([10, 5, 10]), np.array([0.25, 0.0, 0.9])
    expected = stats.binom.logpmf(k, n, np.clip(p, 0.01, 0.99)).sum()
    assert calibration.binomial_log_likelihood(k, n, p, 0.01) == pytest.approx(expected)
    rows = calibration.binomial_log_likelihood(k, n, np.stack([p, p]), 0.01)
    assert rows.shape == (2,) and rows == pytest.approx([expected, expected])
    with pytest.raises(ValueError, match="successes <= trials"):
        calibration.binomial_log_likelihood([4], [3], [0.5], 0.01)


def test_bootstrap_resamples_counts_within_each_condition():
    conditions = [ConditionResult("A", 0.75, 0.8, 0.0, 0, 10), ConditionResult("A", 0.75, 0.8, 30.0, 10, 10),
                  ConditionResult("B", 0.75, 0.8, 0.0, 5, 10)]
    rng = np.random.default_rng(0)
    draws = [calibration.bootstrap_conditions(conditions, rng) for _ in range(200)]
    assert all(d[0].successes == 0 and d[1].successes == 10 and d[2].trials == 10 for d in draws)
    assert np.mean([d[2].successes for d in draws]) == pytest.approx(5, abs=0.5)


def test_simulation_seeds_are_common_within_a_fit_and_differ_between_resamples():
    assert calibration.simulation_seeds(1, 0, 4) == calibration.simulation_seeds(1, 0, 4)
    assert not set(calibration.simulation_seeds(1, 0, 4)) & set(calibration.simulation_seeds(1, 1, 4))


def test_calibrated_file_changes_twin_evaluator_and_rig_settings(tmp_path):
    path = tmp_path / "calibrated.yaml"
    fitted = {"launch_twin.foam.contact_stiffness_npm": 45000.0, "launch_twin.foam.lateral_friction": 0.6,
              "robot.com_offset_z_m": 0.004}
    document = calibration.calibrated_parameter_document(fitted)
    path.write_text(yaml.safe_dump(document), encoding="utf-8")
    rig_path = tmp_path / "calibrated_rig.yaml"
    rig_path.write_text(yaml.safe_dump(calibration.rig_parameter_document(path)), encoding="utf-8")
    default = load_launch_twin_settings()
    twin = load_launch_twin_settings([*calibration.TWIN_CONFIGS, str(path)])
    assert default.twin.foam.contact_stiffness_npm != 45000.0
    assert twin.twin.foam.contact_stiffness_npm == 45000.0
    assert twin.twin.foam.lateral_friction == 0.6
    assert twin.robot.com_offset_z_m == 0.004
    assert twin.twin.foam.contact_damping_nspm == default.twin.foam.contact_damping_nspm   # the rest: defaults
    evaluator = load_settings(["sim", "robot", "evaluator", str(path)])       # evaluate / optimize --config
    assert evaluator.robot.com_offset_z_m == 0.004
    rig = section(load_parameters(["rig", str(rig_path)]), "rig")              # the rig node's --params-file
    assert rig["twin_config"] == [*calibration.TWIN_CONFIGS, str(path)]
    assert load_launch_twin_settings(rig["twin_config"]).twin.foam.lateral_friction == 0.6
    # campaign --rig-config rig --rig-config calibrated.yaml: the in-process rig's twin reads it too
    local = local_rig_settings_from_files("sim", ["rig", str(path)], "rollability campaign --rig-config")
    assert load_launch_twin_settings(local.rig.twin_config).twin.foam.lateral_friction == 0.6
    # every key of calibrated.yaml is one the twin reads: the file holds nothing a command would drop
    assert {name.split(".")[0] for name in load_parameters([str(path)])} <= TWIN_SECTIONS


def test_cli_writes_outputs_from_a_csv_of_physical_outcomes(tmp_path, capsys):
    pytest.importorskip("pybullet")
    pytest.importorskip("cma")
    from rollability_ros.cli import main
    from rollability_ros.core.records import LaunchOutcome

    outcomes = [LaunchOutcome("rig-1", f"t{i}", LaunchCondition("baseline", 0.75, 0.8, angle, i), "physical",
                              upright=bool(i % 2), classified_by="operator")
                for i, angle in enumerate([0.0, 0.0, 30.0, 30.0])]
    source = tmp_path / "physical.csv"
    write_outcome_csv(source, outcomes)
    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"calibration": {
        "parameters": ["launch_twin.foam.lateral_friction"], "lower": [0.3], "upper": [2.0], "log_scale": [True],
        "sim_repetitions": 2, "popsize": 2, "max_generations": 1, "bootstrap_resamples": 1}}}}), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["calibrate", "--physical", str(source), "--config", str(config), "--out", str(out),
                 "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    assert "log-likelihood: before" in printed and "rank agreement after" in printed
    for name in ("calibrated.yaml", "conditions.csv", "configurations.csv", "parameters.csv", "screen.csv",
                 "summary.txt"):
        assert (out / name).is_file(), name
    twin = load_launch_twin_settings([*calibration.TWIN_CONFIGS, str(out / "calibrated.yaml")])
    assert 0.3 <= twin.twin.foam.lateral_friction <= 2.0
    assert main(["calibrate", "--physical", str(tmp_path / "missing.csv"), "--out", str(out)]) == 2


@pytest.mark.slow
def test_recovers_a_hidden_centre_of_mass_offset_from_synthetic_outcomes(tmp_path):
    """Reduced synthetic truth (bench/bench_calibration_direct.py runs the fuller version): 'physical' outcomes from the
    twin with the chassis's COM 6 mm above the box centre instead of 15 mm below; the fit starts at the default."""
    pytest.importorskip("pybullet")
    pytest.importorskip("cma")
    from rollability_ros.core.profile.geometry import ProfileGrid, export_mesh, grid_xy, profile_mesh

    grid = ProfileGrid()
    xy = grid_xy(grid) / [grid.length_m / 2, grid.width_m / 2]
    dome = np.clip(grid.height_max * (1 - 0.5 * xy[:, 0] ** 2 - 0.5 * xy[:, 1] ** 2), 0.0, grid.height_max)
    export_mesh(profile_mesh(dome, grid), tmp_path / "dome.stl")
    parameters = {**twin_parameters(), "launch_twin.designs.mesh_labels": ["dome"],
                  "launch_twin.designs.mesh_files": [str(tmp_path / "dome.stl")]}
    name, truth = "robot.com_offset_z_m", 0.006
    # conditions where the centre of mass decides (rig's rule, stroke launcher, printed dome; 12 launches each):
    # the dome at 0 deg rights 12/11/8 of 12 at COM -15/-5/+6 mm, at +30 deg 10/11/1; the bare chassis at 0 deg
    # rights 12 of 12 at all three, so it says nothing about the COM here
    conditions = [LaunchCondition("dome", 0.75, 0.8, 0.0), LaunchCondition("dome", 0.75, 0.8, 30.0)]
    twin = launch_twin_settings_from_parameters(parameters)
    outcomes = synthetic_outcomes(twin, [name], [truth], conditions, 24)
    settings = calibration.CalibrationSettings(parameters=[name], lower=[-0.019], upper=[0.015], log_scale=[False],
                                               sim_repetitions=8, popsize=4, sigma0=0.3, max_generations=4,
                                               bootstrap_resamples=2, interval_points=9)
    with calibration.LaunchPool(2) as pool:
        result = calibration.calibrate(outcomes, twin, settings, pool)
    (estimate,) = result.estimates
    assert estimate.initial == -0.015
    assert result.after_log_likelihood > result.before_log_likelihood + 5
    assert abs(estimate.fitted - truth) < abs(estimate.initial - truth) / 3
    assert 0 < estimate.std < (settings.upper[0] - settings.lower[0]) / 2
    # the stated 95% interval (likelihood ratio, beta-binomial) holds the truth and says something
    assert estimate.interval_low <= truth <= estimate.interval_high, (estimate.interval_low, estimate.interval_high)
    assert not estimate.interval_low <= estimate.initial <= estimate.interval_high   # rules the start out
    assert estimate.interval_method.startswith("likelihood ratio")


def test_likelihood_interval_of_a_normal_log_likelihood_is_mean_plus_minus_1_96_sd():
    grid = np.linspace(-1.0, 3.0, 81)
    curve = -0.5 * ((grid - 1.0) / 0.4) ** 2
    low, high = calibration.likelihood_interval(grid, curve, ends="interpolate")
    assert low == pytest.approx(1.0 - 1.96 * 0.4, abs=2e-3) and high == pytest.approx(1.0 + 1.96 * 0.4, abs=2e-3)
    # grid ends: the first grid points outside, so never narrower (grid step 0.05)
    assert calibration.likelihood_interval(grid, curve) == pytest.approx((0.20, 1.80))
    # a curve still high at a bound is cut there
    assert calibration.likelihood_interval(grid, -grid)[0] == -1.0


def test_beta_binomial_likelihood_carries_the_simulations_monte_carlo_error():
    k, n = np.array([7]), np.array([10])
    # many simulated launches: the plug-in binomial; few: flatter (a wrong prediction costs less)
    many = calibration.beta_binomial_log_likelihood(k, n, np.array([70000]), 100000)
    assert many == pytest.approx(calibration.binomial_log_likelihood(k, n, np.array([0.7]), 1e-9), abs=1e-3)
    few_wrong = calibration.beta_binomial_log_likelihood(k, n, np.array([1]), 8)
    assert few_wrong > calibration.binomial_log_likelihood(k, n, np.array([1 / 8]), 1e-9)
    with pytest.raises(ValueError, match="upright <= repetitions"):
        calibration.beta_binomial_log_likelihood(k, n, np.array([9]), 8)


def test_interval_settings_are_checked():
    with pytest.raises(ValueError, match="needs bootstrap_resamples >= 20"):
        calibration.CalibrationSettings(interval="bootstrap", bootstrap_resamples=3).validate()
    with pytest.raises(ValueError, match="interval must be one of likelihood, bootstrap"):
        calibration.CalibrationSettings(interval="guess").validate()


def test_the_documented_calibrate_reoptimize_validate_sequence_runs_on_a_synthetic_truth(tmp_path, monkeypatch,
                                                                                          capsys):
    """docs/calibration.md's commands, at a miniature budget: "physical" launches of a hidden truth (the foam's
    friction at 2.5 instead of 1.0) -> calibrate -> optimize on the calibrated twin -> select -> evaluate the
    design on the truth. bench/bench_objective.py measures whether it pays; this checks that each step takes the
    previous one's output and that the calibrated twin is the one optimized on."""
    pytest.importorskip("pybullet")
    pytest.importorskip("cma")
    from rollability_ros.cli import main

    monkeypatch.chdir(tmp_path)
    truth = {"launch_twin.foam.lateral_friction": 2.5}
    conditions = [LaunchCondition("baseline", 0.75, 0.8, angle) for angle in (-30.0, 30.0)]
    outcomes = synthetic_outcomes(launch_twin_settings_from_parameters(twin_parameters()), list(truth),
                                  list(truth.values()), conditions, 6)
    write_outcome_csv(tmp_path / "campaign.csv", outcomes)
    (tmp_path / "small.yaml").write_text(yaml.safe_dump({"/**": {"ros__parameters": {"calibration": {
        "parameters": list(truth), "lower": [0.3], "upper": [3.0], "log_scale": [True], "sim_repetitions": 2,
        "popsize": 2, "max_generations": 1, "interval_points": 5}}}}), encoding="utf-8")
    assert main(["calibrate", "--physical", "campaign.csv", "--config", "small.yaml", "--out", "calibration",
                 "--workers", "1"]) == 0
    fitted = load_launch_twin_settings([*calibration.TWIN_CONFIGS, "calibration/calibrated.yaml"])
    assert fitted.twin.foam.lateral_friction != load_launch_twin_settings().twin.foam.lateral_friction
    # the objective file of the docs, with a miniature budget on top
    (tmp_path / "launch_objective.yaml").write_text(yaml.safe_dump({"/**": {"ros__parameters": {
        "objective": {"kind": "launch_twin",
                      "twin_config": ["sim", "robot", "launch_twin", "calibration/calibrated.yaml"]},
        "optimizer": {"method": "cmaes", "trials": 4, "popsize": 4, "max_generations": 1,
                      "initial_mean_screen": 0},
        "evaluator": {"workers": 1}, "profile": {"rows": 2, "cols": 2}}}}), encoding="utf-8")
    assert main(["optimize", "--config", "optimizer", "--config", "launch_objective.yaml"]) == 0
    (run,) = (tmp_path / "runs").iterdir()
    saved = load_parameters([str(run / "config.yaml")])
    assert saved["objective.kind"] == "launch_twin"
    assert saved["objective.twin_config"][-1] == "calibration/calibrated.yaml"
    assert main(["select", str(run), "--count", "1", "--reevaluate-trials", "4", "--workers", "1",
                 "--race-launches", "0", "--launch-trials", "0", "--world-count", "0"]) == 0
    designs = section(load_parameters([str(run / "designs" / "designs.yaml")]), "designs")
    heights = designs[designs["labels"][0]]["heights"]
    assert len(heights) == 4
    (tmp_path / "truth.yaml").write_text(yaml.safe_dump(calibration.calibrated_parameter_document(truth)),
                                         encoding="utf-8")
    (tmp_path / "on_truth.yaml").write_text(yaml.safe_dump({"/**": {"ros__parameters": {
        "objective": {"kind": "launch_twin", "twin_config": ["sim", "robot", "launch_twin", "truth.yaml"]},
        "profile": {"rows": 2, "cols": 2}}}}), encoding="utf-8")
    capsys.readouterr()
    assert main(["evaluate", "--heights", ",".join(map(str, heights)), "--trials", "4", "--workers", "1",
                 "--config", "on_truth.yaml"]) == 0
    assert "/4" in capsys.readouterr().out
