"""Package faces (issue 29): every subpackage of the core exports its public names with ``__all__``; nodes/, cli/
and the other subpackages import them through the face, never from the modules behind it (a ratchet); importing a
face loads nothing behind it (``lazy_loader.attach_stub`` over the face's ``__init__.pyi``), so no heavy dependency."""
import ast
import importlib
import os
import pathlib
import subprocess
import sys

import code_counts
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SUBPACKAGES = code_counts.subpackages()
FACES = tuple(f"rollability_ros.core.{sub}" for sub in SUBPACKAGES)
#: Never loaded by importing a face: physics, plotting, optimisers, meshes, clusters.
HEAVY = ("pybullet", "mujoco", "ray", "trimesh", "matplotlib", "ribs", "cma")
#: Imports that reach past a face (code_counts.deep_imports), by importer. The ratchet: a new one fails; when one
#: goes, lower the number here. With faces on 3 subpackages there were nodes 29, cli 38, core 53, other 2; with a
#: face on every subpackage all of them import through it.
DEEP_IMPORTS_ALLOWED = {"nodes": 0, "cli": 0, "core": 0, "other": 0}


def _run(script):
    env = dict(os.environ, PYTHONPATH=str(ROOT), LC_ALL="C.UTF-8", PYTHONUNBUFFERED="1")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, env=env)
    assert result.returncode == 0, result.stderr
    return result.stdout.split()


def test_every_subpackage_has_a_face():
    assert len(SUBPACKAGES) == 10
    assert [sub for sub in SUBPACKAGES if code_counts.face_all(sub) is None] == []


@pytest.mark.parametrize("face", FACES)
def test_each_face_exports_resolvable_names(face):
    module = importlib.import_module(face)
    names = module.__all__
    assert len(names) == len(set(names)) and names
    for name in names:
        assert getattr(module, name, None) is not None or importlib.import_module(f"{face}.{name}"), name


@pytest.mark.parametrize("sub", SUBPACKAGES)
def test_a_face_lists_what_it_re_exports(sub):
    """The stub's ``__all__`` (what type checkers export), its imports (what ``lazy_loader.attach_stub`` loads) and
    the package's run-time ``__all__`` agree; no re-exported name hides a submodule of another name, and the face
    exports names, never a whole module (``from . import module``)."""
    exports = code_counts.face_exports(sub)
    assert sorted(code_counts.face_all(sub)) == sorted(exports)
    assert code_counts.face_modules(sub) == []
    modules = {path.stem for path in (code_counts.CORE / sub).glob("*.py")}
    for name, module in exports.items():
        assert name not in modules or module == f"{sub}.{name}", f"{sub}.{name} is both a submodule and a name"
    face = importlib.import_module(f"rollability_ros.core.{sub}")
    assert sorted(face.__all__) == sorted(exports)
    assert (code_counts.CORE / sub / "__init__.py").read_text().count("lazy_loader.attach_stub(__name__, __file__)") == 1


def test_a_name_that_shares_its_module_name_is_the_name():
    """``from rollability_ros.core.bags import recover`` is the function ``recover`` of ``bags/recover.py``, also
    after the module was imported (lazy_loader guards the name against the import system's submodule attribute)."""
    names = _run("import rollability_ros.core.bags.recover\nfrom rollability_ros.core.bags import recover, convert\n"
                 "print(type(recover).__name__, type(convert).__name__)")
    assert names == ["function", "function"]


def test_a_lazy_face_imports_a_name_when_it_is_used():
    loaded = _run("import sys\nimport rollability_ros.core.sim as sim\n"
                  "before = 'rollability_ros.core.sim.evaluation' in sys.modules\n"
                  "from rollability_ros.core.sim import evaluate_profile\n"
                  "from rollability_ros.core.sim.evaluation import evaluate_profile as deep\n"
                  "print(before, evaluate_profile is deep, 'rollability_ros.core.sim.launch.twin' in sys.modules)")
    assert loaded == ["False", "True", "False"]
    with pytest.raises(ImportError, match="cannot import name 'no_such_name'"):
        exec("from rollability_ros.core.sim import no_such_name", {})


def test_importing_every_face_loads_no_heavy_dependency():
    """Every face, in one fresh process: nothing heavy, not even numpy (the rig computer runs without them)."""
    script = (f"import sys\nfor face in {FACES!r}:\n    __import__(face)\n"
              f"print(' '.join(m for m in {HEAVY + ('numpy', 'scipy')!r} if m in sys.modules) or '-')")
    assert _run(script) == ["-"]


def test_every_name_of_every_face_loads_no_heavy_dependency():
    """Heavy dependencies are imported where used (core/optional.py), not when a module behind a face loads."""
    script = (f"import importlib, sys\nfor face in {FACES!r}:\n    module = importlib.import_module(face)\n"
              "    for name in module.__all__:\n"
              "        getattr(module, name, None) or importlib.import_module(face + '.' + name)\n"
              f"print(' '.join(m for m in {HEAVY!r} if m in sys.modules) or '-')")
    assert _run(script) == ["-"]


def test_imports_go_through_the_faces():
    deep = code_counts.deep_imports()
    for client, allowed in DEEP_IMPORTS_ALLOWED.items():
        found = [where for who, where in deep if who == client]
        assert len(found) <= allowed, f"{client} imports past a face (import from the subpackage):\n" + "\n".join(found)
        assert len(found) == allowed, f"{client}: {len(found)} deep imports left, lower DEEP_IMPORTS_ALLOWED to it"


def private_module_imports(path):
    """``line: module`` of each import in ``path`` of a core module with a leading underscore (``import
    rollability_ros.core.sim._worker_pool``, ``from rollability_ros.core.sim._worker_pool import ...``, ``from
    rollability_ros.core.sim import _worker_pool``)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            modules = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            modules = [node.module] + [f"{node.module}.{alias.name}" for alias in node.names
                                       if (ROOT / node.module.replace(".", "/") / f"{alias.name}.py").is_file()]
        else:
            continue
        found += [f"{node.lineno}: {module}" for module in modules if module.startswith("rollability_ros.core.")
                  and any(part.startswith("_") and part != "__init__" for part in module.split(".")[2:])]
    return found


def test_nothing_outside_the_package_imports_a_private_module(tmp_path):
    """The modules behind a face with a leading underscore (``sim/_worker_pool``, ``rig/_valve_backend``, ...) are
    their subpackage's own: tests, benches and scripts use the names the face exports."""
    found = [f"{path.relative_to(ROOT)}:{where}" for folder in ("test", "bench", "scripts", "launch")
             for path in sorted((ROOT / folder).rglob("*.py")) for where in private_module_imports(path)]
    assert not found, "import these names from the subpackage's face:\n" + "\n".join(found)
    made_up = tmp_path / "m.py"
    made_up.write_text("from rollability_ros.core.sim._worker_pool import spawn_pool\n"
                       "from rollability_ros.core.sim import spawn_pool, _worker_pool\n"
                       "import rollability_ros.core.rig._valve_backend\nfrom rollability_ros.core.rig import _LOG\n")
    assert private_module_imports(made_up) == ["1: rollability_ros.core.sim._worker_pool",
                                               "2: rollability_ros.core.sim._worker_pool",
                                               "3: rollability_ros.core.rig._valve_backend"]


def test_the_check_sees_a_deep_import(tmp_path, monkeypatch):
    package = tmp_path / "rollability_ros"
    (package / "nodes").mkdir(parents=True)
    (package / "nodes" / "bad.py").write_text(
        "from rollability_ros.core.rig.valve import ValveConfig\n"
        "import rollability_ros.core.campaign.plan\n"
        "from rollability_ros.core.rig import ValveConfig, _LOG\n"
        "def f():\n    from rollability_ros.core.sim.evaluation import evaluate_profile\n")
    monkeypatch.setattr(code_counts, "PACKAGE", package)
    assert code_counts.deep_imports(package) == [
        ("nodes", "nodes/bad.py:1: rollability_ros.core.rig.valve"),
        ("nodes", "nodes/bad.py:2: rollability_ros.core.campaign.plan"),
        ("nodes", "nodes/bad.py:3: rollability_ros.core.rig._LOG (not in __all__)"),
        ("nodes", "nodes/bad.py:5: rollability_ros.core.sim.evaluation")]


def test_the_layering_check_follows_a_name_through_a_lazy_face():
    """``from rollability_ros.core.sim import evaluate_profile`` is an edge to sim/evaluation, not to the face."""
    path = code_counts.CORE / "optimization" / "optimization_run.py"
    text = path.read_text()
    assert "from rollability_ros.core.sim import" in text
    edges = dict(code_counts.import_graph()["optimization.optimization_run"])
    assert "sim.evaluation" in edges and "sim" not in edges
    assert not any(isinstance(node, ast.ImportFrom) and (node.module or "").startswith("rollability_ros.core.sim.")
                   for node in ast.walk(ast.parse(text)))
