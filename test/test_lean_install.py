"""The robot computer's lean install: the physical-side nodes start and serve with the simulation, cluster and
report packages (pybullet, trimesh, cma, scipy, ray, matplotlib) made unimportable in their processes."""
import os
import subprocess
import sys

import pytest

#: Top-level modules a lean robot computer does not have (the sim, cluster and report extras).
HEAVY_MODULES = ("pybullet", "pybullet_data", "trimesh", "cma", "scipy", "ray", "matplotlib", "ribs", "numba")

BLOCKER = f'''"""Test-only sitecustomize: the heavy extras cannot be imported in this process."""
import sys

BLOCKED = {HEAVY_MODULES!r}


class _LeanInstall:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {{name!r}} (blocked: lean install)", name=name)
        return None


sys.meta_path.insert(0, _LeanInstall())
'''


@pytest.fixture
def lean_env(tmp_path):
    """Environment for child processes whose ``sitecustomize`` blocks :data:`HEAVY_MODULES`."""
    folder = tmp_path / "lean_site"
    folder.mkdir()
    (folder / "sitecustomize.py").write_text(BLOCKER, encoding="utf-8")
    env = os.environ.copy()
    env["PYTHONPATH"] = os.pathsep.join([str(folder)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


def _run(env, *args):
    return subprocess.run([sys.executable, *args], env=env, capture_output=True, text=True, timeout=120)


def test_heavy_modules_are_blocked_and_name_their_extra(lean_env):
    for module in HEAVY_MODULES:
        assert _run(lean_env, "-c", f"import {module}").returncode != 0, module
    probe = _run(lean_env, "-c", "from rollability_ros.core.optional import require; require('pybullet')")
    assert "pip install 'rollability_ros[sim]'" in probe.stderr, probe.stderr
    script = ("import sys, importlib\n"
              "for m in ('valve_controller', 'rig', 'outcome_logger', 'recorder', 'tip_monitor'):\n"
              "    importlib.import_module('rollability_ros.nodes.' + m)\n"
              f"print(sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY_MODULES!r}))\n")
    imported = _run(lean_env, "-c", script)
    assert imported.returncode == 0 and imported.stdout.strip() == "[]", imported.stderr


def test_doctor_rig_passes(lean_env):
    doctor = _run(lean_env, "-m", "rollability_ros.cli", "doctor", "--rig")
    assert doctor.returncode == 0, doctor.stdout + doctor.stderr
    assert "(rig side only)" in doctor.stdout and "FAIL" not in doctor.stdout, doctor.stdout


def _call(ros_node, client, request, timeout_s=30):
    assert client.wait_for_service(timeout_sec=timeout_s), f"no service {client.srv_name}"
    future = client.call_async(request)
    assert ros_node.wait_for(future.done, timeout_s), f"no answer from {client.srv_name}"
    return future.result()


def test_physical_side_nodes_start_and_serve(ros_node, start_node, lean_env, tmp_path):
    from rclpy.action import ActionClient
    from sensor_msgs.msg import Imu
    from valve_client import ValveClient

    from rollability_ros.action import Launch
    from rollability_ros.msg import TipState
    from rollability_ros.nodes._support import LATCHED_QOS
    from rollability_ros.srv import GetSummary, RecordOutcome

    nodes = {
        "valve_controller": start_node("valve_controller", params={"valve.backend": "dry_run"}, env=lean_env),
        "rig": start_node("rig", params={"rig.backend": "physical", "rig.countdown_s": 0.1}, env=lean_env),
        "outcome_logger": start_node("outcome_logger", params={"store_path": str(tmp_path / "store.sqlite")},
                                     env=lean_env),
        "recorder": start_node("recorder", params={"recorder.output_dir": str(tmp_path / "bag"),
                                                   "recorder.discovery_period_s": 0.2}, env=lean_env),
        "tip_monitor": start_node("tip_monitor", env=lean_env),
    }
    node = ros_node.node

    valve = ValveClient(ros_node)   # signed with the session key the valve_controller wrote
    assert valve.arm_client.wait_for_service(timeout_sec=30)
    ok, message = valve.arm()
    assert ok, message
    stray = _call(ros_node, node.create_client(RecordOutcome, "/record_outcome"), RecordOutcome.Request(upright=True))
    assert not stray.accepted and "not authenticated" in stray.message
    assert ActionClient(node, Launch, "/launch").wait_for_server(timeout_sec=30)
    summary = _call(ros_node, node.create_client(GetSummary, "/get_summary"), GetSummary.Request())
    assert (summary.summary.trials, summary.summary.candidates) == (0, 0)  # a fresh store

    states = []
    node.create_subscription(TipState, "/tip_monitor/state", states.append, LATCHED_QOS)
    imu = node.create_publisher(Imu, "imu/data", 10)
    level = Imu()
    level.orientation.w = 1.0
    level.linear_acceleration.z = 9.81

    def tip_state_seen():
        level.header.stamp = node.get_clock().now().to_msg()
        imu.publish(level)
        return bool(states)

    assert ros_node.wait_for(tip_state_seen, 30), nodes["tip_monitor"].log()
    assert states[0].label == "upright"
    assert ros_node.wait_for(lambda: "/imu/data" in nodes["recorder"].log() or
                             os.path.isdir(tmp_path / "bag"), 30), nodes["recorder"].log()

    for name, process in nodes.items():
        assert process.alive(), f"{name} died:\n{process.log()}"
        assert "MissingDependency" not in process.log() and "Traceback" not in process.log(), process.log()
    nodes["recorder"].stop()
    assert (tmp_path / "bag" / "metadata.yaml").is_file(), nodes["recorder"].log()
