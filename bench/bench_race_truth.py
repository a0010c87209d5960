"""What the launch race had to choose from: every raced elite of finished studies measured again, at length.

    nice python bench/bench_race_truth.py STUDY_DIR [STUDY_DIR ...] [--nominal 100] [--robust 100] [--workers 2]
    python bench/bench_race_truth.py --smoke

For each study (a ``rollability study`` folder, e.g. ``transfer-bench/runs/seed-1`` of ``bench/bench_transfer.py``)
the elites its selection raced (``designs/archive.csv``: screen and race columns; heights from the run's archive)
and the bare robot get ``--nominal`` launches on the PyBullet twin under the campaign's nominal conditions (the
campaign's measure: the 20 launch conditions, no draw of the unknowns; other seeds than the campaign's) and
``--robust`` fresh robust launches (the race's measure). Printed per study: each raced elite's screen, race and
the two fresh counts, the race's label (A/B/C), Spearman's rho between the measures, and what the race chose
against what it could have chosen: A's nominal count beside the survivors' and all raced elites' best, and what a
final race round of ``--final-launches`` more robust launches for the ``--keep`` best survivors would pick
(Monte Carlo on the measured rates). A long
measurement of the race's candidates says whether the race's choice or the candidates themselves limit A's
campaign gain. All numbers are simulated. ``--smoke`` makes its own study folder first (:func:`smoke_study`: one
generation of the quick study's quality-diversity search and its selection with the race, at bench/smoke.py's
sizes) and measures it with one launch of each kind.
"""
import argparse
import csv
import dataclasses
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

import numpy as np  # noqa: E402

from rollability_ros.core.optimization import batch_evaluation, run_directory  # noqa: E402
from rollability_ros.core.profile import geometry  # noqa: E402
from rollability_ros.core.stats import spearman_permutation_test  # noqa: E402
from rollability_ros.core.store import Store  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402

#: Base seeds of the two fresh measurements (any seeds the study did not use).
NOMINAL_SEED, ROBUST_SEED = 777001, 777002


def raced_elites(study_dir):
    """``(rows, heights)``: the archive.csv rows of the raced elites and their heights, in the archive's order."""
    run_dir = os.path.join(study_dir, "optimization")
    run_id = run_directory.run_id_of(run_dir)
    with Store(run_dir) as store:
        archive = ((store.run_info(run_id) or {}).get("info") or {}).get("archive")
    if not archive:
        raise SystemExit(f"bench_race_truth: {run_dir} has no quality-diversity archive")
    elites = [e for e in archive["elites"] if not geometry.is_baseline(e["heights"])]
    with open(os.path.join(run_dir, "designs", "archive.csv"), newline="", encoding="utf-8") as stream:
        rows = list(csv.DictReader(stream))
    if len(rows) != len(elites):
        raise SystemExit(f"bench_race_truth: {run_dir}: archive.csv has {len(rows)} rows for {len(elites)} elites")
    raced = [i for i, row in enumerate(rows) if row.get("race_round1_trials")]
    if not raced:
        raise SystemExit(f"bench_race_truth: {run_dir}: no elite was raced (selection.race_launches [0]?)")
    return [rows[i] for i in raced], [np.asarray(elites[i]["heights"], float) for i in raced]


def fresh_counts(study_dir, heights, nominal, robust, executor):
    """``{"nominal": [(s, n), ...], "robust": [...]}`` of ``heights`` and then the bare robot, on the PyBullet twin
    (the launch fidelity's engine) with the study's own settings; nominal = the unknowns not drawn."""
    parameters = run_directory.read_run_config(os.path.join(study_dir, "optimization"))
    launch = evaluation.settings_at_fidelity(evaluation.settings_from_parameters(parameters), "launch")
    # run at the screen fidelity with the launch fidelity's objective and engine: exactly these settings
    launch = dataclasses.replace(launch, objective=dataclasses.replace(launch.objective,
                                                                       screen_engine=launch.physics.engine))
    plain = dataclasses.replace(launch, objective=dataclasses.replace(
        launch.objective, robust=dataclasses.replace(launch.objective.robust, enabled=False)))
    profiles = list(heights) + [np.zeros(len(heights[0]))]
    counts = {}
    for name, settings, trials, seed in (("nominal", plain, nominal, NOMINAL_SEED),
                                         ("robust", launch, robust, ROBUST_SEED)):
        evaluate = batch_evaluation.fidelity_batch_evaluator(settings, executor, "screen")
        counts[name] = [(int(r[0]), int(r[1])) for r in evaluate(profiles, seed, trials)] if trials else None
    return counts, launch.physics.engine


def report(study_dir, rows, counts, engine, final_launches=(), keep=4):
    """Print one study's table and what the race chose against what it could have."""
    nominal, robust = counts["nominal"], counts["robust"]
    column = lambda counts, k: f"{counts[k][0]}/{counts[k][1]}" if counts else "-"  # noqa: E731
    print(f"\n{study_dir}: {len(rows)} raced elites; bare robot {column(nominal, -1)} nominal, "
          f"{column(robust, -1)} robust launches on the {engine} twin (simulated)")
    print(f"  {'elite':>5} {'label':>5} {'screen':>7} {'round 1':>7} {'race':>6} {'stopped':>7} {'nominal':>8} "
          f"{'robust':>7}")
    for k, row in enumerate(rows):
        print(f"  {k:>5} {row['label'] or '':>5} {row['screen_successes']:>3}/{row['screen_trials']:<3} "
              f"{row['race_round1_successes']:>3}/{row['race_round1_trials']:<3} "
              f"{row['race_successes']:>3}/{row['race_trials']:<3} {row['race_stopped'] or '-':>7} "
              f"{column(nominal, k):>8} {column(robust, k):>7}")
    screen = [int(r["screen_successes"]) / int(r["screen_trials"]) for r in rows if r["screen_trials"]]
    first = [int(r["race_round1_successes"]) / int(r["race_round1_trials"]) for r in rows]
    measures = {"screen": screen if len(screen) == len(rows) else None, "race round 1": first,
                "race (pooled)": [int(r["race_successes"]) / int(r["race_trials"]) for r in rows],
                "robust": [c[0] / c[1] for c in robust[:-1]] if robust else None}
    if nominal:
        truth = [c[0] / c[1] for c in nominal[:-1]]
        for name, values in measures.items():
            if values is not None and len(rows) >= 3:
                rho, p = spearman_permutation_test(values, truth)
                print(f"  {name} vs nominal launches: Spearman rho {rho:+.2f} (permutation p {p:.3f})")
        survivors = [k for k, r in enumerate(rows) if not r["race_stopped"]]
        chosen = {r["label"]: k for k, r in enumerate(rows) if r["label"]}
        best = lambda ks: max(nominal[k][0] for k in ks)  # noqa: E731
        print(f"  nominal launches: A {column(nominal, chosen['A']) if 'A' in chosen else '-'}; the survivors' best "
              f"{best(survivors)}, their mean {np.mean([nominal[k][0] for k in survivors]):.1f}; all raced elites' "
              f"best {best(range(len(rows)))}; bare robot {nominal[-1][0]} (of {nominal[-1][1]} each)")
        if robust:
            for extra in final_launches:
                picked = final_round(rows, survivors, robust, nominal, extra, keep)
                print(f"  a final round of {extra} more robust launches for the best {keep} survivors (Monte Carlo "
                      f"on the measured robust rates): A's expected nominal count {picked:.1f}")


def final_round(rows, survivors, robust, nominal, extra, keep, draws=4000):
    """Expected nominal count of the design a final race round would pick: the ``keep`` survivors best by their
    race launches get ``extra`` more robust launches, each drawn at its measured robust rate (a plug-in estimate:
    the measured rates spread more than the true ones, so the gain it shows is an upper bound); the pick is the
    most successes in the race and the final together (ties at random)."""
    rng = np.random.default_rng(0)
    totals = {k: int(rows[k]["race_successes"]) for k in survivors}
    final = sorted(survivors, key=lambda k: (-totals[k], k))[:keep]
    picks = []
    for _ in range(draws):
        score = {k: totals[k] + rng.binomial(extra, robust[k][0] / robust[k][1]) + 0.01 * rng.random()
                 for k in final}
        picks.append(nominal[max(final, key=score.__getitem__)][0])
    return float(np.mean(picks))


def smoke_study(folder):
    """A study folder in ``folder`` whose ``optimization`` holds one generation of the quick study's
    quality-diversity search (a wide step, so its six candidates fill several cells) and its selection, every elite
    screened and three raced on two launches each (otherwise bench/smoke.py's sizes); returns the folder."""
    from bench.bench_quality_diversity import one_run
    from bench.smoke import SMOKE_RUN

    one_run("cma_mae", 1, 1, 0, folder, {**SMOKE_RUN, "optimizer.popsize": 6, "optimizer.sigma0": 0.3,
                                         "selection.top_fraction": 1.0, "selection.race_elites": 3},
            run_dir=os.path.join(folder, "optimization"))
    return folder


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("studies", nargs="*", help="study folders (runs/<study-id>)")
    parser.add_argument("--nominal", type=int, default=100, help="nominal launches per design (campaign's measure)")
    parser.add_argument("--robust", type=int, default=100, help="fresh robust launches per design (race's measure)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--final-launches", type=int, nargs="*", default=[60, 200],
                        help="Monte Carlo of a final race round of this many more robust launches (needs both counts)")
    parser.add_argument("--keep", type=int, default=4, help="designs in that final round (selection.race_keep)")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: a study made here (smoke_study), one "
                        "launch of each kind, in this process; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    scratch = tempfile.TemporaryDirectory(prefix="bench-race-truth-")   # removed when main returns
    if args.smoke:
        args.studies = [smoke_study(os.path.join(scratch.name, "smoke-study"))]
        args.nominal, args.robust, args.workers, args.final_launches, args.keep = 1, 1, 0, [2], 1
    if not args.studies:
        parser.error("give at least one study folder (or --smoke)")
    if args.nominal < 0 or args.robust < 0 or args.nominal + args.robust == 0 or args.workers < 0 or args.keep < 1 \
            or any(n < 1 for n in args.final_launches):
        raise SystemExit("bench_race_truth: need --nominal, --robust, --workers >= 0 (not both counts 0; 0 workers: "
                         "in this process), --keep and --final-launches >= 1")
    for study_dir in args.studies:
        if not os.path.isfile(os.path.join(study_dir, "optimization", "designs", "archive.csv")):
            raise SystemExit(f"bench_race_truth: {study_dir} is not a study folder with a selection "
                             f"(no optimization/designs/archive.csv)")
    parameters = run_directory.read_run_config(os.path.join(args.studies[0], "optimization"))
    executor = evaluation.make_executor(evaluation.settings_from_parameters(parameters).evaluator, args.workers) \
        if args.workers else evaluation.SerialExecutor()
    try:
        for study_dir in args.studies:
            rows, heights = raced_elites(study_dir)
            counts, engine = fresh_counts(study_dir, heights, args.nominal, args.robust, executor)
            report(study_dir, rows, counts, engine, args.final_launches, args.keep)
    finally:
        executor.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
