"""Racing inside the optimizer: does the raced run find as good a design on a fraction of the trials? (simulated)

    nice python bench/bench_racing.py [--config optimizer] [--seeds 1 2 3 4 5] [--looks 10 20 40] [--alpha 0.1]
                                      [--survivors 0] [--set optimizer.trials=60 ...] [--raced-set ...] [--fresh-trials 300]
                                      [--workers 2] [--rule-only] [--smoke]

For every seed, one optimization with every candidate on all of its ``optimizer.trials`` (the full budget) and one
with sequential racing (``optimizer.race_looks`` = ``--looks``, ``optimizer.race_alpha`` = ``--alpha``, successive halving
``optimizer.race_survivors`` = ``--survivors``; docs/engines.md),
the same settings otherwise (``--config`` plus the ``--set`` overrides; the engine ``--engine``, early decision on).
Each run's final design (the incumbent, the best-so-far) is then evaluated on ``--fresh-trials`` fresh trials, the
two designs of a seed on the same fresh seed, never one the run saw. Prints per seed and pooled over the seeds: the
fresh fitness of both designs with its 95% Wilson interval, the raced minus full difference with Newcombe's 95%
interval, the trials each run spent (population, stages and re-evaluations) and their ratio, and whether the raced
design's pooled fresh fitness lies within the full-budget design's interval while spending at most a third of the
trials. Everything is from this one run; the load average is printed. First it prints the rule's exact statistics
(no simulation): for bars 0.3, 0.5, 0.7 and candidates 0 to 0.3 below them, the chance of a stop and the expected
trials, and with ``--survivors`` the halving's trial bound and the chance that a candidate better than the rest of
its generation is dropped at the first look (``--rule-only``: only that); last, what other looks and levels would have spent on the full-budget runs'
own candidates (:func:`print_what_if`, an approximation).
"""
import argparse
import os
import sys
import tempfile
import time

import numpy as np
import yaml
import typing

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from rollability_ros.core.optimization import optimization_run  # noqa: E402
from rollability_ros.core.optimization import batch_evaluation, run_directory  # noqa: E402
from rollability_ros.core.stats import newcombe_interval, wilson_interval  # noqa: E402
from rollability_ros.core.store import Store  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402

FRESH_SEED_BASE = 7_310_000          # far from every optimizer seed stream: the fresh trials are never the run's


def parse_set(items):
    """``["a.b=1", ...]`` -> ``{"a.b": 1}`` (values parsed as YAML)."""
    overrides = {}
    for item in items:
        name, _, value = item.partition("=")
        if not name or not _:
            raise SystemExit(f"--set takes name=value, got {item!r}")
        overrides[name] = yaml.safe_load(value)
    return overrides


def run_parameters(args, racing):
    parameters = run_directory.load_run_parameters(args.config)
    parameters.update({"sim.engine": args.engine, "trial.early_decision": True, **parse_set(args.set)})
    parameters["optimizer.race_looks"] = list(args.looks) if racing else [0]
    parameters["optimizer.race_alpha"] = args.alpha
    parameters["optimizer.race_survivors"] = args.survivors if racing else 0
    if racing:
        parameters.update(parse_set(args.raced_set))
    return parameters


def optimize(parameters, seed, executor, folder, name, reuse=False):
    """Run one optimization (``reuse``: resume the run kept in ``folder``, which ends at once when it is complete);
    return (best heights, trials spent, generations, wall s, settings, stopped candidates' trials, run folder)."""
    parameters = {**parameters, "optimizer.seed": seed}
    settings = evaluation.settings_from_parameters(parameters)
    trials = optimization_run.run_settings(parameters).optimizer.trials
    run_dir = os.path.join(folder, f"{name}-seed-{seed}")
    run = optimization_run.OptimizationRun(
        run_dir, optimization_run.run_config(parameters), settings.grid, batch_evaluation.profile_batch_evaluator(settings, trials, executor),
        evaluate_trials=batch_evaluation.fidelity_batch_evaluator(settings, executor, "screen"),
        resume=reuse and os.path.exists(run_dir))
    started = time.perf_counter()
    try:
        result = run.run()
    finally:
        run.close()
    seconds = time.perf_counter() - started
    popsize, trials = optimization_run.run_settings(parameters).optimizer.popsize, \
        optimization_run.run_settings(parameters).optimizer.trials
    with Store(run_dir) as store:
        candidates = store.candidates()
    spent = sum(c.trials for c in candidates)
    stopped = sorted(c.trials for c in candidates if c.index < popsize and c.trials < trials)
    assert result.best is not None, "the run evaluated no generation"
    return result.best.heights, spent, result.generations, seconds, settings, stopped, run_dir


def executor_of(workers):
    """A pool of ``workers`` processes, or this process (``workers`` 0)."""
    return evaluation.LocalExecutor(workers) if workers else evaluation.SerialExecutor()


def interval_text(successes, trials):
    low, high = wilson_interval(successes, trials)
    return f"{successes / trials:.3f} [{low:.2f}, {high:.2f}]"


def print_rule_statistics(looks, trials, alpha, bars=(0.3, 0.5, 0.7), gaps=(0.0, 0.05, 0.1, 0.2, 0.3)):
    """The rule's exact statistics (:func:`racing.sequential_stop_probability`, no simulation): for a candidate whose
    true success rate is ``gap`` below the bar, the chance it is stopped and its expected trials."""
    from rollability_ros.core.optimization import racing

    print(f"the rule, exactly (looks {list(looks)} of {trials} trials, alpha {alpha}): P(stopped) / expected trials "
          f"of a candidate whose true rate is the bar minus the gap")
    print("| bar | " + " | ".join(f"gap {gap:.2f}" for gap in gaps) + " |")
    print("|---|" + "---|" * len(gaps))
    for bar in bars:
        cells = []
        for gap in gaps:
            stopped, spent = racing.sequential_stop_probability(looks, trials, bar, alpha, max(0.0, bar - gap))
            cells.append(f"{stopped:.3f} / {spent:.1f}")
        print(f"| {bar:.1f} | " + " | ".join(cells) + " |")


def print_halving_statistics(looks, trials, survivors, popsize, rates=(0.2, 0.5), gaps=(0.05, 0.1, 0.2)):
    """Successive halving's fixed cost (:func:`racing.halving_trials`) and, exactly, the chance that one candidate
    ``gap`` better than the other ``popsize - 1`` (all at ``rate``) is dropped at the first look
    (:func:`racing.halving_drop_probability`: independent counts, the conservative case)."""
    from rollability_ros.core.optimization import racing

    first = looks[0]
    bound = racing.halving_trials(popsize, looks, trials, survivors)
    print(f"successive halving: at most {bound} of {popsize * trials} population trials per generation "
          f"({bound / (popsize * trials):.2f}x; {survivors} of {popsize} go on after the first look at {first}); "
          f"chance that a candidate better by the gap than the other {popsize - 1} is dropped at the first look "
          f"(independent counts; common random numbers lower it)")
    print("| rate of the others | " + " | ".join(f"gap {gap:.2f}" for gap in gaps) + " |")
    print("|---|" + "---|" * len(gaps))
    for rate in rates:
        cells = [f"{racing.halving_drop_probability(first, survivors, popsize - 1, rate, gap):.3f}" for gap in gaps]
        print(f"| {rate:.1f} | " + " | ".join(cells) + " |")


def print_first_look_agreement(run_dirs, settings, executor, first, survivors, popsize):
    """How well the halving's first look ranks, measured on the full-budget runs' own generations: each candidate's
    first ``first`` trials are run again (the same seed and trial indices as its stored evaluation, so the same
    trials: common random numbers), the ``survivors`` best by them (ties to the earlier, as the rule) are compared
    with the generation's best by its full trials (the candidate CMA-ES would have made the challenger). Prints the
    share of generations whose full-trial best would have gone on, against chance (survivors / popsize), and the mean
    rank correlation of the two rankings."""
    from scipy.stats import spearmanr

    evaluate = batch_evaluation.fidelity_batch_evaluator(settings, executor, "screen")
    kept = generations = 0
    rhos = []
    for run_dir in run_dirs:
        with Store(run_dir) as store:
            candidates = [c for c in store.candidates() if c.index < popsize]
        by_generation: typing.Dict[int, typing.List[typing.Any]] = {}   # generation -> its candidates
        for candidate in candidates:
            by_generation.setdefault(candidate.generation, []).append(candidate)
        for generation, members in sorted(by_generation.items()):
            members.sort(key=lambda c: c.index)
            looks = evaluate([list(c.heights) for c in members], members[0].seed, first)
            early = [r[0] for r in looks]
            order = list(range(len(members)))
            going_on = sorted(order, key=lambda i: (-early[i], i))[:survivors]
            best = max(order, key=lambda i: (members[i].successes, -i))
            kept += best in going_on
            generations += 1
            if len(set(early)) > 1 and len({c.successes for c in members}) > 1:
                rhos.append(spearmanr(early, [c.successes for c in members])[0])
    print(f"first look, measured on the full-budget runs' {generations} generations (their first {first} trials "
          f"again, common random numbers): the full-trial best would have gone on in {kept}/{generations} = "
          f"{kept / max(1, generations):.2f} (chance {survivors / popsize:.2f}); rank correlation of the first look "
          f"with the full trials, mean Spearman {np.mean(rhos) if rhos else float('nan'):+.2f} over {len(rhos)} "
          f"generations")


WHAT_IF_RULES = (([10, 20, 40], 0.1), ([10, 20, 40], 0.3), ([10, 20], 0.5), ([5, 10, 15, 20, 30, 40], 0.9))
#: The same at ``--smoke``'s 4 trials per candidate (the last rule's looks all come too late: that line too).
SMOKE_WHAT_IF_RULES = (([2], 0.1), ([1, 2, 3], 0.9), ([10, 20], 0.5))


def print_what_if(run_dirs, popsize, trials, rules=WHAT_IF_RULES):
    """What other rules would have spent on the full-budget runs' own candidates: each candidate's rate over its
    full trials taken as its true rate, the bar from the previous generation's best-so-far as if over 2 x trials
    (the incumbent's pooled trials are not stored; it has at least two evaluations), the rule's exact expected
    trials (:func:`racing.sequential_stop_probability`); re-evaluations unchanged. An approximation, stated so.
    A rule's looks at or past the runs' ``trials`` per candidate are left out (a look must come before the end)."""
    from rollability_ros.core.optimization import racing

    for rule_looks, alpha in rules:
        looks = [look for look in rule_looks if look < trials]
        if not looks:
            print(f"what if: looks {rule_looks} all come at or after the runs' {trials} trials: not applicable")
            continue
        full = spent = 0.0
        for run_dir in run_dirs:
            with Store(run_dir) as store:
                best = {g.generation: g.best_so_far for g in store.generations()}
                for candidate in store.candidates():
                    full += candidate.trials
                    if candidate.index >= popsize or candidate.generation - 1 not in best:
                        spent += candidate.trials
                        continue
                    bar = racing.sequential_bar(round(best[candidate.generation - 1] * 2 * candidate.trials),
                                                2 * candidate.trials)
                    spent += racing.sequential_stop_probability(looks, candidate.trials, bar, alpha,
                                                                candidate.fitness)[1]
        print(f"what if (the full-budget runs' candidates, approximate): looks {looks}, alpha {alpha}: expected "
              f"{spent / full:.2f}x the trials")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="optimizer", help="shipped config name or path (default: the quick one)")
    parser.add_argument("--set", nargs="*", default=[], help="parameter overrides name=value")
    parser.add_argument("--raced-set", nargs="*", default=[],
                        help="overrides of the raced run only (e.g. --looks 0 --raced-set optimizer.trials=20: the "
                             "same share of the trials spent evenly, without racing)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--looks", type=int, nargs="+", default=[10, 20, 40])
    parser.add_argument("--alpha", type=float, default=0.1)
    parser.add_argument("--survivors", type=int, default=0,
                        help="successive halving: candidates going on after each look (0: off)")
    parser.add_argument("--engine", default="mujoco")
    parser.add_argument("--fresh-trials", type=int, default=300)
    parser.add_argument("--workers", type=int, default=2, help="worker processes (0: in this process)")
    parser.add_argument("--keep", help="folder to keep the runs in (default: a temporary one)")
    parser.add_argument("--raced-name", default="raced", help="name of the raced runs' folders (with --keep)")
    parser.add_argument("--reuse", action="store_true",
                        help="with --keep: resume the runs kept there (a complete run ends at once)")
    parser.add_argument("--rule-only", action="store_true", help="only the rule's exact statistics (no runs)")
    parser.add_argument("--first-look-from", metavar="FOLDER",
                        help="only the first-look agreement, on the full-budget runs kept in FOLDER by --keep")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers "
                                                             "mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    if args.smoke:   # two seeds (the over-seeds interval), two generations of 2 x 4 trials, a look at 2, halving
        # to one; in this process
        args.seeds, args.looks, args.survivors, args.fresh_trials, args.workers = [1, 2], [2], 1, 2, 0
        args.set = [*args.set, "optimizer.popsize=2", "optimizer.trials=4", "optimizer.max_generations=2",
                    "optimizer.initial_mean_screen=0", "optimizer.stagnation_generations=0",
                    "quality_diversity.emitters=1"]
    full_parameters, raced_parameters = run_parameters(args, False), run_parameters(args, True)
    settings = optimization_run.run_settings(raced_parameters).optimizer
    settings.validate()
    if settings.race_stages is not None:
        print_rule_statistics(args.looks, settings.trials, args.alpha)
    if args.survivors:
        print_halving_statistics(args.looks, settings.trials, args.survivors, settings.popsize)
    if args.rule_only:
        return 0
    if args.first_look_from:
        full_runs = sorted(os.path.join(args.first_look_from, name) for name in os.listdir(args.first_look_from)
                           if name.startswith("full-seed-"))
        if not full_runs or not args.survivors:
            raise SystemExit(f"--first-look-from needs --survivors and full-budget runs (full-seed-*) in "
                             f"{args.first_look_from}")
        with executor_of(args.workers) as executor:
            print_first_look_agreement(full_runs, evaluation.settings_from_parameters(full_parameters), executor,
                                       args.looks[0], args.survivors, settings.popsize)
        return 0
    print(f"racing verification (simulated): --config {args.config} {' '.join(args.set)}, engine {args.engine} + "
          f"early decision, {settings.method}, popsize {settings.popsize}, {settings.trials} trials per candidate, "
          f"at most {settings.max_generations} generations; racing looks {list(args.looks)} alpha {args.alpha} survivors "
          f"{args.survivors}; "
          f"{args.fresh_trials} fresh trials per final design; cores {os.cpu_count()}", flush=True)
    rows, full_runs = [], []
    scratch = tempfile.TemporaryDirectory(prefix="bench-racing-")   # removed when main returns
    folder = args.keep or scratch.name
    started = time.perf_counter()
    with executor_of(args.workers) as executor:
        executor.warm()
        for seed in args.seeds:
            row = {"seed": seed}
            for name, parameters in (("full", full_parameters), ("raced", raced_parameters)):
                heights, spent, generations, seconds, evaluator_settings, stopped, run_dir = optimize(
                    parameters, seed, executor, folder, name if name == "full" else args.raced_name,
                    reuse=args.reuse)
                if name == "full":
                    full_runs.append(run_dir)
                fresh = evaluation.evaluate_profile(heights, args.fresh_trials, FRESH_SEED_BASE + seed,
                                                    evaluator_settings, executor)
                row[name] = {"spent": spent, "generations": generations, "seconds": seconds,
                             "fresh": (fresh.successes, fresh.trials), "stopped": stopped}
            rows.append(row)
            full, raced = row["full"], row["raced"]
            _, low, high = newcombe_interval(*raced["fresh"], *full["fresh"])
            print(f"seed {seed}: full {interval_text(*full['fresh'])} ({full['spent']} trials, "
                  f"{full['generations']} generations, {full['seconds']:.0f} s) | raced {interval_text(*raced['fresh'])} "
                  f"({raced['spent']} trials, {raced['generations']} generations, {raced['seconds']:.0f} s) | "
                  f"raced - full {(raced['fresh'][0] - full['fresh'][0]) / args.fresh_trials:+.3f} [{low:+.2f}, "
                  f"{high:+.2f}] | trials {raced['spent'] / full['spent']:.2f}x; candidates stopped at a look (their "
                  f"trials): {len(raced['stopped'])} {raced['stopped'][:12]}{' ...' if len(raced['stopped']) > 12 else ''}"
                  f" | load average "
                  f"{os.getloadavg()[0]:.1f}", flush=True)
    pooled = {name: (sum(r[name]["fresh"][0] for r in rows), sum(r[name]["fresh"][1] for r in rows))
              for name in ("full", "raced")}
    spent = {name: sum(r[name]["spent"] for r in rows) for name in ("full", "raced")}
    full_low, full_high = wilson_interval(*pooled["full"])
    _, low, high = newcombe_interval(*pooled["raced"], *pooled["full"])
    raced_fitness = pooled["raced"][0] / pooled["raced"][1]
    ratio = spent["raced"] / spent["full"]
    print()
    print("| seed | full budget: fresh fitness [95% CI] | trials | raced: fresh fitness [95% CI] | trials | raced/full "
          "trials | raced - full [Newcombe 95% CI] |")
    print("|---|---|---|---|---|---|---|")
    for row in rows:
        full, raced = row["full"], row["raced"]
        _, d_low, d_high = newcombe_interval(*raced["fresh"], *full["fresh"])
        print(f"| {row['seed']} | {interval_text(*full['fresh'])} | {full['spent']:,} | "
              f"{interval_text(*raced['fresh'])} | {raced['spent']:,} | {raced['spent'] / full['spent']:.2f} | "
              f"{(raced['fresh'][0] - full['fresh'][0]) / full['fresh'][1]:+.3f} [{d_low:+.2f}, {d_high:+.2f}] |")
    print(f"| pooled | {interval_text(*pooled['full'])} | {spent['full']:,} | {interval_text(*pooled['raced'])} | "
          f"{spent['raced']:,} | {ratio:.2f} | {raced_fitness - pooled['full'][0] / pooled['full'][1]:+.3f} "
          f"[{low:+.2f}, {high:+.2f}] |")
    differences = [(r["raced"]["fresh"][0] / r["raced"]["fresh"][1] - r["full"]["fresh"][0] / r["full"]["fresh"][1])
                   for r in rows]
    if len(differences) > 1:
        from scipy.stats import t as student

        half = student.ppf(0.975, len(differences) - 1) * np.std(differences, ddof=1) / np.sqrt(len(differences))
        print(f"over seeds (each seed's two runs are two trajectories of the search, so their spread counts): mean "
              f"raced - full {np.mean(differences):+.3f}, 95% t-interval [{np.mean(differences) - half:+.3f}, "
              f"{np.mean(differences) + half:+.3f}] over {len(differences)} seeds")
    within = full_low <= raced_fitness <= full_high
    print(f"raced design's pooled fresh fitness {raced_fitness:.3f} {'within' if within else 'OUTSIDE'} the full-budget "
          f"design's interval [{full_low:.3f}, {full_high:.3f}]; trials {ratio:.2f}x of the full budget "
          f"({'at most' if ratio <= 1 / 3 else 'MORE than'} a third); wall {time.perf_counter() - started:.0f} s, "
          f"load average {' '.join(f'{v:.1f}' for v in os.getloadavg())} (simulated)")
    print_what_if(full_runs, settings.popsize, optimization_run.run_settings(full_parameters).optimizer.trials,
                  SMOKE_WHAT_IF_RULES if args.smoke else WHAT_IF_RULES)
    if args.survivors:
        with executor_of(args.workers) as executor:
            print_first_look_agreement(full_runs, evaluation.settings_from_parameters(full_parameters), executor,
                                       args.looks[0], args.survivors, settings.popsize)
    return 0


if __name__ == "__main__":
    sys.exit(main())
