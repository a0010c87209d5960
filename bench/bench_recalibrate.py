"""Calibrate -> re-optimise -> validate on a hidden truth, with a learnt likelihood (issue 44). Simulated throughout.

    nice python bench/bench_recalibrate.py --likelihood FILE [--truth-seed 1] [--generations 15] [--popsize 8]
        [--trials 24] [--validate 96] [--optimizer-seed 3] [--workers 2] [--keep DIR]
        [--outcomes none|all|NAMES] [--temperature 0.25] [--no-gate] [--no-tips] [--no-weighing]
        [--engine mujoco|pybullet]
    nice python bench/bench_recalibrate.py --prepare-launches 2048 --keep DIR     # prepare the likelihood first
    python bench/bench_recalibrate.py --smoke                                    # every step once, tiny

1. The twin of bench/bench_calibration.py: the bare robot and three designs (dome, flat top, low pyramid) and its
   five unknowns (centre of mass, foam friction, foam rolling friction, launcher speed bias, profile mass scale),
   on ``--engine`` (``sim.engine``, default mujoco as bench_calibration.py's, so its prepared files serve here:
   the truth's launches, the likelihood, both optimisations and the validation all on that engine).
   ``--likelihood FILE``: a likelihood prepared for exactly that twin (its fingerprint is checked; ``bench_calibration
   --keep DIR`` or ``--prepare-launches N --keep DIR`` here write one); without it one is prepared now from
   ``--prepare-launches`` twin launches.
2. A hidden truth drawn from the prior (uniform over the unknowns' normalised bounds, ``--truth-seed``), printed
   beside the shipped values.
3. The paper's 400 launches (4 configurations x 2 heights x 2 speeds x 5 angles x 5) launched on the twin at the
   truth, every continuous outcome kept, plus the bench readings of bench_calibration.py (its noise): five slide
   angles, three roll-outs, five tilt-table tip angles (``--no-tips``: left out) and a weighing of each design's
   profile (``--no-weighing``).
4. Calibrate as bench_calibration.py measured its coverage: the posterior of the five unknowns (the learnt
   likelihood, ``--steps`` sampler steps) from the verdicts (``--outcomes``: none by default, the learnt
   continuous outcomes are biased; all or NAME,NAME to weigh them), the bench readings, the speed gate's readings
   through the exact term (core/campaign/likelihood_gate.py; ``--no-gate``: left out), the launches' learnt term
   tempered by ``--temperature`` (default 0.25, the value chosen on held-out truths: docs/calibration.md); the
   calibrated twin takes each unknown's posterior median (calibrated.yaml, as `rollability calibrate` writes).
5. Re-optimise: bench_objective's launch-twin CMA-ES (3 x 3 grid, ``--popsize`` x ``--generations``, ``--trials``
   launches per candidate on 0.75 m x {0.8, 1.5} m/s x {-30, +30} deg, the same optimizer seed and start screen for
   both) once on the uncalibrated (shipped) twin and once on the calibrated twin; each run's best pooled design.
6. Validate: each design launched ``--validate`` times on the truth (fresh seeds, the same for both); the gain of
   the recalibrated design over the uncalibrated one with Newcombe's 95% interval, and both against the bare robot.

Cost at the defaults: 400 launches run to rest at the truth, one posterior (about a minute), 2 x 8 x 15 x 24 =
5,760 optimisation launches, 3 x 96 validation launches; every time printed with the load average. One truth and
one optimizer seed: the gain is that run's, its interval the validation launches' (bench_objective's 18-seed
study is the spread over optimizer runs).
"""
import argparse
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np  # noqa: E402


def load() -> str:
    """The 1-minute load average, for the line beside every timing."""
    return f"load {os.getloadavg()[0]:.1f}"


def prepared(args, parameters, unknowns, configurations, levels, folder, pool):
    """The learnt likelihood: ``--likelihood`` loaded (fingerprint and unknowns checked) or prepared now."""
    from rollability_ros.core.campaign import likelihood as learnt

    fingerprint = learnt.twin_fingerprint(parameters, unknowns.names)
    if args.likelihood:
        likelihood = learnt.load_likelihood(args.likelihood)
        if likelihood.fingerprint != fingerprint or likelihood.unknowns != unknowns:
            raise SystemExit(f"{args.likelihood}: prepared for another twin, design set or unknowns' bounds than "
                             "bench_calibration's (prepare it with --prepare-launches)")
        print(f"loaded {args.likelihood}: {likelihood.info.get('training_launches', '?')} training launches")
        return likelihood
    from bench.bench_calibration import PREPARE_SEED

    started = time.perf_counter()
    from rollability_ros.core.sim import launch_twin_settings_from_parameters

    training = learnt.simulate_training_set(launch_twin_settings_from_parameters(parameters), unknowns, configurations,
                                            levels, args.prepare_launches, PREPARE_SEED, pool)
    from rollability_ros.core.campaign import likelihood_learning

    likelihood = likelihood_learning.learn(training, unknowns, configurations, levels, fingerprint, on_progress=print,
                                           pool=pool, **({"members": 2} if args.smoke else {}))
    path = os.path.join(folder, f"likelihood-{args.prepare_launches}.npz")
    likelihood.save(path)
    print(f"prepared {path}: {args.prepare_launches} launches and learning in {time.perf_counter() - started:.0f} s "
          f"[{load()}]", flush=True)
    return likelihood


def calibrated_values(likelihood, parameters, unknowns, truth, matrix, seed, steps, pool, rng, sizes=None,
                      args=None):
    """Steps 3 and 4: the truth's launches and characterisation, the posterior, each unknown's median. ``sizes``:
    the sampler's walkers and start draws and the characterisation's table points (``--smoke``'s; default:
    :func:`posterior.sample_posterior`'s and :func:`posterior.characterisation_term`'s). ``args``: the
    command's ``outcomes``, ``temperature``, ``no_gate``, ``no_tips``, ``no_weighing`` (None: every outcome, the
    file's temperature, no gate, tips or weighings)."""
    import dataclasses

    from bench.bench_calibration import bench_readings, characterise_truth, launch_truth, rollout_parameters
    from rollability_ros.core.campaign import likelihood_gate
    from rollability_ros.core.campaign import posterior as sampling

    started = time.perf_counter()
    observations = launch_truth(parameters, unknowns, truth, matrix, seed)
    readings = characterise_truth(parameters, unknowns, truth, rng)
    if args is not None:
        readings = bench_readings(parameters, unknowns, truth, seed, readings)
        readings = dataclasses.replace(readings, **({"tips": ()} if args.no_tips else {}),
                                       **({"masses": ()} if args.no_weighing else {}))
    print(f"the truth's {len(matrix)} launches ({len(observations)} valid) and characterisation simulated in "
          f"{time.perf_counter() - started:.0f} s [{load()}]", flush=True)
    started = time.perf_counter()
    from rollability_ros.core.sim import launch_twin_settings_from_parameters

    sizes = sizes or {}
    bench = sampling.characterisation_term(readings, launch_twin_settings_from_parameters(rollout_parameters(parameters)),
                                           unknowns, sizes.get("grid_points"))
    gate = (likelihood_gate.gate_term(observations, launch_twin_settings_from_parameters(parameters), unknowns,
                                      *((3, 3) if "grid_points" in sizes else ()))
            if args is not None and not args.no_gate else None)

    def extra(u):
        return bench(u) + gate(u) if gate is not None else bench(u)
    outcomes = None if args is None or args.outcomes == "all" else () if args.outcomes == "none" else tuple(
        args.outcomes.split(","))
    if gate is not None and (outcomes is None or "measured_speed_mps" in outcomes):
        raise SystemExit("the gate's exact term and the learnt measured_speed_mps would weigh the same reading: "
                         "--no-gate, or --outcomes without measured_speed_mps")
    posterior = sampling.sample_posterior(likelihood, observations, extra=extra, seed=seed % 1000 + 1, steps=steps,
                                          outcomes=outcomes, temperature=None if args is None else args.temperature,
                                          **{k: v for k, v in sizes.items() if k != "grid_points"})
    print(f"readings: verdicts{'' if outcomes == () else ', learnt outcomes ' + ', '.join(outcomes or ['all'])}, "
          f"{len(readings.slide_angles_deg)} slide angles, {len(readings.rollouts)} roll-outs, {len(readings.tips)} tip "
          f"angles, {len(readings.masses)} weighings{', the gate readings (exact term)' if gate is not None else ''}; "
          f"temperature {likelihood.temperature if args is None or args.temperature is None else args.temperature:g}")
    fitted = {name: posterior.median(name) for name in unknowns.names}
    print(f"calibration of {len(unknowns.names)} unknowns: {time.perf_counter() - started:.0f} s [{load()}]")
    for i, name in enumerate(unknowns.names):
        sets = posterior.credible_set(name)
        inside = any(low <= truth[i] <= high for low, high in sets)
        print(f"  {name}: shipped {float(parameters[name]):.4g}, truth {truth[i]:.4g}, calibrated {fitted[name]:.4g}, "
              f"95% set {sampling.format_set(sets)} ({'holds' if inside else 'MISSES'} the truth)")
    return fitted


def reoptimise_and_validate(args, unknowns, truth, fitted, folder):
    """Steps 5 and 6 (module docstring); returns {label: (successes, trials)} on the truth."""
    import yaml

    from bench.bench_objective import CAMPAIGN, optimize, report_difference
    from rollability_ros.core.stats import newcombe_interval
    from rollability_ros.core.campaign import calibration
    from rollability_ros.core.sim import evaluation

    from rollability_ros.core.config import parameter_document

    files = {"engine": os.path.join(folder, "engine.yaml")}
    with open(files["engine"], "w", encoding="utf-8") as stream:
        yaml.safe_dump(parameter_document({"sim.engine": args.engine}), stream)
    for label, values in (("calibrated", fitted), ("truth", dict(zip(unknowns.names, map(float, truth))))):
        files[label] = os.path.join(folder, f"{label}.yaml")
        with open(files[label], "w", encoding="utf-8") as stream:
            yaml.safe_dump(calibration.calibrated_parameter_document(values), stream)
    campaign_file = os.path.join(folder, "objective-campaign.yaml")
    with open(campaign_file, "w", encoding="utf-8") as stream:
        yaml.safe_dump(CAMPAIGN, stream)
    options = argparse.Namespace(popsize=args.popsize, sigma0=0.1, generations=args.generations, trials=args.trials,
                                 screen=args.screen)
    scores = {}
    with evaluation.make_executor(evaluation.EvaluatorOptions(workers=args.workers)) as executor:
        designs = {}
        for label, twin in (("uncalibrated", (*calibration.TWIN_CONFIGS, files["engine"])),
                            ("calibrated", (*calibration.TWIN_CONFIGS, files["engine"], files["calibrated"]))):
            started = time.perf_counter()
            print(f"optimising on the {label} twin ({args.popsize} x {args.generations} generations x {args.trials} "
                  f"launches, optimizer seed {args.optimizer_seed})", flush=True)
            designs[label], settings = optimize(os.path.join(folder, f"run-{label}"), twin, campaign_file, options,
                                                args.optimizer_seed, executor)
            print(f"  {time.perf_counter() - started:.0f} s [{load()}]", flush=True)
        on_truth = evaluation.ObjectiveSettings(kind="launch_twin", campaign_config=[campaign_file],
                                                twin_config=[*calibration.TWIN_CONFIGS, files["engine"],
                                                             files["truth"]])
        truth_settings = evaluation.with_objective(settings, on_truth)   # reads the truth twin's files
        designs["bare robot"] = None   # no profile: the bare chassis
        for label, heights in designs.items():
            started = time.perf_counter()
            result = evaluation.evaluate_profile(heights, args.validate, 987_654_321, truth_settings, executor)
            scores[label] = (result.successes, result.trials)
            print(f"{label} design on the truth: {result.successes}/{result.trials} "
                  f"[{time.perf_counter() - started:.0f} s, {load()}]", flush=True)
    report_difference("calibrate -> re-optimise -> validate: ", scores["calibrated"], scores["uncalibrated"])
    for label in ("calibrated", "uncalibrated"):
        (k1, n1), (k2, n2) = scores[label], scores["bare robot"]
        _, low, high = newcombe_interval(k1, n1, k2, n2)
        print(f"  the {label} design against the bare robot on the truth: {k1}/{n1} - {k2}/{n2} = "
              f"{k1 / n1 - k2 / n2:+.2f} [{low:+.2f}, {high:+.2f}] (95%, Newcombe)")
    return scores


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--likelihood", help="a likelihood prepared for bench_calibration's twin")
    parser.add_argument("--prepare-launches", type=int, default=2048, help="without --likelihood: prepare one")
    parser.add_argument("--keep", help="folder for the designs, the prepared likelihood and the runs (default: temp)")
    parser.add_argument("--truth-seed", type=int, default=1)
    parser.add_argument("--steps", type=int, default=600, help="posterior sampler steps")
    parser.add_argument("--generations", type=int, default=8)
    parser.add_argument("--popsize", type=int, default=8)
    parser.add_argument("--trials", type=int, default=16, help="launches per candidate of the optimisation")
    parser.add_argument("--screen", type=int, default=16, help="random starts screened by the stable-pose screen")
    parser.add_argument("--optimizer-seed", type=int, default=3)
    parser.add_argument("--validate", type=int, default=96, help="launches per design on the truth")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--outcomes", default="none",
                        help="the learnt continuous outcomes weighed beside the verdicts: none (default), all, or "
                             "NAME,NAME")
    parser.add_argument("--temperature", type=float, default=0.25,
                        help="the launches' learnt log-likelihood raised to T (default 0.25: chosen on held-out "
                             "truths, docs/calibration.md)")
    parser.add_argument("--no-gate", action="store_true", help="leave out the speed gate's exact term")
    parser.add_argument("--engine", default="mujoco", choices=("mujoco", "pybullet"),
                        help="the twin's engine (sim.engine) throughout (default mujoco, as bench_calibration.py's)")
    parser.add_argument("--no-tips", action="store_true", help="leave out the tilt-table tip angles")
    parser.add_argument("--no-weighing", action="store_true", help="leave out the profiles' weighings")
    parser.add_argument("--smoke", action="store_true",
                        help="every step once at a tiny size (a 2-member likelihood from 64 launches, 40 truth "
                             "launches, 20 sampler steps of 8 walkers, one generation of 2 x 2 launches, 4 validation "
                             "launches, one worker): the numbers mean nothing")
    args = parser.parse_args(argv)
    if args.smoke:
        args.likelihood = None
        args.prepare_launches, args.steps, args.generations, args.popsize, args.trials = 64, 20, 1, 2, 2
        args.screen, args.validate, args.workers = 2, 4, 1
    sizes = {"walkers": 8, "start_draws": 32, "grid_points": 4} if args.smoke else None
    from bench.bench_calibration import TRUTH_SEED, bench_parameters, paper_matrix
    from rollability_ros.core.sim import spawn_pool

    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as scratch:
        folder = args.keep or scratch
        os.makedirs(folder, exist_ok=True)
        parameters, unknowns, configurations = bench_parameters(folder)
        parameters["sim.engine"] = args.engine
        levels, matrix = paper_matrix(configurations)
        if args.smoke:
            matrix = matrix[::10]
        rng = np.random.default_rng([TRUTH_SEED, args.truth_seed])
        truth = unknowns.to_values(rng.uniform(size=len(unknowns.names)))
        pool = spawn_pool(args.workers)
        try:
            likelihood = prepared(args, parameters, unknowns, configurations, levels, folder, pool)
            fitted = calibrated_values(likelihood, parameters, unknowns, truth, matrix,
                                       TRUTH_SEED + 7_000 + args.truth_seed, args.steps, pool, rng, sizes, args)
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
        reoptimise_and_validate(args, unknowns, truth, fitted, folder)
    print(f"calibrate -> re-optimise -> validate: {time.perf_counter() - started:.0f} s in all on {args.workers} "
          f"workers [{load()}]; simulated")
    return 0


if __name__ == "__main__":
    sys.exit(main())
