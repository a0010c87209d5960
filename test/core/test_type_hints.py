"""Public functions carry type hints: every public function and method of every module of the core, the CLI and the
nodes has annotated parameters and a return type; array-valued parameters state their shape in the docstring."""
import ast
import pathlib
import re

import pytest

CORE = pathlib.Path(__file__).resolve().parents[2] / "rollability_ros" / "core"
CLI = CORE.parent / "cli"
NODES = CORE.parent / "nodes"
#: Every module of the core: the ratchet that listed the annotated ones reached all of them (the last,
#: optimization/selection.py, with issue 29).
MODULES = sorted(path.relative_to(CORE).as_posix() for path in CORE.rglob("*.py"))


def unannotated(path):
    """``name:line`` of every public function or method with a parameter or the return left unannotated."""
    missing = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
            params = [a for a in node.args.args + node.args.kwonlyargs if a.arg not in ("self", "cls")]
            if node.returns is None or any(a.annotation is None for a in params):
                missing.append(f"{node.name}:{node.lineno}")
    return missing


@pytest.mark.parametrize("module", MODULES)
def test_public_functions_are_annotated(module):
    assert unannotated(CORE / module) == []


@pytest.mark.parametrize("module", sorted([f"cli/{path.name}" for path in CLI.glob("*.py")]
                                           + [f"nodes/{path.name}" for path in NODES.glob("*.py")]))
def test_every_public_function_of_the_cli_and_the_nodes_is_annotated(module):
    assert unannotated(CORE.parent / module) == []


#: A shape in a docstring: ``(n, 3)``, ``(3,)``, ``(grid.n_variables,)``, ``4x4``.
SHAPE = re.compile(r"\([\w.*+ ]+,[\w.*+ ,]*\)|\d+x\d+")
#: Public functions with an array-valued parameter or return whose docstring states no shape yet (issue 29, point
#: 6); only shrinks, and is empty: every one states its shape.
SHAPES_UNSTATED: set[str] = set()


def shapes_unstated(root):
    """``module:function`` of the public functions under ``root`` with a parameter or return annotated
    ``np.ndarray`` / ``npt.ArrayLike`` whose docstring states no shape (:data:`SHAPE`)."""
    missing = set()
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.FunctionDef) or node.name.startswith("_"):
                continue
            annotations = [a.annotation for a in node.args.posonlyargs + node.args.args + node.args.kwonlyargs]
            annotations.append(node.returns)
            if any(a is not None and re.search(r"ndarray|ArrayLike", ast.unparse(a)) for a in annotations) \
                    and not SHAPE.search(ast.get_docstring(node) or ""):
                missing.add(f"{path.relative_to(root).as_posix()}:{node.name}")
    return missing


def test_array_valued_parameters_state_their_shape():
    missing = shapes_unstated(CORE.parent / "core") | {f"nodes/{m}" for m in shapes_unstated(NODES)}
    assert not missing - SHAPES_UNSTATED, f"say the array's shape in the docstring: {sorted(missing - SHAPES_UNSTATED)}"
    stated = sorted(SHAPES_UNSTATED - missing)
    assert not stated, f"now stated, remove from SHAPES_UNSTATED: {stated}"


def test_the_shape_check_sees_a_missing_shape(tmp_path):
    (tmp_path / "m.py").write_text(
        "import numpy as np\n"
        "def bare(x: np.ndarray) -> int:\n    \"\"\"A number from x.\"\"\"\n"
        "def shaped(x: np.ndarray) -> int:\n    \"\"\"A number from x (n, 3), m.\"\"\"\n"
        "def out() -> np.ndarray:\n    \"\"\"The 4x4 transform.\"\"\"\n"
        "def plain(x: int) -> int:\n    \"\"\"No array.\"\"\"\n")
    assert shapes_unstated(tmp_path) == {"m.py:bare"}
