"""Do the main job's designs work where the rig measures them? The quick default study over several optimizer seeds.

    nice python bench/bench_transfer.py [--seeds 1 2 3] [--robust-launches 100] [--sensitivity-trials 0]
                                        [--worlds 20] [--launches-per-world 40] [--world-engine ENGINE]
                                        [--out transfer-bench] [--config FILE ...] [--smoke]
    nice python bench/bench_transfer.py --designs designs.yaml [...]   # no study: the checks of existing designs

For each seed: ``rollability study`` (the node graph, quick default, all simulated) with ``optimizer.seed`` set to
it (any ``--config`` files are added, e.g. ``paper``), timed; then, from the study's stores and files:

- the launch campaign on the twin: each configuration's upright trials, and design minus baseline with Newcombe's
  95% interval (issue 41's target: A at least +0.30 with the lower bound at least +0.10, no design below the
  baseline);
- the selection's gain over the bare robot on fresh robust twin launches (Table 3);
- the labelling rule read back: the order in which the selection's own world check ranks the designs and the
  campaign gain of the first (A on a study of this branch; on an older study, what the rule would have labelled A);
- the transfer evidence of the report: screen fitness (the search's measure, on its engine) vs the launch race's
  first round (PyBullet robust twin launches) over the raced elites (Spearman rho, permutation p);
- fresh robust launches of the bare robot and every design on both engines (``rollability evaluate --designs
  <designs.yaml> --engines pybullet,mujoco --fidelity launch --trials N``, ``--robust-launches`` N each, seed
  :data:`ROBUST_SEED`; it writes ``engine_agreement.csv`` beside the designs): design minus bare per engine
  (Newcombe 95%; issue 41's target: A's interval above 0 on both engines);
- the plausible-world check (``rollability sensitivity --designs-file <designs.yaml> --worlds N
  --launches-per-world K --seed S``, ``--worlds`` N >= 20 and ``--launches-per-world`` K >= 40 for issue 41; seed
  :data:`WORLD_SEED`; on ``--world-engine``, default the evaluator's launch engine): per design the share of worlds
  won against the bare robot and the worst world's gain with its Newcombe interval (issue 41's target: A wins at
  least 90% of them);
- with ``--sensitivity-trials`` N > 0, the robust sensitivity row (``core/sim/sensitivity.py``: every disturbance
  trial under its own draw of all the unknowns; N each, seed 0): A and the bare chassis, A minus bare;
- the study's wall time (set-up excluded; the machine's load is printed with it) and the CPU time of its processes
  (divided by 2 cores: what it needs of an otherwise idle 2-core machine).

Then the same over seeds: how many seeds meet each target and the pooled campaign gain of A. All numbers are
simulated. Every study stays in ``--out/seed-<n>/`` for inspection. ``--designs FILE`` runs no study: the robust
launches and the world check of an existing designs file (``engine_agreement.csv`` and ``world-check-*/`` are
written beside it; an earlier result there is read, not measured again). ``--smoke``: one seed of the end-to-end
test's miniature study (test/resources/mini_study.yaml) made smaller (test/resources/tiny_study.yaml), two robust
launches, one sensitivity trial, a world check of 2 worlds x 2 launches, in a temporary folder (the numbers mean
nothing).
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile
import time
import typing

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import yaml  # noqa: E402

from rollability_ros.core.results import design_map  # noqa: E402
from rollability_ros.core.stats import newcombe_interval  # noqa: E402
from rollability_ros.core.store import Store  # noqa: E402

#: Base seed of the fresh robust launches on both engines (no seed a study's race, selection or campaign uses).
ROBUST_SEED = 41041
#: Seed of the plausible-world check (its worlds' draws and launches; no seed a study uses).
WORLD_SEED = 41042
#: Issue 41's campaign target for A: the gain over the baseline and the lower bound of its Newcombe interval.
A_GAIN_TARGET, A_LOW_TARGET = 0.30, 0.10
#: Issue 41's world-check target for A: the share of worlds won.
A_WORLD_SHARE_TARGET = 0.9


def run_study(out, seed, configs):
    """Run one study with ``optimizer.seed`` = ``seed``; return (study dir, wall time s, load average at the end)."""
    os.makedirs(out, exist_ok=True)
    seed_file = os.path.join(out, f"seed-{seed}.yaml")
    with open(seed_file, "w", encoding="utf-8") as stream:
        yaml.safe_dump({"/**": {"ros__parameters": {"optimizer": {"seed": seed}}}}, stream)
    study_id = f"seed-{seed}"
    command = [sys.executable, "-m", "rollability_ros.cli", "study", "--study-id", study_id]
    for config in [*configs, seed_file]:
        command += ["--config", config]
    started = time.perf_counter()
    cpu_before = _children_cpu_s()
    with open(os.path.join(out, f"{study_id}.log"), "w", encoding="utf-8") as log:
        code = subprocess.call(command, cwd=out, stdout=log, stderr=subprocess.STDOUT)
    elapsed = time.perf_counter() - started
    if code != 0:
        raise SystemExit(f"study {study_id} failed (exit {code}); see {out}/{study_id}.log")
    return os.path.join(out, "runs", study_id), elapsed, os.getloadavg()[0], _children_cpu_s() - cpu_before


def _children_cpu_s():
    """CPU seconds (user + system) of this process's finished descendants: every node and worker of a study, each
    waited for by its parent. Divided by the 2 cores it is what the study needs of an otherwise idle machine."""
    import resource

    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def search_text(study_dir):
    """What the study's search optimised and on which engines (from its saved parameter files)."""
    from rollability_ros.core.config import load_parameters

    files = sorted(os.path.join(study_dir, "config", name) for name in os.listdir(os.path.join(study_dir, "config")))
    flat = load_parameters(files)
    engine = flat.get("sim.engine", "pybullet")
    return (f"search: objective {flat.get('objective.kind')} (robust {flat.get('objective.robust.enabled')}) on "
            f"{flat.get('objective.screen_engine') or engine}, {flat.get('optimizer.trials')} trials x "
            f"{flat.get('optimizer.popsize')} x {flat.get('optimizer.max_generations')} generations; race and fresh "
            f"launches on {flat.get('objective.launch_engine') or engine}; campaign on {engine}")


#: The study parameters that say how its designs are printed and weighed: what the checks must load as well, or
#: ``rollability evaluate`` / ``sensitivity`` refuse the designs file (chosen for another print) or draw another mass.
PRINT_KEYS = ("robot.profile_print.", "robot.profile_mass_scale", "objective.robust.profile_mass_scale_")


def print_config(study_dir):
    """A parameter file ``<study_dir>/checks-print.yaml`` with the study's print and its search's profile-mass draw
    (:data:`PRINT_KEYS`, read from the parameter files the study loaded), for the checks' commands: a study on the
    quick default prints with gradual infill (config/optimizer.yaml), which those commands do not read."""
    from rollability_ros.core.config import load_parameters

    files = sorted(os.path.join(study_dir, "config", name) for name in os.listdir(os.path.join(study_dir, "config")))
    nested: typing.Dict[str, typing.Any] = {}
    for key, value in sorted(load_parameters(files).items()):
        if key.startswith(PRINT_KEYS):
            *path, name = key.split(".")
            node = nested
            for part in path:
                node = node.setdefault(part, {})
            node[name] = value
    target = os.path.join(study_dir, "checks-print.yaml")
    with open(target, "w", encoding="utf-8") as stream:
        yaml.safe_dump({"/**": {"ros__parameters": nested}}, stream)
    return target


def campaign_counts(study_dir, study_id):
    """{configuration: (upright valid trials, valid trials)} of the study's campaign."""
    counts: typing.Dict[str, typing.Tuple[int, int]] = {}
    with Store(os.path.join(study_dir, "outcomes.sqlite")) as store:
        for outcome in store.launch_outcomes(run_id=study_id):
            if not outcome.valid:
                continue
            upright, trials = counts.get(outcome.condition.configuration, (0, 0))
            counts[outcome.condition.configuration] = (upright + int(outcome.upright), trials + 1)
    return counts


def table3(study_dir):
    with open(os.path.join(study_dir, "optimization", "designs", "table3.csv"), newline="") as stream:
        return list(csv.DictReader(stream))


def evidence_first(study_dir, counts):
    """The selection's labelling rule read back (docs/optimization.md, "Labels follow the evidence"): the order in
    which the selection's own world check ranks the designs, as a line with the campaign gain of the design it
    ranks first; '' without that check. On a study whose selection labelled by the race (before the rule), it says
    what the rule would have labelled A."""
    from rollability_ros.core.optimization.recommendation import evidence_ranking
    from rollability_ros.core.sim import summarize_worlds

    designs = os.path.join(study_dir, "optimization", "designs")
    check = os.path.join(designs, "selection_world_check.csv")
    if not os.path.isfile(check):
        return ""
    with open(check, newline="") as stream:
        summaries = summarize_worlds(list(csv.DictReader(stream)))
    with open(os.path.join(designs, "designs.yaml"), encoding="utf-8") as stream:
        document = yaml.safe_load(stream)["/**"]["ros__parameters"]["designs"]
    share = float((document.get("recommendation") or {}).get("min_world_share", 0.9))
    order = evidence_ranking(summaries, share)
    first = order[0]
    campaign = gain_text(counts[first], counts["baseline"])[0] if first in counts else "not in the campaign"
    return (f"  labels by the evidence (the selection's {summaries[0].worlds}-world check): {', '.join(order)}; "
            f"ranked first: {first}, campaign {campaign}")


def robust_row(study_dir, trials):
    """{configuration: (successes, trials)} of the robust sensitivity row for the bare chassis and the designs."""
    from rollability_ros.core.profile.designs import DesignSources, configuration_ids, profile_mesh_for
    from rollability_ros.core.sim import evaluation
    from rollability_ros.core.sim.sensitivity import sensitivity_rows

    designs_file = os.path.join(study_dir, "optimization", "designs", "designs.yaml")
    sources = DesignSources(designs_file=designs_file)
    profiles: typing.Dict[str, typing.Optional[typing.Any]] = {"baseline": None}
    profiles.update({label: profile_mesh_for(label, sources) for label in configuration_ids(sources)
                     if label != "baseline"})
    settings = evaluation.load_settings(["sim", "robot", "evaluator"])
    with evaluation.make_executor(settings.evaluator) as executor:
        rows = sensitivity_rows(profiles, settings, trials, 0, executor, levels={"disturbance_scale": (1.0,)})
    return {r["configuration"]: (r["successes"], r["trials"]) for r in rows if r["factor"] == "robust"}


def robust_launches(designs_file, launches, workers=2, configs=()):
    """{engine: {configuration: (upright, launches)}}: ``launches`` fresh robust launches of the bare robot and
    every design of ``designs_file`` on both engines, by the ``rollability evaluate`` command a user runs (module
    docstring), with the study's parameter files ``configs`` (the print the designs were chosen for: the command
    refuses another), and the command's wall time (s; 0 when its table was there already)."""
    from rollability_ros.core.results import engine_agreement

    designs = os.path.dirname(os.path.abspath(designs_file))
    table = os.path.join(designs, engine_agreement.TABLE_FILENAME)
    started = time.perf_counter()
    if not os.path.exists(table):
        command = [sys.executable, "-m", "rollability_ros.cli", "evaluate", "--designs", designs_file,
                   "--engines", "pybullet,mujoco", "--fidelity", "launch", "--trials", str(launches), "--seed",
                   str(ROBUST_SEED), "--workers", str(workers)] + [a for c in configs for a in ("--config", c)]
        _run_logged(command, designs, "robust-launches.log", "rollability evaluate")
    elapsed = time.perf_counter() - started
    counts: typing.Dict[str, typing.Dict[str, typing.Tuple[int, int]]] = {}
    for row in engine_agreement.read_table(table):
        counts.setdefault(row.engine, {})[row.design] = (row.successes, row.trials)
    return counts, elapsed


def _run_logged(command, folder, log_name, what):
    """Run ``command`` in ``folder`` with its output in ``log_name`` there; SystemExit naming the log on failure."""
    with open(os.path.join(folder, log_name), "w", encoding="utf-8") as log:
        code = subprocess.call(command, cwd=folder, stdout=log, stderr=subprocess.STDOUT)
    if code != 0:
        raise SystemExit(f"{what} failed (exit {code}); see {os.path.join(folder, log_name)}")


def world_check(designs_file, worlds, launches, engine="", workers=2, configs=()):
    """The plausible-world check of ``designs_file`` (module docstring) by the ``rollability sensitivity --worlds``
    command a user runs, into ``world-check-<engine>/`` beside it (read when there already): its
    ``world_summary.yaml`` as a dict, and the command's wall time (s)."""
    folder = os.path.dirname(os.path.abspath(designs_file))
    out = os.path.join(folder, f"world-check-{engine or 'launch-engine'}-{worlds}x{launches}")
    summary = os.path.join(out, "world_summary.yaml")
    started = time.perf_counter()
    if not os.path.exists(summary):
        command = [sys.executable, "-m", "rollability_ros.cli", "sensitivity", "--designs-file", designs_file,
                   "--worlds", str(worlds), "--launches-per-world", str(launches), "--seed", str(WORLD_SEED),
                   "--workers", str(workers), "--out", out] + (["--engine", engine] if engine else []) + \
            [a for c in configs for a in ("--config", c)]
        _run_logged(command, folder, os.path.basename(out) + ".log", "rollability sensitivity --worlds")
    elapsed = time.perf_counter() - started
    with open(summary, encoding="utf-8") as stream:
        return yaml.safe_load(stream), elapsed


def print_world_check(document, elapsed):
    """Print the check's line per design; return A's (share won, worst gain, worst low) or NaNs without A."""
    print(f"  plausible-world check on the {document['engine']} twin (simulated; {document['worlds']} worlds x "
          f"{document['launches_per_world']} paired launches, seed {document['seed']}; {elapsed:.0f} s wall): "
          "share of worlds won (point gain > 0), worst world's gain [Newcombe 95%], pooled gain")
    for label, design in document["designs"].items():
        worst, pooled = design["worst_world"], design["pooled"]
        print(f"    {label:<8} won {design['wins']}/{design['worlds']} ({design['share_won']:.0%}); worst world "
              f"{worst['world']}: {worst['gain']:+.2f} [{worst['newcombe_95'][0]:+.2f}, {worst['newcombe_95'][1]:+.2f}]"
              f"; pooled {pooled['gain']:+.2f} [{pooled['newcombe_95'][0]:+.2f}, {pooled['newcombe_95'][1]:+.2f}] "
              f"({pooled['successes']}/{pooled['trials']} vs {pooled['baseline_successes']}/"
              f"{pooled['baseline_trials']})")
    print(f"    recommendation: {document['recommendation']['headline']}")
    design = document["designs"].get("A")
    if design is None:
        return float("nan"), float("nan"), float("nan")
    return design["share_won"], design["worst_world"]["gain"], design["worst_world"]["newcombe_95"][0]


def print_robust_launches(engines, launches, elapsed):
    """Print the fresh robust launches per engine; return {design: [lower bound of its gain per engine]}."""
    engine_lows: typing.Dict[str, typing.List[float]] = {}
    for engine, by_design in engines.items():
        print(f"  fresh robust launches on the {engine} twin ({launches} each, seed {ROBUST_SEED}; both engines "
              f"{elapsed:.0f} s wall): bare {by_design['baseline'][0]}/{by_design['baseline'][1]}")
        for label in sorted(d for d in by_design if d != "baseline"):
            text, _difference, low = gain_text(by_design[label], by_design["baseline"])
            engine_lows.setdefault(label, []).append(low)
            print(f"    {label:<8} {text}")
    return engine_lows


def designs_checks(designs_file, args):
    """The robust launches and the world check of ``designs_file`` (``--designs`` / ``--smoke``), printed."""
    load = os.getloadavg()
    print(f"designs {designs_file} (load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}; 2 shared cores)")
    if args.robust_launches:
        engines, elapsed = robust_launches(designs_file, args.robust_launches, args.workers, args.check_config)
        lows = print_robust_launches(engines, args.robust_launches, elapsed)
        print(f"  A above bare with the interval above 0 on both engines: "
              f"{len(lows.get('A', [])) == 2 and min(lows['A']) > 0}")
    if args.worlds:
        share, _gain, _low = print_world_check(*world_check(designs_file, args.worlds, args.launches_per_world,
                                                             args.world_engine, args.workers, args.check_config))
        print(f"  A wins at least {A_WORLD_SHARE_TARGET:.0%} of the worlds: {share >= A_WORLD_SHARE_TARGET}")
    print(f"load average at the end: {' '.join(f'{v:.1f}' for v in os.getloadavg())}")
    return 0


def gain_text(a, b):
    difference, low, high = newcombe_interval(*a, *b)
    return f"{a[0]}/{a[1]} vs {b[0]}/{b[1]}: {difference:+.2f} [{low:+.2f}, {high:+.2f}]", difference, low


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--robust-launches", type=int, default=100,
                        help="fresh robust launches per design and engine (0 = none)")
    parser.add_argument("--sensitivity-trials", type=int, default=0,
                        help="robust disturbance trials per design in the sensitivity row (0 = none)")
    parser.add_argument("--out", default="transfer-bench")
    parser.add_argument("--config", action="append", default=[], help="extra study parameter file(s)")
    parser.add_argument("--worlds", type=int, default=20, help="worlds of the plausible-world check (0 = none)")
    parser.add_argument("--launches-per-world", type=int, default=40, help="paired launches per design and world")
    parser.add_argument("--world-engine", default="", help="engine of the world check (default: the launch engine)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes of the checks")
    parser.add_argument("--designs", metavar="FILE", help="no study: check this designs.yaml (module docstring)")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: one seed of the miniature study, each "
                        "measurement once; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    # the commands below run in the studies' and designs' folders: a file named relative to here, made absolute
    args.config = [os.path.abspath(c) if os.path.isfile(c) else c for c in args.config]
    # the user's parameter files, given to the checks too (the print the designs were chosen for; --smoke's study
    # sizes below are optimizer settings, which the checks' commands refuse)
    args.check_config = list(args.config)
    scratch = tempfile.TemporaryDirectory(prefix="bench-transfer-")   # ROS logs (and --smoke's studies)
    if args.smoke:
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        args.seeds, args.robust_launches, args.sensitivity_trials = [1], 2, 1
        args.worlds, args.launches_per_world, args.workers = 2, 2, 1
        args.out = os.path.join(scratch.name, "transfer-bench")
        args.config = [*(os.path.join(root, "test", "resources", f"{name}_study.yaml") for name in ("mini", "tiny")),
                       *args.config]
    out = os.path.abspath(args.out)
    if args.designs:
        return designs_checks(os.path.abspath(args.designs), args)
    # studies in one DDS domain talk to each other's nodes: this bench's own domain, clear of the tests' 20..100
    from bench.smoke import isolated_ros

    _lock = isolated_ros(scratch.name)   # the studies' nodes inherit it, and a folder for their ROS logs
    print(f"ROS_DOMAIN_ID {os.environ['ROS_DOMAIN_ID']}, localhost discovery (this bench's studies only)", flush=True)
    summary = []
    for seed in args.seeds:
        study_dir, elapsed, load, cpu = run_study(out, seed, args.config)
        study_id = os.path.basename(study_dir)
        counts = campaign_counts(study_dir, study_id)
        base = counts["baseline"]
        print(f"\nseed {seed}: study {elapsed / 60:.1f} min wall (load average {load:.1f} at the end; 2 shared "
              f"cores), {cpu:.0f} s CPU of its processes (/ 2 cores = {cpu / 120:.1f} min), {study_dir}", flush=True)
        print(f"  {search_text(study_dir)}")
        print(f"  campaign on the twin (simulated), upright / valid launches; design minus baseline, Newcombe 95%:")
        print(f"    baseline {base[0]}/{base[1]}")
        gains = {}
        for label in sorted(c for c in counts if c != "baseline"):
            text, difference, low = gain_text(counts[label], base)
            gains[label] = (difference, low)
            print(f"    {label:<8} {text}")
        ranked = evidence_first(study_dir, counts)
        if ranked:
            print(ranked)
        for row in table3(study_dir)[1:]:
            if row.get("gain_source"):
                print(f"  selection ({row['gain_source']}): {row['configuration']} {float(row['gain']):+.2f} "
                      f"[{float(row['gain_low']):+.2f}, {float(row['gain_high']):+.2f}] beats_baseline "
                      f"{row['beats_baseline']}")
        archive = os.path.join(study_dir, "optimization", "designs", design_map.ARCHIVE_FILENAME)
        evidence = design_map.transfer(design_map.read_archive(archive)) if os.path.isfile(archive) else None
        if evidence is not None:
            print(f"  transfer: screen vs race round 1 over {evidence[2]} elites: Spearman rho {evidence[0]:+.2f}, "
                  f"permutation p {evidence[1]:.3f}")
        designs_file = os.path.join(study_dir, "optimization", "designs", "designs.yaml")
        checks = [*args.check_config, print_config(study_dir)]   # the print the designs were chosen for
        engine_lows: typing.Dict[str, typing.List[float]] = {}
        if args.robust_launches:
            engines, launches_s = robust_launches(designs_file, args.robust_launches, args.workers, checks)
            engine_lows = print_robust_launches(engines, args.robust_launches, launches_s)
        worlds = print_world_check(*world_check(designs_file, args.worlds, args.launches_per_world, args.world_engine,
                                                args.workers, checks)) if args.worlds else (float("nan"),) * 3
        robust_gain = robust_low = float("nan")
        if args.sensitivity_trials:
            robust = robust_row(study_dir, args.sensitivity_trials)
            robust_text, robust_gain, robust_low = gain_text(robust["A"], robust["baseline"]) if "A" in robust \
                else ("no design A", float("nan"), float("nan"))
            print(f"  robust sensitivity row ({args.sensitivity_trials} trials): A minus bare {robust_text}")
        sys.stdout.flush()
        summary.append({"seed": seed, "minutes": elapsed / 60, "load": load, "cpu_minutes": cpu / 60,
                        "a_gain": gains.get("A", (float("nan"),) * 2),
                        "lowest": min((g[0] for g in gains.values()), default=float("nan")),
                        "a_counts": counts.get("A", (0, 0)), "base": base, "robust": (robust_gain, robust_low),
                        "a_engines": len(engine_lows.get("A", [])) == 2 and min(engine_lows["A"]) > 0,
                        "transfer": evidence or (float("nan"), float("nan"), 0), "worlds": worlds})
    print(f"\nover seeds (simulated; targets: A - baseline >= {A_GAIN_TARGET:+.2f} with the lower bound >= "
          f"{A_LOW_TARGET:+.2f}, no design below the baseline, A's robust launches above bare with the interval above "
          f"0 on both engines, A winning at least {A_WORLD_SHARE_TARGET:.0%} of the plausible worlds, about 5 min):")
    print(f"{'seed':>5} {'A - base':>9} {'low':>6} {'lowest design':>14} {'A > bare, both engines':>23} "
          f"{'A worlds won':>12} {'worst':>6} {'rho':>6} {'p':>6} {'elites':>6} {'min':>5} {'load':>5} {'CPU min':>7}")
    for row in summary:
        rho, p, elites = row["transfer"]
        print(f"{row['seed']:>5} {row['a_gain'][0]:>+9.2f} {row['a_gain'][1]:>+6.2f} {row['lowest']:>+14.2f} "
              f"{str(row['a_engines']):>23} {row['worlds'][0]:>12.0%} {row['worlds'][1]:>+6.2f} {rho:>+6.2f} "
              f"{p:>6.3f} {elites:>6d} {row['minutes']:>5.1f} {row['load']:>5.1f} {row['cpu_minutes']:>7.1f}")
    met = sum(r["a_gain"][0] >= A_GAIN_TARGET and r["a_gain"][1] >= A_LOW_TARGET for r in summary)
    pooled_a = (sum(r["a_counts"][0] for r in summary), sum(r["a_counts"][1] for r in summary))
    pooled_base = (sum(r["base"][0] for r in summary), sum(r["base"][1] for r in summary))
    print(f"A's campaign target met in {met} of {len(summary)} seeds; pooled A minus baseline "
          f"{gain_text(pooled_a, pooled_base)[0]}; designs below the baseline (point estimate) in "
          f"{sum(r['lowest'] < 0 for r in summary)} seeds; A's robust launches above bare with the interval above 0 on "
          f"both engines in {sum(r['a_engines'] for r in summary)} seeds; A winning at least "
          f"{A_WORLD_SHARE_TARGET:.0%} of the worlds in {sum(r['worlds'][0] >= A_WORLD_SHARE_TARGET for r in summary)} "
          f"seeds; at least 15 raced elites behind the transfer statistic "
          f"in {sum(r['transfer'][2] >= 15 for r in summary)} seeds")
    return 0


if __name__ == "__main__":
    sys.exit(main())
