"""The two install routes and the set-up script's preflight checks.

The colcon route builds this repository with colcon (from PyPI) over the venv as the ROS underlay, the way a
real ROS 2 Jazzy install builds it, then imports the built interfaces and the Python sources from the install
space and checks that the node executables are where `ros2 run rollability_ros <node>` looks. Then it does what
`ros2 run` / `ros2 launch` do, without the launch package: it starts every installed executable file itself, with
the environment `install/setup.sh` gives, and exercises each node. Both are marked `slow` (./scripts/test.sh --slow,
which CI runs): the colcon build compiles the interfaces' C and C++ type support (48 s on a quiet 2-core machine,
5 min at load average 16), and every node it starts is exercised through `python -m` by the README's command.
"""
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import sysconfig
import time

import pytest

from conftest import REPO_ROOT
from ros_fixtures import NodeProcess, transitions_qos

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


class ColconInstall:
    """A colcon install space of this repository and the environment its ``install/setup.sh`` sets up."""

    def __init__(self, root, env):
        self.root = root
        self.package = root / "rollability_ros"
        self.lib = self.package / "lib" / "rollability_ros"
        self.config = self.package / "share" / "rollability_ros" / "config"
        self.site = self.package / pathlib.Path(sysconfig.get_path("purelib")).relative_to(sys.prefix)
        self.env = env

    def python(self, code, *args, timeout=120):
        """Run ``code`` with the venv's Python in the install's environment; its stdout."""
        done = subprocess.run([sys.executable, "-c", code, *args], cwd=self.root, env=self.env, capture_output=True,
                              text=True, timeout=timeout)   # not the checkout's folder: python -c imports from there
        assert done.returncode == 0, done.stderr[-3000:]
        return done.stdout


@pytest.fixture(scope="module")
def colcon_install(tmp_path_factory):
    """Build this repository with colcon over the venv (the underlay), as on a ROS 2 Jazzy install; source it."""
    colcon = shutil.which("colcon", path=os.path.dirname(sys.executable))
    if colcon is None:
        pytest.fail("colcon is not installed in this venv: scripts/setup.sh installs it (extra 'test')")
    workspace = tmp_path_factory.mktemp("colcon") / "ws"
    source = workspace / "src" / "rollability_ros"
    for name in _source_files():
        target = source / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO_ROOT / name, target)
    prefix = sys.prefix
    env = dict(os.environ, AMENT_PREFIX_PATH=prefix, CMAKE_PREFIX_PATH=prefix, VIRTUAL_ENV=prefix,
               PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"])
    env.pop("PYTHONPATH", None)   # conftest points it at this checkout: the install space must stand alone
    build = subprocess.run([colcon, "build", "--event-handlers", "console_direct-",
                            "--cmake-args", f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF"],
                           cwd=workspace, env=env, capture_output=True, text=True, timeout=900)
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    # what `source install/setup.bash` gives a user before `ros2 run` / `ros2 launch`
    sourced = subprocess.run(["sh", "-c", '. "$1" && env -0', "sh", str(workspace / "install" / "setup.sh")],
                             env=env, capture_output=True, timeout=60, check=True).stdout
    run_env = dict(item.split("=", 1) for item in sourced.decode().split("\0") if "=" in item)
    run_env["RCUTILS_LOGGING_BUFFERED_STREAM"] = "0"
    return ColconInstall(workspace / "install", run_env)


@pytest.mark.slow
def test_colcon_build_over_the_venv_underlay(colcon_install):
    install = colcon_install.package
    node_modules = sorted(p.stem for p in (REPO_ROOT / "rollability_ros" / "nodes").glob("*.py")
                          if not p.name.startswith("_"))
    assert sorted(p.name for p in colcon_install.lib.iterdir()) == node_modules
    for node in node_modules:
        executable = colcon_install.lib / node
        assert executable.is_file() and os.access(executable, os.X_OK), f"{executable} missing"
        assert executable.read_text().startswith(f"#!{sys.executable}")
    assert colcon_install.config.is_dir()
    assert (install / "share" / "ament_index" / "resource_index" / "packages" / "rollability_ros").is_file()
    assert str(colcon_install.site) in colcon_install.env["PYTHONPATH"].split(os.pathsep)

    check = ("import rollability_ros, rollability_ros.core.config as c; "
             "from rollability_ros.msg import LaunchOutcome; from rollability_ros.action import Launch; "
             "from rclpy.serialization import serialize_message as s; s(LaunchOutcome()); "
             "print(rollability_ros.__path__[0]); print(c.config_dir())")
    package_dir, config_dir = colcon_install.python(check).split()[-2:]
    assert pathlib.Path(package_dir) == colcon_install.site / "rollability_ros"
    assert pathlib.Path(config_dir) == colcon_install.config


#: The session graph's extra parameter file (the launch files' ``config:=``): one evaluator with a pool of 2
#: workers, a one-generation optimization on a 3 x 3 grid, a one-trial campaign.
GRAPH_CONFIG = """
/**:
  ros__parameters:
    bringup:
      evaluators: 1
      evaluator_workers: 2
    optimizer:
      popsize: 4
      trials: 4
      max_generations: 1
      stagnation_generations: 0
    quality_diversity:
      emitters: 2
    selection:
      count: 1
      min_distance: 0.0
      reevaluate_trials: 2
    profile:
      rows: 3
      cols: 3
    campaign:
      run_id: install-space
      configurations: [baseline]
      heights_m: [0.75]
      speeds_mps: [0.8]
      angles_deg: [0.0]
      repetitions: 1
"""


def _wait_for_text(process, text, timeout_s=120):
    deadline = time.monotonic() + timeout_s
    while text not in process.log() and process.alive() and time.monotonic() < deadline:
        time.sleep(0.2)
    assert text in process.log(), process.log()[-3000:]


@pytest.mark.slow
def test_installed_executables_run_the_session_graph(colcon_install, ros_node, tmp_path):
    """What `ros2 run` / `ros2 launch sim_bringup.launch.py` start, from the install space: each installed
    executable file itself (not `python -m`), with the install's environment and the launch files' exact
    arguments; every node is exercised, then stopped with SIGINT as `ros2 launch` does: no traceback, exit 0."""
    import json

    from action_msgs.msg import GoalStatus
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu
    from std_srvs.srv import Trigger

    from rollability_ros.action import EvaluateProfile
    from rollability_ros.core.bags.reader import bag_info
    from rollability_ros.msg import GenerationSummary, LaunchOutcome, TipState, ValveState
    from rollability_ros.nodes._support import LATCHED_QOS, RECORD_QOS, ThreadSafeActionClient, send_goal_resending
    from rollability_ros.srv import GetSummary
    from test_view import FoxgloveClient

    install, node = colcon_install, ros_node.node
    config, run_dir = tmp_path / "graph.yaml", tmp_path / "run"
    config.write_text(GRAPH_CONFIG)
    # the node list and arguments of sim_bringup.launch.py, computed by the installed package
    listed = install.python("import json, sys\nfrom rollability_ros.launch_support import session_commands\n"
                            "print(json.dumps(session_commands('sim', True, None, sys.argv[1], sys.argv[2])))",
                            str(config), str(run_dir))
    commands = [(executable, arguments) for executable, arguments, _restart in json.loads(listed)]
    assert [executable for executable, _ in commands] == ["recorder", "outcome_logger", "valve_controller",
                                                          "sim_evaluator", "rig", "optimizer"]
    namespace = "/rollability"
    commands += [
        ("tip_monitor", ["--ros-args", "-r", f"__ns:={namespace}", "--params-file",
                         str(install.config / "tip_monitor.yaml")]),
        ("view_bridge", ["--ros-args", "-r", f"__ns:={namespace}", "-p", "port:=0"]),
    ]
    run_dir.mkdir(exist_ok=True)   # session_commands wrote the nodes' override files into it
    started = {}
    try:
        for executable, arguments in commands:
            started[executable] = NodeProcess([str(install.lib / executable), *arguments],
                                              tmp_path / f"{executable}.log", env=install.env)
        states = []
        node.create_subscription(ValveState, f"{namespace}/valve/state", states.append, LATCHED_QOS)
        generations = []
        node.create_subscription(GenerationSummary, f"{namespace}/generations", generations.append, transitions_qos())
        outcomes = []
        node.create_subscription(LaunchOutcome, f"{namespace}/launch_outcomes", outcomes.append, RECORD_QOS)
        tip_states = []
        node.create_subscription(TipState, f"{namespace}/tip_monitor/state", tip_states.append, LATCHED_QOS)

        # sim_evaluator: one EvaluateProfile goal over its pool of 2 spawned workers
        _wait_for_text(started["sim_evaluator"], "ready: evaluate_profile on 2 local worker(s)")
        evaluator = ThreadSafeActionClient(node, EvaluateProfile, f"{namespace}/eval_0/evaluate_profile")
        assert evaluator.wait_for_server(timeout_sec=60)
        sent = send_goal_resending(evaluator, EvaluateProfile.Goal(heights=[], trials=4, seed=7), ros_node.wait_for, 60)
        assert sent is not None and sent.accepted
        evaluated = sent.get_result_async()
        assert ros_node.wait_for(evaluated.done, 300), started["sim_evaluator"].log()[-3000:]
        assert evaluated.result().status == GoalStatus.STATUS_SUCCEEDED, \
            (evaluated.result().result.message, started["sim_evaluator"].log()[-3000:])
        assert evaluated.result().result.trials == 4

        # optimizer: started over its service, completes a generation against the evaluator
        start = node.create_client(Trigger, f"{namespace}/start")
        assert start.wait_for_service(timeout_sec=60)
        assert start.call(Trigger.Request(), timeout_sec=60).success
        assert ros_node.wait_for(lambda: generations, 600), started["optimizer"].log()[-3000:]
        assert generations[0].generation == 1   # generations are numbered from 1

        # valve_controller: the arm service answers a request signed with its session key; the latched state arrives
        from rollability_ros.core.rig import valve_auth
        from rollability_ros.nodes._convert import auth_msg
        from rollability_ros.srv import ArmValve

        arm = node.create_client(ArmValve, f"{namespace}/valve/arm")
        assert arm.wait_for_service(timeout_sec=60)
        signer = valve_auth.RequestSigner(valve_auth.load_session_key(valve_auth.default_key_path(namespace)))
        assert arm.call(ArmValve.Request(arm=False, auth=auth_msg(signer.sign("disarm"))), timeout_sec=60).success
        assert ros_node.wait_for(lambda: states, 30) and states[-1].backend == "dry_run"

        # campaign_runner against the rig (sim backend); the outcome_logger stores the outcome
        runner = NodeProcess([str(install.lib / "campaign_runner"), "--ros-args", "-r", f"__ns:={namespace}",
                              "--params-file", str(install.config / "campaign.yaml"), "--params-file", str(config)],
                             tmp_path / "campaign_runner.log",
                             env=install.env)
        started["campaign_runner"] = runner
        assert ros_node.wait_for(lambda: not runner.alive(), 300), runner.log()[-3000:]
        assert runner.process.returncode == 0, runner.log()[-3000:]
        assert ros_node.wait_for(lambda: outcomes, 30) and outcomes[0].backend == "sim"
        summary = node.create_client(GetSummary, f"{namespace}/get_summary")
        assert summary.wait_for_service(timeout_sec=60)
        assert summary.call(GetSummary.Request(run_id="install-space"), timeout_sec=60).summary.trials == 1

        # tip_monitor: an upright IMU stream gives a state
        imu = node.create_publisher(Imu, f"{namespace}/imu/data", 10)
        deadline = time.monotonic() + 60
        while not tip_states and time.monotonic() < deadline:
            msg = Imu()
            msg.header.stamp = node.get_clock().now().to_msg()
            msg.orientation.w, msg.linear_acceleration.z = 1.0, 9.81
            imu.publish(msg)
            time.sleep(0.02)
        assert tip_states, started["tip_monitor"].log()[-3000:]

        # view_bridge: a Foxglove WebSocket client is answered
        _wait_for_text(started["view_bridge"], "Foxglove view on ws://")
        port = int(started["view_bridge"].log().split("Foxglove view on ws://")[1].split()[0].rsplit(":", 1)[1])
        FoxgloveClient(port).sock.close()

        # player: replays one recorded topic of the committed sample bag under a new name, looping (the recorder
        # subscribes to every topic, so the player may start before this test's subscription has matched it)
        replayed = []
        node.create_subscription(LaunchOutcome, "/replay/launch_outcomes", replayed.append,
                                 QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                                            durability=DurabilityPolicy.VOLATILE))
        sample = REPO_ROOT / "bags" / "sample"
        started["player"] = NodeProcess([str(install.lib / "player"), "--ros-args", "-p", f"player.bag:={sample}",
                                         "-p", "player.rate:=20.0", "-p", "player.loop:=true",
                                         "-p", "player.topics:=['/rollability/launch_outcomes']",
                                         "-p", "player.remap:=['/rollability/launch_outcomes:=/replay/launch_outcomes']"],
                                        tmp_path / "player.log", env=install.env)
        assert ros_node.wait_for(lambda: replayed, 60), started["player"].log()[-3000:]

        # Ctrl-C under `ros2 launch`: SIGINT to every node; the valve publishes its closed state first
        states_before_stop = len(states)
        for process in reversed(started.values()):
            process.signal(signal.SIGINT)
        for name, process in started.items():
            assert process.stop(timeout_s=60) == 0, (name, process.log()[-3000:])
        assert ros_node.wait_for(lambda: len(states) > states_before_stop, 10)
        assert not states[-1].open and not states[-1].armed
    finally:
        for process in started.values():
            process.stop()
    for name, process in started.items():
        log = process.log_path.read_text(errors="replace")
        for trouble in ("Traceback", "Failed to publish", "context is invalid", "InvalidHandle", "RCLError",
                        "ExternalShutdownException", "terminated abruptly"):
            assert trouble not in log, f"{name}: {trouble}\n{log[-3000:]}"
    assert "/rollability/launch_outcomes" in {topic["name"] for topic in bag_info(run_dir / "bag")["topics"]}
    assert not bag_info(run_dir / "bag")["warnings"]
