"""Physics shown, not assumed: contact parameters are live, the bare chassis stays inverted, a light dome rights it
and a heavier print of the same dome does so less often.

Margins are Wilson 95% intervals of the success probability; the trials are deterministic (fixed seeds), so
these tests do not flake, and the intervals say how far the claims are from the thresholds.
"""
import dataclasses
import math

import numpy as np
import pytest

from rollability_ros.core.sim.evaluation import EvaluatorSettings, evaluate_profile
from rollability_ros.core.profile.geometry import grid_xy
from rollability_ros.core.profile.print_mass import ProfilePrintSpec
from rollability_ros.core.sim.world import PhysicsParams, connect, disconnect, reset_world, set_contact

pybullet = pytest.importorskip("pybullet")

SETTINGS = EvaluatorSettings()
#: The dome printed as a hollow shell (0.8 mm walls and skins, no infill): about 70 g, against about 430 g with the
#: shipped print settings (20 % infill), see docs/optimization.md "Profile mass".
LIGHT = dataclasses.replace(SETTINGS, robot=dataclasses.replace(SETTINGS.robot,
                                                                profile_print=ProfilePrintSpec(infill_fraction=0.0)))
TRIALS = 60
SEED = 7


def dome_heights(grid):
    """An elliptic dome over the footprint: tall centre (0.45 units), edges at half height, corners at zero."""
    xy = grid_xy(grid)
    ny, nx = xy[:, 1] / (grid.width_m / 2), xy[:, 0] / (grid.length_m / 2)
    return np.clip(grid.height_max * (1 - 0.5 * ny ** 2 - 0.5 * nx ** 2), 0.0, grid.height_max)


def slide_distance_m(physics, slope_deg, duration_s=1.0):
    """Distance a 0.1 x 0.1 x 0.04 m, 1 kg box placed at rest on a slope travels in ``duration_s``."""
    client = connect()
    try:
        reset_world(client, physics, slope_deg=slope_deg)
        shape = pybullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=[0.05, 0.05, 0.02], physicsClientId=client)
        tilt = math.radians(slope_deg)
        start = [0.0, -0.0201 * math.sin(tilt), 0.0201 * math.cos(tilt)]  # resting on the plane, along its normal
        box = pybullet.createMultiBody(1.0, shape, basePosition=start,
                                       baseOrientation=pybullet.getQuaternionFromEuler([tilt, 0, 0]),
                                       physicsClientId=client)
        set_contact(client, box, physics.body_contact())
        for _ in range(round(duration_s / physics.time_step_s)):
            pybullet.stepSimulation(physicsClientId=client)
        end, _ = pybullet.getBasePositionAndOrientation(box, physicsClientId=client)
        return float(np.linalg.norm(np.subtract(end, start)))
    finally:
        disconnect(client)


@pytest.mark.parametrize("contact_model, critical_deg", [("per_contact", 19.29), ("per_body", 6.99)])
def test_box_slides_only_on_slopes_steeper_than_atan_of_effective_friction(contact_model, critical_deg):
    physics = PhysicsParams(contact_model=contact_model)
    assert math.degrees(math.atan(physics.effective_friction())) == pytest.approx(critical_deg, abs=0.01)
    assert slide_distance_m(physics, critical_deg - 2.5) < 0.005      # static friction holds it
    assert slide_distance_m(physics, critical_deg + 2.5) > 0.2       # it accelerates down the slope


def test_bare_chassis_laid_inverted_stays_inverted():
    result = evaluate_profile(None, TRIALS, SEED, SETTINGS)
    assert result.ci_high < 0.15, f"bare chassis righted itself {result.successes}/{TRIALS} times"
    assert all(outcome.settled for outcome in result.trial_results)
    assert np.median([o.tilt_deg for o in result.trial_results]) > 150


def test_same_disturbances_mostly_leave_an_upright_chassis_upright():
    """The disturbance is no knockout: started on its wheels, the chassis mostly stays there (about 80%)."""
    upright_start = dataclasses.replace(SETTINGS, trial=dataclasses.replace(SETTINGS.trial, start_roll_deg=0.0))
    result = evaluate_profile(None, TRIALS, SEED, upright_start)
    assert result.ci_low > 0.6


def test_dome_profile_rights_the_inverted_chassis():
    bare = evaluate_profile(None, TRIALS, SEED, SETTINGS)
    dome = evaluate_profile(dome_heights(LIGHT.grid), TRIALS, SEED, LIGHT)
    assert dome.ci_low > 0.4, f"dome fitness {dome.fitness:.2f} [{dome.ci_low:.2f}, {dome.ci_high:.2f}]"
    assert dome.ci_low > bare.ci_high  # the intervals do not overlap
    # a trial ended by the early decision reports the tilt at that moment (possibly still swinging upright):
    # the tilt at rest comes from the full rest rule, which must agree on every outcome
    full_rule = dataclasses.replace(LIGHT, trial=dataclasses.replace(LIGHT.trial, early_decision=False))
    rested = evaluate_profile(dome_heights(LIGHT.grid), TRIALS, SEED, full_rule).trial_results
    assert [o.upright for o in rested] == [o.upright for o in dome.trial_results]
    assert all(o.tilt_deg < SETTINGS.robot.upright_tilt_deg for o in rested if o.upright)


def test_a_heavier_print_of_the_same_dome_rights_the_chassis_less_often():
    """The profile's mass is not a detail: the same dome shape printed with 20 % infill (the shipped default, about
    430 g) rights the inverted chassis less often than printed hollow (about 70 g); the intervals do not overlap."""
    light = evaluate_profile(dome_heights(LIGHT.grid), TRIALS, SEED, LIGHT)
    heavy = evaluate_profile(dome_heights(SETTINGS.grid), TRIALS, SEED, SETTINGS)
    assert SETTINGS.robot.profile_print.infill_fraction > LIGHT.robot.profile_print.infill_fraction
    assert light.ci_low > heavy.ci_high, (f"hollow {light.successes}/{TRIALS}, default print "
                                          f"{heavy.successes}/{TRIALS}")
