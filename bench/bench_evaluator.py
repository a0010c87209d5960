"""Benchmark of the rollability evaluator; every ratio is measured in this one run.

    python bench/bench_evaluator.py [--trials 60] [--repeats 3]

Prints: trials/s on one core, simulated steps per trial, wall time of one evaluation with 1 and 2 workers and
the speed-up (target >= 1.7x), the evaluator's overhead over raw ``stepSimulation`` of the same scenes
(target <= 1.25x) with the world-building share, and the peak resident memory of each worker process.
"""
import argparse
import os
import statistics
import sys
import time
import typing

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from rollability_ros.core.sim import evaluation  # noqa: E402
from rollability_ros.core.profile.geometry import grid_xy  # noqa: E402
from rollability_ros.core.optional import require  # noqa: E402
from rollability_ros.core.sim.world import connect, disconnect  # noqa: E402
from rollability_ros.core.sim.trials import TrialWorld, place_on_ground, sample_conditions  # noqa: E402


def dome_heights(grid):
    """A representative profile (test_physics' dome): trials roll, bounce and settle."""
    xy = grid_xy(grid)
    ny, nx = xy[:, 1] / (grid.width_m / 2), xy[:, 0] / (grid.length_m / 2)
    return np.clip(grid.height_max * (1 - 0.5 * ny ** 2 - 0.5 * nx ** 2), 0.0, grid.height_max)


def raw_stepping_s(job, outcomes):
    """Time only the physics of each trial: its steps (with the same push) in the same restored scene.

    Returns (raw stepping s, one world build s, restore + placement s per trial).
    """
    pybullet = require("pybullet")
    settings = job.settings
    client = connect()
    stepping = restoring = 0.0
    try:
        started = time.perf_counter()
        world = TrialWorld(client, settings.robot_model(), job.profile, settings.trial, settings.physics)
        building = time.perf_counter() - started
        body, dt = world.robot.body_id, settings.physics.time_step_s
        push_start = round(settings.trial.disturbance_delay_s / dt)
        push_end = push_start + round(settings.trial.disturbance_duration_s / dt)
        for outcome in outcomes:
            conditions = sample_conditions(outcome.seed, settings.trial)
            started = time.perf_counter()
            pybullet.restoreState(world.saved_state, physicsClientId=client)
            place_on_ground(client, body, conditions.orientation, settings.trial.drop_height_m)
            restoring += time.perf_counter() - started
            force, torque = conditions.force_n.tolist(), conditions.torque_nm.tolist()
            started = time.perf_counter()
            for step in range(outcome.steps):
                if push_start <= step < push_end:
                    centre, _ = pybullet.getBasePositionAndOrientation(body, physicsClientId=client)
                    pybullet.applyExternalForce(body, -1, force, centre, pybullet.WORLD_FRAME, physicsClientId=client)
                    pybullet.applyExternalTorque(body, -1, torque, pybullet.WORLD_FRAME, physicsClientId=client)
                pybullet.stepSimulation(physicsClientId=client)
            stepping += time.perf_counter() - started
    finally:
        disconnect(client)
    return stepping, building, restoring / len(outcomes)


def peak_rss_mb(pid):
    """Peak resident memory (VmHWM) of process ``pid`` in MB (Linux)."""
    with open(f"/proc/{pid}/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def timed_evaluations(heights, trials, settings, worker_counts, repeats):
    """Fastest of ``repeats`` evaluations on a warm pool per entry of ``worker_counts`` (interleaved, so load
    from other processes hits every configuration alike); also every worker's peak RSS (MB)."""
    pools = [evaluation.LocalExecutor(workers) for workers in worker_counts]
    try:
        pids = [pid for pool in pools for pid in pool.warm()]
        times: typing.List[typing.List[float]] = [[] for _ in pools]
        for repeat in range(repeats):
            for pool, record in zip(pools, times):
                record.append(evaluation.evaluate_profile(heights, trials, 100 + repeat, settings,
                                                          executor=pool).eval_time_s)
        memory = [peak_rss_mb(pid) for pid in pids]
    finally:
        for pool in pools:
            pool.close()
    return [min(record) for record in times], memory


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    settings = evaluation.load_settings()
    heights = dome_heights(settings.grid)
    job = evaluation.profile_job(heights, settings)

    evaluation.run_batch(job, [])  # start this process's client and world outside the timing
    serial_times, trial_times, raw_times = [], [], []
    for repeat in range(args.repeats):  # interleaved repeats, fastest kept: the machine may be shared
        started = time.perf_counter()
        result = evaluation.evaluate_profile(heights, args.trials, 100 + repeat, settings)
        serial_times.append(time.perf_counter() - started)
        outcomes = result.trial_results
        started = time.perf_counter()
        evaluation.run_batch(job, [(o.index, o.seed) for o in outcomes])  # the world is built: trials only
        trial_times.append(time.perf_counter() - started)
        stepping_s, building_s, restore_s = raw_stepping_s(job, outcomes)
        raw_times.append(stepping_s)
        if repeat == 0:
            steps = [o.steps for o in outcomes]
    serial_s = min(serial_times)
    overheads = [trial / raw for trial, raw in zip(trial_times, raw_times)]
    (one_s, two_s), memory = timed_evaluations(heights, args.trials, settings, (1, 2), args.repeats)

    print(f"profile: dome, {args.trials} trials, fitness {result.fitness:.3f}, cores {os.cpu_count()}, "
          f"load average {os.getloadavg()[0]:.2f} (other processes compete for the cores above ~0)")
    print(f"trials/s per core (serial, in process)   {args.trials / serial_s:8.1f}")
    print(f"steps per trial mean / median / max      {np.mean(steps):8.1f} / {np.median(steps):.0f} / {max(steps)}"
          f"   (time cap {round(settings.trial.time_cap_s / settings.physics.time_step_s)})")
    print(f"wall time of one evaluation, serial      {serial_s:8.3f} s")
    print(f"wall time of one evaluation, 1 worker    {one_s:8.3f} s")
    print(f"wall time of one evaluation, 2 workers   {two_s:8.3f} s")
    print(f"speed-up 2 workers vs 1                  {one_s / two_s:8.2f} x   (target >= 1.7)")
    print(f"overhead vs raw stepSimulation           {statistics.median(overheads):8.3f} x   (target <= 1.25; "
          f"repeats {', '.join(f'{o:.3f}' for o in overheads)}); raw {min(raw_times) / sum(steps) * 1e6:.1f} us/step")
    print(f"world: build once per profile {building_s * 1e3:.2f} ms, restore + place per trial {restore_s * 1e3:.3f} ms "
          f"(a fresh world per trial would add {building_s / (min(trial_times) / len(steps)):.0%} to a trial)")
    print(f"peak RSS per worker                      {', '.join(f'{m:.0f}' for m in memory)} MB")


if __name__ == "__main__":
    main()
