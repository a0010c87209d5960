"""Benchmark of the trial engines (PyBullet, MuJoCo) and the early decision; every ratio from this one run.

    nice python bench/bench_engines.py [--trials 60] [--repeats 3] [--launch-candidates 3] [--launches-only]
                                       [--racing-generations 8] [--race-looks 10 20 40] [--race-alpha 0.1]
                                       [--racing-only] [--smoke]

Launch twin (first): twin launches per second per core in each engine, with and without the early decision, and
the ratio to the PyBullet twin under the full rest rule (the twin before the MuJoCo twin and the launch early
decision existed) on the same launches: ``--launch-candidates`` candidates (the dome and random profiles on the
built-in chassis), each launched under the paper's 20 launch conditions (``config/campaign.yaml``) with the
launch objective's seeds, in one process; every candidate's world is built anew (the model and early-decision
caches are cleared), as for a new candidate of an optimization. Repeats are interleaved, the fastest kept.

Prints, for the dome profile on the built-in chassis: trials/s per core of the evaluator for each engine with
and without the early decision, steps per trial, the ratio to a naive loop of each engine written here (the
same robot URDF and start states; a world built once, reset per trial, a plain per-step rest check on the base
speed, the engine's default contacts), the speed-up of 2 workers over 1 on the fastest engine, and the
projected wall time of the paper-scale optimization (500 generations x 13 evaluations x 60 trials) on 2 cores,
from one profile's trials and from whole paper-config generations submitted as the optimizer does (each candidate
run whole by one worker, and split into ``evaluator.batch_trials`` tasks as before), and last the paper-scale run
with racing projected from whole generations of two real optimizations on the paper's config, with and without
``optimizer.race_looks``, stepped alternately (:func:`racing_generation_times`).
Repeats are interleaved and the fastest kept (the machine may be shared); the load average is printed.
"""
import argparse
import dataclasses
import math
import os
import sys
import time
import typing

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from bench.bench_evaluator import dome_heights  # noqa: E402
from rollability_ros.core.optional import require  # noqa: E402
from rollability_ros.core.robots.urdf_robot import obj_text, profile_inertia  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402
from rollability_ros.core.sim.mujoco_trials import pose_speeds  # noqa: E402
from rollability_ros.core.sim.trials import sample_conditions  # noqa: E402

PAPER_TRIALS = 500 * 13 * 60


def launch_rates(candidates, repeats, conditions=None):
    """Twin launches per second per core (one process) for each (engine, early decision), steps per launch and
    upright launches, the same launches in every variant (see the module docstring); the first ``conditions`` of the
    paper's (default all)."""
    from rollability_ros.core.robots.robot import ProfileBody
    from rollability_ros.core.profile.geometry import profile_mesh
    from rollability_ros.core.campaign_matrix import load_campaign_spec
    from rollability_ros.core.sim.launch import mujoco_twin, pybullet_twin, settings as twin_settings, twin
    from rollability_ros.core.sim.objectives import launch_conditions

    base = evaluation.load_settings()
    rng = np.random.default_rng(31)
    grid = base.grid
    heights = [dome_heights(grid)] + [rng.uniform(grid.height_min, grid.height_max, grid.n_variables)
                                      for _ in range(candidates - 1)]
    meshes = [profile_mesh(h, grid) for h in heights]
    profiles = [base.profile_body(mesh) for mesh in meshes if mesh is not None]   # a dome, random heights: none flat
    conditions = launch_conditions(load_campaign_spec(("campaign",)))[:conditions]
    shipped = twin_settings.load_launch_twin_settings()
    variants = {(engine, early): dataclasses.replace(
        shipped, physics=dataclasses.replace(shipped.physics, engine=engine),
        trial=dataclasses.replace(shipped.trial, early_decision=early))
        for engine in ("pybullet", "mujoco") for early in (False, True)}
    twin.simulate_launch(conditions[0], variants[("mujoco", False)], 0, use_profile=True)   # imports
    times: typing.Dict[typing.Any, typing.List[float]] = {key: [] for key in variants}
    cpu: typing.Dict[typing.Any, typing.List[float]] = {key: [] for key in variants}
    steps, upright = {}, {}
    for repeat in range(repeats):
        for key, settings in variants.items():
            mujoco_twin._cache.clear()     # every candidate builds its world, as in an optimization
            pybullet_twin._BASINS.clear()
            outcomes = []
            started, cpu_started = time.perf_counter(), time.process_time()
            for candidate, profile in enumerate(profiles):
                for index, condition in enumerate(conditions):
                    outcomes.append(twin.simulate_valid_launch(
                        condition, settings, evaluation.trial_seed(500 + candidate, index), profile=profile,
                        use_profile=True))
            times[key].append(time.perf_counter() - started)
            cpu[key].append(time.process_time() - cpu_started)
            steps[key] = np.mean([o.steps for o in outcomes])
            upright[key] = sum(o.valid and o.upright for o in outcomes)
    launches = len(profiles) * len(conditions)
    return ({key: launches / min(seconds) for key, seconds in times.items()},
            {key: launches / min(seconds) for key, seconds in cpu.items()}, steps, upright, launches, len(conditions))


def print_launch_rates(candidates, repeats, conditions=None):
    """Print the launch twin's table (module docstring): per core = launches per second of this process's CPU
    time (what one core gives when the machine is shared), with the wall-clock rate beside it."""
    wall, rate, steps, upright, launches, paper = launch_rates(candidates, repeats, conditions)
    today, today_wall = rate[("pybullet", False)], wall[("pybullet", False)]
    print(f"launch twin: {candidates} candidates x {paper} paper conditions = {launches} launches per variant, "
          f"{repeats} repeats (fastest kept), one process; load average {os.getloadavg()[0]:.2f}")
    print(f"{'twin':34s} {'launches/s/core':>15s} {'vs PyBullet twin':>16s} {'wall launches/s':>15s} "
          f"{'(ratio)':>8s} {'steps/launch':>12s} {'upright':>7s}")
    for key, value in rate.items():
        engine, early = key
        print(f"{engine + (' + early decision' if early else ' (full rest rule)'):34s} {value:15.2f} "
              f"{value / today:15.2f}x {wall[key]:15.2f} {wall[key] / today_wall:7.2f}x {steps[key]:12.1f} "
              f"{upright[key]:7d}")
    best = max(rate, key=rate.get)
    print(f"best: {best[0]}{' + early decision' if best[1] else ''} at {rate[best] / today:.2f}x today's PyBullet "
          f"twin (full rest rule, per CPU second) on the same launches (target >= 5x, aim 10x)")


def configured(settings, engine, early_decision):
    """``settings`` with ``physics.engine`` and ``trial.early_decision`` set."""
    return dataclasses.replace(settings, physics=dataclasses.replace(settings.physics, engine=engine),
                               trial=dataclasses.replace(settings.trial, early_decision=early_decision))


def naive_pybullet(job, seeds, hold_steps, cap_steps):
    """A plain PyBullet loop: the URDF loaded once, state restored per trial, rest = base speed below the
    thresholds for ``hold_steps`` consecutive steps. Returns (seconds, steps per trial)."""
    import tempfile
    pybullet = require("pybullet")
    settings = job.settings
    client = pybullet.connect(pybullet.DIRECT)
    try:
        pybullet.setGravity(0, 0, settings.physics.gravity_mps2, physicsClientId=client)
        pybullet.setTimeStep(settings.physics.time_step_s, physicsClientId=client)
        plane = pybullet.createMultiBody(0, pybullet.createCollisionShape(pybullet.GEOM_PLANE, physicsClientId=client),
                                         physicsClientId=client)
        with tempfile.TemporaryDirectory() as folder:
            _, hull = profile_inertia(job.profile)
            with open(os.path.join(folder, "p.obj"), "w", encoding="utf-8") as stream:
                stream.write(obj_text(hull))
            with open(os.path.join(folder, "r.urdf"), "w", encoding="utf-8") as stream:
                stream.write(settings.robot_model().simulator_urdf(job.profile, "p.obj"))
            body = pybullet.loadURDF(os.path.join(folder, "r.urdf"), [0, 0, 0.3], physicsClientId=client)
        for link in range(-1, pybullet.getNumJoints(body, physicsClientId=client)):
            pybullet.changeDynamics(body, link, lateralFriction=0.35, rollingFriction=0.01, spinningFriction=0.02,
                                    restitution=0.3, physicsClientId=client)
        del plane
        saved = pybullet.saveState(physicsClientId=client)
        return _naive_loop(seeds, settings, hold_steps, cap_steps, pybullet_engine(pybullet, client, body, saved))
    finally:
        pybullet.disconnect(physicsClientId=client)


def pybullet_engine(pybullet, client, body, saved):
    """Callbacks of the naive PyBullet loop: reset(orientation), push(force, torque), step(), speeds()."""
    def reset(orientation):
        pybullet.restoreState(saved, physicsClientId=client)
        pybullet.resetBasePositionAndOrientation(body, [0, 0, 0.2], orientation, physicsClientId=client)

    def push(force, torque):
        centre, _ = pybullet.getBasePositionAndOrientation(body, physicsClientId=client)
        pybullet.applyExternalForce(body, -1, force, centre, pybullet.WORLD_FRAME, physicsClientId=client)
        pybullet.applyExternalTorque(body, -1, torque, pybullet.WORLD_FRAME, physicsClientId=client)

    def step():
        pybullet.stepSimulation(physicsClientId=client)

    def speeds():
        linear, angular = pybullet.getBaseVelocity(body, physicsClientId=client)
        return math.hypot(*linear), math.hypot(*angular)

    return reset, push, step, speeds


def naive_mujoco(job, seeds, hold_steps, cap_steps):
    """A plain MuJoCo loop on the same URDF with a free joint, the wheel drag and MuJoCo's default contacts."""
    mujoco = require("mujoco")
    settings = job.settings
    _, hull = profile_inertia(job.profile)
    spec = mujoco.MjSpec.from_string(settings.robot_model().simulator_urdf(job.profile, "p.obj"),
                                     assets={"p.obj": obj_text(hull).encode()})
    spec.option.timestep = settings.physics.time_step_s
    for joint in spec.joints:  # the unpowered drives' drag (free wheels would roll a pushed robot away forever)
        joint.frictionloss = settings.robot_model().joint_drag_torque_nm()
    spec.worldbody.first_body().add_freejoint()
    ground = spec.worldbody.add_geom()
    ground.type = mujoco.mjtGeom.mjGEOM_PLANE
    ground.size = [0, 0, 1]
    model = spec.compile()
    data = mujoco.MjData(model)
    root = 1

    def reset(orientation):
        mujoco.mj_resetData(model, data)
        x, y, z, w = orientation
        data.qpos[0:7] = [0, 0, 0.2, w, x, y, z]

    def push(force, torque):
        data.xfrc_applied[root, 0:3] = force
        data.xfrc_applied[root, 3:6] = torque

    previous = [data.qpos[0:7].copy()]

    def step():
        previous[0] = data.qpos[0:7].copy()
        mujoco.mj_step(model, data)
        data.xfrc_applied[root] = 0.0

    def speeds():  # from poses: MuJoCo 4 may put a body at rest to sleep, freezing its pose but not its qvel
        return pose_speeds(previous[0], data.qpos[0:7], model.opt.timestep)

    return _naive_loop(seeds, settings, hold_steps, cap_steps, (reset, push, step, speeds))


def _naive_loop(seeds, settings, hold_steps, cap_steps, engine):
    reset, push, step, speeds = engine
    trial, dt = settings.trial, settings.physics.time_step_s
    push_start = round(trial.disturbance_delay_s / dt)
    push_end = push_start + round(trial.disturbance_duration_s / dt)
    linear_limit, angular_limit = trial.rest_linear_speed_mps, math.radians(trial.rest_angular_speed_dps)
    total_steps = 0
    started = time.perf_counter()
    for seed in seeds:
        conditions = sample_conditions(seed, trial)
        reset(conditions.orientation)
        force, torque = conditions.force_n.tolist(), conditions.torque_nm.tolist()
        still = 0
        for steps in range(1, cap_steps + 1):
            if push_start <= steps - 1 < push_end:
                push(force, torque)
            step()
            linear, angular = speeds()
            still = still + 1 if steps > push_end and linear < linear_limit and angular < angular_limit else 0
            if still >= hold_steps:
                break
        total_steps += steps
    return time.perf_counter() - started, total_steps / len(seeds)


def generation_times(base, fastest, generations, pool, candidates=13, trials=60):
    """Fastest wall time (s) of a paper-config generation (``candidates`` 13, sigma 0.02 around a random mean,
    ``trials`` 60 each, common seed) evaluated as the optimizer does (one thread per candidate on ``pool``, a warm
    2-worker pool): ``{"split": ..., "whole": ...}``, each candidate split into ``evaluator.batch_trials`` tasks
    (every worker builds its world) or run whole by one worker (what ``profile_batch_evaluator`` does with >= 2
    candidates per worker)."""
    from rollability_ros.core.optimization.batch_evaluation import profile_batch_evaluator

    engine, early = fastest
    paper = evaluation.load_settings(("sim", "robot", "evaluator", "paper"))
    settings = configured(paper, engine, early)
    rng = np.random.default_rng(20)
    grid = settings.grid
    mean = rng.uniform(grid.height_min, grid.height_max, grid.n_variables)
    populations = [[np.clip(mean + rng.normal(0.0, 0.02, mean.size), grid.height_min, grid.height_max)
                    for _ in range(candidates)] for _ in range(generations)]
    times: typing.Dict[str, typing.List[float]] = {"split": [], "whole": []}
    evaluators = {"whole": profile_batch_evaluator(settings, trials, pool),
                  "split": _split_evaluator(settings, pool, trials)}
    for index, population in enumerate(populations):   # interleaved, so both meet the same machine load
        for name, evaluate in evaluators.items():
            started = time.perf_counter()
            evaluate(population, 300 + index)
            times[name].append(time.perf_counter() - started)
    return {name: min(seconds) for name, seconds in times.items()}


def racing_generation_times(generations, looks, alpha, pool, overrides=None):
    """Whole paper-config generations of two real optimizations (``config/paper.yaml`` with ``overrides``, MuJoCo +
    early decision, the same seed) on ``pool``, one without racing and one with ``optimizer.race_looks`` =
    ``looks``, their generations stepped alternately so both meet the same machine load: ``{name: (seconds per
    generation, trials per generation)}`` over the generations after the first (the first has no incumbent, so
    nothing races)."""
    import tempfile

    from rollability_ros.core.optimization import optimization_run
    from rollability_ros.core.optimization import batch_evaluation, run_directory
    from rollability_ros.core.store import Store

    scratch = tempfile.TemporaryDirectory(prefix="bench-racing-paper-")   # removed when this returns
    folder = scratch.name
    parameters = run_directory.load_run_parameters(["paper"])
    parameters.update({"sim.engine": "mujoco", "trial.early_decision": True, "optimizer.output_dir": folder,
                       "optimizer.race_alpha": alpha, **(overrides or {})})
    settings = evaluation.settings_from_parameters(parameters)
    trials = optimization_run.run_settings(parameters).optimizer.trials
    times: typing.Dict[str, typing.List[float]] = {"full": [], "raced": []}
    runs = {}
    for name, race_looks in (("full", [0]), ("raced", list(looks))):
        run_parameters = {**parameters, "optimizer.race_looks": race_looks}
        runs[name] = optimization_run.OptimizationRun(
            os.path.join(folder, name), optimization_run.run_config(run_parameters), settings.grid,
            batch_evaluation.profile_batch_evaluator(settings, trials, pool),
            evaluate_trials=batch_evaluation.fidelity_batch_evaluator(settings, pool, "screen"))
    try:
        for _ in range(generations):
            for name, run in runs.items():
                started = time.perf_counter()
                run.step()
                times[name].append(time.perf_counter() - started)
    finally:
        for run in runs.values():
            run.close()
    result = {}
    for name in runs:
        with Store(os.path.join(folder, name)) as store:
            spent = [c.trials for c in store.candidates() if c.generation > 1]
        result[name] = (float(np.mean(times[name][1:])), sum(spent) / max(1, generations - 1))
    return result


def print_racing_projection(generations, looks, alpha, pool, overrides=None):
    seconds = racing_generation_times(generations, looks, alpha, pool, overrides)
    full, raced = seconds["full"], seconds["raced"]
    print(f"paper-scale run with racing (config/paper.yaml, MuJoCo + early decision, 2 workers, race_looks "
          f"{list(looks)}, race_alpha {alpha}; generations 2-{generations} of two real runs stepped alternately, "
          f"simulated):")
    for name, (per_generation, trials) in seconds.items():
        print(f"  {name:5s}: {per_generation:.2f} s and {trials:.0f} trials per generation -> 500 generations "
              f"{500 * per_generation / 60:.1f} min")
    print(f"  racing: {raced[1] / full[1]:.2f}x the trials, {full[0] / raced[0]:.2f}x faster generations; projected "
          f"paper-scale run with racing {500 * raced[0] / 60:.1f} min (target <= 4 min; load average "
          f"{' '.join(f'{v:.1f}' for v in os.getloadavg())})")


def _split_evaluator(settings, pool, trials):
    """A generation's candidates on ``pool``, each split into ``evaluator.batch_trials`` tasks (the optimizer's
    way before it ran candidates whole)."""
    import concurrent.futures

    def evaluate(population, seed):
        with concurrent.futures.ThreadPoolExecutor(len(population)) as threads:
            list(threads.map(lambda heights: evaluation.evaluate_profile(heights, trials, seed, settings, pool),
                             population))
    return evaluate


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--generations", type=int, default=4, help="paper-config generations timed per setting")
    parser.add_argument("--launch-candidates", type=int, default=3, help="candidates launched on the twin (x 20)")
    parser.add_argument("--launches-only", action="store_true", help="only the launch twin's table")
    parser.add_argument("--racing-generations", type=int, default=8,
                        help="paper-config generations of the racing projection (per run; 0 = skip it)")
    parser.add_argument("--race-looks", type=int, nargs="+", default=[10, 20, 40])
    parser.add_argument("--race-alpha", type=float, default=0.1)
    parser.add_argument("--racing-only", action="store_true", help="only the paper-scale racing projection")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers "
                                                             "mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    conditions, candidates, trials, racing = None, 13, 60, None
    if args.smoke:   # one candidate on two conditions, 2 trials, one repeat; generations of 2 candidates x 2 trials
        conditions, candidates, trials = 2, 2, 2
        args.launch_candidates, args.trials, args.repeats, args.generations = 1, 2, 1, 1
        args.racing_generations, args.race_looks = 2, [1]
        racing = {"optimizer.popsize": 2, "optimizer.trials": 2, "optimizer.initial_mean_screen": 0}
    if args.racing_only:
        with evaluation.LocalExecutor(2) as pool:
            pool.warm()
            print_racing_projection(args.racing_generations, args.race_looks, args.race_alpha, pool, racing)
        return 0
    print_launch_rates(args.launch_candidates, args.repeats, conditions)
    if args.launches_only:
        return 0
    base = evaluation.load_settings()
    heights = dome_heights(base.grid)
    variants = {(engine, early): configured(base, engine, early)
                for engine in ("pybullet", "mujoco") for early in (False, True)}
    jobs = {key: evaluation.profile_job(heights, settings) for key, settings in variants.items()}
    hold = round(base.trial.rest_hold_s / base.physics.time_step_s)
    cap = round(base.trial.time_cap_s / base.physics.time_step_s)
    times: typing.Dict[typing.Any, typing.List[float]] = {key: [] for key in list(jobs) + ["naive pybullet", "naive mujoco"]}
    steps: typing.Dict[typing.Any, float] = {}
    fitness: typing.Dict[typing.Any, float] = {}
    for key, job in jobs.items():  # build each world outside the timing
        evaluation.run_batch(job, [])
    for repeat in range(args.repeats):
        seeds = [evaluation.trial_seed(100 + repeat, index) for index in range(args.trials)]
        batch = list(enumerate(seeds))
        for key, job in jobs.items():
            evaluation.run_batch(job, [])  # the world of this job (the process keeps one)
            started = time.perf_counter()
            outcomes = evaluation.run_batch(job, batch)
            times[key].append(time.perf_counter() - started)
            steps[key] = float(np.mean([o.steps for o in outcomes]))
            fitness[key] = float(np.mean([o.upright for o in outcomes]))
        for name, loop in (("naive pybullet", naive_pybullet), ("naive mujoco", naive_mujoco)):
            seconds, mean_steps = loop(jobs[("pybullet", False)], seeds, hold, cap)
            times[name].append(seconds)
            steps[name] = mean_steps
    rate = {key: args.trials / min(record) for key, record in times.items()}
    print(f"dome profile, built-in chassis, {args.trials} trials x {args.repeats} repeats (fastest kept), "
          f"cores {os.cpu_count()}, load average {os.getloadavg()[0]:.2f} at the end")
    print(f"{'evaluator':34s} {'trials/s/core':>13s} {'steps/trial':>11s} {'fitness':>7s} {'vs naive loop':>13s}")
    for (engine, early) in jobs:
        print(f"{engine + (' + early decision' if early else ' (full rest rule)'):34s} "
              f"{rate[(engine, early)]:13.1f} {steps[(engine, early)]:11.1f} {fitness[(engine, early)]:7.3f} "
              f"{rate[(engine, early)] / rate['naive ' + engine]:12.2f}x")
    for name in ("naive pybullet", "naive mujoco"):
        print(f"{name + ' loop':34s} {rate[name]:13.1f} {steps[name]:11.1f}")
    fastest = max(jobs, key=lambda key: rate[key])
    print(f"fastest: {fastest[0]}{' + early decision' if fastest[1] else ''}: "
          f"{rate[fastest] / rate['naive mujoco']:.2f}x the naive MuJoCo loop's trials/s per core (target >= 1)")
    pools = {workers: evaluation.LocalExecutor(workers) for workers in (1, 2)}
    try:
        for pool in pools.values():
            pool.warm()
        pool_times: typing.Dict[int, typing.List[float]] = {workers: [] for workers in pools}
        for repeat in range(args.repeats):
            for workers, pool in pools.items():
                pool_times[workers].append(evaluation.evaluate_profile(
                    heights, args.trials, 200 + repeat, variants[fastest], executor=pool).eval_time_s)
        pools.pop(1).close()
        one, two = min(pool_times[1]), min(pool_times[2])
        print(f"one evaluation of {args.trials} trials: 1 worker {one:.3f} s, 2 workers {two:.3f} s, "
              f"speed-up {one / two:.2f}x")
        projected_min = PAPER_TRIALS / (args.trials / two) / 60
        print(f"projected paper-scale run (500 x 13 x 60 = {PAPER_TRIALS} trials) on 2 workers: {projected_min:.1f} "
              f"min (one profile's trials only; load average {os.getloadavg()[0]:.2f})")
        generation = generation_times(base, fastest, args.generations, pools[2], candidates, trials)
        for name, seconds in generation.items():
            print(f"paper-config generation ({candidates} candidates near a random mean x {trials} trials, 2 workers, "
                  f"each candidate {'run whole by one worker' if name == 'whole' else 'split into batch_trials tasks'}"
                  f"): {seconds:.2f} s -> 500 generations {500 * seconds / 60:.1f} min")
        print(f"whole candidates per worker: {generation['split'] / generation['whole']:.2f}x faster generations; "
              f"projected paper-scale run from generations: {500 * generation['whole'] / 60:.1f} min (target <= 15; "
              f"CMA-ES and the store excluded)")
        if args.racing_generations > 1:
            print_racing_projection(args.racing_generations, args.race_looks, args.race_alpha, pools[2], racing)
    finally:
        for pool in pools.values():
            pool.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
