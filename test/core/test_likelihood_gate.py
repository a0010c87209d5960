"""The speed gate's exact term (core/campaign/likelihood_gate.py): the readings' Gaussian around the tabulated
reading without scatter, its spread from the twin's launch scatter, what it refuses, and the twin's stroke
launcher reading the set speed without bias on the bare robot."""
import dataclasses
import math

import numpy as np
import pytest

from rollability_ros.core.campaign import likelihood as learnt
from rollability_ros.core.campaign import likelihood_gate as gate
from rollability_ros.core.campaign.adaptive import Unknowns

BIAS = gate.BIAS_KEY
UNKNOWNS = Unknowns(("launch_twin.foam.lateral_friction", BIAS, "robot.profile_mass_scale"), (0.3, -0.15, 0.15),
                    (3.0, 0.15, 2.0), (True, False, True))


def twin():
    from rollability_ros.core.campaign import calibration
    from rollability_ros.core.config import load_parameters
    from rollability_ros.core.sim import launch_twin_settings_from_parameters

    return launch_twin_settings_from_parameters(load_parameters(list(calibration.TWIN_CONFIGS)))


def analytic_table(factor):
    """A gate_table stand-in: G = set speed x (1 + bias) x factor[configuration], x (1 + 0.1 (mass_u - 0.5)) for
    the profile "A" (mass_u the normalised profile mass), on the grid gate_table would use."""
    def table(twin, unknowns, groups, bias_points, other_points, sampled=None, bare_only=False):
        assert not bare_only   # the profile's mass spanned: "A" is weighed
        b = np.linspace(-0.15, 0.15, bias_points)[:, None, None]
        m = np.linspace(0.0, 1.0, other_points)[None, :, None]
        return np.stack([speed * (1 + b[..., 0]) * factor[c] * (1 + 0.1 * (m[..., 0] - 0.5) * (c == "A"))
                         for c, speed in groups], axis=-1)
    return table


def readings(rng, bias, mass_u, sigma, n=200):
    factor = {"baseline": 1.0, "A": 1.05}
    out = []
    for i in range(n):
        configuration, speed = ("baseline", "A")[i % 2], (0.8, 1.5)[(i // 2) % 2]
        value = speed * (1 + bias) * (1 + sigma * rng.standard_normal()) * factor[configuration] * (
            1 + 0.1 * (mass_u - 0.5) * (configuration == "A"))
        out.append(learnt.Observation(configuration, 0.75, speed, 0.0, False, {"measured_speed_mps": value}))
    return factor, out


def test_the_term_peaks_at_the_bias_with_the_spread_of_the_launch_scatter(monkeypatch):
    rng = np.random.default_rng(3)
    settings = twin()
    sigma = settings.twin.speed_sigma_fraction
    factor, observations = readings(rng, 0.06, 0.3, sigma)
    # not measured: a gate that timed out (0), a missing reading; neither may move the term
    observations += [learnt.Observation("A", 0.75, 0.8, 0.0, True, {"measured_speed_mps": 0.0}),
                     learnt.Observation("A", 0.75, 0.8, 0.0, True, {"measured_speed_mps": math.nan}),
                     learnt.Observation("A", 0.75, 0.8, 0.0, True, {})]
    monkeypatch.setattr(gate, "gate_table", analytic_table(factor))
    every = dict(bias_points=13, other_points=5, configurations=None)   # the profile "A"'s readings too
    term = gate.gate_term(observations, settings, UNKNOWNS, model_error=0.0, **every)
    u = np.zeros((2001, 3))
    u[:, 1] = np.linspace(0.0, 1.0, 2001)
    u[:, 2] = 0.3
    values = term(u)
    bias = -0.15 + 0.3 * u[np.argmax(values), 1]
    # the log-likelihood's curvature: sd of the bias = (1 + b) sigma / sqrt(n) for readings proportional to it
    sd = (1 + 0.06) * sigma / math.sqrt(200)
    assert abs(bias - 0.06) < 4 * sd
    near = np.abs(-0.15 + 0.3 * u[:, 1] - bias) < 3 * sd
    curvature = np.polyfit(-0.15 + 0.3 * u[near, 1], values[near], 2)[0]
    assert math.sqrt(-1 / (2 * curvature)) == pytest.approx(sd, rel=0.1)
    # the table's own error, shared by a group's readings, widens the term (it does not average away)
    shared = gate.gate_term(observations, settings, UNKNOWNS, model_error=0.004, **every)(u)
    width = math.sqrt(-1 / (2 * np.polyfit(-0.15 + 0.3 * u[near, 1], shared[near], 2)[0]))
    per_group = math.sqrt(((1 + 0.06) * sigma) ** 2 / 50 + 0.004 ** 2)   # a group's mean, as a fraction
    assert width == pytest.approx(per_group * (1 + 0.06) / 2, rel=0.15)   # four groups of 50
    # the profile's mass moves the reading, so the term weighs it too: the truth's mass beats a wrong one
    wrong = u.copy()
    wrong[:, 2] = 0.9
    assert values.max() > term(wrong).max() + 10
    # the scatter as an unknown: a wider scatter, a flatter term
    wide = Unknowns((*UNKNOWNS.names, gate.SCATTER_KEY), (*UNKNOWNS.lower, 0.0), (*UNKNOWNS.upper, 0.15),
                    (*UNKNOWNS.log_scale, False))
    with_scatter = gate.gate_term(observations, settings, wide, model_error=0.0, **every)
    at = np.array([[0.0, 0.7, 0.3, sigma / 0.15], [0.0, 0.7, 0.3, 2 * sigma / 0.15]])
    assert with_scatter(at[:1]) == pytest.approx(term(at[:1, :3]))
    assert np.ptp(with_scatter(np.array([[0.0, 0.55, 0.3, 2 * sigma / 0.15], [0.0, 0.7, 0.3, 2 * sigma / 0.15]]))) < \
        np.ptp(term(np.array([[0.0, 0.55, 0.3], [0.0, 0.7, 0.3]])))


def test_by_default_only_the_bare_robots_readings_are_weighed(monkeypatch):
    """A design's reading also moves with the profile's mass and the centre of mass; by default the term leaves it
    out, so the mass does not move the term, and the table spans the bias alone (no mass axis)."""
    factor, observations = readings(np.random.default_rng(4), -0.05, 0.7, 0.03)
    spans = []

    def table(twin, unknowns, groups, bias_points, other_points, sampled=None, bare_only=False):
        spans.append((tuple(groups), bare_only))
        return analytic_table(factor)(twin, unknowns, groups, bias_points, 1)[:, 0, :]   # (bias, groups)
    monkeypatch.setattr(gate, "gate_table", table)
    term = gate.gate_term(observations, twin(), Unknowns(UNKNOWNS.names[1:2], (-0.15,), (0.15,), (False,)))
    assert spans == [((("baseline", 0.8), ("baseline", 1.5)), True)]
    u = np.linspace(0.0, 1.0, 301)[:, None]
    assert abs(-0.15 + 0.3 * u[np.argmax(term(u)), 0] + 0.05) < 0.01


def test_what_the_term_refuses():
    settings = twin()
    with pytest.raises(ValueError, match="must be a fitted unknown"):
        gate.gate_term([], settings, Unknowns(("robot.profile_mass_scale",), (0.15,), (2.0,), (True,)))
    crowded = Unknowns((BIAS, "robot.profile_mass_scale", "robot.com_offset_z_m", "launch_twin.wheel_drag_torque_nm"),
                       (-0.15, 0.15, -0.019, 0.0005), (0.15, 2.0, 0.015, 0.02), (False, True, False, True))
    with pytest.raises(ValueError, match="at most 2 unknowns besides the bias"):
        gate.gate_term([], settings, crowded, configurations=None)
    gate.gate_term([], settings, crowded)   # the bare robot's readings alone: the profile's mass is not spanned
    with pytest.raises(ValueError, match="must be a fitted unknown"):
        gate.gate_term([], settings, crowded, sampled=crowded.names[1:])
    assert gate.gate_unknowns(crowded, sampled=crowded.names[:2]) == [1]   # the others held: not spanned
    # the foam's unknowns lie past the edge: not tabulated; no readings, no term
    term = gate.gate_term([], settings, UNKNOWNS)
    assert np.all(term(np.full((3, 3), 0.5)) == 0.0)


def test_the_stroke_launcher_reads_the_set_speed_without_bias_and_more_with_it():
    """The stroke's plate speed is solved so that the bare robot square to the edge reads the set speed
    (core/sim/launch/drive.py); a bias raises the reading, not in exact proportion (module docstring)."""
    from rollability_ros.core.sim import twin_with_values

    pytest.importorskip("pybullet")
    settings = twin()
    plain = gate.gate_reading_mps(settings, "baseline", 0.8)
    faster = gate.gate_reading_mps(twin_with_values(settings, {BIAS: 0.1}), "baseline", 0.8)
    assert plain == pytest.approx(0.8, rel=0.005)
    assert 1.05 < faster / plain < 1.15


def bare_table(twin, unknowns, groups, bias_points, other_points, sampled=None, bare_only=False):
    """A gate_table stand-in for the bare robot's readings alone: G = set speed x (1 + bias), the bias only."""
    assert bare_only
    b = np.linspace(-0.15, 0.15, bias_points)[:, None]
    return np.concatenate([speed * (1 + b) for _, speed in groups], axis=1)


def test_gate_shots_pin_the_bias_and_share_their_groups_error_with_the_campaigns_readings(monkeypatch):
    """The launcher's characterisation (characterisation.GateShot, bare robot on the bench) is the gate's model:
    on synthetic shots its term peaks at the true bias with the launch scatter's width; in a GateModel the shots
    join the campaign's bare-robot readings of their set speed in one group (one shared table error), which two
    separate terms would count twice."""
    from rollability_ros.core.campaign.characterisation import GateShot

    monkeypatch.setattr(gate, "gate_table", bare_table)
    settings = twin()
    sigma = settings.twin.speed_sigma_fraction
    rng = np.random.default_rng(11)
    shots = [GateShot(v, v * (1 + 0.06) * (1 + sigma * rng.standard_normal())) for v in (0.8, 1.5) for _ in range(50)]
    observations = gate.shot_observations(shots)
    assert {(o.configuration, o.speed_mps) for o in observations} == {("baseline", 0.8), ("baseline", 1.5)}
    term = gate.gate_term(observations, settings, UNKNOWNS, model_error=0.0)
    u = np.full((3001, 3), 0.5)
    u[:, 1] = np.linspace(0.0, 1.0, 3001)
    bias = -0.15 + 0.3 * u[:, 1]
    values = term(u)
    sd = (1 + 0.06) * sigma / math.sqrt(100)
    assert abs(bias[np.argmax(values)] - 0.06) < 3 * sd
    near = np.abs(bias - bias[np.argmax(values)]) < 3 * sd
    assert math.sqrt(-1 / (2 * np.polyfit(bias[near], values[near], 2)[0])) == pytest.approx(sd, rel=0.1)
    # in a plan's model: the term of no campaign reading is the shots'; with readings, one group per set speed
    campaign = [learnt.Observation("baseline", 1.3, 0.8, 30.0, True, {"measured_speed_mps": 0.8 * 1.06})] * 3
    model = gate.GateModel(settings, UNKNOWNS, [("baseline", 0.8), ("A", 0.8)], shots=observations)
    assert model.groups == [("baseline", 0.8), ("baseline", 1.5)]
    shared = gate.gate_term(observations, settings, UNKNOWNS)(u)
    assert np.allclose(model.term([])(u), shared)
    together = model.term(campaign)(u)
    assert np.allclose(together, gate.gate_term([*observations, *campaign], settings, UNKNOWNS)(u))
    apart = shared + gate.gate_term(campaign, settings, UNKNOWNS)(u)
    assert np.max(np.abs((together - together.max()) - (apart - apart.max()))[near]) > 0.05
    assert np.allclose(model.with_shots([]).term(campaign)(u), gate.gate_term(campaign, settings, UNKNOWNS)(u))
    with pytest.raises(ValueError, match="bare robot's readings"):
        gate.GateModel(settings, UNKNOWNS, [], shots=[dataclasses.replace(observations[0], configuration="A")])
