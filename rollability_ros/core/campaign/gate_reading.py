"""The speed gate's reading in the twin, and the Gaussian of a group of readings: the measurement model that
:mod:`~rollability_ros.core.campaign.likelihood_gate` tabulates for the learnt likelihood's calibration and the
plans, and that the launcher characterisation's direct fit
(:func:`~rollability_ros.core.campaign.characterisation.gate_shots_log_likelihood`) simulates at each parameter set
(docs/calibration.md, "The speed gate's term"; docs/characterisation.md, (c)). numpy; the twin on call."""
import dataclasses
import math
import typing

import numpy as np

if typing.TYPE_CHECKING:
    from rollability_ros.core.sim import LaunchTwinSettings

#: The unknown the gate's readings are weighed for, and the launch speed's scatter (read from the samples when it
#: is sampled).
BIAS_KEY, SCATTER_KEY = "launch_twin.launcher.speed_bias_fraction", "launch_twin.speed_sigma_fraction"
#: Simulated time per tabulated launch, s: the gate's reading is taken at the edge (0.4-0.6 s on the paper's
#: speeds); the rest of the launch is not needed (the speed gate's own timeout, config/rig.yaml, is 3 s).
GATE_CAP_S = 3.0
#: The ledge height of the tabulated launches, m (the paper's lower ledge; the height does not move the reading).
GATE_HEIGHT_M = 0.75
#: The bare robot's configuration id (core/profile/designs.py): the configuration whose readings the gate's term
#: weighs by default, and the launcher characterisation's gate shots are of.
BARE_ROBOT = "baseline"
#: Readings at or below this fraction of the set speed are "not measured" (a gate that timed out reads 0).
MIN_READING_FRACTION = 0.05

#: The table's error (interpolation, and the ledge height and angle it leaves out), as a fraction of the reading:
#: the root mean square of interpolated against simulated readings at random parameter sets (docs/calibration.md).
MODEL_ERROR = 0.004


def gate_reading_mps(twin: "LaunchTwinSettings", configuration: str, speed_mps: float) -> float:
    """The gate's reading (m/s) of a launch of ``configuration`` at the set speed ``speed_mps`` on ``twin``
    without the speed and angle scatter (deterministic; the ledge height and the angle do not move it:
    likelihood_gate's module docstring). ``ValueError`` when the launch never reaches the edge within
    :data:`GATE_CAP_S`."""
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.sim import simulate_launch

    exact = dataclasses.replace(
        twin, twin=dataclasses.replace(twin.twin, speed_sigma_fraction=0.0, angle_sigma_deg=0.0),
        trial=dataclasses.replace(twin.trial, time_cap_s=min(twin.trial.time_cap_s, GATE_CAP_S)))
    condition = LaunchCondition(configuration, GATE_HEIGHT_M, float(speed_mps), 0.0)
    reading = simulate_launch(condition, exact, 0).measured_speed_mps
    if not (math.isfinite(reading) and reading > MIN_READING_FRACTION * speed_mps):
        raise ValueError(f"the twin's launch of {configuration} at {speed_mps} m/s does not reach the speed gate's "
                         f"edge within {GATE_CAP_S} s: no gate reading to weigh")
    return float(reading)


def readings_log_density(mean: np.ndarray, sd: np.ndarray, readings: typing.Sequence[typing.Sequence[float]],
                         model_error: float = MODEL_ERROR) -> np.ndarray:
    """The readings' Gaussian log-likelihood (s,), summed over the groups: ``mean`` and ``sd`` (s, g), the model at
    each parameter set and group (:func:`gate_predictor`), ``readings`` one list per group (each non-empty).
    Readings g_i = G + shared + scatter_i: the group's mean carries the table's error (``model_error`` x G, shared
    by its readings), each reading its own scatter (sd): the Gaussian with covariance sd^2 I + tau^2 1 1'."""
    count = np.array([len(r) for r in readings], dtype=np.float64)
    first = np.array([sum(r) for r in readings], dtype=np.float64)
    second = np.array([sum(v * v for v in r) for r in readings], dtype=np.float64)
    variance, shared = sd ** 2, (model_error * mean) ** 2
    within = second - first ** 2 / count   # sum of squares about the group's mean
    offset = first / count - mean
    return -0.5 * ((count - 1.0) * np.log(variance) + np.log(variance + count * shared) + within / variance
                   + count * offset ** 2 / (variance + count * shared)
                   + count * math.log(2.0 * math.pi)).sum(axis=1)
