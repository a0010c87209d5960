"""The core's layers as ``rollability_ros/core/__init__.py`` states them, checked statically (ast, nothing imported;
test/code_counts.py): no new upward import and no new import cycle, between subpackages or inside one.

The allow-lists below are what is left of the violations counted in issue 29; they only shrink. A new upward
import or cycle fails with its file and line; an entry that no longer occurs fails too, so it is removed here.
"""
import ast
import re

import code_counts

#: (module, imported module) pairs that import from a subpackage listed later (module names below core/). Issue
#: 29 counted 17 (records, stats, store in results/ imported by sim, optimization, imu and rig; results <-> campaign
#: and bags): records, record_messages, store and stats moved to the shared bottom, bags below results,
#: trial_id_for into records, and the campaign's matrix (CampaignSpec, read by the robust objective in sim/) into
#: the shared campaign_matrix. None is left.
UPWARD_ALLOWED: set = set()
#: Strongly connected components of the subpackage graph. Issue 29 counted one over 7 subpackages; the last,
#: campaign -> optimization -> results -> sim -> campaign, went with the last upward import. None is left.
SUBPACKAGE_CYCLES_ALLOWED: list = []
#: Strongly connected components of the module graph inside each subpackage.
#: Issue 29 counted a 7-module cycle in sim/ (broken by the engine tables' string entries and sim/_body_points)
#: and bags/recover <-> bags/writer (broken by bags/_mcap_file). None is left.
MODULE_CYCLES_ALLOWED: list = []


def _where(graph, pairs):
    return "\n".join(f"  core/{m.replace('.', '/')}.py line {graph[m][t]}: imports {t}" for m, t in sorted(pairs))


def test_no_new_upward_import():
    graph = code_counts.import_graph()
    upward = set(code_counts.upward_imports(graph))
    new = upward - UPWARD_ALLOWED
    assert not new, ("imports from a subpackage listed later in core/__init__.py (move the shared type down, or "
                     "the code up):\n" + _where(graph, new))
    gone = UPWARD_ALLOWED - upward
    assert not gone, f"no longer upward, remove from UPWARD_ALLOWED: {sorted(gone)}"


def _check_components(found, allowed, what):
    new = [c for c in found if not any(set(c) <= set(a) for a in allowed)]
    assert not new, f"new import cycle(s) {what}: {new}"
    stale = [a for a in allowed if a not in found]
    assert not stale, f"the allowed cycle(s) {stale} {what} changed or went: record what is left {found}"


def test_no_new_cycle_between_subpackages():
    _check_components(code_counts.subpackage_cycles(), SUBPACKAGE_CYCLES_ALLOWED, "between subpackages")


def test_no_new_cycle_inside_a_subpackage():
    _check_components(code_counts.module_cycles(), MODULE_CYCLES_ALLOWED, "inside a subpackage")


def test_no_alias_module_is_left(tmp_path, monkeypatch):
    """The old paths (``results.records`` re-exporting ``records`` with ``import *``, ...) are gone: every caller
    imports the module where the code lives. The check sees a made-up alias."""
    assert code_counts.aliases() == {}
    alias = tmp_path / "old.py"
    alias.write_text('"""Moved."""\nfrom rollability_ros.core.records import *  # noqa: F401,F403\n')
    assert code_counts.aliases({"results.old": alias}) == {"results.old": "records"}


def test_the_check_sees_a_violation(tmp_path):
    """The analysis finds an upward import, a function-level one too, and a cycle, in a made-up graph."""
    graph = {"profile.geometry": {"sim.trials": 3}, "sim.trials": {"profile.geometry": 1, "sim.world": 2},
             "sim.world": {"sim.trials": 9}, "config": {}}
    assert code_counts.upward_imports(graph) == [("profile.geometry", "sim.trials")]
    assert code_counts.subpackage_cycles(graph) == [("profile", "sim")]
    assert code_counts.module_cycles(graph) == [("sim.trials", "sim.world")]
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from rollability_ros.core.sim.trials import run_trial, make_trial_world\n"
                      "from rollability_ros.core import config\n")
    assert sorted(code_counts.imports_of(module, {"sim.trials", "config"})) == [("config", 3), ("sim.trials", 2),
                                                                                 ("sim.trials", 2)]


def unmapped_modules(core=code_counts.CORE):
    """``[module path below core]`` of the modules that the map of their package (the docstring of its
    ``__init__.py``, which says in a few lines what each module holds) does not name."""
    missing = []
    for init in sorted(core.rglob("__init__.py")):
        text = ast.get_docstring(ast.parse(init.read_text())) or ""
        missing += [module.relative_to(core).as_posix() for module in sorted(init.parent.glob("*.py"))
                    if module.name != "__init__.py" and not re.search(rf"(?<![\w.]){re.escape(module.stem)}\b", text)]
    return missing


def test_every_module_is_on_its_packages_map(tmp_path):
    """Each package's ``__init__.py`` maps its modules (what each holds): a module it does not name fails here, as a
    made-up package with one unnamed module does."""
    assert unmapped_modules() == []
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "__init__.py").write_text('"""A package.\n\n- held: what it holds\n"""\n')
    for name in ("held", "forgotten"):
        (tmp_path / "pkg" / f"{name}.py").write_text("")
    assert unmapped_modules(tmp_path) == ["pkg/forgotten.py"]
