"""The posterior of a learnt likelihood's unknowns (:mod:`~rollability_ros.core.campaign.likelihood`): the
ensemble sampler, the 95% highest-density sets (a split set stays a union of intervals), and the characterisation
readings as a log-likelihood term over the same unknowns. docs/calibration.md, "The learnt likelihood"."""
import contextlib
import dataclasses
import hashlib
import math
import pickle
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core.campaign.characterisation import Characterisation
from rollability_ros.core.campaign.adaptive import Unknowns
from rollability_ros.core.campaign.likelihood import (CHOSEN_TEMPERATURE, LearntLikelihood, Observation, normalised_one,
                                                      values_one)
from rollability_ros.core.optional import require

if typing.TYPE_CHECKING:
    from rollability_ros.core.sim import LaunchTwinSettings

LogDensity = typing.Callable[[np.ndarray], np.ndarray]

#: The characterisation's tables of predictions per process (:func:`_tabulated`).
_TABLES: typing.Dict[str, np.ndarray] = {}


def stretch_sampler(log_density: LogDensity, start: np.ndarray, steps: int, rng: np.random.Generator,
                    a: float = 2.0) -> typing.Tuple[np.ndarray, np.ndarray]:
    """Goodman and Weare's affine-invariant ensemble sampler (the stretch move, two half-ensembles updated in
    turn) on the unit box: ``log_density`` (w, k) -> (w,), -inf outside the box; ``start`` (w, k) with w even
    and >= 2 k. Returns the chain (steps, w, k) and its log densities (steps, w)."""
    walkers, k = start.shape
    half = walkers // 2
    position = start.copy()
    current = log_density(position)
    chain = np.empty((steps, walkers, k))
    densities = np.empty((steps, walkers))
    for step in range(steps):
        for active, other in ((slice(0, half), slice(half, walkers)), (slice(half, walkers), slice(0, half))):
            mine, theirs = position[active], position[other]
            z = ((a - 1.0) * rng.uniform(size=len(mine)) + 1.0) ** 2 / a
            partners = theirs[rng.integers(len(theirs), size=len(mine))]
            proposal = partners + z[:, None] * (mine - partners)
            proposed = np.full(len(mine), -np.inf)
            inside = np.all((proposal >= 0.0) & (proposal <= 1.0), axis=1)
            if inside.any():
                proposed[inside] = log_density(proposal[inside])
            accept = np.log(rng.uniform(size=len(mine))) < (k - 1) * np.log(z) + proposed - current[active]
            mine = np.where(accept[:, None], proposal, mine)
            position[active] = mine
            current[active] = np.where(accept, proposed, current[active])
        chain[step] = position
        densities[step] = current
    return chain, densities


@dataclasses.dataclass(frozen=True)
class Posterior:
    """Posterior samples of the sampled unknowns: ``names`` (k,), ``samples`` (n, k) own units, ``normalised``
    (n, k), the :class:`Unknowns` entry of each (``unknowns``, indices ``index``), the sampler's wall time and
    each sample's log posterior density ``log_density`` (n,) (up to a constant)."""

    names: typing.Tuple[str, ...]
    samples: np.ndarray
    normalised: np.ndarray
    unknowns: Unknowns
    index: typing.Tuple[int, ...]
    wall_s: float
    log_density: np.ndarray
    best_index: typing.Optional[int] = None

    def best(self) -> typing.Dict[str, float]:
        """The sample of highest posterior density (own units): the fitted values (inside a split set, where a
        marginal median might fall in the gap). ``best_index`` when given (the ensemble's: the sample of highest
        density under the members' mean likelihood), else the highest ``log_density``."""
        top = int(np.argmax(self.log_density)) if self.best_index is None else self.best_index
        return {name: float(self.samples[top, i]) for i, name in enumerate(self.names)}

    def credible_set(self, name: str, mass: float = 0.95) -> typing.List[typing.Tuple[float, float]]:
        """The highest-density ``mass`` set of unknown ``name``'s marginal (own units): :func:`credible_set`."""
        i = self.names.index(name)
        intervals = credible_set(self.normalised[:, i], mass)
        j = self.index[i]
        return [(float(values_one(self.unknowns, j, lo)), float(values_one(self.unknowns, j, hi)))
                for lo, hi in intervals]

    def set_width_fraction(self, name: str, mass: float = 0.95) -> float:
        """The total length of the credible set as a fraction of the range, on the unknown's own scale."""
        i = self.names.index(name)
        return float(sum(hi - lo for lo, hi in credible_set(self.normalised[:, i], mass)))

    def median(self, name: str) -> float:
        """Posterior median (own units)."""
        return float(np.median(self.samples[:, self.names.index(name)]))


#: Bins of the marginal histogram a credible set is read from (over the unknown's normalised range).
SET_BINS = 50


def credible_set(normalised_samples: npt.ArrayLike, mass: float = 0.95, bins: int = SET_BINS,
                 gap_bins: int = 1) -> typing.List[typing.Tuple[float, float]]:
    """The highest-density set holding ``mass`` of the samples (normalised coordinates, (n,)): the fullest bins
    of a ``bins``-bin histogram over [0, 1] until they hold ``mass``, adjacent bins merged, and so are intervals
    separated by at most ``gap_bins`` left-out bins (a gap that narrow is the samples' noise in a flat stretch,
    measured: a verdicts-only posterior came out in five pieces of one-bin gaps); a list of disjoint (low, high)
    intervals, ascending. Conservative by up to a bin at each end (a bin is in or out whole)."""
    x = np.clip(np.asarray(normalised_samples, dtype=np.float64), 0.0, 1.0)
    counts, edges = np.histogram(x, bins=bins, range=(0.0, 1.0))
    order = np.argsort(-counts, kind="stable")
    kept = np.zeros(bins, dtype=bool)
    total = 0
    for b in order:
        if total >= mass * len(x):
            break
        kept[b] = True
        total += counts[b]
    intervals: typing.List[typing.Tuple[float, float]] = []
    width = 1.0 / bins
    for b in np.flatnonzero(kept):
        if intervals and edges[b] - intervals[-1][1] < (gap_bins + 0.5) * width:
            intervals[-1] = (intervals[-1][0], float(edges[b + 1]))
        else:
            intervals.append((float(edges[b]), float(edges[b + 1])))
    return intervals


def format_set(intervals: typing.Sequence[typing.Tuple[float, float]]) -> str:
    """A credible set as text: ``[a, b]``, or ``[a, b] U [c, d]`` when it is split (never the hull)."""
    return " U ".join(f"[{lo:.4g}, {hi:.4g}]" for lo, hi in intervals)


#: The temperatures at which the 95% sets' coverage was measured: temperature -> the smallest coverage over the
#: unknowns on truths 0-49 and on truths 50-99 (:data:`COVERAGE_SETTING`; docs/calibration.md, the tables of "A
#: temperature chosen on held-out truths" and of the section after it).
MEASURED_COVERAGE = {1.0: (0.84, 0.80), 0.5: (0.88, 0.90), 0.25: (0.90, 0.94)}
#: What those coverages were measured with (bench/bench_calibration.py).
COVERAGE_SETTING = ("measured with five unknowns on the paper's 400 launches of the bare robot and three designs, "
                    "roll-outs, slide and tip angles, weighings and the gate (--gate), verdicts only: docs/"
                    "calibration.md, \"A temperature chosen on held-out truths\" and the section after it")


def temperature_statement(temperature: float, source: str) -> str:
    """One line for a calibration's report: the launches' ``temperature``, where it came from (``source``) and the
    coverage of the 95% sets measured at it (:data:`MEASURED_COVERAGE`), or that none was measured at it."""
    head = f"launches' temperature {temperature:g} ({source}). "
    measured = next((v for t, v in MEASURED_COVERAGE.items() if math.isclose(t, temperature)), None)
    if measured is None:
        return (f"{head}The coverage of the 95% sets was not measured at this temperature (only at "
                f"{', '.join(f'{t:g}' for t in MEASURED_COVERAGE)}, {COVERAGE_SETTING}).")
    return (f"{head}The smallest coverage of an unknown's 95% sets measured at it: {measured[0]:.0%} on truths 0-49, "
            f"{measured[1]:.0%} on truths 50-99 ({COVERAGE_SETTING})"
            + ("." if min(measured) >= 0.9 else f"; under the 90% target: these sets may be too narrow for their "
               f"truths (temperature {CHOSEN_TEMPERATURE:g} was measured to cover)."))


def sample_posterior(likelihood: LearntLikelihood, observations: typing.Sequence[Observation],
                     sample: typing.Optional[typing.Sequence[str]] = None,
                     fixed: typing.Optional[typing.Mapping[str, float]] = None,
                     extra: typing.Optional[LogDensity] = None, outcomes: typing.Optional[typing.Sequence[str]] = None,
                     walkers: int = 32, steps: int = 300, seed: int = 1,
                     temperature: typing.Optional[float] = None, start_draws: int = 2000) -> Posterior:
    """Posterior samples of the unknowns ``sample`` (default: all of the likelihood's) given ``observations``,
    the others held at ``fixed`` (own units; every unknown not sampled needs a value inside its bounds).
    ``extra``: a log-likelihood (s,) of the full normalised unknowns (s, d) added to the launches' (the
    characterisation's, :func:`characterisation_term`). Uniform prior on the normalised box. The emulator's
    error enters twice: one posterior per ensemble member (each its own stretch sampler of ``walkers`` walkers,
    started from the best of ``start_draws`` prior draws under that member), pooled with equal weights, so where the members disagree the sets
    widen; and the launches' log-likelihood is raised to ``temperature`` (default: the file's,
    :attr:`LearntLikelihood.temperature`). Each sampler discards the first half of ``steps`` and keeps every
    step after (correlated samples, but more of them: a 50-bin histogram of every 5th step came out in noisy
    pieces). ``log_density`` of each sample is its own member's."""
    import time

    started = time.perf_counter()
    unknowns = likelihood.unknowns
    names = tuple(sample or unknowns.names)
    missing = [n for n in names if n not in unknowns.names]
    if missing:
        raise ValueError(f"{missing[0]} is not an unknown of the prepared likelihood ({', '.join(unknowns.names)})")
    index = tuple(unknowns.names.index(n) for n in names)
    base = np.full(len(unknowns.names), np.nan)
    for i, name in enumerate(unknowns.names):
        if name in names:
            continue
        if fixed is None or name not in fixed:
            raise ValueError(f"{name}: not sampled, so it needs a fixed value")
        base[i] = float(normalised_one(unknowns, i, fixed[name]))
        if not -1e-9 <= base[i] <= 1 + 1e-9:
            raise ValueError(f"{name} = {fixed[name]:g} lies outside the bounds the likelihood was learnt on "
                             f"[{unknowns.lower[i]:g}, {unknowns.upper[i]:g}]: prepare it with wider bounds")

    def full(u: np.ndarray) -> np.ndarray:
        """Samples (n, k) of the fitted unknowns -> (n, d) with the others at their loaded values."""
        out = np.repeat(base[None, :], len(u), axis=0)
        out[:, index] = u
        return out

    arranged = likelihood.arrange(observations, outcomes)
    power = likelihood.temperature if temperature is None else float(temperature)
    if not 0.0 < power <= 1.0:
        raise ValueError(f"temperature must lie in (0, 1], got {power:g}")
    rng = np.random.default_rng(seed)
    k = len(index)
    walkers = max(walkers, 2 * k + 2) + (max(walkers, 2 * k + 2) % 2)
    members = likelihood.ensemble_size
    kept, kept_densities = [], []
    try:   # small matrices: BLAS threads only contend (4x slower measured on a loaded 2-core machine)
        limits: typing.Any = require("threadpoolctl").threadpool_limits(1)
    except ImportError:
        limits = contextlib.nullcontext()
    with limits:
        for member in range(members):
            def log_density(u: np.ndarray, member: int = member) -> np.ndarray:
                """Log posterior (n,) of samples (n, k) of the fitted unknowns under one member, the
                characterisation included (not tempered: its model is not learnt)."""
                value = power * likelihood.log_likelihood(full(u), arranged, member=member)
                return value + extra(full(u)) if extra is not None else value
            candidates = rng.uniform(size=(max(start_draws, walkers), k))
            scores = np.concatenate([log_density(part) for part in np.array_split(candidates, 10)])
            start = candidates[np.argsort(-scores)[:walkers]]
            chain, densities = stretch_sampler(log_density, start, steps, rng)
            kept.append(chain[steps // 2:].reshape(-1, k))
            kept_densities.append(densities[steps // 2:].reshape(-1))
        pooled = np.concatenate(kept)
        best = None
        if members > 1:   # each sample's density is its own member's: the best is read under the members' mean
            thinned = np.arange(0, len(pooled), max(1, len(pooled) // 2000))
            mixture = np.concatenate([
                power * likelihood.log_likelihood(full(pooled[part]), arranged)
                + (extra(full(pooled[part])) if extra is not None else 0.0)
                for part in np.array_split(thinned, max(1, len(thinned) // 250))])
            best = int(thinned[int(np.argmax(mixture))])
    values = np.array([values_one(unknowns, j, pooled[:, i]) for i, j in enumerate(index)]).T
    return Posterior(names, values, pooled, unknowns, index, time.perf_counter() - started,
                     np.concatenate(kept_densities), best)


def characterisation_term(characterisation: Characterisation, twin: "LaunchTwinSettings",
                          unknowns: Unknowns, grid_points: typing.Optional[int] = None,
                          gate_shots: bool = True, sampled: typing.Optional[typing.Sequence[str]] = None
                          ) -> LogDensity:
    """The characterisation's log-likelihood as a function of normalised unknowns (s, d) -> (s,), for
    :func:`sample_posterior`'s ``extra``. Slide angles: analytic (``characterisation.slide_angle_deg`` of each
    parameter set). Roll-outs, tip angles and profile weighings: each reading's prediction computed on a grid of
    ``grid_points`` values of each unknown it depends on that is sampled (:data:`ROLLOUT_KEYS`, :data:`TIP_KEYS`,
    :data:`MASS_KEYS`; at most two per kind, the others at their loaded values), interpolated (cubic in the
    normalised coordinates) and scored by the reading's Gaussian, since a roll-out (a simulation), a tip angle (the
    robot's hull) or a profile's mass (its printed shell) per parameter set would cost as much as the launches it
    replaces. ``grid_points`` defaults to 17 for one such unknown and 9 for two (the table's predictions: 17 or 81
    per kind of reading). Gate shots (the launcher's characterisation): the speed gate's term
    (``likelihood_gate.gate_term`` of ``likelihood_gate.shot_observations``; ``sampled`` as there), unless
    ``gate_shots`` is False: a caller that weighs the campaign's gate readings too must weigh the shots in the same
    term, since they share its error per set speed."""
    from rollability_ros.core.campaign.characterisation import profile_mass_kg, tip_angles_deg
    from rollability_ros.core.sim import rollout_distance_m, twin_value

    names = unknowns.names

    def slide(u: np.ndarray) -> np.ndarray:
        """The slide angles' log-likelihood (s,): bench.slide_angle_deg's model, vectorised over the samples."""
        if not characterisation.slide_angles_deg:
            return np.zeros(len(u))
        values = unknowns.to_values(u)
        mu = np.ones(len(u))
        for key in SLIDE_KEYS:   # the contact friction is the product of the two
            mu = mu * (values[:, names.index(key)] if key in names else twin_value(twin, key))
        angle = np.degrees(np.arctan(mu))
        sigma = characterisation.slide_sigma_deg
        readings = np.asarray(characterisation.slide_angles_deg)
        return (-0.5 * ((readings[None, :] - angle[:, None]) / sigma) ** 2
                - math.log(sigma * math.sqrt(2.0 * math.pi))).sum(axis=1)
    terms: typing.List[LogDensity] = [slide]
    if characterisation.rollouts:
        keys = sorted({(r.surface, r.speed_mps) for r in characterisation.rollouts})
        terms.append(_tabulated(
            twin, unknowns, ROLLOUT_KEYS, grid_points, ("roll-out", tuple(keys)),
            lambda settings: [rollout_distance_m(settings, speed, surface) for surface, speed in keys],
            [r.distance_m for r in characterisation.rollouts],
            [keys.index((r.surface, r.speed_mps)) for r in characterisation.rollouts], characterisation.rollout_sigma_m))
    if characterisation.tips:
        sides = sorted({t.side for t in characterisation.tips})
        terms.append(_tabulated(
            twin, unknowns, TIP_KEYS, grid_points, ("tip", tuple(sides)),
            lambda settings: tip_angles_deg(settings, sides),
            [t.angle_deg for t in characterisation.tips], [sides.index(t.side) for t in characterisation.tips],
            characterisation.tip_sigma_deg))
    if characterisation.masses:
        weighed = sorted({m.configuration for m in characterisation.masses})
        terms.append(_tabulated(
            twin, unknowns, MASS_KEYS, grid_points, ("weighing", tuple(weighed)),
            lambda settings: [profile_mass_kg(settings, c) for c in weighed],
            [m.mass_kg for m in characterisation.masses], [weighed.index(m.configuration) for m in
                                                            characterisation.masses], characterisation.mass_sigma_kg))

    if characterisation.gate_shots and gate_shots:
        from rollability_ros.core.campaign.likelihood_gate import gate_term, shot_observations

        terms.append(gate_term(shot_observations(characterisation.gate_shots), twin, unknowns, sampled=sampled))

    def total(u: np.ndarray) -> np.ndarray:
        """Every reading's log-likelihood (s,), summed."""
        out = np.zeros(len(u))
        for term in terms:
            out = out + term(u)
        return out
    return total


def _tabulated(twin: "LaunchTwinSettings", unknowns: Unknowns, depends_on: typing.Sequence[str],
               grid_points: typing.Optional[int], what: typing.Tuple[str, typing.Tuple[typing.Any, ...]],
               predict: typing.Callable[["LaunchTwinSettings"], typing.Sequence[float]],
               readings: typing.Sequence[float], which: typing.Sequence[int], sigma: float) -> LogDensity:
    """The Gaussian log-likelihood (s,) of ``readings`` (r,), reading i predicted by ``predict(twin)[which[i]]``,
    as a function of normalised unknowns (s, d): the predictions tabulated on a grid of the sampled unknowns among
    ``depends_on`` (at most two) and interpolated (cubic): the predictions are smooth in the unknowns and are what
    is interpolated; the likelihood's peak, narrower than a grid step at precise readings, is computed from them
    (interpolating the log-likelihood itself put the peak on a grid point). ``what`` names the predictions (kind,
    and the conditions they are of): the table is kept per process under it, the twin, the unknowns and the grid
    (the roll-outs' table, 243 PyBullet roll-outs, is the same for every calibration of one twin)."""
    from rollability_ros.core.sim import twin_with_values

    names = unknowns.names
    varied = [names.index(k) for k in depends_on if k in names]
    if len(varied) > 2:
        raise ValueError(f"at most two of {', '.join(depends_on)} can be tabulated")
    points = grid_points or (17 if len(varied) <= 1 else 9)
    grids = [np.linspace(0.0, 1.0, points) for _ in varied]
    mesh = np.array(np.meshgrid(*grids, indexing="ij")).reshape(len(varied), -1).T if varied else np.zeros((1, 0))
    key = hashlib.sha256(pickle.dumps((twin, unknowns, what, tuple(varied), points), protocol=4)).hexdigest()
    if key not in _TABLES:
        _TABLES[key] = np.array([predict(twin_with_values(
            twin, {names[j]: float(values_one(unknowns, j, point[i])) for i, j in enumerate(varied)}))
            for point in mesh])
        while len(_TABLES) > 16:
            del _TABLES[next(iter(_TABLES))]
    table = _TABLES[key]
    observed, index = np.asarray(readings, dtype=np.float64), np.asarray(which, dtype=int)

    def gaussian(predicted: np.ndarray) -> np.ndarray:
        """The readings' Gaussian log-likelihood (s,) from the predictions (s, kinds)."""
        z = (observed[None, :] - predicted[:, index]) / sigma
        return (-0.5 * z * z - math.log(sigma * math.sqrt(2.0 * math.pi))).sum(axis=1)
    if not varied:
        fixed = gaussian(table[:1])[0]
        return lambda u: np.full(len(u), fixed)
    method = "cubic" if points >= 4 else "linear"
    interpolate = require("scipy.interpolate", feature="tabulated characterisation readings").RegularGridInterpolator(
        grids, table.reshape([points] * len(varied) + [table.shape[1]]), method=method)
    return lambda u: gaussian(interpolate(np.clip(u[:, varied], 0.0, 1.0)))


#: The keys whose product is the printed part's friction on the foam (the slide angle's model).
SLIDE_KEYS = ("sim.lateral_friction", "launch_twin.foam.lateral_friction")
#: The unknowns a roll-out depends on (:func:`characterisation_term` tabulates the roll-out over those sampled):
#: the foam's friction among them (measured on the bench's chassis at 0.8 m/s: 0.20 m at friction 1.0, 0.28 m at
#: 0.33; the centre of mass, the profile's mass and the speed bias moved it by under 0.002 m).
ROLLOUT_KEYS = ("launch_twin.foam.rolling_friction", "launch_twin.wheel_drag_torque_nm",
                "launch_twin.foam.lateral_friction")
#: The unknowns a tip angle depends on (the bare robot's centre of mass; :func:`characterisation_term` tabulates
#: it over those sampled).
TIP_KEYS = ("robot.com_offset_z_m",)
#: The unknowns a profile's weighed mass depends on (its mass multiplier, on the built-in chassis or a URDF robot).
MASS_KEYS = ("robot.profile_mass_scale", "urdf_robot.profile_mass_scale")
