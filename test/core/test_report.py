"""The report: from a store, a run directory and a CSV; identical tables; HTML rendered by headless Chromium."""
import csv
import dataclasses
import os
import random
import re
import shutil
import subprocess

import pytest
from doubles import design_twin_files
from resimulation import assert_reproduces, printed_command, resimulated

from rollability_ros.cli import main as cli_main
from rollability_ros.core.campaign.plan import CampaignSpec, plan_trials
from rollability_ros.core.results import write_outcome_csv
from rollability_ros.core.records import CandidateRecord, LaunchOutcome, TipEventRecord
from rollability_ros.core.results.report import source_kind
from rollability_ros.core.store import Store

SUCCESS_PROBABILITY = {"baseline": 0.3, "A": 0.3, "B": 0.75, "C": 0.6}
FIGURES = ("fig04_convergence.png", "fig09_height_angle.png", "fig10_speed_angle.png", "fig11_angle_curves.png",
           "fig12_overall.png", "fig12b_overall_trials.png", "sim_vs_experiment.png")


def _campaign_outcomes(run_id="camp", repetitions=3):
    rng = random.Random(3)
    spec = CampaignSpec(run_id=run_id, repetitions=repetitions)
    return [LaunchOutcome(run_id, t.trial_id, t.condition, "sim",
                          rng.random() < SUCCESS_PROBABILITY[t.condition.configuration] + 0.2 * (t.condition.height_m > 1))
            for t in plan_trials(spec)]


@pytest.fixture(scope="module")
def store_report(tmp_path_factory):
    """A run directory with a campaign, an optimization and a tip event, reported through the CLI."""
    run_dir = tmp_path_factory.mktemp("run")
    outcomes = _campaign_outcomes()
    with Store(run_dir) as store:
        for outcome in outcomes:
            store.add_launch_outcome(outcome)
        for generation in range(6):
            for index in range(4):
                store.add_candidate(CandidateRecord("opt", generation, index, (0.1, 0.2), 0.1 * generation
                                                    + 0.05 * index, 0, 20, 7, 1.0))
        store.add_tip_event(TipEventRecord("rover", 5.0, 1.5, True, 130.0, 3.0))
        store.set_run_info("camp", "campaign", {"sim_fitness": {"A": 0.66, "B": 0.35, "C": 0.46}, "geometry": [
            {"configuration": "B", "length_m": 0.2, "width_m": 0.15, "max_height_m": 0.07}]})
    out = run_dir / "report"
    assert cli_main(["report", str(run_dir), "--out", str(out)]) == 0
    return run_dir, out, outcomes


def test_report_writes_figures_tables_and_one_self_contained_html(store_report, capsys):
    _, out, outcomes = store_report
    for name in FIGURES:
        assert (out / name).stat().st_size > 10_000, name
    tables = {p.stem for p in out.glob("*.csv")}
    assert tables == {"conditions", "by_configuration", "height_angle", "speed_angle", "by_speed", "by_height",
                      "by_angle", "sim_vs_experiment", "convergence", "geometry", "tip_events"}
    with open(out / "by_configuration.csv", newline="") as stream:
        rows = {row["configuration"]: row for row in csv.DictReader(stream)}
    for configuration in SUCCESS_PROBABILITY:
        own = [o for o in outcomes if o.condition.configuration == configuration]
        assert int(rows[configuration]["trials"]) == len(own) == 60
        assert int(rows[configuration]["successes"]) == sum(o.upright for o in own)
        assert int(rows[configuration]["conditions"]) == 20
    page = (out / "report.html").read_text()
    assert len(re.findall(r"<img [^>]*src='data:image/png;base64,", page)) == len(FIGURES)
    assert not re.search(r"src=['\"](?!data:)", page)  # nothing loaded from outside the file
    for href in re.findall(r"href='([^']*)'", page):   # links: sections of the page, or files next to it
        assert (href.startswith("#") and f"id='{href[1:]}'" in page) or (out / href).exists(), href
    assert "Spearman rho -1.00" in page


def test_summary_is_printed(tmp_path, capsys):
    path = tmp_path / "o.csv"
    write_outcome_csv(path, _campaign_outcomes(repetitions=1)[:20])
    assert cli_main(["report", str(path), "--out", str(tmp_path / "r"), "--sim-fitness", "baseline=0.2"]) == 0
    printed = capsys.readouterr().out
    assert "launch outcomes, simulated campaign (launch twin): 20 trials, 20 grouped conditions" in printed
    assert re.search(r"baseline\s+\d+/20", printed) and "report.html" in printed


def test_csv_source_gives_the_same_tables_as_the_store(store_report, tmp_path):
    run_dir, out, outcomes = store_report
    exported = tmp_path / "outcomes.csv"
    write_outcome_csv(exported, outcomes)
    assert cli_main(["report", str(exported), "--out", str(tmp_path / "r")]) == 0
    for name in ("conditions", "by_configuration", "height_angle", "speed_angle", "by_speed", "by_height",
                 "by_angle"):
        assert (tmp_path / "r" / f"{name}.csv").read_text() == (out / f"{name}.csv").read_text(), name


def test_sources_are_recognised_and_ambiguity_refused(store_report, tmp_path, capsys):
    run_dir, _, _ = store_report
    assert source_kind(run_dir) == "store" and source_kind(run_dir / "store.sqlite") == "store"
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(ValueError, match="not a store"):
        source_kind(tmp_path / "notes.txt")
    session = tmp_path / "session-1"   # what bringup and study write: outcomes.sqlite (issue 45)
    session.mkdir()
    shutil.copyfile(run_dir / "store.sqlite", session / "outcomes.sqlite")   # the module's store stays for the rest
    assert source_kind(session) == "store"
    assert cli_main(["report", str(session), "--out", str(tmp_path / "s")]) == 0
    assert not (session / "store.sqlite").exists() and (tmp_path / "s" / "report.html").is_file()
    with pytest.raises(ValueError, match="outcomes.sqlite .a study or bringup session"):
        source_kind(tmp_path / "s")
    two_runs = tmp_path / "two.sqlite"
    with Store(two_runs) as store:
        for outcome in _campaign_outcomes("r1", 1)[:3] + _campaign_outcomes("r2", 1)[:3]:
            store.add_launch_outcome(outcome)
    assert cli_main(["report", str(two_runs), "--out", str(tmp_path / "x")]) == 2
    assert "several runs (r1, r2); choose one with --run" in capsys.readouterr().err
    assert cli_main(["report", str(two_runs), "--run", "r3", "--out", str(tmp_path / "x")]) == 2
    assert cli_main(["report", str(two_runs), "--run", "r2", "--out", str(tmp_path / "x")]) == 0
    assert "launch outcomes, simulated campaign (launch twin): 3 trials" in capsys.readouterr().out


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def test_html_report_renders_its_figures_in_headless_chromium(store_report, tmp_path):
    chromium = _chromium()
    if chromium is None:
        pytest.skip("chromium not found (apt-get install -y chromium): cannot check the HTML renders")
    _, out, _ = store_report
    probe = tmp_path / "probe.html"
    # the report itself has no script; the probe records each image's decoded size once the page has loaded
    probe.write_text((out / "report.html").read_text() + "<script>window.addEventListener('load', () => "
                     "document.body.setAttribute('data-decoded', [...document.images].map(i => i.complete ? "
                     "i.naturalWidth + 'x' + i.naturalHeight : 'pending').join(' ')))</script>")
    dom = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                          "--disable-quic", "--disable-component-update", "--disable-sync", "--no-first-run",
                          f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=5000",
                          "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=120,
                         env=dict(os.environ, HOME=str(tmp_path))).stdout
    decoded = re.search(r'data-decoded="([^"]*)"', dom)
    assert decoded, "chromium did not load the page"
    sizes = decoded.group(1).split()
    assert len(sizes) == len(FIGURES)
    for size in sizes:
        width, height = (int(v) for v in size.split("x"))
        assert width > 300 and height > 300, sizes


def test_bag_of_the_campaign_gives_the_same_report_as_the_store(store_report, tmp_path):
    from rollability_ros.core.bags.messages import message_from_record, read_records_from_bag, typestore
    from rollability_ros.core.bags.writer import BagWriter

    run_dir, out, _ = store_report
    with Store(run_dir) as store:
        records = store.launch_outcomes() + store.candidates() + store.tip_events()
    records.insert(5, records[2])  # a republished outcome: stored once, so read once
    bag_dir = tmp_path / "campaign_bag"
    topics = {"rollability_ros/msg/LaunchOutcome": "/rollability/launch_outcomes",
              "rollability_ros/msg/CandidateResult": "/rollability/candidates",
              "rollability_ros/msg/TipEvent": "/tip_monitor/events"}
    with BagWriter(bag_dir) as bag:
        for type_name, topic in topics.items():
            bag.add_topic(topic, type_name)
        for number, record in enumerate(records):
            type_name, message = message_from_record(record)
            bag.write(topics[type_name], bytes(typestore().serialize_cdr(message, type_name)), 10**18 + number)
    outcomes, candidates, generations, tip_events = read_records_from_bag(bag_dir)
    with Store(run_dir) as store:
        assert repr(outcomes) == repr(store.launch_outcomes()) and candidates == store.candidates()  # NaN != NaN
        assert tip_events == store.tip_events() and generations == []
    assert cli_main(["report", str(bag_dir), "--out", str(tmp_path / "r"), "--sim-fitness", "A=0.66,B=0.35,C=0.46"]) == 0
    for name in ("conditions", "by_configuration", "height_angle", "speed_angle", "by_speed", "by_height",
                 "by_angle", "convergence", "tip_events", "sim_vs_experiment"):
        assert (tmp_path / "r" / f"{name}.csv").read_text() == (out / f"{name}.csv").read_text(), name


def test_table3_of_the_design_selection_gives_geometry_and_simulated_fitness(tmp_path, capsys):
    with Store(tmp_path) as store:
        for outcome in _campaign_outcomes(repetitions=1):
            store.add_launch_outcome(outcome)
    (tmp_path / "designs").mkdir()
    # the format selection.write_selection writes: the baseline has no profile and was not re-evaluated
    (tmp_path / "designs" / "table3.csv").write_text(
        "configuration,length_m,width_m,max_height_m,simulated_fitness,ci_low,ci_high,successes,trials,fitness_source\n"
        "baseline,0,0,0,nan,nan,nan,0,0,not evaluated\n"
        "A,0.2,0.15,0.031,0.66,0.6,0.7,132,200,reevaluated\n"
        "B,0.2,0.15,0.072,0.35,0.3,0.4,70,200,reevaluated\n")
    assert cli_main(["report", str(tmp_path), "--out", str(tmp_path / "r"), "--sim-fitness", "B=0.4"]) == 0
    # two configurations cannot be ranked (any correlation is +-1): no statistic, and the reason
    assert ("simulated fitness vs simulated campaign (2 configurations): no rank statistic: 2 configuration(s), "
            "ranks need at least 3") in capsys.readouterr().out
    with open(tmp_path / "r" / "sim_vs_experiment.csv", newline="") as stream:
        assert {row["configuration"]: float(row["sim_fitness"]) for row in csv.DictReader(stream)} == {
            "A": 0.66, "B": 0.4}  # the command line wins over the table
    with open(tmp_path / "r" / "geometry.csv", newline="") as stream:
        assert [row["configuration"] for row in csv.DictReader(stream)] == ["baseline", "A", "B"]


def _dom_after_script(chromium, page, script, tmp_path):
    """Load ``page`` plus ``script`` in headless chromium; return the DOM it dumps."""
    probe = tmp_path / "probe_nav.html"
    probe.write_text(page.read_text() + f"<script>window.addEventListener('load', () => {{{script}}})</script>")
    return subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                           "--disable-quic", "--disable-component-update", "--disable-sync", "--no-first-run",
                           f"--user-data-dir={tmp_path / 'profile_nav'}", "--virtual-time-budget=5000",
                           "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, HOME=str(tmp_path))).stdout


def test_report_navigation_links_and_per_trial_drill_down_in_headless_chromium(tmp_path):
    """The committed sample run plus a design folder: every contents entry leads to a section, every file link to
    a file, and each launch of the bag has its pose trace."""
    from rollability_ros.core.profile import geometry

    chromium = _chromium()
    if chromium is None:
        pytest.skip("chromium not found (apt-get install -y chromium): cannot check the HTML renders")
    run = tmp_path / "sample_run"
    shutil.copytree(os.path.join(os.path.dirname(__file__), "..", "..", "bags", "sample"), run / "bag")
    grid = geometry.ProfileGrid(rows=3, cols=3)
    (run / "designs").mkdir()
    geometry.export_mesh(geometry.profile_mesh([0.1, 0.2, 0.3] * 3, grid), run / "designs" / "mesh_A.stl")
    out = run / "report"
    assert cli_main(["report", str(run / "bag"), "--out", str(out)]) == 0
    dom = _dom_after_script(chromium, out / "report.html", (
        "const anchors = [...document.querySelectorAll('#contents a')].map(a => a.getAttribute('href'));"
        "document.body.setAttribute('data-missing', anchors.filter(h => !document.getElementById(h.slice(1)))"
        ".join(' ') || 'none');"
        "document.body.setAttribute('data-anchors', anchors.length);"
        "document.body.setAttribute('data-files', [...document.querySelectorAll('ul.artefacts a')]"
        ".map(a => a.getAttribute('href')).join(' '));"
        "document.body.setAttribute('data-traced', document.querySelectorAll('table.trials code').length);"
        "document.body.setAttribute('data-trials', document.querySelectorAll('table.trials tr[id]').length);"),
        tmp_path)
    attributes = dict(re.findall(r'data-(missing|anchors|files|traced|trials)="([^"]*)"', dom))
    assert attributes, "chromium did not load the page"
    assert attributes["missing"] == "none" and int(attributes["anchors"]) >= 8
    files = attributes["files"].split()
    assert os.path.join("..", "designs", "mesh_A.stl") in files and os.path.join("..", "bag") in files
    assert all((out / href).exists() for href in files), files
    assert int(attributes["trials"]) == 36                     # every launch of the sample bag
    assert int(attributes["traced"]) >= 30, attributes         # with its chassis poses in the bag


def test_heat_map_text_contrasts_with_its_cell_and_a_design_preview_renders(tmp_path):
    from rollability_ros.core.profile import geometry
    from rollability_ros.core.results.report_figures import _text_colour, render_profile_preview

    assert _text_colour(0.0) == "white" and _text_colour(1.0) == "white" and _text_colour(0.5) == "black"
    mesh = geometry.profile_mesh([0.1, 0.2, 0.3] * 3, geometry.ProfileGrid(rows=3, cols=3))
    path = render_profile_preview(mesh, str(tmp_path / "preview.png"), title="A")
    assert open(path, "rb").read(8) == b"\x89PNG\r\n\x1a\n" and os.path.getsize(path) > 5000
    assert os.path.getsize(render_profile_preview(None, str(tmp_path / "none.png"))) > 1000


def test_report_leads_with_fresh_reevaluations_beside_the_in_run_estimates(tmp_path, capsys):
    """Table 3 of the selection (design_set.TABLE_COLUMNS) carries both estimates; the summary opens with them,
    the selection bias between them, and labels the launch-twin campaign simulated."""
    with Store(tmp_path) as store:
        for outcome in _campaign_outcomes(repetitions=1):
            store.add_launch_outcome(outcome)
    (tmp_path / "designs").mkdir()
    (tmp_path / "designs" / "table3.csv").write_text(
        "configuration,length_m,width_m,max_height_m,simulated_fitness,ci_low,ci_high,successes,trials,fitness_source,"
        "in_run_fitness,in_run_ci_low,in_run_ci_high,in_run_successes,in_run_trials,selection_bias\n"
        "baseline,0,0,0,0.1,0.04,0.2,6,60,reevaluated,nan,nan,nan,0,0,nan\n"
        "A,0.2,0.15,0.031,0.35,0.24,0.48,21,60,reevaluated,0.75,0.53,0.89,15,20,0.4\n")
    assert cli_main(["report", str(tmp_path), "--out", str(tmp_path / "r")]) == 0
    printed = capsys.readouterr().out.splitlines()
    # the lead first: no world check of the designs, so nothing is recommended, and that is said first
    assert printed[0].startswith("RECOMMENDATION: NO DESIGN IS RECOMMENDED: no plausible-world check")
    lines = printed[next(i for i, line in enumerate(printed) if line.startswith("source: ")):]
    assert lines[1].startswith("simulated fitness of the chosen designs: fresh re-evaluation (headline)")
    assert re.match(r"A\s+21/60\s+0.35 \[0.24, 0.48\]\s+15/20\s+0.75 \[0.53, 0.89\]\s+\+0.40$", lines[4]), lines[4]
    assert re.match(r"baseline\s+6/60\s+0.10 .*-\s+-$", lines[3]), lines[3]
    assert lines[5].startswith("launch outcomes, simulated campaign (launch twin): ")


def test_physical_campaign_is_experimental_and_invalid_launches_are_left_out(tmp_path, capsys):
    outcomes = [dataclasses.replace(o, backend="physical", classified_by="operator")
                for o in _campaign_outcomes(repetitions=1)[:20]]
    invalid = dataclasses.replace(outcomes[0], trial_id="again", upright=True,
                                  note="invalid launch: did not leave the ledge")
    path = tmp_path / "o.sqlite"
    with Store(path) as store:
        for outcome in outcomes + [invalid]:
            store.add_launch_outcome(outcome)
    assert cli_main(["report", str(path), "--out", str(tmp_path / "r")]) == 0
    printed = capsys.readouterr().out
    assert ("launch outcomes, experimental campaign (rig): 20 trials, 20 grouped conditions (run camp; backend "
            "physical); 1 invalid launch(es) left out") in printed
    with open(tmp_path / "r" / "by_configuration.csv", newline="") as stream:
        assert sum(int(row["trials"]) for row in csv.DictReader(stream)) == 20


def test_drill_down_shows_each_seed_and_its_command_simulates_the_stored_launch_again(tmp_path, capsys):
    """trial -> seed -> the same launch again: simulated launches go msg -> store -> CSV -> report with their seed,
    and the command the drill-down shows for one reproduces the stored outcome and final orientation."""
    import html
    import shlex

    pytest.importorskip("pybullet")
    from rollability_ros.core.bags.messages import message_from_record, record_from_message, typestore
    from rollability_ros.core.campaign.runner import LocalRig, local_rig_settings
    from rollability_ros.core.config import load_parameters
    from rollability_ros.core.sim import load_launch_twin_settings
    from rollability_ros.core.results import read_outcome_csv
    from rollability_ros.core.records import NO_SEED

    rig = LocalRig(local_rig_settings("sim", load_parameters(["rig"])), read_twin=load_launch_twin_settings)
    try:
        baseline = [t for t in plan_trials(CampaignSpec(run_id="seeded", repetitions=1))
                    if t.condition.configuration == "baseline"]       # the shipped twin has no designs A/B/C
        launched = [rig.backend.launch("seeded", t.trial_id, t.condition) for t in baseline[::5]]
    finally:
        rig.close()
    physical = LaunchOutcome("seeded", "hand/1", launched[0].condition, "physical", True, classified_by="operator")
    assert all(o.seed >= 0 for o in launched) and physical.seed == NO_SEED
    received = []
    for outcome in launched + [physical]:                        # as the outcome_logger receives them
        type_name, message = message_from_record(outcome)
        cdr = bytes(typestore().serialize_cdr(message, type_name))
        received.append(record_from_message(type_name, typestore().deserialize_cdr(cdr, type_name)))
    with Store(tmp_path / "run") as store:
        for outcome in received:
            store.add_launch_outcome(outcome)
        stored = store.launch_outcomes()
    assert [o.seed for o in stored] == [o.seed for o in launched] + [NO_SEED]
    write_outcome_csv(tmp_path / "outcomes.csv", stored)
    assert [o.seed for o in read_outcome_csv(tmp_path / "outcomes.csv")] == [o.seed for o in stored]

    assert cli_main(["report", str(tmp_path / "outcomes.csv"), "--out", str(tmp_path / "report")]) == 0
    page = (tmp_path / "report" / "report.html").read_text()
    rows = {trial: row for trial, row in re.findall(r"<tr id='trial-[^']*'><td>([^<]*)</td>(.*?)</tr>", page)}
    assert "seed: re-simulate" in page and "none (physical launch)" in rows["hand/1"]
    target = stored[1]
    commands = re.findall(r"<code>(rollability campaign [^<]*)</code>", rows[html.escape(target.trial_id)])
    assert len(commands) == 1 and f"--seed {target.seed}" in commands[0]
    capsys.readouterr()
    assert cli_main(shlex.split(html.unescape(commands[0]))[1:]) == 0
    printed = dict(line.split(": ", 1) for line in capsys.readouterr().out.splitlines())
    assert printed["upright"] == str(target.upright).lower()
    assert tuple(float(v) for v in printed["final_orientation (x, y, z, w)"].split()) == target.final_orientation
    assert float(printed["travel_time_s"]) == pytest.approx(target.travel_time_s, abs=1e-12)
    for name, value in target.continuous().items():   # the stored continuous outcomes, repeated exactly
        assert float(printed[name]) == pytest.approx(value, abs=1e-12, nan_ok=True), name
    assert cli_main(["campaign", "--backend", "physical", "--resimulate", "baseline", "0.75", "0.8", "0",
                     "--seed", "1"]) == 2                       # a physical launch cannot be simulated again
    assert "--resimulate needs --backend sim" in capsys.readouterr().err


def test_report_draws_only_the_designs_of_the_run_it_reports(tmp_path):
    """Two optimization runs side by side under runs/ and a campaign store next to them (issue 28: the report drew
    a sibling run's "Design A", another robot's part): a store or run directory shows the designs of the run it
    names (its recorded designs_file, or its own designs/ folder) and never a sibling's."""
    from rollability_ros.core.campaign.runner import record_campaign_run
    from rollability_ros.core.profile import geometry
    from rollability_ros.core.results import report

    runs = tmp_path / "runs"
    grid = geometry.ProfileGrid(rows=3, cols=3)
    meshes = {}
    for name, height in (("small-robot", 0.05), ("large-robot", 0.3)):
        folder = runs / name / "designs"
        folder.mkdir(parents=True)
        meshes[name] = str(folder / "mesh_A.stl")
        geometry.export_mesh(geometry.profile_mesh([height] * 9, grid), meshes[name])
        (folder / "designs.yaml").write_text("/**:\n  ros__parameters:\n    designs:\n      labels: [A]\n",
                                             encoding="utf-8")
        with Store(runs / name) as store:
            store.add_candidate(CandidateRecord(name, 1, 0, (height,), 0.5, 0, 20, 10, 1.0))
    for name in meshes:   # each optimization run directory: its own designs only
        assert report.load_report_data(runs / name).design_meshes == {"A": meshes[name]}
    campaign = runs / "campaign.sqlite"
    with Store(str(campaign)) as store:
        for outcome in _campaign_outcomes(repetitions=1)[:8]:
            store.add_launch_outcome(outcome)
    data = report.load_report_data(campaign)
    assert data.design_meshes == {} and data.design_folders == []        # names no run: no sibling's design
    with Store(str(campaign)) as store:
        record_campaign_run(store, "camp", "sim", {"designs_file": str(runs / "large-robot" / "designs" /
                                                                       "designs.yaml"), "mesh_files": {}})
    data = report.load_report_data(campaign)
    assert data.design_meshes == {"A": meshes["large-robot"]}
    linked = [path for path, _ in report.find_artefacts(data.design_folders, str(campaign))]
    assert meshes["large-robot"] in linked and meshes["small-robot"] not in linked
    assert cli_main(["report", str(campaign), "--out", str(tmp_path / "out")]) == 0
    html = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    assert "large-robot" in html and "small-robot" not in html


def test_a_study_reports_only_the_designs_its_campaign_launched(tmp_path):
    """Issue 42: a campaign run through the graph recorded no designs_file, so after a later `select` the study's
    report listed designs-2/ and designs-3/ beside the set the campaign launched. The study records it (the logger
    stopped: one writer) and a report with a recorded set lists that set only."""
    from rollability_ros.core.graph import Study, study_config
    from rollability_ros.core.results import report

    config = tmp_path / "study.yaml"
    config.write_text(f"/**:\n  ros__parameters:\n    bringup: {{output_dir: '{tmp_path / 'runs'}'}}\n")
    study = Study(study_config([str(config)], "s1"), say=lambda text: None)
    launched = os.path.dirname(study.designs_file)
    for folder in (launched, launched + "-2", launched + "-3"):   # the study's selection, then two later ones
        os.makedirs(folder)
        with open(os.path.join(folder, "designs.yaml"), "w", encoding="utf-8") as stream:
            stream.write("/**:\n  ros__parameters:\n    designs:\n      labels: [A]\n")
    with Store(study.store_path) as store:
        for outcome in _campaign_outcomes(run_id="s1", repetitions=1)[:4]:
            store.add_launch_outcome(outcome)
    assert len(report.load_report_data(study.store_path, run_id="s1").design_folders) == 3   # nothing recorded
    study._record_campaign_designs()
    with Store(study.store_path) as store:
        assert store.run_info("s1")["info"]["designs"]["designs_file"] == study.designs_file
    assert report.load_report_data(study.store_path, run_id="s1").design_folders == [launched]


def test_the_sim_rig_records_where_its_designs_come_from(tmp_path):
    from rollability_ros.core.rig.launch_backend import RigSettings
    from rollability_ros.core.rig.rig_session import SimulatedLaunch
    from rollability_ros.core.rig.speed_gate import SpeedGateConfig

    twin = tmp_path / "twin.yaml"
    twin.write_text("/**:\n  ros__parameters:\n    launch_twin:\n      designs:\n        designs_file: d/designs.yaml\n",
                    encoding="utf-8")
    from rollability_ros.core.sim import load_launch_twin_settings

    twin_config = ["sim", "robot", "launch_twin", str(twin)]
    backend = SimulatedLaunch(RigSettings(twin_config=twin_config), SpeedGateConfig(),
                              load_launch_twin_settings(twin_config))
    assert backend.design_sources() == {"designs_file": os.path.abspath("d/designs.yaml"), "mesh_files": {}}


def _tiny_design_campaign(folder):
    """Two launches (the bare robot and design A at one condition) on the sim rig in this process, through
    `rollability campaign`; its twin file, designs file and store all in ``folder``. Returns the store path."""
    import yaml

    pytest.importorskip("pybullet")
    os.makedirs(folder)
    _, twin = design_twin_files(folder)
    campaign = os.path.join(folder, "campaign.yaml")
    with open(campaign, "w", encoding="utf-8") as stream:
        yaml.safe_dump({"/**": {"ros__parameters": {"campaign": {
            "run_id": "tiny", "configurations": ["baseline", "A"], "heights_m": [0.75], "speeds_mps": [0.8],
            "angles_deg": [0.0], "repetitions": 1}}}}, stream)
    store = os.path.join(folder, "outcomes.sqlite")
    assert cli_main(["campaign", "--backend", "sim", "--config", campaign, "--rig-config", "rig", "--rig-config", twin,
                     "--store", store]) == 0
    return store


def test_a_designs_launch_is_resimulated_as_printed_on_the_twin_files_its_campaign_recorded(tmp_path, capsys):
    """The docs audit: the report's command for design A's launch stopped with "unknown configuration 'A'" (the
    run recorded no twin files; only --rig-config added by hand worked). The campaign records its twin files and
    the printed command reproduces the stored outcome exactly, also after the folder moved; a changed or missing
    twin file is refused in one line naming it; --rig-config still overrides, and says so."""
    store = _tiny_design_campaign(tmp_path / "run")
    command, target = printed_command(store, tmp_path / "report", "A")
    code, printed, _ = resimulated(command, capsys)
    assert code == 0
    assert_reproduces(printed, target)

    twin = tmp_path / "run" / "twin.yaml"
    original = twin.read_text()
    twin.write_text(original + "# edited\n")
    code, _, err = resimulated(command, capsys)
    assert code == 2 and err.count("\n") == 1
    assert f"its twin file {twin} changed since the campaign" in err
    code, again, err = resimulated(_with_rig_config(command, ["rig", str(twin)]), capsys)
    assert code == 0 and err.startswith("note: --rig-config given: re-simulating on its files")   # the user's win
    twin.write_text(original)

    shutil.move(tmp_path / "run", tmp_path / "moved")       # the study folder moved whole: its own files found
    moved = command.replace(store, str(tmp_path / "moved" / "outcomes.sqlite"))
    assert resimulated(moved, capsys)[1] == printed
    twin = tmp_path / "moved" / "twin.yaml"
    twin.unlink()
    code, _, err = resimulated(moved, capsys)
    assert code == 2 and f"its twin file {twin} (recorded as " in err and "is missing" in err
    twin.write_text(original)
    designs = tmp_path / "moved" / "designs.yaml"
    designs.write_text(designs.read_text().replace("0.4", "0.35"))
    code, _, err = resimulated(moved, capsys)
    assert code == 2 and f"its designs file {designs} changed since the campaign" in err


def _with_rig_config(command, files):
    """``command`` with ``--rig-config FILE`` for each of ``files``."""
    import shlex

    return command + "".join(f" --rig-config {shlex.quote(path)}" for path in files)


def test_a_run_stored_before_twin_files_were_recorded_resimulates_as_before_with_a_note(tmp_path, capsys):
    """A run whose info records no twin (stored before this record existed) falls back to the shipped rig files,
    with a one-line note saying so: the bare robot's launch still reproduces; a design's needs --rig-config."""
    store = _tiny_design_campaign(tmp_path / "run")
    with Store(store) as opened:
        info = dict(opened.run_info("tiny")["info"])
        assert [entry["given"] for entry in info["twin"]["files"]][:3] == ["sim", "robot", "launch_twin"]
        assert info["twin"]["designs_file"]["path"] == "designs.yaml"       # inside the store's folder: relative
        del info["twin"]
        opened.set_run_info("tiny", "campaign", info)
    command, target = printed_command(store, tmp_path / "report", "baseline")
    code, printed, err = resimulated(command, capsys)
    assert code == 0 and printed["upright"] == str(target.upright).lower()
    assert err.startswith("note: run tiny's twin files were not recorded") and err.count("\n") == 1
    assert resimulated(printed_command(store, tmp_path / "report", "A")[0], capsys)[0] == 2


def test_a_physical_run_records_that_it_had_no_twin_and_its_resimulation_says_so(tmp_path, capsys):
    """A physical rig launches on no twin: its campaign records that plainly, and a re-simulation of its run is
    refused in one line saying the run was physical (not run on the shipped files as if they were its twin)."""
    from rollability_ros.core.campaign import record_campaign_run

    store = tmp_path / "o.sqlite"
    with Store(store) as opened:
        record_campaign_run(opened, "bench", "physical", {}, [])
        assert opened.run_info("bench")["info"] == {"backend": "physical", "twin": {"no_twin": "physical"}}
    capsys.readouterr()
    assert cli_main(["campaign", "--backend", "sim", "--resimulate", "baseline", "0.75", "0.8", "0", "--seed", "1",
                     "--store", str(store), "--run-id", "bench"]) == 2
    err = capsys.readouterr().err
    assert "run bench was launched on the physical rig, not on a twin" in err and err.count("\n") == 1


def test_a_study_records_its_rigs_twin_files_relative_to_its_folder(tmp_path):
    """The study's rig loads the study's copies of its parameter files and its study.yaml (naming the designs it
    launches); the study records them, relative to its folder, so a moved study re-simulates on its own files."""
    from rollability_ros.core.campaign import recorded_twin
    from rollability_ros.core.graph import Study, study_config

    config = tmp_path / "study.yaml"
    config.write_text(f"/**:\n  ros__parameters:\n    bringup: {{output_dir: '{tmp_path / 'runs'}'}}\n")
    study = Study(study_config([str(config)], "s1"), say=lambda text: None)
    study.make_study_dir()
    os.makedirs(os.path.dirname(study.designs_file))
    with open(study.designs_file, "w", encoding="utf-8") as stream:
        stream.write("/**:\n  ros__parameters:\n    designs:\n      labels: [A]\n")
    rig = study._campaign_nodes(["A"])[0]
    with Store(study.store_path) as store:
        for outcome in _campaign_outcomes(run_id="s1", repetitions=1)[:4]:
            store.add_launch_outcome(outcome)
    study._record_campaign_designs()
    with Store(study.store_path) as store:
        info = store.run_info("s1")["info"]
    recorded = [entry["path"] for entry in info["twin"]["files"]]
    assert recorded == [os.path.relpath(path, study.study_dir) for path in rig.params["rig.twin_config"]]
    assert recorded[-1] == "study.yaml" and all(not os.path.isabs(path) for path in recorded)
    moved = tmp_path / "moved"
    shutil.copytree(study.study_dir, moved)
    twin = recorded_twin(info, str(moved), "s1")
    assert twin.twin_config == [str(moved / path) for path in recorded]
    assert twin.designs_file == str(moved / "optimization" / "designs" / "designs.yaml")


def test_a_run_whose_sessions_loaded_different_twin_files_is_refused_for_resimulation(tmp_path):
    """A campaign resumed on edited twin files: no one set re-simulates all its launches, so the record says so
    and a re-simulation is refused in one line (not run on the later session's files)."""
    from rollability_ros.core.campaign import record_campaign_run, recorded_twin

    twin = tmp_path / "twin.yaml"
    twin.write_text("/**:\n  ros__parameters:\n    launch_twin: {}\n", encoding="utf-8")
    with Store(tmp_path / "o.sqlite") as store:
        record_campaign_run(store, "camp", "sim", {}, ["sim", str(twin)])
        first = store.run_info("camp")["info"]
        assert recorded_twin(first, str(tmp_path), "camp").twin_config[1] == str(twin)
        record_campaign_run(store, "camp", "sim", {}, ["sim", str(twin)])     # the same files again: kept
        assert store.run_info("camp")["info"] == first
        twin.write_text("/**:\n  ros__parameters:\n    launch_twin: {foam: {restitution: 0.3}}\n", encoding="utf-8")
        record_campaign_run(store, "camp", "sim", {}, ["sim", str(twin)])
        info = store.run_info("camp")["info"]
    with pytest.raises(ValueError, match="^run camp was launched on different twin files in different sessions"):
        recorded_twin(info, str(tmp_path), "camp")
