"""Bench characterisation (docs/characterisation.md): the strict file format, the measurement models, and
`rollability calibrate --characterisation` narrowing the interval of the unknown a reading measures."""
import dataclasses
import math

import pytest
import yaml

from rollability_ros.core.campaign import calibration
from rollability_ros.core.campaign.characterisation import (FORMAT, characterisation_log_likelihood,
                                                            load_characterisation, parse_characterisation,
                                                            slide_angle_deg)
from rollability_ros.core.config import load_parameters
from rollability_ros.core.sim.launch.settings import launch_twin_settings_from_parameters


def twin_parameters():
    return load_parameters(list(calibration.TWIN_CONFIGS))


def twin(**values):
    """The typed twin of the shipped files, with ``values`` (config keys: ``{"sim.lateral_friction": 0.35}``)."""
    return launch_twin_settings_from_parameters({**twin_parameters(), **values})


def one_unknown(name, lower, upper, **changes):
    """Calibration settings fitting ``name`` alone, small enough for a test."""
    return calibration.CalibrationSettings(parameters=[name], lower=[lower], upper=[upper], log_scale=[True],
                                           popsize=4, max_generations=3, interval_points=9, **changes)


@pytest.mark.parametrize("document, problem", [
    ("[1, 2]", "must be a mapping"),
    ("format: rollability-characterisation-1\n", "holds no measurements"),
    ("format: v0\nslide_angle: {sigma_deg: 1, readings_deg: [20]}\n", "format must be"),
    (f"format: {FORMAT}\nslope: {{}}\n", "unknown section 'slope'"),
    (f"format: {FORMAT}\nslide_angle: {{sigma_deg: 1}}\n", "slide_angle: missing key 'readings_deg'"),
    (f"format: {FORMAT}\nslide_angle: {{sigma_deg: 0, readings_deg: [20]}}\n", "slide_angle.sigma_deg must be in"),
    (f"format: {FORMAT}\nslide_angle: {{sigma_deg: 1, readings_deg: [20, .nan]}}\n",
     r"slide_angle.readings_deg\[1\] must be a finite number"),
    (f"format: {FORMAT}\nslide_angle: {{sigma_deg: 1, readings_deg: []}}\n", "must be a non-empty list"),
    (f"format: {FORMAT}\nrollout: {{sigma_m: 0.03, readings: [{{surface: ice, speed_mps: 1, distance_m: 0.3}}]}}\n",
     r"rollout.readings\[0\].surface must be one of foam, floor"),
    (f"format: {FORMAT}\nrollout: {{sigma_m: 0.03, readings: [{{surface: foam, speed_mps: '1', distance_m: 0.3}}]}}\n",
     r"rollout.readings\[0\].speed_mps must be a finite number"),
    (f"format: {FORMAT}\nrollout: {{sigma_m: 0.03, readings: [{{surface: foam, speed_mps: 1, distance_m: 0.3, "
     "by: me}]}\n", "unknown key 'by'"),
    ("format: [unclosed\n", "not valid YAML at line"),
    (f"format: {FORMAT}\nslide_angle: !!python/object/apply:os.system [echo]\n", "not valid YAML"),
    (f"format: {FORMAT}\ntip_angle: {{sigma_deg: 1, readings: [{{side: up, angle_deg: 60}}]}}\n",
     r"tip_angle.readings\[0\].side must be one of front, back, left, right"),
    (f"format: {FORMAT}\ntip_angle: {{sigma_deg: 1, readings: [{{side: left, angle_deg: 95}}]}}\n",
     r"tip_angle.readings\[0\].angle_deg must be in"),
    (f"format: {FORMAT}\ngate_shots: {{readings: [{{speed_mps: 0.8, measured_speed_mps: 0.79}}, "
     "{speed_mps: 0.8, measured_speed_mps: .nan}]}\n",
     r"gate_shots.readings\[1\].measured_speed_mps must be a finite"),
    (f"format: {FORMAT}\ngate_shots: {{readings: [{{speed_mps: 0, measured_speed_mps: 0.79}}]}}\n",
     r"gate_shots.readings\[0\].speed_mps must be in \(0, 5\]"),
    (f"format: {FORMAT}\ngate_shots: {{sigma: 0.1, readings: [{{speed_mps: 0.8, measured_speed_mps: 0.79}}]}}\n",
     "gate_shots: unknown key 'sigma'"),
    (f"format: {FORMAT}\ngate_shots: {{readings: [{{speed_mps: 0.8}}]}}\n",
     r"gate_shots.readings\[0\]: missing key 'measured_speed_mps'"),
    # a section written twice: YAML keeps the second's readings and drops the first's without a word
    (f"format: {FORMAT}\ngate_shots: {{readings: [{{speed_mps: 0.8, measured_speed_mps: 0.79}}]}}\n"
     "gate_shots: {readings: [{speed_mps: 1.5, measured_speed_mps: 1.52}]}\n", "duplicate key 'gate_shots' at line 3"),
    (f"format: {FORMAT}\nslide_angle: {{sigma_deg: 1, sigma_deg: 9, readings_deg: [20]}}\n", "duplicate key 'sigma_deg'"),
    (f"format: {FORMAT}\nslide_angle: " + "[" * 30000 + "\n", "nesting deeper than"),   # was a RecursionError
])
def test_malformed_characterisation_files_are_refused_in_one_line_naming_the_problem(tmp_path, document, problem):
    path = tmp_path / "bench.yaml"
    path.write_text(document, encoding="utf-8")
    with pytest.raises(ValueError, match=problem) as caught:
        load_characterisation(path)
    assert str(caught.value).startswith(str(path)) and "\n" not in str(caught.value)


def test_the_slide_angle_model_is_atan_of_the_contacts_friction():
    flat = {"sim.lateral_friction": 0.35, "launch_twin.foam.lateral_friction": 2.0}
    assert slide_angle_deg(twin(**flat)) == pytest.approx(math.degrees(math.atan(0.7)))   # 35.0 deg
    readings = parse_characterisation({"format": FORMAT, "slide_angle": {"sigma_deg": 2.0, "readings_deg": [35.0]}},
                                      "bench")
    at_truth = characterisation_log_likelihood(readings, twin(**flat))
    assert at_truth == pytest.approx(-math.log(2.0 * math.sqrt(2 * math.pi)), abs=1e-3)
    assert characterisation_log_likelihood(readings, twin(**{**flat, "launch_twin.foam.lateral_friction": 1.0})) < (
        at_truth - 10)


def test_a_slide_angle_alone_pins_the_foam_friction_before_any_launch():
    """No launch outcomes: the fit of the foam's friction to three slide angles of a simulated truth (2.0: a
    35 deg slide) holds the truth in an interval far narrower than the declared range."""
    pytest.importorskip("cma")
    truth = 2.0
    angle = math.degrees(math.atan(0.35 * truth))
    readings = parse_characterisation({"format": FORMAT, "slide_angle": {
        "sigma_deg": 1.0, "readings_deg": [angle - 0.5, angle + 0.3, angle + 0.2]}}, "bench")
    settings = one_unknown("launch_twin.foam.lateral_friction", 0.3, 3.0)
    with calibration.LaunchPool(1) as pool:
        result = calibration.calibrate([], twin(), settings, pool, characterisation=readings)
    (estimate,) = result.estimates
    assert estimate.interval_low <= truth <= estimate.interval_high
    assert estimate.interval_high / estimate.interval_low < (3.0 / 0.3) ** 0.3   # < a third of the range, in log
    assert not estimate.interval_low <= estimate.initial <= estimate.interval_high   # the shipped 1.0 ruled out


def test_a_simulated_rollout_narrows_the_foam_rolling_friction_around_its_truth():
    """A roll-out on the foam simulated with foam rolling friction 0.006 m is the 'bench reading'; the fit of that
    one unknown (a new one) from the roll-out alone holds the truth in a narrower interval than its range."""
    pytest.importorskip("pybullet")
    pytest.importorskip("cma")
    from rollability_ros.core.sim.rollout import rollout_distance_m

    name, truth = "launch_twin.foam.rolling_friction", 0.006
    parameters = twin_parameters()
    distance = rollout_distance_m(launch_twin_settings_from_parameters({**parameters, name: truth}), 1.0)
    shipped = rollout_distance_m(launch_twin_settings_from_parameters(parameters), 1.0)
    assert distance > shipped + 0.05   # less rolling resistance, a longer roll (the reading can tell them apart)
    readings = parse_characterisation({"format": FORMAT, "rollout": {"sigma_m": 0.02, "readings": [
        {"surface": "foam", "speed_mps": 1.0, "distance_m": distance}]}}, "bench")
    settings = dataclasses.replace(one_unknown(name, 0.002, 0.05), max_generations=2, interval_points=7)
    with calibration.LaunchPool(1) as pool:
        result = calibration.calibrate([], twin(), settings, pool, characterisation=readings)
    (estimate,) = result.estimates
    assert estimate.interval_low <= truth <= estimate.interval_high, (estimate.interval_low, estimate.interval_high)
    assert estimate.interval_high / estimate.interval_low < (0.05 / 0.002) ** 0.5   # under half the range, in log
    assert abs(math.log(estimate.fitted / truth)) < abs(math.log(estimate.initial / truth))


def test_the_rollout_model_refuses_an_engine_without_one():
    from rollability_ros.core.sim.launch.settings import load_launch_twin_settings
    from rollability_ros.core.sim.rollout import rollout_distance_m

    settings = load_launch_twin_settings()
    mujoco = dataclasses.replace(settings, physics=dataclasses.replace(settings.physics, engine="mujoco"))
    with pytest.raises(ValueError, match="PyBullet twin only; sim.engine is 'mujoco'"):
        rollout_distance_m(mujoco, 1.0)
    with pytest.raises(ValueError, match="surface must be one of"):
        rollout_distance_m(settings, 1.0, "ice")


def test_calibrate_selects_declared_unknowns_and_refuses_the_rest(tmp_path, capsys):
    from rollability_ros.cli import main

    settings = calibration.calibration_settings(load_parameters([*calibration.TWIN_CONFIGS, "calibration"]))
    chosen = settings.selected(["launch_twin.wheel_drag_torque_nm"])
    assert (chosen.parameters, chosen.lower, chosen.upper, chosen.log_scale) == (
        ["launch_twin.wheel_drag_torque_nm"], [0.0005], [0.02], [True])
    with pytest.raises(ValueError, match="sim.gravity is not declared in calibration.parameters"):
        settings.selected(["sim.gravity"])
    robot_wheels = twin(**{"launch_twin.wheel_model": "robot"})
    with pytest.raises(ValueError, match="launch_twin.wheel_drag_torque_nm acts on the twin's Mecanum wheels only"):
        calibration.check_fittable(robot_wheels, chosen)
    bench = tmp_path / "bench.yaml"
    bench.write_text(yaml.safe_dump({"format": FORMAT, "slide_angle": {"sigma_deg": 1, "readings_deg": ["x"]}}))
    assert main(["calibrate", "--characterisation", str(bench), "--out", str(tmp_path / "out")]) == 2
    assert "slide_angle.readings_deg[0] must be a finite number" in capsys.readouterr().err
    assert main(["calibrate", "--out", str(tmp_path / "out")]) == 2
    assert "--physical" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_the_tip_angle_is_the_tilt_tables_analytic_angle_and_pins_the_centre_of_mass():
    """The built-in chassis (config/robot.yaml): the body's mass at its centre-of-mass offset below the box centre,
    four wheels on axles at axle_offset_z_m, their bottoms the support. Tipping sideways pivots over the wheels'
    outer edges (track / 2 + wheel width / 2), forwards over the front wheels' contact (wheelbase / 2); tan(angle)
    = reach / height of the centre of mass above the wheels' bottoms. Five simulated readings of a truth then pin
    the centre of mass (the characterisation's term over a grid of it) to under a fifth of its declared range."""
    import numpy as np

    from rollability_ros.core.campaign.adaptive import Unknowns
    from rollability_ros.core.campaign.characterisation import Characterisation, TipReading, tip_angles_deg
    from rollability_ros.core.campaign.posterior import characterisation_term

    pytest.importorskip("pybullet")
    flat = twin_parameters()
    body, wheel = flat["robot.body_mass_kg"], flat["robot.wheel_mass_kg"]
    ground = flat["robot.axle_offset_z_m"] - flat["robot.wheel_radius_m"]
    sideways = flat["robot.track_m"] / 2 + flat["robot.wheel_width_m"] / 2
    for offset in (-0.015, 0.01):
        height = (body * offset + 4 * wheel * flat["robot.axle_offset_z_m"]) / (body + 4 * wheel) - ground
        front, left, right = tip_angles_deg(twin(**{"robot.com_offset_z_m": offset}), ("front", "left", "right"))
        assert front == pytest.approx(math.degrees(math.atan2(flat["robot.wheelbase_m"] / 2, height)), abs=0.05)
        assert left == pytest.approx(math.degrees(math.atan2(sideways, height)), abs=0.05) and right == pytest.approx(left)
    truth = 0.004
    sides = ("front", "back", "left", "right", "front")
    rng = np.random.default_rng(5)
    readings = Characterisation("test", tips=tuple(TipReading(side, angle + rng.standard_normal()) for side, angle in
                                                   zip(sides, tip_angles_deg(twin(**{"robot.com_offset_z_m": truth}),
                                                                             sides))), tip_sigma_deg=1.0)
    unknowns = Unknowns(("robot.com_offset_z_m",), (-0.019,), (0.015,), (False,))
    term = characterisation_term(readings, twin(), unknowns, grid_points=9)
    grid = np.linspace(0.0, 1.0, 341)[:, None]
    log_likelihood = term(grid)
    kept = grid[log_likelihood >= log_likelihood.max() - 1.92, 0]   # the likelihood-ratio 95% interval
    low, high = unknowns.to_values(kept[[0, -1], None])[:, 0]
    assert low <= truth <= high and kept[-1] - kept[0] < 0.2
    assert characterisation_log_likelihood(readings, twin(**{"robot.com_offset_z_m": truth})) == pytest.approx(
        float(term(unknowns.to_normalised(np.array([[truth]])))[0]), abs=0.05)   # the direct fit's model, the same


def test_a_weighed_profile_pins_its_mass_multiplier(tmp_path):
    """The profile's weighed mass is the twin's printed mass of its mesh times ``profile_mass_scale`` (linear in
    it); one weighing at 1 g pins the multiplier to a few percent of its declared (log) range; the bare robot has
    no profile to weigh."""
    import numpy as np
    import trimesh

    from rollability_ros.core.campaign.adaptive import Unknowns
    from rollability_ros.core.campaign.characterisation import Characterisation, MassReading, profile_mass_kg
    from rollability_ros.core.campaign.posterior import characterisation_term

    path = tmp_path / "box.stl"
    trimesh.creation.box((0.12, 0.1, 0.03)).apply_translation((0, 0, 0.015)).export(path)
    designs = {"launch_twin.designs.mesh_labels": ["A"], "launch_twin.designs.mesh_files": [str(path)]}
    one = profile_mass_kg(twin(**designs, **{"robot.profile_mass_scale": 1.0}), "A")
    assert one > 0.01 and profile_mass_kg(twin(**designs, **{"robot.profile_mass_scale": 1.3}), "A") == \
        pytest.approx(1.3 * one)
    with pytest.raises(ValueError, match="no printed profile"):
        profile_mass_kg(twin(**designs), "baseline")
    readings = Characterisation("test", masses=(MassReading("A", 1.3 * one + 0.0004),), mass_sigma_kg=0.001)
    unknowns = Unknowns(("robot.profile_mass_scale",), (0.15,), (2.0,), (True,))
    term = characterisation_term(readings, twin(**designs), unknowns, grid_points=9)
    grid = np.linspace(0.0, 1.0, 2001)[:, None]
    log_likelihood = term(grid)
    kept = grid[log_likelihood >= log_likelihood.max() - 1.92, 0]
    low, high = unknowns.to_values(kept[[0, -1], None])[:, 0]
    assert low <= 1.3 <= high and kept[-1] - kept[0] < 0.05
    assert characterisation_log_likelihood(readings, twin(**designs, **{"robot.profile_mass_scale": 1.3})) == \
        pytest.approx(float(term(unknowns.to_normalised(np.array([[1.3]])))[0]), abs=0.05)
    document = {"format": FORMAT, "profile_mass": {"sigma_kg": 0.001, "readings": [{"configuration": "A",
                                                                                   "mass_kg": 0.05}]}}
    assert parse_characterisation(document, "x").masses == (MassReading("A", 0.05),)
    document["profile_mass"]["readings"][0]["mass_kg"] = -1
    with pytest.raises(ValueError, match=r"profile_mass.readings\[0\].mass_kg must be in"):
        parse_characterisation(document, "x")


def test_gate_shots_are_read_and_summarised(tmp_path):
    """The launcher's characterisation (gate shots of the bare robot): each a set speed and the gate's reading."""
    from rollability_ros.core.campaign.characterisation import GateShot

    path = tmp_path / "bench.yaml"
    path.write_text(f"format: {FORMAT}\ngate_shots:\n  readings:\n"
                    "    - {speed_mps: 0.8, measured_speed_mps: 0.79}\n"
                    "    - {speed_mps: 1.5, measured_speed_mps: 1.52}\n", encoding="utf-8")
    loaded = load_characterisation(path)
    assert loaded.gate_shots == (GateShot(0.8, 0.79), GateShot(1.5, 1.52))
    assert "2 gate shot(s) at 0.8, 1.5 m/s" in loaded.summary()


def test_gate_shots_enter_the_direct_fit_and_the_learnt_likelihoods_term_alike():
    """The launcher's characterisation has one model on both calibration paths: the direct fit's
    characterisation_log_likelihood simulates the gate's reading at each parameter set, the learnt likelihood's
    characterisation_term tabulates it over the bias (likelihood_gate); on six simulated shots of a truth (bias
    0.05) both peak at the truth's grid point and agree near the peak to the table's interpolation."""
    import numpy as np

    from rollability_ros.core.campaign import likelihood_gate as gate
    from rollability_ros.core.campaign.adaptive import Unknowns
    from rollability_ros.core.campaign.characterisation import Characterisation, GateShot
    from rollability_ros.core.campaign.posterior import characterisation_term
    from rollability_ros.core.sim import twin_with_values

    pytest.importorskip("pybullet")
    settings = twin()
    truth = twin_with_values(settings, {gate.BIAS_KEY: 0.05})
    rng = np.random.default_rng(1)
    sigma = settings.twin.speed_sigma_fraction
    shots = tuple(GateShot(v, gate.gate_reading_mps(truth, "baseline", v * (1 + sigma * rng.standard_normal())))
                  for v in (0.8, 1.5) for _ in range(3))
    readings = Characterisation("bench.yaml", gate_shots=shots)
    biases = np.array([-0.15, 0.0, 0.025, 0.05, 0.075, 0.15])
    tabulated = characterisation_term(readings, settings, Unknowns((gate.BIAS_KEY,), (-0.15,), (0.15,), (False,)))(
        ((biases + 0.15) / 0.3)[:, None])
    direct = np.array([characterisation_log_likelihood(readings, twin_with_values(settings, {gate.BIAS_KEY: b}))
                       for b in biases])
    assert biases[np.argmax(direct)] == pytest.approx(0.05) and np.argmax(tabulated) == np.argmax(direct)
    near = direct > direct.max() - 5.0
    assert near.sum() >= 3 and np.max(np.abs(direct - tabulated)[near]) < 1.0
    assert direct.max() - direct.min() > 100   # the shots pin the bias: far from it they are implausible
