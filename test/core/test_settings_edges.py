"""Issue 29, point 5 and issue 43, item 3: settings are parsed once, at the edge (a node's declared sections, or the
CLI's loaded files), into typed dataclasses that the core is handed; the core does not re-parse flat parameters or
read parameter files into settings itself.

The rule, checked statically (test/code_counts.py ``parse_sites``, printed by ``python test/code_counts.py`` as
"flat parameters parsed below the edge"): a parse is a call of config's ``section``, ``from_mapping`` or
``settings_from_sections``, or of a function declared ``@config.edge_parse``. In the core (outside config.py,
which defines them) a parse may stand in two declared places only:

- an ``@config.edge_parse`` function: the parse of one kind of settings, defined next to its dataclasses (so a node
  and the CLI parse alike). Its declaration is a promise checked here, not a licence: no core function calls it
  (such a call is counted below like any other parse), and an edge (rollability_ros/cli/, rollability_ros/nodes/)
  or another edge parse does (``edge_parses_without_edge``), so it runs once, where the parameters enter.
- an ``@config.file_schema(kind)`` reader: the one reader of a kind of file that records its own settings (a
  designs file holds the profile grid its designs were made on next to their heights; the rig and the report read
  it wherever a design is launched or drawn). It may cut its own document (``section``, ``from_mapping``) but calls
  no edge parse (no parameter file is read through it), and a kind has one reader (``file_schemas``).

Everything else is counted, and the count must be 0: there is no list of exceptions, so a new parse below the edge
fails with its function (parse it in the node or the command, or declare it as above and call it from there).

Why this is the rule and not an allow-list by another name: a declaration is checked against what the code does.
An ``edge_parse`` that a core function calls is counted at the caller, and one that no edge calls fails
``test_every_edge_parse_is_called_by_an_edge``, so declaring a core function an edge parse does not hide a parse,
it moves the call to the node or the command. A ``file_schema`` reader cannot read parameter files through an edge
parse, and a second reader of one kind fails. Parameter files that a setting names are read by the edge too: the
rig's twin (``rig.twin_config``: ``RigPorts.open_twin``, the node's, the campaign command's ``read_twin``), and the
evaluation's launch twin and conditions (``objective.twin_config``, ``objective.campaign_config``:
``objectives.resolve_launch`` through the evaluator's edge parses, which the commands and the sim_evaluator node
call; carried to every trial job in ``EvaluatorSettings.resolved_launch``).

Counts: issue 29 began at 45 calls in 26 functions; issue 43 found 30 in 24, then 27 in 21 (every edge parse
counted, the calibration re-parsing its twin from flat parameters for every candidate, the sim rig and the study
parsing the files they were named), then 2 in 2 (the evaluation reading its objective's twin and campaign files
where it built a job). Now 0: the edge parses and the designs file's reader are declared; the calibration, the
characterisation, the learnt likelihood's training launches, the adaptive plan and the posterior take the twin
typed and set fitted config keys on it (``sim.twin_with_values``, ``config.with_values``); the rig is handed its
twin by its caller; a study is parsed by ``graph.study_config`` in the command; an evaluation is handed its launch
twin and conditions in its settings.
"""
import re

import pytest

import code_counts


def test_the_core_parses_no_flat_parameters():
    found = code_counts.parse_sites()
    assert found == {}, ("flat parameters parsed below the edge (parse them once in the node or CLI and hand the core "
                         f"the typed settings): {found}")


def test_every_edge_parse_is_called_by_an_edge():
    assert code_counts.edge_parses_without_edge() == [], "declared @config.edge_parse, but no node or CLI calls it"


def test_one_schema_reader_per_kind_of_file():
    kinds = code_counts.file_schemas()
    assert kinds and all(len(readers) == 1 for readers in kinds.values()), kinds


def test_the_check_sees_a_parse(tmp_path):
    """A made-up core with one re-parse inside a method is found, with its function."""
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "m.py").write_text(
        "from rollability_ros.core import config\n"
        "class Run:\n    def step(self, flat):\n        return config.from_mapping(X, config.section(flat, 'a'), 'a')\n")
    (tmp_path / "config.py").write_text("def section(flat, prefix):\n    return section(flat, prefix)\n")
    assert code_counts.parse_sites(tmp_path) == {("sub/m.py", "Run.step"): 2}


def test_the_check_sees_through_declarations(tmp_path):
    """A declared edge parse may parse, but a core function calling it is counted, and so is a file reader calling
    it; an edge parse no edge calls is named; two readers of one kind of file are both listed."""
    core = tmp_path / "core"
    core.mkdir()
    (core / "m.py").write_text(
        "from rollability_ros.core import config\n"
        "@config.edge_parse\ndef parse_a(flat):\n    return config.from_mapping(A, config.section(flat, 'a'), 'a')\n"
        "@config.edge_parse\ndef unused(flat):\n    return config.section(flat, 'b')\n"
        "def core_step(flat):\n    return parse_a(flat)\n"
        "@config.file_schema('a file')\ndef read_a(path):\n    return config.section(load(path), 'a'), parse_a({})\n"
        "@config.file_schema('a file')\ndef read_a_again(path):\n    return config.section(load(path), 'a')\n")
    (tmp_path / "edge").mkdir()
    (tmp_path / "edge" / "cli.py").write_text("from m import parse_a\nparse_a({})\n")
    assert code_counts.parse_sites(core) == {("m.py", "core_step"): 1, ("m.py", "read_a"): 1}
    assert code_counts.edge_parses_without_edge(core, [tmp_path / "edge"]) == [("m.py", "unused")]
    assert code_counts.file_schemas(core) == {"a file": [("m.py", "read_a"), ("m.py", "read_a_again")]}


def test_fitted_keys_are_set_on_the_typed_twin_as_the_files_would_set_them():
    """The calibration's candidate twins are the typed twin with its fitted config keys set (no parse): the same
    settings as the files with those values, and the same one-line refusal of a value outside its range."""
    from rollability_ros.core.campaign.calibration import TWIN_CONFIGS, CalibrationSettings, twin_values
    from rollability_ros.core.config import ConfigError, load_parameters
    from rollability_ros.core.sim import launch_twin_settings_from_parameters, twin_with_values

    flat = load_parameters(list(TWIN_CONFIGS))
    twin = launch_twin_settings_from_parameters(flat)
    keys = CalibrationSettings().parameters
    assert twin_values(twin, keys) == [float(flat[key]) for key in keys]
    values = {key: (low + high) / 2 for key, low, high in
              zip(keys, CalibrationSettings().lower, CalibrationSettings().upper)}
    assert twin_with_values(twin, values) == launch_twin_settings_from_parameters({**flat, **values}) != twin
    for bad in ({"launch_twin.foam.contact_stiffness_npm": -1.0}, {"robot.com_offset_z_m": float("nan")},
                {"launch_twin.foam.stiffness": 1.0}):
        with pytest.raises(ConfigError) as from_files:
            launch_twin_settings_from_parameters({**flat, **bad})
        with pytest.raises(ConfigError, match="^" + re.escape(str(from_files.value)) + "$"):
            twin_with_values(twin, bad)
