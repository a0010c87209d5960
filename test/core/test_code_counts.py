"""Issue 43's counts (test/code_counts.py prints them all): the limits met are held here; the module and function
sizes and the back-references owned by the rooms that split those modules are printed until they land."""
import code_counts

#: Issue 43's limit on public core signatures that mention ``Any`` or a core alias standing for it.
ANY_SIGNATURES_LIMIT = 40
#: Those counted today (179 before this ratchet, 150 without the aliases; the parameter maps, documents and rows,
#: MuJoCo handles and the robustness draw's settings typed since). A ratchet: a new one fails; when one goes, lower
#: the number.
ANY_SIGNATURES_ALLOWED = 34


#: Modules another room is splitting this round: their sizes are printed, and asserted here once the split lands.
#: None left: selection and report (issue 43 item 5) are split (deciding in selection.py and report.py, writing in
#: design_set.py and report_writer.py), and optimization_run (its run directory and batch evaluators apart).
SPLIT_ELSEWHERE: tuple = ()


def test_no_module_over_700_lines_and_no_function_over_80_elsewhere():
    modules = [path for path, lines in code_counts.module_lines().items()
               if lines > code_counts.MODULE_LINES_LIMIT and path not in SPLIT_ELSEWHERE]
    functions = [name for name, lines in code_counts.function_lines().items()
                 if lines > code_counts.FUNCTION_LINES_LIMIT and name.split(":")[0] not in SPLIT_ELSEWHERE]
    assert modules == [] and functions == [], (modules, functions)


def test_no_alias_module_and_no_name_used_past_a_face():
    assert code_counts.aliases() == {}
    assert code_counts.names_past_faces() == []


def test_mypy_checks_untyped_bodies_and_every_bench_script():
    assert code_counts.check_untyped_defs()
    scripts, smoke, checked = code_counts.bench_coverage()
    assert checked == scripts and len(scripts) >= 20
    assert smoke and set(smoke) <= set(scripts)


def test_any_in_public_core_signatures_only_shrinks():
    found = code_counts.any_signatures()
    assert ANY_SIGNATURES_ALLOWED <= ANY_SIGNATURES_LIMIT
    assert len(found) <= ANY_SIGNATURES_ALLOWED, "new public signatures with Any:\n" + "\n".join(found)
    assert len(found) == ANY_SIGNATURES_ALLOWED, f"{len(found)} left: lower ANY_SIGNATURES_ALLOWED to it"


def test_the_counts_see_what_they_count(tmp_path, monkeypatch):
    """A made-up core: a public signature with Any (also inside a subscript or a string), a private one (not
    counted), a long function and a module past the limits, an unannotated mypy.ini."""
    core = tmp_path / "rollability_ros" / "core"
    (core / "sim").mkdir(parents=True)
    body = "\n".join(f"    x{i} = {i}" for i in range(85))
    (core / "sim" / "m.py").write_text(
        "import typing\n"
        "Row = typing.Dict[str, typing.Any]\n"
        "def rows() -> typing.List[Row]: ...\n"
        "def f(a: typing.Any) -> int: ...\n"
        "def g(a: typing.Mapping[str, typing.Any]) -> None: ...\n"
        "def h(a: 'typing.Any') -> None: ...\n"
        "def _p(a: typing.Any) -> None: ...\n"
        "class _Private:\n    def q(self, a: typing.Any) -> None: ...\n"
        "class Public:\n    def r(self) -> typing.Any: ...\n"
        f"def long():\n{body}\n" + "\n" * 620)
    assert code_counts.any_signatures(core) == ["sim/m.py:rows", "sim/m.py:f", "sim/m.py:g", "sim/m.py:h",
                                                "sim/m.py:Public.r"]
    assert code_counts.function_lines(tmp_path / "rollability_ros")["rollability_ros/core/sim/m.py:long"] == 86
    assert code_counts.module_lines(tmp_path / "rollability_ros")["rollability_ros/core/sim/m.py"] > 700
    ini = tmp_path / "mypy.ini"
    ini.write_text("[mypy]\nstrict_optional = True\n")
    assert not code_counts.check_untyped_defs(ini)
    ini.write_text("[mypy]\ncheck_untyped_defs = True\n")
    assert code_counts.check_untyped_defs(ini)
