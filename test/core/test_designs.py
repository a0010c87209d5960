"""Configuration ids resolve to the right solids: baseline, a selection's designs.yaml, STL files; bad ids refused."""
import os

import numpy as np
import pytest
import yaml

from rollability_ros.core.profile import geometry
from rollability_ros.core.config import ConfigError
from rollability_ros.core.profile.designs import DesignSources, configuration_ids, profile_mesh_for
from rollability_ros.core.optimization.design_set import designs_document
from rollability_ros.core.optimization.selection import PooledDesign, SelectedDesign, SelectionResult

pytest.importorskip("trimesh")

GRID = geometry.ProfileGrid(rows=4, cols=3)
#: GRID as a designs file holds it (flow style, one line).
GRID_YAML = ("grid: {rows: 4, cols: 3, length_m: 0.18, width_m: 0.14, height_min: 0.0, height_max: 0.45, "
             "unit_m: 0.2}")


def ramp_heights(top):
    """Heights rising along x to ``top`` (simulation units): a valid, non-flat design."""
    return np.repeat(np.linspace(0.05, top, GRID.rows), GRID.cols)


def write_designs(folder, tops):
    """A designs.yaml exactly as ``rollability select`` writes it, with one ramp design per label -> top."""
    chosen = [SelectedDesign(label, PooledDesign(ramp_heights(top), 9, 10, 1, 1), mesh=None, metrics=None,
                             reason="a ramp to the given top") for label, top in tops.items()]
    document = designs_document(SelectionResult(designs=chosen, requested=len(chosen), considered=len(chosen), rejected={}),
                                GRID, "run-1")
    path = os.path.join(folder, "designs.yaml")
    with open(path, "w", encoding="utf-8") as stream:
        yaml.safe_dump(document, stream)
    return path


def test_baseline_is_the_bare_chassis_without_any_source():
    sources = DesignSources()
    assert configuration_ids(sources) == ["baseline"]
    assert profile_mesh_for("baseline", sources) is None


def test_designs_file_labels_rebuild_the_selected_heights(tmp_path):
    sources = DesignSources(designs_file=write_designs(str(tmp_path), {"A": 0.4, "B": 0.2}))
    assert configuration_ids(sources) == ["baseline", "A", "B"]
    for label, top in (("A", 0.4), ("B", 0.2)):
        mesh = profile_mesh_for(label, sources)
        expected = geometry.profile_mesh(ramp_heights(top), GRID)
        assert mesh.volume == pytest.approx(expected.volume, rel=1e-9)
        assert mesh.bounds[1][2] == pytest.approx(top * GRID.unit_m)


def test_rewritten_designs_file_is_read_again(tmp_path):
    path = write_designs(str(tmp_path), {"A": 0.4})
    sources = DesignSources(designs_file=path)
    before = profile_mesh_for("A", sources).bounds[1][2]
    write_designs(str(tmp_path), {"A": 0.2})
    stat = os.stat(path)
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))  # a new version even on a coarse clock
    assert profile_mesh_for("A", sources).bounds[1][2] == pytest.approx(before / 2)


def test_stl_files_resolve_by_label(tmp_path):
    path = str(tmp_path / "mesh_X.stl")
    geometry.export_mesh(geometry.profile_mesh(ramp_heights(0.3), GRID), path)
    sources = DesignSources(mesh_labels=["X"], mesh_files=[path])
    assert configuration_ids(sources) == ["baseline", "X"]
    assert profile_mesh_for("X", sources).bounds[1][2] == pytest.approx(0.3 * GRID.unit_m, abs=1e-6)


def test_empty_placeholder_pair_means_no_mesh_files():
    sources = DesignSources(mesh_labels=[""], mesh_files=[""])
    sources.validate()
    assert configuration_ids(sources) == ["baseline"]


def test_unknown_id_is_refused_naming_the_known_ones(tmp_path):
    sources = DesignSources(designs_file=write_designs(str(tmp_path), {"A": 0.4}))
    with pytest.raises(ValueError, match=r"unknown configuration 'C': known ids are baseline, A"):
        profile_mesh_for("C", sources)


@pytest.mark.parametrize("labels, files, message", [
    (["A"], [], "same length"),
    (["A"], [""], "needs a mesh_files entry"),
    (["baseline"], ["x.stl"], "bare chassis"),
    (["A", "A"], ["a.stl", "b.stl"], "repeats A"),
])
def test_bad_mesh_mappings_are_refused(labels, files, message):
    with pytest.raises(ValueError, match=message):
        DesignSources(mesh_labels=labels, mesh_files=files).validate()


def test_a_label_defined_twice_is_refused(tmp_path):
    stl = str(tmp_path / "a.stl")
    geometry.export_mesh(geometry.profile_mesh(ramp_heights(0.3), GRID), stl)
    sources = DesignSources(designs_file=write_designs(str(tmp_path), {"A": 0.4}), mesh_labels=["A"], mesh_files=[stl])
    with pytest.raises(ValueError, match="defined both"):
        profile_mesh_for("A", sources)


def test_missing_and_broken_files_are_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="nowhere.yaml"):
        profile_mesh_for("A", DesignSources(designs_file=str(tmp_path / "nowhere.yaml")))
    broken = tmp_path / "designs.yaml"
    broken.write_text(f"/**:\n  ros__parameters:\n    designs:\n      labels: [A]\n      {GRID_YAML}\n")
    with pytest.raises(ConfigError, match="design A has no designs.A.heights"):
        profile_mesh_for("A", DesignSources(designs_file=str(broken)))
    # a lone number was a TypeError traceback, true / false read as heights 1 and 0, a label listed twice passed
    for name, body, problem in (("number", "labels: [A]\n      A: {heights: 3}", r"designs.A.heights must be a list of "
                                 r"numbers \(simulation units\), got 3"),
                                ("boolean", "labels: [A]\n      A: {heights: [false, 0.1]}", "got \\[False, 0.1\\]"),
                                ("twice", "labels: [A, A]\n      A: {heights: [0.1]}", "design A is listed twice")):
        (tmp_path / name).mkdir()
        path = tmp_path / name / "designs.yaml"
        path.write_text(f"/**:\n  ros__parameters:\n    designs:\n      {body}\n      {GRID_YAML}\n")
        with pytest.raises(ConfigError, match=problem):
            configuration_ids(DesignSources(designs_file=str(path)))


def test_a_designs_file_without_its_grid_is_refused_naming_the_file_and_the_key(tmp_path):
    """Without ``designs.grid`` (or with a key of it missing) the heights were read on the default grid (10 x 10,
    0.18 x 0.14 m, 0.2 m a unit), which the design may not have been chosen on: another solid, silently. Every
    designs file the project writes carries the whole grid (design_set.designs_document), so a missing one is
    refused in one line."""
    heights = "A: {heights: [0.1, 0.2, 0.3, 0.1, 0.2, 0.3, 0.1, 0.2, 0.3, 0.1, 0.2, 0.3]}"
    cases = (("none", "", r"designs.yaml: designs.grid is missing: the heights mean nothing without the grid they "
                          r"were chosen on \(rows, cols, length_m, width_m, height_min, height_max, unit_m; "
                          r"rollability select writes it\)"),
             ("partial", "grid: {rows: 4, cols: 3}", r"designs.yaml: designs.grid has no length_m, width_m, "
                                                     r"height_min, height_max, unit_m: the heights mean nothing"),
             ("no_unit", GRID_YAML.replace(", unit_m: 0.2", ""), "designs.yaml: designs.grid has no unit_m: "))
    for name, grid, problem in cases:
        (tmp_path / name).mkdir()
        path = tmp_path / name / "designs.yaml"
        path.write_text(f"/**:\n  ros__parameters:\n    designs:\n      labels: [A]\n      {heights}\n      {grid}\n")
        for read in (lambda: configuration_ids(DesignSources(designs_file=str(path))),
                     lambda: profile_mesh_for("A", DesignSources(designs_file=str(path)))):
            with pytest.raises(ConfigError, match=problem) as refused:
                read()
            assert "\n" not in str(refused.value) and str(path) in str(refused.value)
    # the same file with the whole grid builds the design on it
    (tmp_path / "whole").mkdir()
    path = tmp_path / "whole" / "designs.yaml"
    path.write_text(f"/**:\n  ros__parameters:\n    designs:\n      labels: [A]\n      {heights}\n      {GRID_YAML}\n")
    assert profile_mesh_for("A", DesignSources(designs_file=str(path))).bounds[1][0] == pytest.approx(GRID.length_m / 2)


def test_every_designs_file_the_project_writes_carries_the_whole_grid():
    """The writer and the reader share DESIGN_GRID_KEYS: a selection's designs.yaml names every key of its grid."""
    from rollability_ros.core.profile.designs import DESIGN_GRID_KEYS

    document = designs_document(SelectionResult(designs=[], requested=0, considered=0, rejected={}), GRID, "run-1")
    grid = document["/**"]["ros__parameters"]["designs"]["grid"]
    assert tuple(grid) == DESIGN_GRID_KEYS and geometry.ProfileGrid(**grid) == GRID


def test_designs_are_launched_only_under_the_print_they_were_chosen_for(tmp_path):
    """designs.print states the print a design set's masses assume; evaluating its designs under another print
    would weigh them differently, so it is refused naming each setting that differs (a file without the block,
    written before it was recorded, is accepted). The commands that launch a designs file refuse it in one line
    before any launch."""
    from rollability_ros.cli import main
    from rollability_ros.core.profile.designs import check_printed_with
    from rollability_ros.core.sim import evaluation

    default = evaluation.load_settings(["sim", "robot", "evaluator"]).print_instructions()
    gradual = evaluation.load_settings(["sim", "robot", "evaluator", "gradual_print"]).print_instructions()
    assert gradual != default
    path = write_designs(str(tmp_path), {"A": 0.3})
    check_printed_with(path, default)                 # no print block: nothing to compare
    with open(path, encoding="utf-8") as stream:
        document = yaml.safe_load(stream)
    document["/**"]["ros__parameters"]["designs"]["print"] = dict(gradual)
    with open(path, "w", encoding="utf-8") as stream:
        yaml.safe_dump(document, stream)
    check_printed_with(path, gradual)
    with pytest.raises(ConfigError, match=r"gradual_infill_steps 5 \(designs\) vs 0 \(loaded\)") as refused:
        check_printed_with(path, default)
    assert "\n" not in str(refused.value) and "--config" in str(refused.value)
    check_printed_with(path, {**gradual, "profile_mass_scale": 0.9})   # the model's error, fitted: not the print
    with pytest.raises(ConfigError, match="infill_fraction"):
        check_printed_with(path, {**gradual, "infill_fraction": 0.1})
    for command in (["evaluate", "--designs", path, "--engines", "pybullet,mujoco", "--fidelity", "launch"],
                    ["sensitivity", "--designs-file", path, "--worlds", "2", "--out", str(tmp_path / "worlds")]):
        assert main(command) == 2
        assert not (tmp_path / "engine_agreement.csv").exists() and not (tmp_path / "worlds").exists()
    # the rig's twin backend (the campaign on the simulated rig) refuses it at start-up, and takes the matching print
    from rollability_ros.core.rig.launch_backend import RigSettings
    from rollability_ros.core.rig.rig_session import SimulatedLaunch
    from rollability_ros.core.rig.speed_gate import SpeedGateConfig
    from rollability_ros.core.sim import load_launch_twin_settings

    twin = tmp_path / "twin.yaml"
    twin.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"launch_twin": {"designs": {"designs_file": path}}}}}),
                    encoding="utf-8")
    for prints, refused in (([], True), (["gradual_print"], False)):
        twin_config = ["sim", "robot", "launch_twin", *prints, str(twin)]
        backend = SimulatedLaunch(RigSettings(twin_config=twin_config), SpeedGateConfig(),
                                  load_launch_twin_settings(twin_config))
        if refused:
            with pytest.raises(ConfigError, match="gradual_infill_steps"):
                backend.load()
        else:
            backend.load()


@pytest.mark.parametrize("text, message", [
    ("not json", "print instructions are not JSON"),
    ("[0.2]", "must be a JSON object of settings, got list"),
    ('{"infill_fraction": NaN}', "'infill_fraction' must be a string or a finite number, got nan"),
    ('{"infill_fraction": true}', "'infill_fraction' must be a string or a finite number, got True"),
    ('{"model": {"shell": 1}}', "'model' must be a string or a finite number"),
])
def test_print_instructions_from_text_refuse_what_is_not_a_print(text, message):
    """What an EvaluateProfile goal's ``printed_with`` carries is parsed as data only, and refused in one line."""
    from rollability_ros.core.profile.designs import print_instructions_from_text

    with pytest.raises(ValueError, match=message) as refused:
        print_instructions_from_text(text)
    assert "\n" not in str(refused.value)


def test_print_differences_name_each_setting_both_ways_and_skip_the_ignored():
    import json

    from rollability_ros.core.profile.designs import print_differences, print_instructions_from_text
    from rollability_ros.core.sim import evaluation

    default = evaluation.load_settings(["sim", "robot", "evaluator"]).print_instructions()
    assert print_instructions_from_text(json.dumps(default, sort_keys=True)) == default   # the goal's round trip
    assert print_differences(default, dict(default), ("a", "b")) == []
    assert print_differences(default, {**default, "infill_fraction": default["infill_fraction"] * (1 + 1e-12)},
                             ("a", "b")) == []
    changed = {**default, "infill_fraction": 0.35, "profile_mass_scale": 2.0}
    assert print_differences(default, changed, ("optimizer", "here")) == [
        f"infill_fraction {default['infill_fraction']} (optimizer) vs 0.35 (here)",
        f"profile_mass_scale {default['profile_mass_scale']} (optimizer) vs 2.0 (here)"]
    assert print_differences(default, changed, ("a", "b"), ignore={"infill_fraction", "profile_mass_scale"}) == []
    missing = dict(default)
    del missing["model"]
    assert print_differences(default, missing, ("a", "b")) == [f"model {default['model']} (a) vs None (b)"]
    # a goal's 5 MB value was echoed whole into the evaluator's one-line rejection
    assert print_differences({"model": "a" * 5_000_000}, {"model": "shell"}, ("optimizer", "here")) == [
        f"model {'a' * 40} (optimizer) vs shell (here)"]
    with pytest.raises(ValueError, match="nested too deep"):   # was a RecursionError: the evaluator node died
        print_instructions_from_text("[" * 100_000)


def test_calibrate_and_the_adaptive_plan_weigh_designs_only_under_the_print_they_were_chosen_for(tmp_path, capsys):
    """`rollability calibrate` weighs and launches the designs of ``launch_twin.designs.designs_file``: under
    another print than their ``designs.print`` it is refused in one line naming the setting and the file to give,
    before anything is written (a bench fit and --prepare alike). Given the print file they were chosen with
    (config/gradual_print.yaml, whose objective.robust keys are the search's: named as not read, kept out of the
    loaded parameters) it weighs them as that print: a weighing of the gradual print fits the multiplier to 1, where
    the default print's model would put it near 0.3. The adaptive plan's --twin-config is held to the same rule."""
    from rollability_ros.cli import main
    from rollability_ros.core.campaign.calibration import TWIN_CONFIGS
    from rollability_ros.core.campaign.characterisation import FORMAT, profile_mass_kg
    from rollability_ros.core.config import load_parameters
    from rollability_ros.core.sim import TWIN_SECTIONS, evaluation, launch_twin_settings_from_parameters

    gradual = evaluation.load_settings(["sim", "robot", "evaluator", "gradual_print"]).print_instructions()
    path = write_designs(str(tmp_path), {"A": 0.3})
    with open(path, encoding="utf-8") as stream:
        document = yaml.safe_load(stream)
    document["/**"]["ros__parameters"]["designs"]["print"] = dict(gradual)
    with open(path, "w", encoding="utf-8") as stream:
        yaml.safe_dump(document, stream)
    twin = tmp_path / "twin.yaml"
    twin.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"launch_twin": {"designs": {"designs_file": path}}}}}),
                    encoding="utf-8")
    default = load_parameters([*TWIN_CONFIGS, str(twin)])
    gradual_robot = {k: v for k, v in load_parameters(["gradual_print"]).items() if k.startswith("robot.")}
    weighed = profile_mass_kg(launch_twin_settings_from_parameters({**default, **gradual_robot}), "A")
    # the wrong print would weigh the designs more than twice as heavy
    assert weighed < 0.5 * profile_mass_kg(launch_twin_settings_from_parameters(default), "A")
    bench = tmp_path / "bench.yaml"
    bench.write_text(yaml.safe_dump({"format": FORMAT, "profile_mass": {
        "sigma_kg": 0.0005, "readings": [{"configuration": "A", "mass_kg": float(weighed)}]}}), encoding="utf-8")
    out = tmp_path / "out"
    fit = ["calibrate", "--characterisation", str(bench), "--fit", "robot.profile_mass_scale", "--workers", "1",
           "--out", str(out)]
    for command in (fit, ["calibrate", "--prepare", str(tmp_path / "likelihood.npz"), "--out", str(out)],
                    ["campaign", "--backend", "sim", "--propose-next", "--store", str(tmp_path / "store"),
                     "--twin-config", str(twin)]):
        assert main([*command, "--config", str(twin)] if command[0] == "calibrate" else command) == 2
        refused = capsys.readouterr().err
        assert "gradual_infill_steps 5 (designs) vs 0 (loaded)" in refused and refused.count("\n") == 1
        assert ("--twin-config gradual_print" if command[0] == "campaign" else "--config gradual_print") in refused
        assert sorted(os.listdir(tmp_path)) == ["bench.yaml", "designs.yaml", "twin.yaml"]   # nothing written
    assert main(["campaign", "--backend", "sim", "--propose-next", "--store", str(tmp_path / "store"),
                 "--twin-config", "gradual_print", "--twin-config", str(twin)]) == 2
    assert "no store at" in capsys.readouterr().err   # the print passed; no store to read
    assert main([*fit, "--config", "gradual_print", "--config", str(twin)]) == 0
    assert "rollability calibrate: not read from gradual_print.yaml: objective.robust" in capsys.readouterr().out
    with open(out / "calibrated.yaml", encoding="utf-8") as stream:
        fitted = yaml.safe_load(stream)["/**"]["ros__parameters"]["robot"]["profile_mass_scale"]
    assert fitted == pytest.approx(1.0, abs=0.05)
    from rollability_ros.core.campaign import load_twin_files

    parameters, unread = load_twin_files(TWIN_CONFIGS, ["gradual_print", str(twin)], TWIN_SECTIONS, "a command")
    assert parameters == {**default, **gradual_robot}   # the search's keys left out: nothing calibrate computes
    assert unread == ("a command: not read from gradual_print.yaml: objective.robust.profile_mass_scale_max, "
                      "objective.robust.profile_mass_scale_min (the search's robust draws of the print model's "
                      "error; calibration.lower / upper bound a fitted robot.profile_mass_scale)")
    search_keys = tmp_path / "search.yaml"   # the same keys in a file that sets no print: refused as before
    search_keys.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"objective": {"robust": {
        "profile_mass_scale_min": 0.8}}}}}), encoding="utf-8")
    with pytest.raises(ConfigError, match="a command does not read objective.robust.profile_mass_scale_min"):
        load_twin_files(TWIN_CONFIGS, [str(search_keys)], TWIN_SECTIONS, "a command")
