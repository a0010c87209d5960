"""The two install routes and the set-up script's preflight checks.

The colcon route builds this repository with colcon (from PyPI) over the venv as the ROS underlay, the way a
real ROS 2 Jazzy install builds it, then imports the built interfaces and the Python sources from the install
space and checks that the node executables are where `ros2 run rollability_ros <node>` looks.
"""
import os
import pathlib
import shutil
import subprocess
import sys
import sysconfig
import time

import pytest

from conftest import REPO_ROOT
from ros_fixtures import NodeProcess

SETUP = REPO_ROOT / "scripts" / "setup.sh"


def test_package_xml_is_valid_for_catkin_pkg():
    from catkin_pkg.package import parse_package

    package = parse_package(str(REPO_ROOT / "package.xml"))
    package.validate()
    assert package.name == "rollability_ros" and package.package_format == 3
    assert package.get_build_type() == "ament_cmake"
    assert "rosidl_interface_packages" in [group.name for group in package.member_of_groups]


def _source_files():
    listed = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=REPO_ROOT, check=True,
                            capture_output=True, text=True).stdout.split()
    return [name for name in listed if (REPO_ROOT / name).is_file()]


@pytest.mark.slow
def test_colcon_build_over_the_venv_underlay(tmp_path):
    colcon = shutil.which("colcon", path=os.path.dirname(sys.executable))
    if colcon is None:
        pytest.fail("colcon is not installed in this venv: scripts/setup.sh installs it (extra 'test')")
    source = tmp_path / "ws" / "src" / "rollability_ros"
    for name in _source_files():
        target = source / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO_ROOT / name, target)
    prefix = sys.prefix
    env = dict(os.environ, AMENT_PREFIX_PATH=prefix, CMAKE_PREFIX_PATH=prefix, VIRTUAL_ENV=prefix,
               PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"])
    env.pop("PYTHONPATH", None)
    build = subprocess.run([colcon, "build", "--event-handlers", "console_direct-",
                            "--cmake-args", f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF"],
                           cwd=tmp_path / "ws", env=env, capture_output=True, text=True, timeout=900)
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]

    install = tmp_path / "ws" / "install" / "rollability_ros"
    lib = install / "lib" / "rollability_ros"
    node_modules = sorted(p.stem for p in (REPO_ROOT / "rollability_ros" / "nodes").glob("*.py")
                          if not p.name.startswith("_"))
    for node in node_modules:
        executable = lib / node
        assert executable.is_file() and os.access(executable, os.X_OK), f"{executable} missing"
        assert executable.read_text().startswith(f"#!{sys.executable}")
    assert (install / "share" / "rollability_ros" / "config").is_dir()
    assert (install / "share" / "ament_index" / "resource_index" / "packages" / "rollability_ros").is_file()

    site = install / pathlib.Path(sysconfig.get_path("purelib")).relative_to(sys.prefix)
    check = ("import rollability_ros, rollability_ros.core.config as c; "
             "from rollability_ros.msg import LaunchOutcome; from rollability_ros.action import Launch; "
             "from rclpy.serialization import serialize_message as s; s(LaunchOutcome()); "
             "print(rollability_ros.__path__[0]); print(c.config_dir())")
    run_env = dict(env, PYTHONPATH=str(site), LD_LIBRARY_PATH=f"{install / 'lib'}:{os.environ.get('LD_LIBRARY_PATH', '')}")
    imported = subprocess.run([sys.executable, "-c", check], cwd=tmp_path, env=run_env, capture_output=True,
                              text=True, timeout=120)
    assert imported.returncode == 0, imported.stderr[-3000:]
    package_dir, config_dir = imported.stdout.split()[-2:]
    assert pathlib.Path(package_dir) == site / "rollability_ros"
    assert pathlib.Path(config_dir) == install / "share" / "rollability_ros" / "config"

    # what `ros2 run rollability_ros valve_controller` starts: the installed executable, from the install space
    node = NodeProcess([str(lib / "valve_controller"), "--ros-args", "-p", "valve.backend:=dry_run"],
                       tmp_path / "valve_controller.log", env=dict(run_env, RCUTILS_LOGGING_BUFFERED_STREAM="0"))
    deadline = time.monotonic() + 60
    while "valve ready: backend dry_run" not in node.log() and node.alive() and time.monotonic() < deadline:
        time.sleep(0.2)
    assert "valve ready: backend dry_run" in node.log(), node.log()
    assert node.stop() == 0, node.log()
