"""sim_evaluator with a URDF robot from the robot_description topic (std_msgs/String, transient local)."""
import os

import pytest
import yaml
from action_msgs.msg import GoalStatus
from std_msgs.msg import String

from rollability_ros.action import EvaluateProfile
from rollability_ros.core.config import config_dir
from rollability_ros.nodes._support import LATCHED_QOS, ThreadSafeActionClient, send_goal_resending

pybullet_data = pytest.importorskip("pybullet_data")
HUSKY_DIR = os.path.join(pybullet_data.getDataPath(), "husky")
FIXTURE = os.path.join(os.path.dirname(__file__), "resources", "husky_optimized_profile.yaml")


def _husky_params_without_source(tmp_path):
    """config/husky.yaml with no urdf_path: the node must take the description from the topic."""
    with open(os.path.join(config_dir(), "husky.yaml"), encoding="utf-8") as stream:
        document = yaml.safe_load(stream)
    urdf_robot = document["/**"]["ros__parameters"]["urdf_robot"]
    del urdf_robot["urdf_path"]
    urdf_robot["search_paths"] = [HUSKY_DIR]  # the string's relative mesh paths
    path = tmp_path / "husky_topic.yaml"
    path.write_text(yaml.safe_dump(document), encoding="utf-8")
    return path


def test_description_from_the_topic(ros_node, start_node, tmp_path):
    from rollability_ros.core.config import load_parameters
    from rollability_ros.core.sim.evaluation import evaluate_profile, settings_from_parameters

    params_file = _husky_params_without_source(tmp_path)
    evaluator = start_node("sim_evaluator", params={"evaluator.workers": 1}, ros_args=["--params-file", str(params_file)])
    client = ThreadSafeActionClient(ros_node.node, EvaluateProfile, "/evaluate_profile")
    assert client.wait_for_server(timeout_sec=120), evaluator.log()
    with open(FIXTURE, encoding="utf-8") as stream:
        heights = yaml.safe_load(stream)["heights"]
    goal = EvaluateProfile.Goal(heights=heights, trials=4, seed=5)

    def send():
        handle = send_goal_resending(client, goal, ros_node.wait_for, 60)
        assert handle is not None, evaluator.log()
        return handle

    assert not send().accepted
    assert ros_node.wait_for(lambda: "no robot description yet" in evaluator.log(), 10), evaluator.log()

    publisher = ros_node.node.create_publisher(String, "/robot_description", LATCHED_QOS)
    publisher.publish(String(data=""))   # was a ValueError in the callback: the node died
    assert ros_node.wait_for(lambda: "ignored robot_description: the message is empty" in evaluator.log(), 30), \
        evaluator.log()
    publisher.publish(String(data="<robot name='broken'><link name='a'>"))
    assert ros_node.wait_for(lambda: "ignored robot_description: robot description is not valid XML"
                             in evaluator.log(), 30), evaluator.log()
    with open(os.path.join(HUSKY_DIR, "husky.urdf"), encoding="utf-8") as stream:
        text = stream.read()
    publisher.publish(String(data=text))
    assert ros_node.wait_for(lambda: "robot description 'husky_robot' received" in evaluator.log(), 30), \
        evaluator.log()

    handle = send()
    assert handle.accepted
    future = handle.get_result_async()
    assert ros_node.wait_for(future.done, 180), evaluator.log()
    response = future.result()
    assert response.status == GoalStatus.STATUS_SUCCEEDED, response.result.message
    flat = load_parameters(["sim", "robot", "evaluator", str(params_file)])
    settings = settings_from_parameters({**flat, "urdf_robot.robot_description": text})
    expected = evaluate_profile(heights, 4, 5, settings)
    assert [t.upright for t in response.result.trial_results] == [t.upright for t in expected.trial_results]
    assert [t.steps for t in response.result.trial_results] == [t.steps for t in expected.trial_results]

