"""Calibration with the learnt likelihood on simulated hidden truths: preparation time, calibration time, coverage,
widths, the two-unknown `rollability calibrate`, and calibrate -> re-optimise -> validate. All simulated.

    nice python bench/bench_calibration.py [--prepare-launches 8000] [--members 3] [--truths 50] [--steps 200]
        [--first-truth K] [--temperature T] [--outcomes all|none|NAMES] [--no-rollouts] [--no-tips] [--no-weighing] [--gate]
        [--engine mujoco|pybullet] [--workers 2] [--likelihood FILE] [--keep DIR]
        [--skip-cli] [--skip-adaptive] [--skip-reoptimize] [--reoptimize-generations 15] [--smoke]

0. The twin: ``--engine`` (``sim.engine``; default mujoco, whose launch run to rest costs about a fifth of
   PyBullet's: 0.035 against 0.18 CPU s measured) launches the preparation and the truths alike; the
   characterisation's roll-out is modelled in the PyBullet twin only and is used for both sides.
1. Designs: the bare robot and three profiles (bench_launch_twin's dome, a flat top at the 0.09 m bound and a low
   pyramid: docs/twin-model.md's shapes), as STLs. The unknowns: :data:`UNKNOWNS` (centre of mass, foam friction,
   wheel-on-foam rolling resistance, launcher speed bias, profile mass scale), with the bounds and scales of
   ``config/calibration.yaml``.
2. Preparation (once): ``--prepare-launches`` twin launches at unknowns drawn over the bounds, the four
   configurations and the campaign's conditions, then the ensemble of ``--members`` networks learnt
   (:mod:`rollability_ros.core.campaign.likelihood`; its held-out log loss, Brier score and reliability against a
   constant are printed). ``--likelihood FILE`` loads a prepared file instead (its twin fingerprint must match);
   ``--keep DIR`` writes it there and a later run with the same folder loads it.
3. ``--truths`` hidden truths drawn from the prior (uniform over the normalised bounds, each from its own seed).
   For each: the paper's 400-launch matrix (4 configurations x 2 heights x 2 speeds x 5 angles x 5) launched on
   the twin at the truth (fresh seeds), five slide angles (the analytic model plus 1 deg noise) and three
   roll-outs on the foam (the simulated roll-out plus 0.02 m noise), kept in ``--keep`` (JSON) for re-runs, five
   tilt-table tip angles of the bare robot (1 deg noise; ``--no-tips`` leaves them out) and one weighing of each
   design's profile (1 g noise; ``--no-weighing``), drawn afresh from the truth's seed; then,
   in a worker, the posterior of all unknowns from the verdicts, the gate's speed and the IMU's tilt, peak
   deceleration, time to rest and the rest distance, plus the characterisation. Prints each unknown's coverage of
   the 95% sets (``--gate``: the speed gate's readings through the twin's tabulated launcher model instead of the
   learnt gate outcome, core/campaign/likelihood_gate.py; ``--first-truth K``: truths K.. instead of 0..), their
   widths as a fraction of the range (own scale), the SBC ranks (the truth among 99 thinned
   posterior samples: their histogram by fifths and its chi-squared p-value), the calibration time, and the
   learnt P(upright) on these fresh launches against a constant (Brier, log loss, reliability by deciles).
4. ``rollability calibrate --likelihood`` (the CLI, a subprocess) with two unknowns (centre of mass, foam friction)
   on the first truth's 400 launches, written as an outcome CSV, then again with its slide angles, then with its
   slide and tip angles.
5. Calibrate -> re-optimise -> validate on the first truth (bench_objective's optimisation, one seed): the design
   optimised on the calibrated twin against the one on the uncalibrated twin, each launched ``--validate`` times on
   the truth; the gain with Newcombe's 95% interval.
6. The adaptive plan against the paper's matrix with the learnt likelihood (:func:`adaptive_comparison`).

``--smoke``: every step but 5 at a tiny size (160 training launches, 2 members, 2 truths of 20 launches, 8
walkers x 20 sampler steps from 32 start draws, 4-point characterisation tables, one worker; the CLI at 20 sampler
steps); its numbers mean nothing. Every line with a time carries the load average (``os.getloadavg``):
the machine is shared.
"""
import argparse
import dataclasses
import math
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np  # noqa: E402

from rollability_ros.core.campaign import calibration  # noqa: E402
from rollability_ros.core.campaign import likelihood as learnt  # noqa: E402
from rollability_ros.core.campaign import likelihood_learning as learning  # noqa: E402
from rollability_ros.core.campaign import likelihood_gate  # noqa: E402
from rollability_ros.core.campaign import posterior as sampling  # noqa: E402
from rollability_ros.core.campaign.adaptive import Unknowns  # noqa: E402
from rollability_ros.core.config import load_parameters  # noqa: E402
from rollability_ros.core.sim import launch_twin_settings_from_parameters  # noqa: E402

#: The unknowns (config keys) of the bench, bounds and scales from config/calibration.yaml.
UNKNOWNS = ("robot.com_offset_z_m", "launch_twin.foam.lateral_friction", "launch_twin.foam.rolling_friction",
            "launch_twin.launcher.speed_bias_fraction", "robot.profile_mass_scale")
#: The two unknowns of the CLI check.
CLI_UNKNOWNS = ("robot.com_offset_z_m", "launch_twin.foam.lateral_friction")
#: Noise of the simulated characterisation readings.
SLIDE_SIGMA_DEG, ROLLOUT_SIGMA_M, TIP_SIGMA_DEG, MASS_SIGMA_KG = 1.0, 0.02, 1.0, 0.001
SLIDE_READINGS, ROLLOUT_SPEEDS_MPS = 5, (0.8, 1.0, 1.2)
#: Tilt-table readings of the bare robot (docs/characterisation.md (d)): the sides it tips towards, one each.
TIP_SIDES = ("front", "back", "left", "right", "front")
#: Base seeds (none used by a campaign, a study or the preparation's own draws).
PREPARE_SEED, TRUTH_SEED = 31_001, 41_001


def load() -> str:
    """The 1-minute load average, for the line beside every timing."""
    return f"load {os.getloadavg()[0]:.1f}"


def design_files(folder):
    """Write the three designs' STLs into ``folder``; return (labels, paths)."""
    from bench.bench_launch_twin import dome_mesh
    from bench.bench_shape_ceiling import shapes
    from rollability_ros.core.profile import geometry
    from rollability_ros.core.sim import EvaluatorSettings

    grid = EvaluatorSettings().grid
    family = shapes(grid)
    meshes = {"dome": dome_mesh(), "flat": geometry.profile_mesh(family["H 0.45 a 0.0 b 0.0"], grid),
              "pyramid": geometry.profile_mesh(family["H 0.20 a 0.5 b 0.5"], grid)}
    paths = []
    for label, mesh in meshes.items():
        paths.append(os.path.join(folder, f"{label}.stl"))
        geometry.export_mesh(mesh, paths[-1])
    return list(meshes), paths


def bench_parameters(folder):
    """The twin's flat parameters with the three designs, and the bench's :class:`Unknowns`."""
    parameters = load_parameters([*calibration.TWIN_CONFIGS, "calibration"])
    labels, paths = design_files(folder)
    parameters.update({"launch_twin.designs.mesh_labels": labels, "launch_twin.designs.mesh_files": paths})
    settings = calibration.calibration_settings(parameters).selected(list(UNKNOWNS))
    unknowns = Unknowns(tuple(settings.parameters), tuple(settings.lower), tuple(settings.upper),
                               tuple(settings.log_scale))
    return parameters, unknowns, ["baseline", *labels]


def paper_matrix(configurations):
    """The paper's 400 launches: (configuration, height, speed, angle) x 5 repetitions."""
    from rollability_ros.core.campaign_matrix import load_campaign_spec

    spec = load_campaign_spec(["campaign"])
    levels = learnt.ConditionLevels(tuple(spec.heights_m), tuple(spec.speeds_mps), tuple(spec.angles_deg))
    cells = [(c, h, v, a) for c in configurations for h in spec.heights_m for v in spec.speeds_mps
             for a in spec.angles_deg]
    return levels, [cell for cell in cells for _ in range(spec.repetitions)]


def launch_truth(parameters, unknowns, truth, matrix, seed):
    """The matrix launched at ``truth`` (own units), in this process: Observations with every continuous outcome,
    invalid ones left out."""
    from rollability_ros.core.sim import trial_seed

    jobs = [(tuple(truth), *cell, trial_seed(seed, i)) for i, cell in enumerate(matrix)]
    rows = learnt.simulate_rows(launch_twin_settings_from_parameters(parameters), unknowns.names, jobs)
    return [learnt.Observation(cell[0], cell[1], cell[2], cell[3], bool(row[1] > 0.5),
                               dict(zip(learnt.OUTCOMES, map(float, row[2:]))))
            for cell, row in zip(matrix, rows) if row[0] > 0.5]


def rollout_parameters(parameters):
    """``parameters`` for the characterisation: the roll-out is modelled in the PyBullet twin only, so its
    readings and their likelihood use that engine's roll-out whichever engine launches (the same model on both
    sides, the truth's and the calibration's)."""
    return {**parameters, "sim.engine": "pybullet"}


def characterise_truth(parameters, unknowns, truth, rng):
    """Simulated bench readings of ``truth``: slide angles (analytic + noise) and roll-outs on the foam (the tip
    angles and weighings: :func:`bench_readings`)."""
    from rollability_ros.core.campaign import characterisation as bench
    from rollability_ros.core.sim import rollout_distance_m

    settings = truth_settings(parameters, unknowns, truth)
    angle = bench.slide_angle_deg(settings)
    rollouts = tuple(bench.RolloutReading("foam", v, max(0.0, rollout_distance_m(settings, v, "foam")
                                                         + ROLLOUT_SIGMA_M * rng.standard_normal()))
                     for v in ROLLOUT_SPEEDS_MPS)
    return bench.Characterisation(source="simulated", rollouts=rollouts, rollout_sigma_m=ROLLOUT_SIGMA_M,
                                  slide_angles_deg=tuple(angle + SLIDE_SIGMA_DEG * rng.standard_normal(SLIDE_READINGS)),
                                  slide_sigma_deg=SLIDE_SIGMA_DEG)


def truth_settings(parameters, unknowns, truth):
    """The typed twin at ``truth`` (own units) for its bench readings (:func:`rollout_parameters`)."""
    flat = rollout_parameters(parameters)
    flat.update(zip(unknowns.names, map(float, truth)))
    return launch_twin_settings_from_parameters(flat)


def bench_readings(parameters, unknowns, truth, number, readings):
    """``readings`` with the truth's tilt-table tip angles (the model's angle towards each of :data:`TIP_SIDES`
    plus noise of :data:`TIP_SIGMA_DEG`) and one weighing of each design's profile (the model's mass plus noise of
    :data:`MASS_SIGMA_KG`), drawn with the truth's own seed (so the truths kept by earlier runs get theirs)."""
    from rollability_ros.core.campaign import characterisation as bench

    settings = truth_settings(parameters, unknowns, truth)
    rng = np.random.default_rng([TRUTH_SEED, number, 7])
    tips = tuple(bench.TipReading(side, angle + TIP_SIGMA_DEG * rng.standard_normal())
                 for side, angle in zip(TIP_SIDES, bench.tip_angles_deg(settings, TIP_SIDES)))
    masses = tuple(bench.MassReading(label, bench.profile_mass_kg(settings, label) + MASS_SIGMA_KG
                                     * rng.standard_normal())
                   for label in parameters["launch_twin.designs.mesh_labels"])
    return dataclasses.replace(readings, tips=tips, tip_sigma_deg=TIP_SIGMA_DEG, masses=masses,
                               mass_sigma_kg=MASS_SIGMA_KG)


def adaptive_comparison(likelihood, truths, configurations, levels, samples=4000):
    """The adaptive plan against the paper's matrix (issue 44 item 4; the ``adaptive`` room's
    ``plan_comparison.adaptive_to_match_matrix``, bench/bench_adaptive_plan.py benches it on its own) with the
    learnt likelihood as its predictor (``adaptive.PerLaunchAdapter``; outcomes drawn from it): on ``len(truths)``
    truths from the prior, the launches the adaptive plan needs to reach the widths of the matrix's 400."""
    from rollability_ros.core.campaign import adaptive, plan_comparison
    from rollability_ros.core.records import LaunchCondition

    u = likelihood.unknowns
    candidates = [LaunchCondition(c, h, v, a) for c in configurations for h in levels.heights_m
                  for v in levels.speeds_mps for a in levels.angles_deg]
    started = time.perf_counter()
    results = plan_comparison.adaptive_to_match_matrix(
        adaptive.Unknowns(u.names, u.lower, u.upper, u.log_scale), adaptive.PerLaunchAdapter(likelihood), candidates,
        len(truths), 5 * len(candidates), samples=samples, seed=TRUTH_SEED)
    reached = sorted(r.adaptive_launches for r in results if r.adaptive_launches is not None)
    print(f"adaptive plan vs the paper's matrix ({5 * len(candidates)} launches), outcomes drawn from the learnt "
          f"likelihood, {len(results)} truths from the prior: the adaptive plan reached the matrix's widths in "
          f"{len(reached)} of {len(results)}, median {np.median(reached) if reached else math.nan:.0f} launches "
          f"(target <= 150) [{time.perf_counter() - started:.0f} s, {load()}]", flush=True)


def rank_p_value(ranks, samples, bins=10):
    """Chi-squared p-value of uniform SBC ranks (``ranks`` in [0, samples]) over ``bins`` bins."""
    from scipy import stats

    counts, _ = np.histogram(ranks, bins=bins, range=(0, samples + 1))
    return float(stats.chisquare(counts).pvalue)


def truth_data(parameters, unknowns, matrix, number, cache):
    """Hidden truth ``number`` (drawn from the prior with its own seed), its launches of the matrix and its
    characterisation readings: simulated, or read from ``cache`` (a folder; JSON, written after simulating) when
    an earlier run left them there, so a re-run with another sampler setting simulates nothing."""
    import json

    from rollability_ros.core.campaign import characterisation as bench

    path = os.path.join(cache, f"truth-{number}.json") if cache else None
    if path and os.path.exists(path):
        with open(path, encoding="utf-8") as stream:
            data = json.load(stream)
        observations = [learnt.Observation(str(o[0]), float(o[1]), float(o[2]), float(o[3]), bool(o[4]),
                                           dict(zip(learnt.OUTCOMES, map(float, o[5]))))
                        for o in data["observations"]]
        readings = bench.Characterisation(
            source="simulated", rollouts=tuple(bench.RolloutReading(*r) for r in data["rollouts"]),
            rollout_sigma_m=ROLLOUT_SIGMA_M, slide_angles_deg=tuple(data["slides"]), slide_sigma_deg=SLIDE_SIGMA_DEG)
        truth_u = np.array(data["truth_u"])
        return truth_u, observations, bench_readings(parameters, unknowns, unknowns.to_values(truth_u), number,
                                                     readings), 0.0
    rng = np.random.default_rng([TRUTH_SEED, number])
    truth_u = rng.uniform(size=len(unknowns.names))
    truth = unknowns.to_values(truth_u)
    started = time.process_time()
    observations = launch_truth(parameters, unknowns, truth, matrix, TRUTH_SEED + 1000 * number)
    readings = bench_readings(parameters, unknowns, truth, number, characterise_truth(parameters, unknowns, truth, rng))
    cpu = time.process_time() - started
    if path:
        with open(path, "w", encoding="utf-8") as stream:
            json.dump({"truth_u": truth_u.tolist(), "slides": list(readings.slide_angles_deg),
                       "rollouts": [[r.surface, r.speed_mps, r.distance_m] for r in readings.rollouts],
                       "observations": [[o.configuration, o.height_m, o.speed_mps, o.angle_deg, o.upright,
                                         [o.outcomes[k] for k in learnt.OUTCOMES]] for o in observations]}, stream)
    return truth_u, observations, readings, cpu


def calibrate_truth(likelihood, parameters, unknowns, matrix, number, steps, temperature, cache, walkers=16,
                    start_draws=500, outcomes=None, rollouts=True, tips=True, weighing=True, grid_points=None,
                    gate_points=None):
    """One truth of step 3 in a worker process: its data (:func:`truth_data`), then the posterior of every
    unknown. ``gate_points``: (bias, other) grid points of the speed gate's exact term
    (:mod:`~rollability_ros.core.campaign.likelihood_gate`; None = without it). Returns a dict: the truth, the
    normalised samples, times (the gate's table, built once per worker, apart), and the learnt P(upright) at the
    truth of each launch."""
    truth_u, observations, readings, simulated_cpu = truth_data(parameters, unknowns, matrix, number, cache)
    table_cpu = 0.0
    if gate_points:
        table_cpu = time.process_time()
        gate = likelihood_gate.gate_term(observations, launch_twin_settings_from_parameters(parameters), unknowns,
                                         *gate_points)
        table_cpu = time.process_time() - table_cpu
    started, cpu = time.perf_counter(), time.process_time()
    if not rollouts:
        readings = dataclasses.replace(readings, rollouts=())
    if not tips:
        readings = dataclasses.replace(readings, tips=())
    if not weighing:
        readings = dataclasses.replace(readings, masses=())
    extra = sampling.characterisation_term(
        readings, launch_twin_settings_from_parameters(rollout_parameters(parameters)), unknowns, grid_points)
    if gate_points:
        readings_term = extra

        def extra(u):
            return readings_term(u) + gate(u)
    posterior = sampling.sample_posterior(likelihood, observations, extra=extra, seed=number + 1, steps=steps,
                                          temperature=temperature, walkers=walkers, start_draws=start_draws,
                                          outcomes=outcomes)
    truth = unknowns.to_values(truth_u)
    predicted = [float(likelihood.predict_upright_probability(
        truth[None, :], o.configuration, (o.height_m, o.speed_mps, o.angle_deg))[0]) for o in observations]
    return {"truth_u": truth_u, "normalised": posterior.normalised, "wall_s": time.perf_counter() - started,
            "cpu_s": time.process_time() - cpu, "simulated_cpu_s": simulated_cpu, "table_cpu_s": table_cpu,
            "launches": len(observations),
            "predicted": predicted, "observed": [o.upright for o in observations], "load": os.getloadavg()[0]}


def coverage(likelihood, parameters, unknowns, matrix, args, pool):
    """Step 3 (module docstring), the truths calibrated in ``pool``'s workers; returns the first truth
    calibrated, its observations and characterisation (for the CLI check)."""
    d = len(unknowns.names)
    hits = np.zeros(d)
    split = 0
    widths: list = [[] for _ in range(d)]
    ranks: list = [[] for _ in range(d)]
    walls, cpus, simulated, tables, predicted, observed = [], [], [], [], [], []
    started = time.perf_counter()
    count = args.truths
    # the truths whose launches an earlier run kept come first (their calibrations start at once)
    order = sorted(range(args.first_truth, args.first_truth + count),
                   key=lambda n: not os.path.exists(os.path.join(args.cache, f"truth-{n}.json")))
    jobs = pool.map(calibrate_truth, [likelihood] * count, [parameters] * count, [unknowns] * count,
                    [matrix] * count, order, [args.steps] * count, [args.temperature] * count,
                    [args.cache] * count, [args.walkers] * count, [args.start_draws] * count,
                    [args.outcome_names] * count, [not args.no_rollouts] * count, [not args.no_tips] * count,
                    [not args.no_weighing] * count, [args.grid_points] * count, [args.gate_points] * count)
    for done, (number, result) in enumerate(zip(order, jobs)):
        truth_u = result["truth_u"]
        truth = unknowns.to_values(truth_u)
        walls.append(result["wall_s"])
        cpus.append(result["cpu_s"])
        simulated.append(result["simulated_cpu_s"])
        tables.append(result["table_cpu_s"])
        predicted += result["predicted"]
        observed += result["observed"]
        parts = []
        for i, name in enumerate(unknowns.names):
            sets = sampling.credible_set(result["normalised"][:, i])
            inside = any(lo <= truth_u[i] <= hi for lo, hi in sets)
            hits[i] += inside
            widths[i].append(sum(hi - lo for lo, hi in sets))
            split += len(sets) > 1
            thinned = result["normalised"][:: max(1, len(result["normalised"]) // 99), i][:99]
            ranks[i].append(int(np.sum(thinned < truth_u[i])))
            shown = [(float(learnt.values_one(unknowns, i, lo)), float(learnt.values_one(unknowns, i, hi)))
                     for lo, hi in sets]
            parts.append(f"{name.split('.')[-1]} {truth[i]:.4g} {'in' if inside else 'OUT'} "
                         f"{sampling.format_set(shown)}")
        print(f"truth {number} ({done + 1} of {count}): {result['launches']} valid launches (simulated in "
              f"{result['simulated_cpu_s']:.0f} CPU s), calibration {result['wall_s']:.1f} s wall, "
              f"{result['cpu_s']:.1f} CPU s [worker's load {result['load']:.1f}]; " + "; ".join(parts)
              + f"; so far covered {', '.join(str(int(h)) for h in hits)} of {done + 1}", flush=True)
    n = count
    print(f"{n} truths in {time.perf_counter() - started:.0f} s wall on {args.workers} workers [{load()}]")
    readings = ", ".join(name for name, used in (("slide angles", True), ("roll-outs", not args.no_rollouts),
                                                 ("tip angles", not args.no_tips),
                                                 ("profile weighings", not args.no_weighing),
                                                 ("the speed gate's exact term", args.gate)) if used)
    print(f"calibration of {d} unknowns from the paper's {len(matrix)} launches plus characterisation ({readings}) "
          f"(outcomes: {args.outcomes}; {likelihood.ensemble_size} members x {args.walkers} walkers x {args.steps} "
          f"sampler steps, temperature "
          f"{likelihood.temperature if args.temperature is None else args.temperature:g}): median "
          f"{np.median(walls):.1f} s wall ({np.median(cpus):.1f} CPU s), max {max(walls):.1f} s wall over {n} truths "
          f"(target <= 180 s); simulating a truth's launches {np.median(simulated):.0f} CPU s (median)"
          + (f"; the gate's table {max(tables):.0f} CPU s once per worker" if args.gate else ""))
    for i, name in enumerate(unknowns.names):
        print(f"coverage {name}: {int(hits[i])}/{n} = {hits[i] / n:.0%} of the 95% sets hold the truth (target >= "
              f"90%); width median {np.median(widths[i]):.0%}, max {max(widths[i]):.0%} of the range "
              f"({'log' if unknowns.log_scale[i] else 'linear'} scale; target < 25%); SBC rank chi-squared p = "
              f"{rank_p_value(ranks[i], 99):.2f}; ranks per fifth {np.histogram(ranks[i], 5, (0, 100))[0].tolist()}")
    print(f"split 95% sets (printed as unions, never as the hull): {split} of {n * d}")
    p, y = np.array(predicted), np.array(observed, dtype=float)
    base = y.mean()
    print(f"learnt P(upright) on these {len(y)} fresh launches at their truths: Brier {np.mean((p - y) ** 2):.4f} "
          f"(constant {np.mean((base - y) ** 2):.4f}); log loss "
          f"{-np.mean(y * np.log(p) + (1 - y) * np.log1p(-p)):.4f} (constant "
          f"{-np.mean(y * np.log(base) + (1 - y) * np.log1p(-base)):.4f}); predicted mean {p.mean():.3f} vs "
          f"observed {base:.3f}")
    table = learning.reliability(p, y)
    print("reliability on them (deciles of the predicted P: predicted / observed / launches): "
          + ", ".join(f"{a:.2f}/{b:.2f}/{c}" for a, b, c in table))
    truth_u, observations, readings, _ = truth_data(parameters, unknowns, matrix, order[0], args.cache)
    return unknowns.to_values(truth_u), observations, readings


def write_csv(observations, path):
    """The observations as an outcome CSV (docs/outcome-csv.md): verdict, gate speed, final orientation (imu)."""
    from rollability_ros.core.records import LaunchCondition, LaunchOutcome
    from rollability_ros.core.results import write_outcome_csv

    outcomes: list = []
    counts: dict = {}
    for o in observations:
        key = (o.configuration, o.height_m, o.speed_mps, o.angle_deg)
        counts[key] = counts.get(key, -1) + 1
        tilt = math.radians(o.outcomes["final_tilt_deg"])
        condition = LaunchCondition(*key, repetition=counts[key])
        outcomes.append(LaunchOutcome("truth", f"t{len(outcomes)}", condition, "physical", o.upright,
                                      measured_speed_mps=float(o.outcomes["measured_speed_mps"]),
                                      final_orientation=(math.sin(tilt / 2), 0.0, 0.0, math.cos(tilt / 2)),
                                      classified_by="imu"))
    write_outcome_csv(path, outcomes)


def cli_check(likelihood_path, first, unknowns, folder, parameters, args):
    """Step 4 (module docstring)."""
    import yaml

    truth, observations, bench_readings = first
    csv_path = os.path.join(folder, "truth.csv")
    write_csv(observations, csv_path)
    config = os.path.join(folder, "bench.yaml")
    fixed = {name: float(value) for name, value in zip(unknowns.names, truth) if name not in CLI_UNKNOWNS}
    from rollability_ros.core.config import section

    with open(config, "w", encoding="utf-8") as stream:   # the designs, and the truth's other unknowns as known
        yaml.safe_dump({"/**": {"ros__parameters": section({
            **fixed, "sim.engine": parameters["sim.engine"],
            "launch_twin.designs.mesh_labels": list(parameters["launch_twin.designs.mesh_labels"]),
            "launch_twin.designs.mesh_files": list(parameters["launch_twin.designs.mesh_files"])}, "")}}, stream)
    slide, tip = os.path.join(folder, "slide.yaml"), os.path.join(folder, "slide-tip.yaml")
    readings = {"format": "rollability-characterisation-1", "slide_angle": {
        "sigma_deg": SLIDE_SIGMA_DEG, "readings_deg": [float(a) for a in bench_readings.slide_angles_deg]}}
    with open(slide, "w", encoding="utf-8") as stream:
        yaml.safe_dump(readings, stream)
    with open(tip, "w", encoding="utf-8") as stream:
        yaml.safe_dump({**readings, "tip_angle": {"sigma_deg": TIP_SIGMA_DEG, "readings": [
            {"side": t.side, "angle_deg": float(t.angle_deg)} for t in bench_readings.tips]}}, stream)
    runs = [("launches only", []), ("with the slide angles", ["--characterisation", slide])]
    if bench_readings.tips and not args.no_tips:
        runs.append(("with the slide and tip angles", ["--characterisation", tip]))
    for label, extra in runs:
        out = tempfile.mkdtemp(prefix=f"cli-{runs.index((label, extra))}-", dir=folder)   # a fresh folder per run
        command = [sys.executable, "-m", "rollability_ros.cli", "calibrate", "--physical", csv_path, "--run", "truth",
                   "--likelihood", likelihood_path, "--config", config, "--out", out,
                   *(["--temperature", str(args.temperature)] if args.temperature is not None else []),
                   *(["--sampler-steps", str(args.steps)] if args.smoke else []),
                   *[arg for name in CLI_UNKNOWNS for arg in ("--fit", name)], *extra]
        started = time.perf_counter()
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))   # this checkout, as the bench imports
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))}
        done = subprocess.run(command, capture_output=True, text=True, check=False, env=env)
        wall = time.perf_counter() - started
        if done.returncode != 0:
            print(f"rollability calibrate ({label}) FAILED: {done.stderr.strip().splitlines()[-1:]}")
            continue
        import csv

        with open(os.path.join(out, "parameters.csv"), encoding="utf-8") as stream:
            rows = {row["parameter"]: row for row in csv.DictReader(stream)}
        parts = []
        for name in CLI_UNKNOWNS:
            i = unknowns.names.index(name)
            row = rows[name]
            sets = [tuple(map(float, part.strip(" []").split(","))) for part in row["set"].split(" U ")]
            inside = any(lo <= truth[i] <= hi for lo, hi in sets)
            parts.append(f"{name} truth {truth[i]:.4g} set {row['set']} ({'holds' if inside else 'MISSES'} it, "
                         f"width {float(row['set_width_fraction']):.0%} of the range)")
        print(f"rollability calibrate --likelihood, 2 unknowns, {label}: {wall:.0f} s (target <= 300 s) [{load()}]; "
              + "; ".join(parts), flush=True)


def reoptimize(likelihood, parameters, unknowns, first, args, folder):
    """Step 5 (module docstring): calibrate on the first truth, then bench_recalibrate's optimisation on both twins
    and validation on the truth."""
    from bench.bench_recalibrate import reoptimise_and_validate

    truth, observations, bench_readings = first
    extra = sampling.characterisation_term(
        bench_readings, launch_twin_settings_from_parameters(rollout_parameters(parameters)), unknowns)
    posterior = sampling.sample_posterior(likelihood, observations, extra=extra, seed=7, steps=args.steps,
                                          temperature=args.temperature)
    fitted = {name: posterior.median(name) for name in unknowns.names}
    options = argparse.Namespace(popsize=8, generations=args.reoptimize_generations, trials=24, screen=16,
                                 optimizer_seed=args.reoptimize_seed, validate=args.validate, workers=args.workers)
    reoptimise_and_validate(options, unknowns, truth, fitted, folder)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--prepare-launches", type=int, default=8000, help="twin launches of the preparation")
    parser.add_argument("--members", type=int, default=learnt.MEMBERS, help="networks of the ensemble")
    parser.add_argument("--truths", type=int, default=50, help="hidden truths of the coverage (>= 50 for the claim)")
    parser.add_argument("--first-truth", type=int, default=0,
                        help="number of the first hidden truth (truths K..K+N-1: e.g. a held-out set to choose a "
                        "temperature on, apart from the truths it is then measured on)")
    parser.add_argument("--steps", type=int, default=200, help="sampler steps per calibration and ensemble member")
    parser.add_argument("--walkers", type=int, default=16, help="sampler walkers per ensemble member")
    parser.add_argument("--start-draws", type=int, default=500,
                        help="prior draws the best walkers start from, per member")
    parser.add_argument("--outcomes", default="all",
                        help="continuous outcomes the calibrations use: all, none (the verdicts and the "
                        "characterisation alone) or names of likelihood.OUTCOMES, comma-separated")
    parser.add_argument("--no-rollouts", action="store_true",
                        help="leave the roll-outs out of the calibrations (the slide angles stay)")
    parser.add_argument("--no-tips", action="store_true",
                        help="leave the tilt-table tip angles out of the calibrations and of the CLI check")
    parser.add_argument("--no-weighing", action="store_true",
                        help="leave the profiles' weighings out of the calibrations")
    parser.add_argument("--gate", action="store_true",
                        help="weigh the speed gate's readings through the twin's tabulated launcher model (exact, "
                        "never tempered; core/campaign/likelihood_gate.py) instead of the learnt gate outcome")
    parser.add_argument("--temperature", type=float, help="the launches' log-likelihood exponent (default: the "
                        "prepared file's: 0.25, the one chosen on held-out truths, for a file prepared now or "
                        "before files recorded theirs; docs/calibration.md's runs at 1 passed none, before this default: pass "
                        "--temperature 1 to repeat them)")
    parser.add_argument("--engine", default="mujoco", choices=("mujoco", "pybullet"),
                        help="the twin's engine (sim.engine) for the preparation and the truths")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--likelihood", help="a prepared likelihood file to load instead of preparing")
    parser.add_argument("--keep", help="folder to keep the prepared likelihood, the designs and the truths' "
                        "simulated launches in (a re-run with the same folder reuses them)")
    parser.add_argument("--skip-cli", action="store_true")
    parser.add_argument("--skip-adaptive", action="store_true")
    parser.add_argument("--skip-reoptimize", action="store_true")
    parser.add_argument("--reoptimize-generations", type=int, default=15)
    parser.add_argument("--reoptimize-seed", type=int, default=3)
    parser.add_argument("--validate", type=int, default=96, help="launches per design on the truth")
    parser.add_argument("--smoke", action="store_true", help="every step at a tiny size (the numbers mean nothing): "
                        "160 training launches, 2 ensemble members, 2 truths, 8 walkers x 20 sampler steps, no re-optimisation")
    args = parser.parse_args(argv)
    args.outcome_names = (None if args.outcomes == "all" else () if args.outcomes == "none"
                          else tuple(args.outcomes.split(",")))
    unknown = set(args.outcome_names or ()) - set(learnt.OUTCOMES)
    if unknown:
        parser.error(f"--outcomes: unknown {sorted(unknown)} (known: {', '.join(learnt.OUTCOMES)})")
    args.grid_points = None   # the characterisation's tables: posterior.characterisation_term's default
    args.gate_points = (likelihood_gate.BIAS_POINTS, likelihood_gate.OTHER_POINTS) if args.gate else None
    if args.smoke:   # the sampler's and the tables' smallest sizes, the pool's workers started once each
        args.prepare_launches, args.members, args.truths, args.steps = 160, 2, 2, 20
        args.walkers, args.start_draws, args.grid_points, args.workers = 8, 32, 4, 1
        args.gate, args.gate_points = True, (2, 2)   # the gate's term, at its smallest table
        args.skip_reoptimize, args.adaptive_samples = True, 200
    else:
        args.adaptive_samples = 4000
    if args.gate and (args.outcome_names is None or "measured_speed_mps" in args.outcome_names):
        # the gate's reading is weighed once, by the exact term
        args.outcome_names = tuple(n for n in (args.outcome_names or learnt.OUTCOMES) if n != "measured_speed_mps")
    from rollability_ros.core.sim import spawn_pool

    with tempfile.TemporaryDirectory() as scratch:
        folder = args.keep or scratch
        os.makedirs(folder, exist_ok=True)
        args.cache = folder
        parameters, unknowns, configurations = bench_parameters(folder)
        parameters["sim.engine"] = args.engine
        levels, matrix = paper_matrix(configurations)
        if args.smoke:
            matrix = matrix[::20]
        fingerprint = learnt.twin_fingerprint(parameters, unknowns.names)
        print(f"the {args.engine} twin (simulated throughout); unknowns {', '.join(unknowns.names)}", flush=True)
        pool = spawn_pool(args.workers)
        try:
            path = args.likelihood or os.path.join(folder, "likelihood.npz")
            if args.likelihood or os.path.exists(path):
                likelihood = learnt.load_likelihood(path)
                if likelihood.fingerprint != fingerprint or likelihood.unknowns != unknowns:
                    raise SystemExit(f"{path}: prepared for another twin, design set or unknowns' bounds")
                print(f"loaded {path}: {likelihood.info}")
            else:
                started = time.perf_counter()
                training = learnt.simulate_training_set(launch_twin_settings_from_parameters(parameters), unknowns,
                                                        configurations, levels, args.prepare_launches, PREPARE_SEED,
                                                        pool)
                simulated = time.perf_counter() - started
                print(f"preparation: {args.prepare_launches} launches simulated in {simulated:.0f} s wall "
                      f"({simulated / args.prepare_launches * 1000 * args.workers:.0f} ms per launch per worker) "
                      f"[{load()}]", flush=True)
                likelihood = learning.learn(training, unknowns, configurations, levels, fingerprint, on_progress=print,
                                          members=args.members, pool=pool)
                likelihood.info["prepare_s"] = time.perf_counter() - started
                likelihood.save(path)
                print(f"preparation: learning {time.perf_counter() - started - simulated:.0f} s wall; total "
                      f"{time.perf_counter() - started:.0f} s wall on {args.workers} workers (target <= 900 s) "
                      f"[{load()}]", flush=True)
            first = coverage(likelihood, parameters, unknowns, matrix, args, pool)
            if not args.skip_adaptive:
                rng = np.random.default_rng(TRUTH_SEED)
                adaptive_comparison(likelihood, unknowns.to_values(rng.uniform(size=(args.truths, len(unknowns.names)))),
                                    configurations, levels, args.adaptive_samples)
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
        if not args.skip_cli:
            cli_check(path, first, unknowns, folder, parameters, args)
        if not args.skip_reoptimize:
            reoptimize(likelihood, parameters, unknowns, first, args, folder)
    return 0


if __name__ == "__main__":
    sys.exit(main())
