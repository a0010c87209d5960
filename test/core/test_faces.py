"""Package faces (issue 29): core/rig, core/campaign and core/imu export their public names with ``__all__``, and nodes/ and
cli/ import from those subpackages only through the face, never from the modules behind it."""
import ast
import importlib
import os
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "rollability_ros"
#: subpackages with a face -> who must use it
FACES = ("rollability_ros.core.rig", "rollability_ros.core.campaign", "rollability_ros.core.imu")
CLIENTS = ("nodes", "cli")


def deep_imports(root, faces=FACES):
    """``["file:line: what", ...]`` of imports under ``root`` that reach past a face (or a name it does not export)."""
    found = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            where = f"{path.relative_to(root)}:{getattr(node, 'lineno', 0)}"
            if isinstance(node, ast.Import):
                found += [f"{where}: import {a.name}" for a in node.names
                          if any(a.name.startswith(face + ".") for face in faces)]
            elif isinstance(node, ast.ImportFrom) and node.module:
                if any(node.module.startswith(face + ".") for face in faces):
                    found.append(f"{where}: from {node.module} import ...")
                elif node.module in faces:
                    exported = importlib.import_module(node.module).__all__
                    found += [f"{where}: {a.name} is not in {node.module}.__all__" for a in node.names
                              if a.name not in exported]
    return found


@pytest.mark.parametrize("face", FACES)
def test_each_face_exports_resolvable_names(face):
    module = importlib.import_module(face)
    names = module.__all__
    assert len(names) == len(set(names)) and names
    for name in names:
        assert getattr(module, name, None) is not None or importlib.import_module(f"{face}.{name}"), name


@pytest.mark.parametrize("client", CLIENTS)
def test_nodes_and_cli_import_rig_and_campaign_only_through_their_faces(client):
    assert deep_imports(PACKAGE / client) == []


def test_the_check_sees_a_deep_import(tmp_path):
    (tmp_path / "bad.py").write_text("from rollability_ros.core.rig.valve import ValveConfig\n"
                                     "import rollability_ros.core.campaign.plan\n"
                                     "from rollability_ros.core.rig import ValveConfig, _LOG\n")
    assert deep_imports(tmp_path) == ["bad.py:1: from rollability_ros.core.rig.valve import ...",
                                      "bad.py:2: import rollability_ros.core.campaign.plan",
                                      "bad.py:3: _LOG is not in rollability_ros.core.rig.__all__"]


def test_the_faces_load_no_heavy_dependency():
    """The rig computer imports these faces: no numpy, physics or plotting behind them."""
    script = ("import sys, rollability_ros.core.rig, rollability_ros.core.campaign, rollability_ros.core.imu\n"
              "print(' '.join(m for m in ('numpy', 'pybullet', 'mujoco', 'trimesh', 'matplotlib', 'scipy', 'ray') "
              "if m in sys.modules))")
    env = dict(os.environ, PYTHONPATH=str(ROOT), LC_ALL="C.UTF-8", PYTHONUNBUFFERED="1")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60, env=env)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == ""
