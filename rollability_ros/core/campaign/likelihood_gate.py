"""The speed gate's readings as an exact term of the calibration's likelihood (docs/calibration.md, "The speed
gate's term"): the rig's gate records every launch's speed, and that reading pins the lab's speed-setting bias
(``launch_twin.launcher.speed_bias_fraction``) without the learnt networks, whose continuous outcomes are biased
(measured in docs/calibration.md).

The twin's model of a reading (:mod:`rollability_ros.core.sim.launch`, "Launch"): the launch speed is the set speed
x (1 + bias) x (1 + ``speed_sigma_fraction`` z), z standard normal from the launch's seed; the stroke launcher's
plate then pushes, the robot coasts on the launcher's base plate, and the gate reads ``run_length_m /
travel_time_s``. That reading is not the launch speed: the coast and the cylinder's force limit make it depend on
the configuration, the set speed, the bias (not in proportion: on the bench's chassis at 1.5 m/s a bias of -0.15
reads 0.851 of the set speed, +0.15 reads 1.139) and on the robot (the flat top at 0.8 m/s without bias reads
1.018 of the set speed at profile mass scale 0.2 and 1.058 at 1.4, 1.061 at a centre of mass 0.01 m lower and
1.024 at 0.015 m higher). The ledge height, the angle, and the foam (past the edge) do not move it (under 0.001 of
the set speed, measured on the same twin). So :func:`gate_term` tabulates the reading without scatter, G, per
(configuration, set speed) over the bias and the sampled unknowns that act before the edge (at most
:data:`MAX_OTHER`: the profile's mass, the centre of mass, the base plate's rolling friction, the wheels' drag),
interpolates it (cubic), and scores each reading by the Gaussian of the delta method: mean G(b), standard deviation
G'(b) (1 + b) ``speed_sigma_fraction`` (the scatter enters exactly as the bias does), the table's own error
(:data:`MODEL_ERROR` of the reading) shared by the readings of each (configuration, set speed). Exact in the
twin's sense: never tempered, like the characterisation's terms. By default only the bare robot's readings are
weighed (:data:`BARE_ROBOT`; :func:`gate_term`'s ``configurations``): they depend on the bias alone.

The launcher's characterisation (a characterisation file's ``gate_shots``: the bare robot fired at a set speed on
the bench, no campaign launch) is the same measurement, so it has the same model (:func:`shot_observations` makes
its readings observations of the bare robot): its readings join the campaign's of the same set speed in one group,
whose table error they share (:class:`GateModel`'s ``shots``), never a second term with an error of its own."""
import hashlib
import math
import pickle
import typing

import numpy as np

from rollability_ros.core.campaign.adaptive import Unknowns
from rollability_ros.core.campaign.gate_reading import (BARE_ROBOT, BIAS_KEY, GATE_CAP_S, GATE_HEIGHT_M,
                                                        MIN_READING_FRACTION, MODEL_ERROR, SCATTER_KEY,
                                                        gate_reading_mps, readings_log_density)
from rollability_ros.core.campaign.likelihood import Observation, values_one
from rollability_ros.core.optional import require

if typing.TYPE_CHECKING:
    from rollability_ros.core.campaign.characterisation import GateShot
    from rollability_ros.core.sim import LaunchTwinSettings

LogDensity = typing.Callable[[np.ndarray], np.ndarray]

#: Unknowns that cannot move a reading: the foam lies past the edge, the gate before it.
AFTER_THE_EDGE = ("launch_twin.foam.",)
#: Grid points of the table: over the bias, and over each other unknown it spans (at most MAX_OTHER of them).
BIAS_POINTS, OTHER_POINTS, MAX_OTHER = 7, 7, 2
#: The profile's mass multipliers, which do not act on the bare robot (:data:`BARE_ROBOT`): what its table need not
#: span.
PROFILE_MASS_KEYS = ("robot.profile_mass_scale", "urdf_robot.profile_mass_scale")

_TABLES: typing.Dict[str, np.ndarray] = {}


def shot_observations(shots: typing.Iterable["GateShot"]) -> typing.List[Observation]:
    """The launcher characterisation's gate shots (the bare robot fired at a set speed on the bench) as the bare
    robot's gate readings (:data:`GATE_HEIGHT_M`, angle 0: neither moves a reading; no verdict is weighed), so they
    enter :func:`gate_term` and :class:`GateModel` in the same group as the campaign's bare-robot readings of that
    set speed."""
    return [Observation(BARE_ROBOT, GATE_HEIGHT_M, float(s.speed_mps), 0.0, False,
                        {"measured_speed_mps": float(s.measured_speed_mps)}) for s in shots]


def gate_unknowns(unknowns: Unknowns, sampled: typing.Optional[typing.Sequence[str]] = None,
                  bare_only: bool = False) -> typing.List[int]:
    """Indices of the unknowns the table spans besides the bias: those of ``sampled`` (default: all of
    ``unknowns``) not past the edge (module docstring), without the profile's mass when only the bare robot's
    readings are weighed (``bare_only``); the others are held at the twin's values. ``ValueError`` without the
    bias among the sampled unknowns, on a log-scaled bias, or with more than :data:`MAX_OTHER` others."""
    names = unknowns.names
    sampled = names if sampled is None else tuple(sampled)
    if bare_only:
        sampled = tuple(name for name in sampled if name not in PROFILE_MASS_KEYS)
    if BIAS_KEY not in names or BIAS_KEY not in sampled:
        raise ValueError(f"the speed gate's term weighs the speed bias: {BIAS_KEY} must be a fitted unknown")
    if unknowns.log_scale[names.index(BIAS_KEY)]:
        raise ValueError(f"{BIAS_KEY} must be searched on a linear scale (it changes sign)")
    others = [i for i, name in enumerate(names) if name in sampled
              and name not in (BIAS_KEY, SCATTER_KEY) and not name.startswith(AFTER_THE_EDGE)]
    if len(others) > MAX_OTHER:
        raise ValueError(f"the speed gate's term tabulates at most {MAX_OTHER} unknowns besides the bias; "
                         f"{', '.join(names[i] for i in others)} act before the edge: fit fewer")
    return others


def gate_table(twin: "LaunchTwinSettings", unknowns: Unknowns, groups: typing.Sequence[typing.Tuple[str, float]],
               bias_points: int = BIAS_POINTS, other_points: int = OTHER_POINTS,
               sampled: typing.Optional[typing.Sequence[str]] = None, bare_only: bool = False) -> np.ndarray:
    """G: the gate's readings without scatter (m/s), shape (bias_points, other_points, ... , len(groups)), on
    the normalised grid of the bias and of :func:`gate_unknowns`' others (``sampled``, ``bare_only`` as there),
    per (configuration, set speed) of ``groups``; the unknowns not spanned at ``twin``'s values. Kept per process (the same twin, unknowns and groups
    give the same table: every truth of a bench, every calibration of a session)."""
    from rollability_ros.core.sim import twin_with_values

    names = unknowns.names
    spanned = [names.index(BIAS_KEY), *gate_unknowns(unknowns, sampled, bare_only)]
    shape = [bias_points] + [other_points] * (len(spanned) - 1)
    key = hashlib.sha256(pickle.dumps((twin, unknowns, tuple(groups), shape, spanned), protocol=4)).hexdigest()
    if key not in _TABLES:
        axes = [np.linspace(0.0, 1.0, n) for n in shape]
        grid = np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(shape), -1).T
        rows = []
        for point in grid:
            settings = twin_with_values(twin, {names[j]: float(values_one(unknowns, j, point[i]))
                                               for i, j in enumerate(spanned)})
            rows.append([gate_reading_mps(settings, configuration, speed) for configuration, speed in groups])
        _TABLES[key] = np.array(rows).reshape(*shape, len(groups))
        while len(_TABLES) > 8:
            del _TABLES[next(iter(_TABLES))]
    return _TABLES[key]


def gate_term(observations: typing.Sequence[Observation], twin: "LaunchTwinSettings", unknowns: Unknowns,
              bias_points: int = BIAS_POINTS, other_points: int = OTHER_POINTS,
              sampled: typing.Optional[typing.Sequence[str]] = None, model_error: float = MODEL_ERROR,
              configurations: typing.Optional[typing.Sequence[str]] = (BARE_ROBOT,)) -> LogDensity:
    """The gate readings' log-likelihood as a function of normalised unknowns (s, d) -> (s,), for
    :func:`~rollability_ros.core.campaign.posterior.sample_posterior`'s ``extra`` (module docstring). Uses each
    observation's ``measured_speed_mps`` (a reading absent, not finite or at most :data:`MIN_READING_FRACTION` of
    the set speed is not measured and adds nothing). ``sampled``: the unknowns the posterior samples (default:
    all); the others must be ``twin``'s values. ``model_error``: the table's error as a fraction of the reading
    (:data:`MODEL_ERROR`), shared by the readings of one (configuration, set speed), so it does not average away.
    ``configurations``: whose readings are weighed (None: every one's). Default: the bare robot's, whose reading
    depends on the bias alone; a design's also moves with the profile's mass and the centre of mass (up to 4%
    of the reading), and with them in the term the table's error pulled the centre of mass off its truth
    (measured: docs/calibration.md, "The speed gate's term"). The learnt likelihood must then not weigh the same
    reading (``outcomes`` without ``measured_speed_mps``)."""
    bare_only = configurations is not None and all(c == BARE_ROBOT for c in configurations)
    gate_unknowns(unknowns, sampled, bare_only)   # refuses unknowns the term cannot weigh, readings or not
    readings = grouped_readings(observations, configurations)
    if not readings:
        return lambda u: np.zeros(len(u))
    groups = sorted(readings)
    predict = gate_predictor(twin, unknowns, groups, bias_points, other_points, sampled, bare_only)
    return lambda u: readings_log_density(*predict(u), [readings[g] for g in groups], model_error)


def grouped_readings(observations: typing.Sequence[Observation],
                     configurations: typing.Optional[typing.Sequence[str]] = (BARE_ROBOT,)
                     ) -> typing.Dict[typing.Tuple[str, float], typing.List[float]]:
    """The gate readings (m/s) of ``observations`` by (configuration, set speed), of ``configurations`` only (None:
    every one's); a reading absent, not finite or at most :data:`MIN_READING_FRACTION` of the set speed is left
    out."""
    readings: typing.Dict[typing.Tuple[str, float], typing.List[float]] = {}
    for o in observations:
        if configurations is not None and o.configuration not in configurations:
            continue
        value = float(o.outcomes.get("measured_speed_mps", math.nan))
        if math.isfinite(value) and value > MIN_READING_FRACTION * o.speed_mps:
            readings.setdefault((o.configuration, float(o.speed_mps)), []).append(value)
    return readings


def gate_predictor(twin: "LaunchTwinSettings", unknowns: Unknowns, groups: typing.Sequence[typing.Tuple[str, float]],
                   bias_points: int = BIAS_POINTS, other_points: int = OTHER_POINTS,
                   sampled: typing.Optional[typing.Sequence[str]] = None, bare_only: bool = False
                   ) -> typing.Callable[[np.ndarray], typing.Tuple[np.ndarray, np.ndarray]]:
    """normalised unknowns (s, d) -> (G, sd) (s, len(groups)): the reading without scatter at each (configuration,
    set speed) of ``groups`` (:func:`gate_table`, interpolated) and the scatter's standard deviation of one reading
    (the delta method: G'(b) (1 + b) ``speed_sigma_fraction``); the model :func:`gate_term` weighs readings by."""
    names = unknowns.names
    others = gate_unknowns(unknowns, sampled, bare_only)
    bias = names.index(BIAS_KEY)
    table = gate_table(twin, unknowns, groups, bias_points, other_points, sampled, bare_only)
    grids = [np.linspace(0.0, 1.0, n) for n in table.shape[:-1]]
    interpolate = require("scipy.interpolate", feature="the speed gate's term").RegularGridInterpolator(
        grids, table, method="cubic" if min(table.shape[:-1]) >= 4 else "linear")
    span = unknowns.upper[bias] - unknowns.lower[bias]
    step = 0.5 / (table.shape[0] - 1)   # half a grid step, normalised: the slope's central difference
    scatter = names.index(SCATTER_KEY) if SCATTER_KEY in (names if sampled is None else sampled) else None
    sigma_fixed = twin.twin.speed_sigma_fraction

    def predict(u: np.ndarray) -> typing.Tuple[np.ndarray, np.ndarray]:
        """The gate's reading without scatter and its spread (m/s, each (n, groups): per (configuration, set
        speed) group of the table) at the normalised unknowns ``u`` (n, unknowns)."""
        point = np.clip(u[:, [bias, *others]], 0.0, 1.0)
        low, high = point.copy(), point.copy()
        low[:, 0] = np.clip(point[:, 0] - step, 0.0, 1.0)
        high[:, 0] = np.clip(point[:, 0] + step, 0.0, 1.0)
        mean, below, above = interpolate(point), interpolate(low), interpolate(high)
        slope = (above - below) / ((high[:, 0] - low[:, 0]) * span)[:, None]   # dG / d bias, m/s per unit
        b = values_one(unknowns, bias, point[:, 0])
        sigma = values_one(unknowns, scatter, u[:, scatter]) if scatter is not None else np.full(len(u), sigma_fixed)
        return mean, np.maximum(np.abs(slope) * ((1.0 + b) * sigma)[:, None], 1e-6)
    return predict


class GateModel:
    """The speed gate's term for a plan (:class:`~rollability_ros.core.campaign.learnt_plan.OutcomePosterior`'s
    ``gate``): :meth:`term` weighs the readings so far (:func:`gate_term`), :meth:`predict` gives the model at the
    weighed (configuration, set speed) of ``groups`` (:attr:`groups`: those of ``configurations``, and the shots')
    for the expected information of a launch's reading. ``shots``: the launcher characterisation's readings
    (:func:`shot_observations`), weighed with every plan's readings in their groups (:meth:`term` of no readings is
    theirs alone); a plan's samples are then drawn from a density that holds them (learnt_plan.OutcomePosterior)."""

    def __init__(self, twin: "LaunchTwinSettings", unknowns: Unknowns,
                 groups: typing.Iterable[typing.Tuple[str, float]], model_error: float = MODEL_ERROR,
                 configurations: typing.Optional[typing.Sequence[str]] = (BARE_ROBOT,),
                 shots: typing.Sequence[Observation] = ()) -> None:
        self.twin, self.unknowns, self.model_error, self.configurations = twin, unknowns, model_error, configurations
        self.shots = tuple(o for o in shots if configurations is None or o.configuration in configurations)
        if len(self.shots) != len(shots):
            raise ValueError("the gate shots are the bare robot's readings: its configuration must be weighed")
        self.groups = sorted({(c, float(v)) for c, v in groups if configurations is None or c in configurations}
                             | set(grouped_readings(self.shots, None)))
        bare_only = configurations is not None and all(c == BARE_ROBOT for c in configurations)
        self.predict = gate_predictor(twin, unknowns, self.groups, bare_only=bare_only) if self.groups else None

    def with_shots(self, shots: typing.Sequence[Observation]) -> "GateModel":
        """This model with ``shots`` as its launcher characterisation's readings instead of its own (another
        truth's, another lab's; the table is the same, kept per process)."""
        return GateModel(self.twin, self.unknowns, self.groups, self.model_error, self.configurations, shots)

    def term(self, observations: typing.Sequence[Observation]) -> LogDensity:
        """:func:`gate_term` of the shots and ``observations`` on this model's twin, unknowns, error and
        configurations."""
        return gate_term([*self.shots, *observations], self.twin, self.unknowns, model_error=self.model_error,
                         configurations=self.configurations)


def groups_log_density(groups: typing.Sequence[typing.Tuple[str, float]],
                       predicted: typing.Tuple[np.ndarray, np.ndarray], observations: typing.Sequence[Observation],
                       model_error: float = MODEL_ERROR) -> np.ndarray:
    """The readings of ``observations`` in ``groups`` (the weighed (configuration, set speed) pairs; the others'
    readings are not weighed) scored by :func:`readings_log_density` against ``predicted`` = (mean, sd) (s,
    len(groups)), the model at each parameter set and group."""
    mean, sd = predicted
    readings = grouped_readings(observations, None)
    where = {g: i for i, g in enumerate(groups)}
    present = [g for g in sorted(readings) if g in where]
    if not present:
        return np.zeros(len(mean))
    columns = [where[g] for g in present]
    return readings_log_density(mean[:, columns], sd[:, columns], [readings[g] for g in present], model_error)

