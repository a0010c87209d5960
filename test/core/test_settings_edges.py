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

Everything else is counted and must be listed below with why it stays; a new one fails with its function, one
that went fails too, so the list only shrinks. Before (issue 29): 45 calls in 26 functions; issue 43: 30 in 24,
then 27 in 21 (every edge parse counted, readers of files' own settings, the calibration rebuilding its twin from
flat parameters once per candidate); now the edge parses and the designs file's reader are declared and the
calibration sets its fitted keys on the typed twin (``config.with_values``).
"""
import code_counts

#: (module below core, function): (calls, why the parse stays there)
ALLOWED = {
    ("sim/objectives.py", "_resolve"): (1, "x"),
    ("sim/objectives.py", "launch_conditions"): (1, "x"),
}


def test_the_core_parses_flat_parameters_only_where_listed():
    found = code_counts.parse_sites()
    allowed = {site: calls for site, (calls, _why) in ALLOWED.items()}
    new = {site: calls for site, calls in found.items() if calls > allowed.get(site, 0)}
    assert not new, ("flat parameters parsed below the edge (parse them once in the node or CLI and hand the core "
                     f"the typed settings, or list the site here with why): {new}")
    gone = {site: calls for site, calls in allowed.items() if found.get(site, 0) < calls}
    assert not gone, f"fewer parses than listed, lower or remove the entries: {gone} (found {found})"


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
