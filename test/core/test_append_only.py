"""Issue 26, point 2: recorded results are append-only. A second `select` writes a new design set beside the one a
campaign used, a resumed study keeps the id it was started under whatever its folder is called now, and a refused
command writes nothing. Every check compares the SHA-256 of every existing file before and after."""
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
import yaml

from doubles import SyntheticEvaluator, damaged_store, tree_checksums
from rollability_ros.cli import main
from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config
from rollability_ros.core.profile import geometry
from rollability_ros.core.records import LaunchCondition, LaunchOutcome
from rollability_ros.core.store import Store

REPO = os.path.join(os.path.dirname(__file__), "..", "..")
GRID = geometry.ProfileGrid(rows=3, cols=3)


def _run(root):
    """A finished 12-generation optimization run on the synthetic fitness, in ``<root>/run``."""
    run_dir = os.path.join(root, "run")
    parameters = {"optimizer.max_generations": 12, "optimizer.seed": 5, "optimizer.trials": 30,
                  "optimizer.sigma0": 0.1, "profile.rows": GRID.rows, "profile.cols": GRID.cols}
    run = OptimizationRun(run_dir, run_config(parameters), GRID, SyntheticEvaluator(np.linspace(0.1, 0.4, GRID.n_variables), 30))
    run.run()
    run.close()
    return run_dir


def _outcome(trial, configuration):
    condition = LaunchCondition(configuration, 0.1, 1.0, 0.0, trial)
    return LaunchOutcome("campaign-1", f"t{trial}-{configuration}", condition, "physical", trial % 2 == 0,
                         classified_by="operator", stamp_s=1.7e9 + trial)


def test_select_on_a_run_whose_designs_a_campaign_used_writes_a_new_design_set(tmp_path, capsys):
    """Was: the second `select` rewrote designs.yaml, the meshes and table3.csv the stored outcomes point at."""
    from rollability_ros.core.optimization.design_set import design_set_folders
    from rollability_ros.core.profile.designs import DesignSources, profile_mesh_for
    from rollability_ros.core.results import report

    run_dir = _run(tmp_path)
    assert main(["select", run_dir, "--count", "2", "--min-distance", "0.05"]) == 0
    first = os.path.join(run_dir, "designs")
    with Store(os.path.join(run_dir, "campaign.sqlite")) as store:   # a campaign launched A and B of that set
        for trial in range(4):
            for configuration in ("baseline", "A", "B"):
                store.add_launch_outcome(_outcome(trial, configuration))
    with Store(run_dir) as store:
        first_info = store.run_info("run")["info"]
    capsys.readouterr()
    before = tree_checksums(run_dir)

    assert main(["select", run_dir, "--count", "1", "--min-distance", "0.3", "--mesh-units", "m"]) == 0
    out = capsys.readouterr().out
    second = os.path.join(run_dir, "designs-2")
    assert f"wrote {second}/" in out and "earlier design set(s) kept unchanged (designs:" in out
    after = tree_checksums(run_dir)
    store_files = {name for name in before if name.startswith("store.sqlite")}   # the run's record: appended to
    assert {name: after.get(name) for name in before if name not in store_files} == \
        {name: digest for name, digest in before.items() if name not in store_files}
    assert sorted(set(after) - set(before)) == sorted(os.path.join("designs-2", name) for name in (
        "designs.yaml", "mesh_A.3mf", "mesh_A.stl", "table3.csv"))
    assert design_set_folders(run_dir) == [first, second]

    with Store(run_dir) as store:   # the first selection's numbers stay in the run's record
        info = store.run_info("run")["info"]
    assert info["selection"]["folder"] == "designs-2"
    assert info["earlier_selections"] == [{key: first_info[key] for key in ("sim_fitness", "geometry", "table3",
                                                                          "selection")}]
    # both sets stay usable by a campaign (the twin's designs_file) and a report (--geometry)
    for folder in (first, second):
        sources = DesignSources(designs_file=os.path.join(folder, "designs.yaml"))
        assert profile_mesh_for("A", sources).is_watertight
        data = report.load_report_data(os.path.join(run_dir, "campaign.sqlite"))
        report.use_geometry_csv(data, os.path.join(folder, "table3.csv"))
        assert [row["configuration"] for row in data.geometry][-1] in ("A", "B")


def _study_config(tmp_path):
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"bringup": {"output_dir": str(tmp_path / "runs")}}}}))
    return str(path)


def test_a_resumed_study_keeps_its_recorded_id_whatever_its_folder_is_called(tmp_path):
    """Was: the id came from the folder name, so a copied folder ran a second campaign under a new run id."""
    from rollability_ros.core.graph.study import STUDY_ID_FILE, Study, study_config

    study = Study(study_config([_study_config(tmp_path)], "field-week"), say=lambda text: None)
    study.make_study_dir()
    copied = tmp_path / "elsewhere" / "copy-of-field-week"
    shutil.copytree(study.study_dir, copied)
    said = []
    resumed = Study(study_config(resume=str(copied)), say=said.append)
    assert resumed.study_id == "field-week" and resumed.study_dir == str(copied)
    _, runner = resumed._campaign_nodes(["A"])
    assert runner.params["campaign.run_id"] == "field-week"

    # a study made before the id was recorded: the one campaign run its outcome store holds
    os.remove(copied / STUDY_ID_FILE)
    with Store(str(copied / "outcomes.sqlite")) as store:
        store.add_launch_outcome(_outcome(0, "baseline"))
    assert Study(study_config(resume=str(copied)), say=said.append).study_id == "campaign-1"
    os.remove(copied / "outcomes.sqlite")
    assert Study(study_config(resume=str(copied)), say=said.append).study_id == "copy-of-field-week"   # no campaign yet


def _cli(*argv, cwd):
    environment = dict(os.environ, PYTHONPATH=os.path.abspath(REPO), LC_ALL="C.UTF-8", TERM="dumb",
                       PYTHONUNBUFFERED="1")
    return subprocess.run([sys.executable, "-m", "rollability_ros.cli", *argv], capture_output=True, text=True,
                          timeout=300, cwd=cwd, env=environment)


@pytest.mark.parametrize("argv, reason", [
    (["study", "--study-id", "existing"], "already exists"),
    (["study", "--study-id", "../escaped"], "one folder name"),
    (["study", "--study-id", ""], "one folder name"),
    (["optimize", "--config", "optimizer", "--run-id", "existing"], "already exists"),
    (["optimize", "--config", "optimizer", "--run-id", "../escaped"], "one folder name"),
    (["optimize", "--config", "optimizer", "--run-id", ""], "one folder name"),
    (["optimize", "--config", "optimizer", "--run-id", "a/b"], "one folder name"),
    (["optimize", "--config", "optimizer", "--run-id", "."], "one folder name"),
])
def test_a_refused_command_writes_nothing(tmp_path, argv, reason):
    """Was: FileExistsError tracebacks, a run written outside the output folder, a refused run writing config.yaml."""
    if argv[0] == "study":
        argv = [*argv, "--config", _study_config(tmp_path)]
    existing = tmp_path / "runs" / "existing"
    existing.mkdir(parents=True)
    (existing / "config.yaml").write_text("/**:\n  ros__parameters: {}\n")
    (existing / "notes.txt").write_text("the operator's notes\n")
    before = tree_checksums(tmp_path)
    result = _cli(*argv, cwd=tmp_path)
    assert result.returncode == 2, result.stdout + result.stderr
    assert reason in result.stderr and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert "Traceback" not in result.stderr
    assert tree_checksums(tmp_path) == before                 # nothing new, nothing changed


def test_a_run_resumed_from_a_copied_folder_keeps_its_settings_but_not_its_old_location(tmp_path):
    """A copied study resumes its optimization with optimizer.output_dir naming the new folder: the location is
    not a setting of the run (was: "configuration differs ... optimizer.output_dir"); a real change is refused."""
    from rollability_ros.core.config import ConfigError

    parameters = {"optimizer.max_generations": 3, "optimizer.seed": 5, "optimizer.trials": 20,
                  "optimizer.output_dir": str(tmp_path / "first"), "profile.rows": 3, "profile.cols": 3}
    evaluator = SyntheticEvaluator(np.linspace(0.1, 0.4, GRID.n_variables), 20)
    run = OptimizationRun(str(tmp_path / "first" / "optimization"), run_config(parameters), GRID, evaluator)
    run.run()
    run.close()
    shutil.copytree(tmp_path / "first", tmp_path / "copy")
    moved = {**parameters, "optimizer.output_dir": str(tmp_path / "copy")}
    resumed = OptimizationRun(str(tmp_path / "copy" / "optimization"), run_config(moved), GRID, evaluator, resume=True)
    assert resumed.optimizer.generation == 3 and resumed.run_id == "optimization"
    resumed.close()
    with pytest.raises(ConfigError, match="optimizer.trials"):
        OptimizationRun(str(tmp_path / "copy" / "optimization"), run_config({**moved, "optimizer.trials": 30}), GRID, evaluator,
                        resume=True)


def _flip_middle(path):
    data = bytearray(path.read_bytes())
    for index in range(len(data) // 2, len(data) // 2 + 16):
        data[index] ^= 0xFF
    path.write_bytes(bytes(data))


def _closed_bag(directory):
    from test_bags import write_string_bag

    write_string_bag(directory, 10)
    return directory


@pytest.mark.parametrize("damage, named", [
    (lambda study: _flip_middle(study / "optimization" / "checkpoint.json"), "optimization/checkpoint.json is damaged"),
    (lambda study: (study / "optimization" / "checkpoint.json").write_bytes(b""), "checkpoint.json is damaged"),
    (lambda study: damaged_store(study / "optimization" / "store.sqlite", run_id="optimization"),
     "optimization/store.sqlite is damaged"),
    (lambda study: damaged_store(study / "outcomes.sqlite", run_id="field-week"), "outcomes.sqlite is damaged"),
    (lambda study: (study / "outcomes.sqlite").write_bytes(b"garbage" * 1000), "outcomes.sqlite is not a usable"),
    (lambda study: (study / "study-id.txt").write_bytes(b"\xff\xfe\x00x"), "study-id.txt must be one folder name"),
    (lambda study: (study / "config" / "00-sim.yaml").write_bytes(b"\xff\xfe\x00"), "00-sim.yaml is not UTF-8"),
    (lambda study: _closed_bag(study / "bag").joinpath("metadata.yaml").write_bytes(b"\xff\x00"),
     "bag/metadata.yaml: not UTF-8 text"),
], ids=["checkpoint-flipped", "checkpoint-empty", "run-store", "outcome-store", "outcome-store-garbage",
        "study-id-binary", "config-binary", "closed-bag-metadata"])
def test_a_resume_of_a_damaged_study_is_refused_before_anything_starts(tmp_path, damage, named):
    """Was: `study --resume` started the graph on a damaged checkpoint or store; the optimizer or the outcome
    logger failed (the logger three times) and the reason was left in a node's log; a binary study-id.txt or
    parameter file gave "'utf-8' codec can't decode" naming no file; an earlier bag whose metadata.yaml was damaged
    failed the study after its campaign, with no summary. Now one ValueError naming the file, before any
    process starts, and no file changes."""
    from rollability_ros.core.graph.study import Study, study_config

    study = Study(study_config([_study_config(tmp_path)], "field-week"), say=lambda text: None)
    study.make_study_dir()
    run = OptimizationRun(study.optimization_dir, run_config({
        "optimizer.max_generations": 2, "optimizer.trials": 10, "profile.rows": 3, "profile.cols": 3}), GRID,
        SyntheticEvaluator(np.linspace(0.1, 0.4, GRID.n_variables), 10))
    run.run()
    run.close()
    root = tmp_path / "runs" / "field-week"
    Study(study_config(resume=str(root)), say=lambda text: None)   # intact: resumable
    damage(root)
    before = tree_checksums(root)
    with pytest.raises(ValueError, match=named.replace(".", r"\.")):
        study_config(resume=str(root))
    assert tree_checksums(root) == before
