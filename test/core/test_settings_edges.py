"""Issue 29, point 5: settings are parsed once, at the edge (a node's declared sections, or the CLI's loaded files),
into typed dataclasses that the core is handed; the core does not re-parse a flat parameter dict passed down to it.

Checked statically (test/code_counts.py ``parse_sites``): every call in the core (outside config.py) of a parse
(``section``, ``from_mapping``, ``settings_from_sections`` and the core's parse functions built on them) is listed
below with why it stays. A new one fails with its function; one that went fails too, so the list only shrinks.
Before (issue 29): 45 calls in 26 functions, among them ``optimizer_settings(`` re-parsing the ``optimizer`` section
in four functions of one run and ``LocalRig`` re-parsing four sections it was handed flat. Issue 43: 30 in 24, of
them ``OptimizationRun`` parsing the flat dict it was handed twice and three writers nesting it again; now 26 in 20
(``OptimizationRun`` takes a typed ``RunConfig``, the writers go through ``config.parameter_document``).
"""
import code_counts

#: (module below core, function): (calls, why the parse stays there)
ALLOWED = {
    # the parse functions an edge calls once (defined in the core next to their dataclasses)
    ("optimization/optimization_run.py", "run_settings"): (1, "the edge parse of a run's parameters"),
    ("optimization/optimization_run.py", "run_config"): (1, "the edge parse of a run's parameters, kept with them as "
                                                            "the run's record (OptimizationRun takes it typed)"),
    ("campaign/runner.py", "local_rig_settings"): (1, "the edge parse of the in-process rig's parameters"),
    ("campaign/runner.py", "local_rig_settings_from_files"): (1, "the edge parse of the rig files a command was "
                                                                 "given, once their keys are checked"),
    ("sim/evaluation.py", "settings_from_parameters"): (1, "the edge parse of the evaluator's parameters"),
    ("campaign/calibration.py", "calibration_settings"): (2, "the edge parse of the calibration section, checked "
                                                             "against the twin's keys"),
    ("sim/launch/settings.py", "launch_twin_settings_from_parameters"): (2, "the edge parse of the twin's "
                                                                               "parameters, with settings overrides"),
    # a file's own settings, read where the file is read
    ("sim/evaluation.py", "load_settings"): (1, "reads parameter files"),
    ("sim/launch/settings.py", "load_launch_twin_settings"): (1, "reads parameter files"),
    ("rig/rig_session.py", "SimulatedLaunch.load"): (1, "reads the twin files rig.twin_config names"),
    ("sim/objectives.py", "_resolve"): (1, "reads the twin files objective.twin_config names"),
    ("campaign_matrix.py", "load_campaign_spec"): (2, "reads a campaign's parameter files"),
    ("graph/bringup.py", "load_graph_settings"): (2, "reads the graph's parameter files"),
    ("graph/preflight.py", "check_graph_parameters"): (2, "checks every node's parameter files before a start"),
    ("graph/preflight.py", "_twin_problems"): (1, "loads the sim rig's twin files before a session starts"),
    ("profile/designs.py", "_read_designs"): (2, "reads a designs file"),
    # the calibration fits config keys: each candidate's twin is the parameter files with the fitted keys set
    ("campaign/calibration.py", "twin_settings_with"): (1, "rebuilds the twin with fitted config keys"),
    ("campaign/calibration.py", "check_fittable"): (1, "the twin of the given keys, to refuse a fitted key it ignores"),
    ("campaign/calibration.py", "fit"): (1, "the twin of the given keys, for the characterisation readings' model"),
    ("campaign/characterisation.py", "characterisation_log_likelihood"): (
        1, "the roll-out's twin at one candidate point of the fitted keys"),
}


def test_the_core_parses_flat_parameters_only_where_listed():
    found = code_counts.parse_sites()
    allowed = {site: calls for site, (calls, _why) in ALLOWED.items()}
    new = {site: calls for site, calls in found.items() if calls > allowed.get(site, 0)}
    assert not new, ("flat parameters parsed below the edge (parse them once in the node or CLI and hand the core "
                     f"the typed settings, or list the site here with why): {new}")
    gone = {site: calls for site, calls in allowed.items() if found.get(site, 0) < calls}
    assert not gone, f"fewer parses than listed, lower or remove the entries: {gone} (found {found})"


def test_the_check_sees_a_parse(tmp_path):
    """A made-up core with one re-parse inside a method is found, with its function."""
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "m.py").write_text(
        "from rollability_ros.core import config\n"
        "class Run:\n    def step(self, flat):\n        return config.from_mapping(X, config.section(flat, 'a'), 'a')\n")
    (tmp_path / "config.py").write_text("def section(flat, prefix):\n    return section(flat, prefix)\n")
    assert code_counts.parse_sites(tmp_path) == {("sub/m.py", "Run.step"): 2}
