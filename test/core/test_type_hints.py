"""Public functions carry type hints: a ratchet over the core modules already annotated (add a module to MODULES once
every public function and method in it has annotated parameters and a return type), and every module of the CLI
and of the nodes; array-valued parameters state their shape in the docstring."""
import ast
import pathlib
import re

import pytest

CORE = pathlib.Path(__file__).resolve().parents[2] / "rollability_ros" / "core"
CLI = CORE.parent / "cli"
NODES = CORE.parent / "nodes"
MODULES = ["imu/quaternion.py", "imu/upright.py", "records.py", "record_messages.py",
           "rig/launch_backend.py", "rig/rig_session.py", "campaign/runner.py", "optimization/optimization_run.py",
           "bags/messages.py", "graph/bringup.py",
           "bags/convert.py", "graph/preflight.py", "optional.py", "registry.py", "results/sensitivity_table.py",
           "rig/relay_protocol.py", "rig/rig_network.py", "rig/valve_auth.py", "rig/valve_backend.py",
           "sim/body_points.py", "sim/trial_engine.py", "sim/worker_pool.py",
           "campaign_matrix.py", "faces.py", "profile/descriptors.py", "profile/designs.py", "profile/geometry.py",
           "robots/robot.py", "robots/urdf_description.py", "robots/urdf_robot.py",
           "config.py", "stats.py", "campaign/plan.py", "graph/ros_domain.py", "rig/rig_auth.py", "sim/robustness.py",
           "sim/world.py", "bags/metadata.py", "bags/msg_definitions.py", "bags/playback.py", "bags/qos.py",
           "bags/record_play.py", "bags/mcap_file.py", "bags/reader.py", "bags/recover.py", "bags/writer.py",
           "graph/progress.py", "graph/supervisor.py", "imu/tip_tracker.py", "results/design_map.py",
           "results/outcome_csv.py", "sim/sensitivity.py", "results/engine_agreement.py", "sim/launcher_geometry.py",
           "sim/trials.py", "store.py", "rig/speed_gate.py", "rig/valve.py", "results/outcome_log.py",
           "sim/early_decision.py", "sim/objectives.py", "graph/foxglove_view.py",
           "rig/valve_backends.py", "sim/stable_poses.py",
           "sim/mujoco_trials.py", "results/report_figures.py",
           "rig/relay_device_sim.py", "results/analysis.py", "sim/launch_twin.py", "sim/mujoco_launch_twin.py",
           "sim/evaluation.py", "campaign/calibration.py", "results/report.py",
           "graph/study.py", "rig/gpio_line_holder.py", "optimization/racing.py", "optimization/checkpoint.py", "optimization/quality_diversity.py", "optimization/evaluator_pool.py",
           "optimization/cmaes.py"]


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
