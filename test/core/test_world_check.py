"""The plausible-world check, the recommendation rule and the report's lead table (issue 41 items 2 and 3)."""
import csv
import dataclasses
import html.parser

import pytest

from rollability_ros.core.optimization import recommendation
from rollability_ros.core.sim import world_check
from rollability_ros.core.sim.objectives import ObjectiveSettings, at_fidelity, check_fidelity, world_fidelity
from rollability_ros.core.sim.robustness import RobustSettings, draw


def rows_from(counts, launches=20):
    """World-check rows from ``{design: [upright launches per world]}`` (``baseline`` included), ``launches``
    each; the draws of each world recorded as a made-up foam friction."""
    rows = []
    for configuration, per_world in counts.items():
        for world, successes in enumerate(per_world):
            rows.append({"world": world, "world_seed": 100 + world, "launch_seed": 200 + world,
                         "configuration": configuration, "successes": successes, "trials": launches,
                         **dict.fromkeys(world_check.WORLD_UNKNOWNS, ""), "foam_lateral_friction": 0.5 + world})
    return rows


# --- the world fidelity: every launch of an evaluation in one world -----------------------------------------------
def test_a_world_fidelity_fixes_one_draw_for_every_launch():
    objective = at_fidelity(ObjectiveSettings(), world_fidelity(7))
    assert objective.kind == "launch_twin" and objective.robust.enabled and objective.robust.world_seed == 7
    assert at_fidelity(ObjectiveSettings(), "launch").robust.world_seed == -1   # each launch its own draw
    from rollability_ros.core.sim.robustness import robust_settings_for
    from rollability_ros.core.sim.evaluation import EvaluatorSettings

    settings = EvaluatorSettings()
    in_world = dataclasses.replace(RobustSettings(enabled=True), world_seed=7)
    assert robust_settings_for(settings, 1, in_world) == robust_settings_for(settings, 2, in_world)
    assert robust_settings_for(settings, 1, RobustSettings(enabled=True)) != \
        robust_settings_for(settings, 2, RobustSettings(enabled=True))
    assert draw(7, RobustSettings(), 0.0, 0.05) != draw(8, RobustSettings(), 0.0, 0.05)   # worlds differ
    for bad in ("world:", "world:-1", "world:x", "worlds:3", "world:99999999999"):
        assert check_fidelity(bad), bad
    for bad in ("world:\u00b2", "world:\u0663", "world:" + "9" * 5000):   # int() refused / read 3 / hit its limit
        assert "a world fidelity is world:<seed>, seed in [0, 2^32 - 1]" in (check_fidelity(bad) or ""), bad
    assert len(check_fidelity("world:" + "9" * 5000)) < 120   # a goal's 5000 digits were echoed whole into the log
    assert check_fidelity("world:0") is None and check_fidelity("launch") is None and check_fidelity("") is None


# --- the check: paired launches, shares, the worst world -----------------------------------------------------------
def test_every_configuration_of_a_world_launches_on_the_same_seeds():
    calls = []

    def evaluate(world_seed, launch_seed, launches):
        calls.append((world_seed, launch_seed, launches))
        return {"baseline": (3, launches), "A": (5, launches)}

    rows = world_check.run_world_check(evaluate, worlds=4, launches=6, seed=11,
                                       describe=lambda seed: {"wheel_drag_nm": seed % 7})
    assert len(calls) == 4 and len({c[0] for c in calls}) == 4 and len({c[1] for c in calls}) == 4
    assert [(r["world"], r["configuration"]) for r in rows[:2]] == [(0, "baseline"), (0, "A")]
    assert all(r["trials"] == 6 and r["wheel_drag_nm"] == r["world_seed"] % 7 for r in rows)
    assert world_check.world_seeds(11, 4) == [c[:2] for c in calls]             # reproducible from the seed
    assert world_check.world_seeds(11, 6)[:4] == world_check.world_seeds(11, 4)  # more worlds keep the first


def test_a_huge_world_count_draws_each_worlds_seeds_as_it_comes(monkeypatch):
    """`--worlds 100000000` listed every world's seeds before the first launch (16 s and 8 MB of list per 10^6
    worlds, measured: 26 minutes and gigabytes before anything ran); each world's seeds are now drawn as it comes."""
    import numpy as np

    drawn = []
    seed_sequence = np.random.SeedSequence

    def counted(*args, **kwargs):
        drawn.append(kwargs.get("spawn_key"))
        assert len(drawn) <= 2, "seeds drawn ahead of the worlds"
        return seed_sequence(*args, **kwargs)

    class Stop(Exception):
        """The user's Ctrl-C after the second world."""

    def evaluate(world_seed, launch_seed, launches):
        if len(drawn) == 2:
            raise Stop
        return {"baseline": (1, launches), "A": (1, launches)}

    monkeypatch.setattr(np.random, "SeedSequence", counted)
    with pytest.raises(Stop):
        world_check.run_world_check(evaluate, worlds=10 ** 8, launches=1, seed=11)
    monkeypatch.undo()
    assert world_check.world_seeds(11, 2) == [world_check.world_seed_pair(11, w) for w in range(2)]


def test_the_local_evaluator_launches_bare_robot_and_designs_on_one_seed_in_one_world(monkeypatch):
    from rollability_ros.core.sim import evaluation

    seen = []

    def fake_evaluate_mesh(mesh, trials, seed, settings, executor=None):
        seen.append((mesh, trials, seed, settings.objective.robust.world_seed, settings.objective.kind))
        return evaluation.EvaluationResult(1 / trials, 1, trials, 0.0, 1.0, 0.0, [])

    monkeypatch.setattr(evaluation, "evaluate_mesh", fake_evaluate_mesh)
    evaluate = world_check.local_world_evaluator({"baseline": None, "A": "mesh-A"}, evaluation.EvaluatorSettings())
    assert evaluate(42, 9, 4) == {"baseline": (1, 4), "A": (1, 4)}
    assert seen == [(None, 4, 9, 42, "launch_twin"), ("mesh-A", 4, 9, 42, "launch_twin")]


def test_shares_worst_world_and_pooled_gain():
    rows = rows_from({"baseline": [6, 6, 6, 6], "A": [12, 6, 7, 2], "B": [16, 16, 15, 14]})
    summaries = {s.configuration: s for s in world_check.summarize_worlds(rows)}
    a, b = summaries["A"], summaries["B"]
    assert (a.wins, a.worlds, a.share_won) == (2, 4, 0.5)        # world 1 is a tie: not a win
    assert a.clear_wins == 0 and b.wins == 4 and b.clear_wins == 4
    assert a.worst.world == 3 and a.worst.interval[0] == pytest.approx(-0.2)
    assert a.worst.draws["foam_lateral_friction"] == 3.5 and "foam friction 3.5" in a.text()
    assert a.pooled[0] == pytest.approx((27 - 24) / 80)
    assert "wins 2/4 worlds (50%)" in a.text() and "worst world 3: -0.20" in a.text()
    document = b.as_dict()
    assert document["share_won"] == 1.0 and document["pooled"]["trials"] == 80
    with pytest.raises(ValueError, match="pairs equal launches"):
        world_check.summarize_worlds([{**r, "trials": 5} if r["configuration"] == "A" else r for r in rows])
    with pytest.raises(ValueError, match="no bare-robot row"):
        world_check.summarize_worlds([r for r in rows if not (r["configuration"] == "baseline" and r["world"] == 2)])


# --- the recommendation rule ---------------------------------------------------------------------------------------
def _verdict(counts, share=0.9):
    return recommendation.recommend(world_check.summarize_worlds(rows_from(counts)), share)


def test_recommended_only_where_it_wins_at_least_the_share_of_worlds():
    bare = [5] * 10
    verdict = _verdict({"baseline": bare, "A": [12] * 9 + [5],      # 9/10 worlds: recommended
                        "B": [14] * 8 + [5, 4],                      # 8/10 worlds, larger pooled gain: not
                        "C": [4] * 10})                              # loses everywhere
    assert verdict.recommended == ("A",) and verdict.first == "A"
    assert verdict.headline().startswith("print design A first") and "wins 9/10" in verdict.headline()
    assert "wins too few worlds" in verdict.reasons["B"] and "not recommended" in verdict.reasons["C"]
    assert _verdict({"baseline": bare, "A": [12] * 9 + [5], "B": [14] * 8 + [5, 4]}, share=0.8).first == "B"


def test_a_design_that_loses_is_never_first_and_none_is_said_plainly():
    verdict = _verdict({"baseline": [10] * 10, "A": [9] * 10, "B": [10] * 10})   # a loss and a tie everywhere
    assert verdict.first is None and verdict.recommended == ()
    assert verdict.headline().startswith("NO DESIGN IS RECOMMENDED")
    # wins every world by one launch out of 20: the pooled interval still straddles 0, so not recommended
    narrow = _verdict({"baseline": [10] * 10, "A": [11] * 10})
    assert narrow.first is None and "pooled gain's interval is not above 0" in narrow.reasons["A"]


def test_ties_between_recommended_designs_keep_a_fixed_order_and_the_campaign_can_veto():
    verdict = _verdict({"baseline": [5] * 10, "A": [15] * 10, "B": [15] * 10})
    assert verdict.recommended == ("A", "B")                     # equal evidence: the selection's order
    vetoed = recommendation.with_campaign(verdict, {"A": (0.05, -0.07, 0.17), "B": (0.2, 0.08, 0.32)})
    assert vetoed.first == "B" and "campaign does not show it beating" in vetoed.reasons["A"]
    nothing = recommendation.with_campaign(verdict, {"A": (0.0, -0.1, 0.1), "B": (-0.1, -0.2, 0.0)})
    assert nothing.first is None and nothing.headline().startswith("NO DESIGN TO PRINT FIRST")


# --- the report's lead table ---------------------------------------------------------------------------------------
class _Tables(html.parser.HTMLParser):
    """The text of each table's rows, in document order, and the order of h2 headings."""

    def __init__(self):
        super().__init__()
        self.tables, self.headings, self._cell, self._in_h2 = [], [], None, False

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append({"class": dict(attrs).get("class", ""), "rows": []})
        elif tag == "tr" and self.tables:
            self.tables[-1]["rows"].append([])
        elif tag in ("td", "th"):
            self._cell = ""
        elif tag == "h2":
            self._in_h2 = True
            self.headings.append("")

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.tables[-1]["rows"][-1].append(self._cell)
            self._cell = None
        elif tag == "h2":
            self._in_h2 = False

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data
        if self._in_h2:
            self.headings[-1] += data


def _campaign_with_designs(tmp_path, world_counts, upright):
    """A CSV campaign (``upright``: configuration -> upright launches of 40) next to a designs folder holding
    designs.yaml and a world check of ``world_counts``."""
    from rollability_ros.core.records import LaunchCondition, LaunchOutcome
    from rollability_ros.core.results import write_outcome_csv

    designs = tmp_path / "designs"
    designs.mkdir()
    (designs / "designs.yaml").write_text("/**:\n  ros__parameters:\n    designs:\n      labels: [A, B]\n"
                                          "      recommendation:\n        min_world_share: 0.9\n")
    with open(designs / "world_check.csv", "w", newline="", encoding="utf-8") as stream:
        writer = csv.DictWriter(stream, fieldnames=world_check.WORLD_CHECK_COLUMNS)
        writer.writeheader()
        writer.writerows(rows_from(world_counts))
    outcomes = [LaunchOutcome("r", f"{name}-{i}", LaunchCondition(name, 0.75, 0.8, 0.0, i), "sim", i < count)
                for name, count in upright.items() for i in range(1, 41)]
    path = str(tmp_path / "outcomes.csv")
    write_outcome_csv(path, outcomes)
    return path


def test_the_report_opens_with_the_recommendation_table(tmp_path):
    from rollability_ros.core.results import report, report_writer

    source = _campaign_with_designs(tmp_path, {"baseline": [5] * 10, "A": [6] * 9 + [5], "B": [15] * 10},
                                    {"baseline": 10, "A": 14, "B": 30})
    built = report_writer.build_report(report.load_report_data(source), str(tmp_path / "report"))
    assert built.summary.splitlines()[0].startswith("RECOMMENDATION: print design B first")
    lead_lines = built.summary.split("source: ")[0].splitlines()
    assert len(lead_lines) >= 4 and all(len(line) <= 120 for line in lead_lines)
    parser = _Tables()
    parser.feed(open(built.html_path, encoding="utf-8").read())
    assert parser.headings[:2] == ["Recommendation: which design to print first", "Contents"]   # first on the page
    lead = parser.tables[0]
    assert lead["class"] == "lead"
    header, first, second = lead["rows"][:3]
    assert header[0] == "design" and "simulated campaign" in header[2]
    assert first[:2] == ["B", "print first"] and first[3] == "10/10 (100%)" and first[2].startswith("+0.")
    assert second[:2] == ["A", "not recommended"] and "interval is not above 0" in second[-1]   # 9/10 worlds, tiny gain


def test_the_report_never_lists_a_losing_design_first(tmp_path):
    from rollability_ros.core.results import analysis, report, report_writer

    source = _campaign_with_designs(tmp_path, {"baseline": [10] * 10, "A": [8] * 10, "B": [9] * 10},
                                    {"baseline": 20, "A": 12, "B": 18})
    data = report.load_report_data(source)
    views = analysis.paper_views(data.outcomes, report.CONFIGURATION_ORDER)
    lead = report.report_lead(data, views)
    summary = report.summary_text(data, views, None, [], lead)
    assert summary.startswith("RECOMMENDATION: NO DESIGN IS RECOMMENDED") and "print first" not in summary
    parser = _Tables()
    parser.feed(report_writer.lead_html(lead))
    verdicts = [row[1] for row in parser.tables[0]["rows"][1:]]
    assert verdicts == ["not recommended", "not recommended"]
    # the same designs, now B wins every world clearly but loses on the campaign: still not listed first
    with open(tmp_path / "designs" / "world_check.csv", "w", newline="", encoding="utf-8") as stream:
        writer = csv.DictWriter(stream, fieldnames=world_check.WORLD_CHECK_COLUMNS)
        writer.writeheader()
        writer.writerows(rows_from({"baseline": [5] * 10, "A": [4] * 10, "B": [15] * 10}))
    data = report.load_report_data(source)
    lead = report.report_lead(data, views)
    assert lead.headline.startswith("NO DESIGN TO PRINT FIRST") and lead.rows[0].verdict == "not listed first"


# --- the selection uses it -----------------------------------------------------------------------------------------
def test_the_selection_checks_its_designs_in_worlds_and_records_the_recommendation():
    import numpy as np

    from rollability_ros.core.optimization.design_set import designs_document
    from rollability_ros.core.optimization.labelling import label_by_evidence
    from rollability_ros.core.optimization.selection import (PooledDesign, SelectedDesign, SelectionResult,
                                                             SelectionSettings, with_world_check)
    from rollability_ros.core.profile.geometry import ProfileGrid

    grid = ProfileGrid(rows=2, cols=2)
    designs = [SelectedDesign(label, PooledDesign(np.full(grid.n_variables, top), 9, 10, 1, 1), None, None)
               for label, top in (("A", 0.1), ("B", 0.3))]
    result = SelectionResult(designs, 2, 2, {})
    calls = []

    def world_launch(heights_list, world_seed, launch_seed, launches):
        """B rights 15 of 20 in every world, A 6, the bare robot (zeros) 5; one call per world."""
        calls.append((len(heights_list), world_seed, launch_seed))
        return [(5 if not h.any() else 15 if h[0] > 0.2 else 6, launches, 0.0, "fake") for h in heights_list]

    settings = SelectionSettings(world_count=10, world_launches=20)
    checked = with_world_check(result, grid, settings, world_launch, run_seed=3)
    assert len(calls) == 10 and all(n == 3 for n, _, _ in calls)          # bare robot + both designs together
    assert len(checked.world_rows) == 30 and checked.recommendation.first == "B"
    assert checked.recommendation.recommended == ("B",)                  # A wins every world, pooled not above 0
    body = designs_document(checked, grid, "run")["/**"]["ros__parameters"]["designs"]
    assert body["recommendation"]["first"] == "B" and body["recommendation"]["min_world_share"] == 0.9
    assert body["world_check"] == {"worlds": 10, "launches_per_world": 20, "file": "selection_world_check.csv"}
    # the labels follow that evidence: B, picked second, becomes A (the design to print first), A becomes B
    labelled = label_by_evidence(checked, settings.recommend_world_share)
    assert [(d.label, float(d.design.heights[0])) for d in labelled.designs] == [("A", 0.3), ("B", 0.1)]
    assert labelled.designs[0].reason.startswith("labelled A: rank 1 of 2 by the plausible-world check")
    assert "pick 2" in labelled.designs[0].reason and labelled.recommendation.first == "A"
    assert {r["configuration"] for r in labelled.world_rows} == {"baseline", "A", "B"}
    assert sum(r["successes"] for r in labelled.world_rows if r["configuration"] == "A") == 150
    assert with_world_check(result, grid, SelectionSettings(), None, 3) is result   # world_count 0: no check
    with pytest.raises(ValueError, match="world launch evaluator"):
        with_world_check(result, grid, settings, None, 3)


def test_without_a_world_check_the_fresh_launches_label_and_a_loser_is_never_a():
    """Picked first by the race, a design whose fresh launches do not beat the bare robot is labelled after one
    that does; without fresh launches the pick order stays."""
    import numpy as np

    from rollability_ros.core.optimization.labelling import label_by_evidence
    from rollability_ros.core.optimization.selection import PooledDesign, SelectedDesign, SelectionResult

    def design(label, launches):
        return SelectedDesign(label, PooledDesign(np.full(4, 0.1), 9, 10, 1, 1), None, None, reason="race",
                              launches=launches)

    # A (the race's first pick): 14/40 against the bare robot's 10/40, interval not above 0; B 30/40, C 22/40
    picked = SelectionResult([design("A", (14, 40, 7)), design("B", (30, 40, 7)), design("C", (22, 40, 7))], 3, 3,
                             {}, baseline_launches=(10, 40, 7))
    labelled = label_by_evidence(picked, 0.9)
    assert [(d.label, d.launches[0]) for d in labelled.designs] == [("A", 30), ("B", 22), ("C", 14)]
    assert [g.beats for g in labelled.gains()] == [True, True, False]
    assert "by the fresh robust launches" in labelled.designs[2].reason and "pick 1: race" in labelled.designs[2].reason
    unlaunched = SelectionResult([design("A", None), design("B", None)], 2, 2, {})
    assert [d.label for d in label_by_evidence(unlaunched, 0.9).designs] == ["A", "B"]


def test_the_command_launches_in_real_worlds_and_writes_its_tables(tmp_path, capsys, monkeypatch):
    """``rollability sensitivity --worlds``: MuJoCo launches (the cheaper engine), 2 worlds x 2 paired launches,
    in this process (the command's worker pool would cost more to start than the launches)."""
    import numpy as np
    import yaml

    from rollability_ros.core.sim import evaluation

    def serial(options, workers=None):
        return evaluation.SerialExecutor()

    monkeypatch.setattr(evaluation, "make_executor", serial)
    monkeypatch.setattr("rollability_ros.core.sim.make_executor", serial)   # the face caches a resolved name

    pytest.importorskip("mujoco")
    pytest.importorskip("trimesh")
    from rollability_ros.cli import main
    from rollability_ros.core.optimization.design_set import designs_document
    from rollability_ros.core.optimization.selection import PooledDesign, SelectedDesign, SelectionResult
    from rollability_ros.core.profile.geometry import ProfileGrid

    grid = ProfileGrid(rows=3, cols=3)
    chosen = [SelectedDesign("A", PooledDesign(np.repeat(np.linspace(0.05, 0.3, 3), 3), 9, 10, 1, 1), None, None)]
    document = designs_document(SelectionResult(chosen, 1, 1, {}), grid, "run-1")
    (tmp_path / "designs.yaml").write_text(yaml.safe_dump(document), encoding="utf-8")
    out = tmp_path / "worlds"
    assert main(["sensitivity", "--designs-file", str(tmp_path / "designs.yaml"), "--worlds", "2",
                 "--launches-per-world", "2", "--engine", "mujoco", "--seed", "4",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "plausible-world check (simulated on mujoco): 2 worlds" in printed and "recommendation (" in printed
    with open(out / "world_check.csv", newline="", encoding="utf-8") as stream:
        rows = list(csv.DictReader(stream))
    assert [(r["world"], r["configuration"]) for r in rows] == [("0", "baseline"), ("0", "A"), ("1", "baseline"),
                                                                ("1", "A")]
    for world in ("0", "1"):   # paired: one launch seed and one draw per world
        own = [r for r in rows if r["world"] == world]
        assert own[0]["launch_seed"] == own[1]["launch_seed"] and own[0]["wheel_drag_nm"] == own[1]["wheel_drag_nm"]
    assert rows[0]["wheel_drag_nm"] != rows[2]["wheel_drag_nm"] and all(r["trials"] == "2" for r in rows)
    summary = yaml.safe_load((out / "world_summary.yaml").read_text(encoding="utf-8"))
    assert summary["simulated"] is True and summary["engine"] == "mujoco" and summary["designs"]["A"]["worlds"] == 2
    assert main(["sensitivity", "--designs-file", str(tmp_path / "designs.yaml"), "--worlds", "2",
                 "--out", str(out)]) == 2                                  # an earlier check is never overwritten


def test_a_check_stopped_by_ctrl_c_keeps_the_worlds_it_ran(tmp_path, capsys, monkeypatch):
    """world_check.csv was written once the last world was done: a check stopped after hours (28 worlds, measured)
    left an empty --out. Each row is written as it comes; the summary only for a finished check."""
    import numpy as np
    import yaml

    from rollability_ros.cli import main
    from rollability_ros.core import sim
    from rollability_ros.core.optimization.design_set import designs_document
    from rollability_ros.core.optimization.selection import PooledDesign, SelectedDesign, SelectionResult
    from rollability_ros.core.profile.geometry import ProfileGrid
    from rollability_ros.core.sim import evaluation

    def local_world_evaluator(profiles, settings, executor):
        def evaluate(world_seed, launch_seed, launches):
            if world_seed != sim.world_check.world_seed_pair(4, 0)[0]:
                raise KeyboardInterrupt   # the user's Ctrl-C during the second world
            return {"baseline": (1, launches), "A": (2, launches)}
        return evaluate

    monkeypatch.setattr(sim, "local_world_evaluator", local_world_evaluator)
    monkeypatch.setattr(sim, "make_executor", lambda options, workers=None: evaluation.SerialExecutor())
    chosen = [SelectedDesign("A", PooledDesign(np.repeat(np.linspace(0.05, 0.3, 3), 3), 9, 10, 1, 1), None, None)]
    document = designs_document(SelectionResult(chosen, 1, 1, {}), ProfileGrid(rows=3, cols=3), "run-1")
    (tmp_path / "designs.yaml").write_text(yaml.safe_dump(document), encoding="utf-8")
    out = tmp_path / "worlds"
    assert main(["sensitivity", "--designs-file", str(tmp_path / "designs.yaml"), "--worlds", "1000",
                 "--launches-per-world", "2", "--seed", "4", "--out", str(out)]) == 130
    assert "world_check.csv keeps the rows of the worlds done" in capsys.readouterr().err
    with open(out / "world_check.csv", newline="", encoding="utf-8") as stream:
        rows = list(csv.DictReader(stream))
    assert [(r["world"], r["configuration"], r["successes"]) for r in rows] == [("0", "baseline", "1"), ("0", "A", "2")]
    assert not (out / "world_summary.yaml").exists()
