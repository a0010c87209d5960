"""The adaptive plan against the paper's matrix (issue 44.4): how many launches each needs for the same interval
widths of the twin's unknowns, on the same hidden truths. Simulated throughout.

    python bench/bench_adaptive_plan.py [--truths 10] [--unknowns 4] [--samples 20000] [--matrix-launches 400]
    nice python bench/bench_adaptive_plan.py --likelihood twin --unknowns 2 --samples 48 --sim-repetitions 4
    nice python bench/bench_adaptive_plan.py --learnt likelihood.npz [--outcomes all|none|NAME,...] --samples 500
        [--characterisation DIR [--gate-shots N]] [--gate DIR] [--precise 8000 --budget 250] [--first-truth K]

For each hidden truth drawn from the prior (uniform on each unknown's search scale, its calibration bounds): the
paper's matrix launches ``--matrix-launches`` times (the 80 grouped conditions of config/campaign.yaml -- the bare
chassis and designs A, B, C at 2 heights, 2 speeds, 5 angles -- once per shuffled round); then the adaptive plan
(each launch the BALD choice, core/campaign/adaptive.py) launches on the same truth from the same prior samples
until every unknown's 95 % interval is at most as wide as the matrix's. Prints both per truth, the median, and the
effective sample sizes (the importance-sampling posterior is only as good as its samples: under about 50, rerun
with more). The same outcomes the launches' P(upright) predict at the truth, drawn with a seeded generator.

``--learnt FILE``: a likelihood prepared by ``rollability calibrate --prepare`` (or bench_calibration /
``--prepare-launches`` here) over the twin's unknowns, designs and condition levels: the candidates are the file's
configurations x levels; each launch of a truth draws the verdict and the continuous outcomes (``--outcomes``)
from the learnt model at the truth; both plans weigh the samples by all of it and renew them; the adaptive plan
scores the expected information of verdict and outcomes (learnt_plan.OutcomePosterior). ``--outcomes none``: the
verdicts alone (the exact BALD score). ``--characterisation DIR`` (a file over bench_calibration.py's unknowns and
designs, e.g. its ``--keep`` folder's): both plans start from each truth's bench readings (issue 44: the
characterisation on both sides), simulated as bench_calibration.py does. ``--gate DIR``: every launch of both plans
also gives its speed gate reading (the truth's, from the twin), the bare robot's weighed by the exact term of
core/campaign/likelihood_gate.py, and the adaptive plan scores verdict and reading together (with ``--outcomes``
that leave out measured_speed_mps, so the reading is weighed once). ``--precise DRAWS``: the adaptive plan
launches its whole budget (``--budget``), then both plans' widths are estimated again from their recorded launches
by importance sampling (learnt_plan.importance_widths: DRAWS draws of a kernel proposal, the same draws for both
plans, ``--precise-sets`` independent times), and the counts to those widths are printed beside the others (the
renewed samples' widths carry a Monte Carlo error that decides the strict count: docs/calibration.md).
``--first-truth K``: truths K.. of the same draw (a run split over processes). ``--gate-shots N`` (with
``--characterisation``): the launcher characterised before the first launch, N gate-only shots of the bare robot at
each set speed among each truth's bench readings (docs/characterisation.md, (c)), so both plans start with the
speed bias pinned; with ``--gate`` the shots and the campaign's bare-robot readings are weighed in one term.

``--likelihood toy`` (default without --learnt): an analytic logistic stand-in (LogisticToyPredictor: each condition's own sensitivity
to each unknown, seeded), cheap; it shows the machinery, not the rig. ``--likelihood twin``: the
simulation-based likelihood (TwinPredictor: ``--sim-repetitions`` twin launches per sample and condition, the
configurations from ``--twin-config`` files' launch_twin.designs, e.g. the optimizer's designs), expensive
(samples x 80 x repetitions launches, about 50 ms each per core). A learnt likelihood (the calib room's) plugs in
through :func:`run` with any object that has ``probabilities(theta (s, d), conditions) -> (s, c)``:
bench/bench_calibration.py calls :func:`run` with its own predictor.
"""
import argparse
import math
import os
import sys
import time
import typing

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from rollability_ros.core.campaign import adaptive, plan_comparison  # noqa: E402
from rollability_ros.core.sim import launch_twin_settings_from_parameters  # noqa: E402


def run(predictor: typing.Union[adaptive.UprightPredictor, adaptive.PerLaunchPredictor],
        unknowns: adaptive.HasBounds, candidates: typing.Sequence[adaptive.LaunchCondition], truths: int,
        matrix_launches: int, samples: int, seed: int = 2026, say: typing.Callable[[str], None] = print,
        renew: bool = True, acquisition: str = "joint") -> typing.List[plan_comparison.MatchedWidths]:
    """Print and return the matrix-vs-adaptive comparison (:func:`plan_comparison.adaptive_to_match_matrix`); ``renew``:
    renew the samples as the posterior narrows (asks the predictor again: for a cheap one, not the twin's)."""
    import numpy as np

    bounds = adaptive.Unknowns.like(unknowns)   # a learnt likelihood's own unknowns are accepted as they are
    table: adaptive.UprightPredictor = (adaptive.PerLaunchAdapter(predictor)
                                        if isinstance(predictor, adaptive.PerLaunchPredictor) else predictor)
    started = time.perf_counter()
    results = plan_comparison.adaptive_to_match_matrix(bounds, table, candidates, truths, matrix_launches, samples,
                                                       seed, renew=renew, acquisition=acquisition)
    for i, r in enumerate(results):
        needed = f"{r.adaptive_launches}" if r.adaptive_launches is not None else f">{matrix_launches}"
        say(f"truth {i}: matrix {matrix_launches} launches -> widths "
            + ", ".join(f"{w:.0%}" for w in r.matrix_widths)
            + f" (ESS {r.matrix_ess:.0f}); adaptive reaches them in {needed} launches (ESS {r.adaptive_ess:.0f})")
    counts = [r.adaptive_launches if r.adaptive_launches is not None else np.inf for r in results]
    median = float(np.median(counts))
    say(f"median launches to the matrix's widths: adaptive {median:g} against matrix {matrix_launches} "
        f"(ratio {median / matrix_launches:.2f}; target: at most 150 against 400); adaptive within 150 on "
        f"{sum(c <= 150 for c in counts)} of {len(counts)} truths; {time.perf_counter() - started:.1f} s; simulated")
    return results


def load() -> str:
    """The 1-minute load average, beside every time (the machine is shared)."""
    return f"load {os.getloadavg()[0]:.1f}"


def characterisation_start(likelihood: typing.Any, folder: str, samples: int,
                           shots: typing.Optional[typing.Callable[[int, typing.Any], typing.Any]] = None,
                           shot_model: typing.Any = None, plans_weigh_shots: bool = False) -> plan_comparison.Start:
    """``--characterisation DIR``: each truth's bench readings as bench_calibration.py simulates them (slide
    angles, roll-outs, tip angles, weighings; the designs' STLs written to ``folder``, as there), and ``samples``
    draws of the posterior from those readings alone (``posterior.sample_posterior`` without launches), where both
    plans start; their term is the density the renewals keep. ``replica`` > 0 (the matrix posterior's replicas):
    the same readings, another sampler seed and other draws. ``shots`` (``--gate-shots``): (truth index, truth) ->
    the truth's launcher characterisation (characterisation.GateShot), weighed by ``shot_model``'s term (a
    likelihood_gate.GateModel on the launching twin: the roll-outs' PyBullet twin is not the one that launches);
    the start is drawn from the bench readings' term times the shots'. ``plans_weigh_shots`` (``--gate``: the
    plans' gate term holds the shots with the campaign's readings, one term per set speed): the density returned
    is the bench readings' alone; else it holds the shots' term too."""
    import dataclasses

    import numpy as np

    from bench import bench_calibration as bench
    from rollability_ros.core.campaign import likelihood_gate
    from rollability_ros.core.campaign import posterior as sampling

    parameters, unknowns, _ = bench.bench_parameters(folder)
    if unknowns != likelihood.unknowns:
        raise SystemExit(f"--characterisation: the likelihood's unknowns are not bench_calibration.py's "
                         f"({', '.join(likelihood.unknowns.names)})")
    twin = launch_twin_settings_from_parameters(bench.rollout_parameters(parameters))

    terms: typing.Dict[int, typing.Tuple[typing.Callable[[np.ndarray], np.ndarray],
                                         typing.Callable[[np.ndarray], np.ndarray]]] = {}

    def start(t: int, truth: np.ndarray, replica: int = 0
              ) -> typing.Tuple[np.ndarray, typing.Callable[[np.ndarray], np.ndarray]]:
        number = 100_000 + t   # the readings' seeds: none of bench_calibration's truths
        if t not in terms:
            readings = bench.bench_readings(parameters, unknowns, truth, number, bench.characterise_truth(
                parameters, unknowns, truth, np.random.default_rng([bench.TRUTH_SEED, number])))
            if shots is not None:
                readings = dataclasses.replace(readings, gate_shots=tuple(shots(t, truth)))
            kept = sampling.characterisation_term(readings, twin, unknowns, gate_shots=False)
            if shot_model is not None and readings.gate_shots:
                shot_term = shot_model.with_shots(likelihood_gate.shot_observations(readings.gate_shots)).term([])
                both = (lambda u, kept=kept, shot_term=shot_term: kept(u) + shot_term(u))
                terms[t] = (kept if plans_weigh_shots else both), both
            else:
                terms[t] = kept, kept
        kept, drawn_from = terms[t]
        drawn = sampling.sample_posterior(likelihood, [], extra=drawn_from, seed=t + 1 + 7919 * replica, steps=150,
                                          walkers=16, start_draws=300)
        picks = np.random.default_rng([bench.TRUTH_SEED, number, 1, *([replica] if replica else [])]).choice(
            len(drawn.samples), samples, replace=False)
        return drawn.samples[picks], kept
    return start


def truth_gate_reader(likelihood: typing.Any, folder: str, every: bool = False
                      ) -> typing.Tuple[typing.Any, typing.Any, typing.Callable[..., float]]:
    """bench_calibration.py's twin, its unknowns, and each truth's gate reading (t, truth, condition, rng) -> m/s:
    the twin's reading without scatter at the truth's unknowns (its bias among them), tabulated over the launch
    speed's scatter z (the set speed x (1 + sigma z); 9 points over +-4 sigma, cubic) per set speed, then read at
    z drawn from ``rng``; NaN for a design's launch unless ``every`` (the designs' readings are not weighed)."""
    import numpy as np
    from scipy.interpolate import CubicSpline

    from bench import bench_calibration as bench
    from rollability_ros.core.campaign import likelihood_gate
    from rollability_ros.core.sim import twin_with_values

    os.makedirs(folder, exist_ok=True)
    parameters, unknowns, _ = bench.bench_parameters(folder)
    if unknowns != likelihood.unknowns:
        raise SystemExit(f"--gate/--gate-shots: the likelihood's unknowns are not bench_calibration.py's "
                         f"({', '.join(likelihood.unknowns.names)})")
    twin = launch_twin_settings_from_parameters(parameters)
    sigma = twin.twin.speed_sigma_fraction
    splines: typing.Dict[typing.Tuple[int, str, float], typing.Any] = {}

    def reading(t: int, truth: np.ndarray, condition: adaptive.LaunchCondition, rng: np.random.Generator) -> float:
        if not every and condition.configuration != likelihood_gate.BARE_ROBOT:
            return math.nan
        key = (t, condition.configuration, float(condition.speed_mps))
        if key not in splines:
            at_truth = twin_with_values(twin, dict(zip(unknowns.names, map(float, truth))))
            z = np.linspace(-4.0, 4.0, 9)   # the scatter as a set speed x (1 + sigma z): the same launch speed
            splines[key] = CubicSpline(z, [likelihood_gate.gate_reading_mps(
                at_truth, condition.configuration, condition.speed_mps * (1.0 + sigma * float(e))) for e in z])
        return float(splines[key](float(np.clip(rng.standard_normal(), -4.0, 4.0))))
    return twin, unknowns, reading


def gate_model(likelihood: typing.Any, candidates: typing.Sequence[adaptive.LaunchCondition],
               folder: str, every: bool = False) -> typing.Tuple[typing.Any, typing.Any]:
    """``--gate``: the speed gate's exact term (likelihood_gate.GateModel, the bare robot's readings, on
    bench_calibration.py's twin: both plans weigh the readings, the adaptive plan scores them) and each truth's
    readings (:func:`truth_gate_reader`). ``every`` (``--gate-every``): every configuration's readings are drawn
    and weighed (the term's 7 x 7 x 7 table over the bias, the centre of mass and the profile's mass,
    likelihood_gate.gate_term with configurations=None)."""
    from rollability_ros.core.campaign import likelihood_gate

    twin, unknowns, reading = truth_gate_reader(likelihood, folder, every)
    model = likelihood_gate.GateModel(twin, unknowns, [(c.configuration, c.speed_mps) for c in candidates],
                                      configurations=None if every else (likelihood_gate.BARE_ROBOT,))
    return model, reading


def gate_shots(likelihood: typing.Any, per_speed: int, reading: typing.Callable[..., float]
               ) -> typing.Callable[[int, typing.Any], typing.Tuple[typing.Any, ...]]:
    """``--gate-shots N``: each truth's launcher characterisation, N shots of the bare robot at each set speed of
    the likelihood's levels (characterisation.GateShot), read as the campaign's launches are (``reading``:
    :func:`truth_gate_reader`'s) from a generator of their own per truth, the same for both plans and every
    replica."""
    import numpy as np

    from bench import bench_calibration as bench
    from rollability_ros.core.campaign.characterisation import GateShot
    from rollability_ros.core.campaign.likelihood_gate import BARE_ROBOT, GATE_HEIGHT_M

    made: typing.Dict[int, typing.Tuple[GateShot, ...]] = {}

    def shots(t: int, truth: np.ndarray) -> typing.Tuple[GateShot, ...]:
        if t not in made:
            rng = np.random.default_rng([bench.TRUTH_SEED, 100_000 + t, 3])
            made[t] = tuple(GateShot(float(v), reading(t, truth, adaptive.LaunchCondition(BARE_ROBOT, GATE_HEIGHT_M,
                                                                                        float(v), 0.0), rng))
                            for v in likelihood.levels.speeds_mps for _ in range(per_speed))
        return made[t]
    return shots


def launched_where(candidates: typing.Sequence[adaptive.LaunchCondition], launched: typing.Sequence[int]) -> str:
    """Where launches were made: counts by configuration, set speed and ledge height."""
    picked = [candidates[i] for i in launched]
    parts = []
    for label, key in (("configuration", lambda c: c.configuration), ("speed", lambda c: f"{c.speed_mps:g} m/s"),
                       ("height", lambda c: f"{c.height_m:g} m")):
        counts: typing.Dict[str, int] = {}
        for c in picked:
            counts[key(c)] = counts.get(key(c), 0) + 1
        parts.append(" ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    return "; ".join(parts)


def run_learnt(path: str, truths: int, matrix_launches: int, samples: int, seed: int, outcomes: str,
               draws: int, acquisition: str = "joint", characterisation: typing.Optional[str] = None,
               gate: typing.Optional[str] = None, replicas: int = 0, gate_every: bool = False,
               precise: int = 0, precise_sets: int = 3, first_truth: int = 0,
               budget: typing.Optional[int] = None, shots: int = 0) -> typing.List[plan_comparison.MatchedWidths]:
    """``--learnt FILE`` (module docstring): print each truth as it finishes, then the median."""
    import numpy as np

    from rollability_ros.core.campaign import likelihood as learnt
    from rollability_ros.core.campaign.learnt_plan import LearntTable

    likelihood = learnt.load_likelihood(path)
    levels = likelihood.levels
    candidates = adaptive.candidate_conditions(likelihood.configurations, levels.heights_m, levels.speeds_mps,
                                               levels.angles_deg)
    chosen = None if outcomes == "all" else () if outcomes == "none" else tuple(outcomes.split(","))
    table = LearntTable(likelihood, candidates, chosen)
    print(f"learnt likelihood {os.path.basename(path)} ({likelihood.info.get('training_launches', '?')} training "
          f"launches); unknowns {', '.join(likelihood.unknowns.names)}; {len(candidates)} grouped conditions; "
          f"outcomes: verdict{''.join(', ' + n for n in table.outcomes)}; {truths} truths from the prior; {samples} "
          f"{'samples of the characterisation posterior' if characterisation else 'prior samples'} (renewed); "
          f"{acquisition} acquisition; outcomes drawn from the learnt model at each truth"
          + (f"; {'every configuration' if gate_every else 'the bare robot'}'s gate readings weighed by the exact term"
             if gate else "")
          + (f"; the launcher characterised by {shots} gate shots of the bare robot per set speed in both plans' start"
             if shots else "") + "; simulated", flush=True)
    if shots and not characterisation:
        raise SystemExit("--gate-shots: needs --characterisation (the shots are among the bench readings both plans "
                         "start from)")
    model, reading = gate_model(likelihood, candidates, gate, gate_every) if gate else (None, None)
    truth_shots = shot_model = None
    if shots and characterisation:
        from rollability_ros.core.campaign import likelihood_gate

        twin, unknowns, read = truth_gate_reader(likelihood, characterisation)
        truth_shots = gate_shots(likelihood, shots, reading or read)
        shot_model = model or likelihood_gate.GateModel(twin, unknowns, ())   # the bare robot's term, the shots only
    start = (characterisation_start(likelihood, characterisation, samples, truth_shots, shot_model, model is not None)
             if characterisation else None)
    shot_readings = None
    if truth_shots is not None and model is not None:
        from rollability_ros.core.campaign.likelihood_gate import shot_observations

        def shot_readings(t: int, truth: np.ndarray) -> typing.List[typing.Any]:
            return shot_observations(truth_shots(t, truth))
    started = time.perf_counter()

    def say(t: int, r: plan_comparison.MatchedWidths) -> None:
        needed = f"{r.adaptive_launches}" if r.adaptive_launches is not None else f">{budget or matrix_launches}"
        print(f"truth {t}: matrix {matrix_launches} launches -> widths " + ", ".join(f"{w:.0%}" for w in r.matrix_widths)
              + f" (ESS {r.matrix_ess:.0f}); adaptive reaches them in {needed} launches (ESS {r.adaptive_ess:.0f}"
              + ("" if r.adaptive_launches else "; widths then " + ", ".join(f"{w:.0%}" for w in r.adaptive_widths))
              + f") [{time.perf_counter() - started:.0f} s, {load()}]", flush=True)
        if replicas:
            tolerant = f"{r.tolerant_launches}" if r.tolerant_launches is not None else f">{budget or matrix_launches}"
            print(f"  Monte Carlo sd of one width estimate (the matrix's launches, {replicas + 1} sample draws): "
                  + ", ".join(f"{e:.1%}" for e in r.width_error) + "; to the mean width + that sd ("
                  + ", ".join(f"{w:.0%}" for w in r.tolerant_widths) + f"): adaptive {tolerant} launches", flush=True)
        if r.precise is not None:
            e = r.precise

            def shown(count: typing.Optional[int], launched: int = len(r.adaptive_launched)) -> str:
                """A launch count, or ">N" where the adaptive plan's N launches did not reach the widths."""
                return f"{count}" if count is not None else f">{launched}"

            counts = "/".join(shown(c) for c in e.launches)
            spread = np.std(e.matrix_widths, axis=0, ddof=1) if len(e.matrix_widths) > 1 else np.zeros(0)
            print(f"  importance-sampled widths ({precise} draws x {len(e.launches)} sets, common to both plans): "
                  "matrix " + ", ".join(f"{w:.1%}" for w in e.matrix_widths[0])
                  + (" (sd over the sets " + ", ".join(f"{x:.2%}" for x in spread) + ")" if len(spread) else "")
                  + f"; adaptive reaches them in {counts} launches (per set; set 0's widths there or at its "
                  "last launch " + ", ".join(f"{w:.1%}" for w in e.adaptive_widths[0]) + "); to the mean + 1 sd: "
                  + shown(e.tolerant_launches)
                  + f"; ESS matrix {e.matrix_ess.min():.0f}-{e.matrix_ess.max():.0f}, adaptive there "
                  f"{e.adaptive_ess.min():.0f}-{e.adaptive_ess.max():.0f}; to the matrix's widths + "
                  + ", + ".join(f"{tolerance:.2%}: " + "/".join(shown(c) for c in per_set)
                                for tolerance, per_set in e.within),
                  flush=True)
            print("  set 0, the first launch at or under the matrix's width, per unknown: "
                  + ", ".join(f"{name.rsplit('.', 1)[-1]} {shown(c)}"
                              for name, c in zip(table.unknowns.names, e.per_unknown)), flush=True)
        stop = (r.precise.launches[0] if r.precise is not None else r.adaptive_launches) or len(r.adaptive_launched)
        print(f"  the adaptive plan's first {stop} launches: "
              + launched_where(table.candidates, r.adaptive_launched[:stop]), flush=True)
    _, results = plan_comparison.learnt_to_match_matrix(table, truths, matrix_launches, samples, seed, draws=draws,
                                                        acquisition=acquisition, on_truth=say, start=start,
                                                        gate=model, gate_reading=reading, replicas=replicas,
                                                        precise=precise, precise_sets=precise_sets,
                                                        first_truth=first_truth, budget=budget, shots=shot_readings)
    limit = budget or matrix_launches
    for label, counts in (("", [r.adaptive_launches for r in results]),
                          (" + the Monte Carlo sd (tolerance-aware)", [r.tolerant_launches for r in results]),
                          (" (importance-sampled, set 0)",
                           [r.precise.launches[0] if r.precise else None for r in results]),
                          (" (importance-sampled) + their sd (tolerance-aware)",
                           [r.precise.tolerant_launches if r.precise else None for r in results]),
                          *((f" (importance-sampled, set 0) + {tolerance:.2%} of each range",
                             [r.precise.within[i][1][0] if r.precise else None for r in results])
                            for i, tolerance in enumerate(plan_comparison.WIDTH_TOLERANCES))):
        if ("Monte Carlo" in label and not replicas) or ("importance" in label and not precise) or (
                "their sd" in label and precise_sets < 2):
            continue
        finite = [c if c is not None else np.inf for c in counts]
        median = float(np.median(finite))
        shown = f">{limit}" if math.isinf(median) else f"{median:g}"
        print(f"median launches to the matrix's widths{label}: adaptive {shown} against matrix {matrix_launches} "
              f"(ratio {median / matrix_launches:.2f}; target: at most 150 against 400); adaptive within 150 on "
              f"{sum(c <= 150 for c in finite)} of {len(finite)} truths; {time.perf_counter() - started:.0f} s, "
              f"{load()}; simulated (the learnt model of the twin)")
    return results


def main(argv: typing.Optional[typing.Sequence[str]] = None) -> int:
    import numpy as np

    from rollability_ros.core.campaign import calibration
    from rollability_ros.core.campaign.plan import load_campaign_spec
    from rollability_ros.core.config import load_parameters

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--likelihood", choices=("toy", "twin"), default="toy")
    parser.add_argument("--learnt", metavar="FILE", help="a prepared likelihood file (module docstring)")
    parser.add_argument("--outcomes", default="all",
                        help="with --learnt: all (default), none (verdicts only) or NAME,NAME of the continuous outcomes")
    parser.add_argument("--characterisation", metavar="DIR",
                        help="with --learnt (a file over bench_calibration.py's unknowns and designs): both plans "
                             "start from each truth's bench readings (slide, roll-out, tip angles, weighings), "
                             "simulated as bench_calibration.py does; its designs' STLs are written to DIR")
    parser.add_argument("--gate", metavar="DIR",
                        help="with --learnt (bench_calibration.py's unknowns): every launch of both plans also gives "
                             "its speed gate reading, the bare robot's weighed by the exact term "
                             "(core/campaign/likelihood_gate.py); the designs' STLs are written to DIR")
    parser.add_argument("--gate-shots", type=int, default=0, metavar="N",
                        help="with --characterisation: the launcher characterised on the bench before the first "
                             "launch, N gate-only shots of the bare robot at each set speed (the truth's readings), "
                             "among the bench readings both plans start from (docs/characterisation.md, (c)); with "
                             "--gate weighed in one term with the campaign's readings")
    parser.add_argument("--gate-every", action="store_true",
                        help="with --gate: every configuration's readings drawn and weighed, not the bare robot's only")
    parser.add_argument("--replicas", type=int, default=0,
                        help="with --learnt: weigh the matrix's launches again from N other sample draws (N >= 2) "
                             "to measure the Monte Carlo error of the widths, and count the adaptive launches to "
                             "the mean width + that error too (the strict count is kept)")
    parser.add_argument("--precise", type=int, default=0, metavar="DRAWS",
                        help="with --learnt: the adaptive plan launches its whole budget, then both plans' widths are "
                             "estimated again by importance sampling with DRAWS draws (e.g. 8000), the same draws for "
                             "both plans, --precise-sets independent times; the counts to those widths are printed "
                             "beside the others")
    parser.add_argument("--precise-sets", type=int, default=3, help="with --precise: independent draw sets (default 3)")
    parser.add_argument("--first-truth", type=int, default=0,
                        help="with --learnt: begin at this truth (the same truths as from 0: a run split in parts)")
    parser.add_argument("--budget", type=int, default=None,
                        help="with --learnt: the adaptive plan's launches at most (default --matrix-launches)")
    parser.add_argument("--draws", type=int, default=32,
                        help="with --learnt: Monte Carlo outcomes per candidate of the expected information")
    parser.add_argument("--acquisition", choices=plan_comparison.ACQUISITIONS, default="joint",
                        help="the adaptive plan's score: joint = the expected information about all the unknowns "
                             "(BALD, default); targeted = about the unknown farthest from the width to reach; "
                             "lagging = about every unknown not yet at its width, summed")
    parser.add_argument("--truths", type=int, default=10)
    parser.add_argument("--unknowns", type=int, default=4,
                        help="the first N of calibration.parameters' shipped order after the two of "
                             "adaptive.DEFAULT_UNKNOWNS (default 4)")
    parser.add_argument("--samples", type=int, default=None,
                        help="prior samples of the unknowns (default 20000; 500 with --learnt, renewed)")
    parser.add_argument("--matrix-launches", type=int, default=400)
    parser.add_argument("--sim-repetitions", type=int, default=4, help="--likelihood twin: launches per entry")
    parser.add_argument("--twin-config", action="append", default=[], metavar="FILE")
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--smoke", action="store_true",
                        help="every step once at a tiny size (1 truth, 2 unknowns, 200 samples, 40 matrix launches); "
                             "the numbers mean nothing")
    args = parser.parse_args(argv)
    if args.samples is None:
        args.samples = 500 if args.learnt else 20000
    if args.smoke:
        args.truths, args.unknowns, args.samples, args.matrix_launches = 1, 2, 200, 40
    if args.learnt:
        run_learnt(args.learnt, args.truths, args.matrix_launches, args.samples, args.seed, args.outcomes, args.draws,
                   args.acquisition, args.characterisation, args.gate, args.replicas, args.gate_every,
                   args.precise, args.precise_sets, args.first_truth, args.budget, args.gate_shots)
        return 0
    parameters = load_parameters([*calibration.TWIN_CONFIGS, "calibration", *args.twin_config])
    settings = calibration.calibration_settings(parameters)
    order = list(adaptive.DEFAULT_UNKNOWNS) + [n for n in settings.parameters if n not in adaptive.DEFAULT_UNKNOWNS]
    settings = settings.selected(order[:args.unknowns])
    unknowns = adaptive.Unknowns.from_settings(settings)
    spec = load_campaign_spec(["campaign"])
    candidates = adaptive.candidate_conditions(spec.configurations, spec.heights_m, spec.speeds_mps, spec.angles_deg)
    print(f"{args.likelihood} likelihood; unknowns {', '.join(unknowns.names)}; {len(candidates)} grouped conditions; "
          f"{args.truths} truths from the prior; {args.samples} prior samples; {args.acquisition} acquisition; "
          "simulated")
    if args.likelihood == "toy":
        run(adaptive.LogisticToyPredictor(unknowns, seed=args.seed), unknowns, candidates, args.truths,
            args.matrix_launches, args.samples, args.seed, acquisition=args.acquisition)
        return 0
    with calibration.LaunchPool(args.workers) as pool:
        twin = launch_twin_settings_from_parameters(parameters)
        predictor = adaptive.TwinPredictor(twin, unknowns, pool, args.sim_repetitions, settings.seed)

        class Cached:   # the prior's table and the truths' are launched once each
            def probabilities(self, theta: np.ndarray,
                              conditions: typing.Sequence[adaptive.LaunchCondition]) -> np.ndarray:
                return predictor.probabilities(np.asarray(theta), conditions)
        # no renewal: each would launch samples x 80 x repetitions again; watch the effective sample sizes printed
        run(Cached(), unknowns, candidates, args.truths, args.matrix_launches, args.samples, args.seed, renew=False,
            acquisition=args.acquisition)
    return 0


if __name__ == "__main__":
    sys.exit(main())
