"""optimizer + sim_evaluator over real DDS, both on config/husky.yaml: the grid spans the Husky's mount footprint,
the run equals the in-process run on the same config, the marker sits on the mount link."""
import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from visualization_msgs.msg import Marker

from conftest import REPO_ROOT

pytest.importorskip("pybullet_data")

HUSKY_CONFIG = str(REPO_ROOT / "config" / "husky.yaml")
#: A tiny real run on husky.yaml's 4 x 3 grid, two generations whatever the fitness (target > 1 disables it),
#: started from the best of 4 random means by the stable-pose screen of the Husky.
RUN = {"optimizer.popsize": 4, "optimizer.trials": 3, "optimizer.max_generations": 2,
       "optimizer.stagnation_generations": 0, "optimizer.target_fitness": 2.0, "optimizer.seed": 3,
       "optimizer.initial_mean_screen": 4}
MARKER_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def ros_args(params):
    """``--params-file husky.yaml`` then ``-p`` overrides (a -p after the file wins)."""
    args = ["--params-file", HUSKY_CONFIG]
    for key, value in params.items():
        args += ["-p", f"{key}:={str(value).lower() if isinstance(value, bool) else value}"]
    return args


def candidate_rows(run_dir, run_id):
    """The stored candidates and the initial-mean screen of the run."""
    from rollability_ros.core.store import Store

    with Store(run_dir) as store:
        return ([(c.generation, c.index, c.heights, c.successes, c.trials, c.seed)
                 for c in sorted(store.candidates(run_id=run_id), key=lambda c: (c.generation, c.index))],
                store.run_info(run_id)["info"]["initial_mean_screen"])


def in_process_run(run_dir):
    """The same run without ROS, on the settings the CLI reads from husky.yaml (footprint grid)."""
    from rollability_ros.core.sim import evaluation
    from rollability_ros.core.optimization import optimization_run as optimization_run
    from rollability_ros.core.config import load_parameters

    parameters = {**load_parameters([HUSKY_CONFIG]), **RUN}
    settings = evaluation.settings_from_parameters(parameters)
    with evaluation.LocalExecutor(1) as executor:   # a batch's evaluations run in threads: one client each
        evaluate_batch = optimization_run.profile_batch_evaluator(settings, RUN["optimizer.trials"], executor)
        run = optimization_run.OptimizationRun(run_dir, optimization_run.run_config(parameters), settings.grid, evaluate_batch,
                                               screen_profiles=optimization_run.profile_screen(
                                                   optimization_run.run_settings(parameters), settings))
        run.run()
        run.close()
    return candidate_rows(run_dir, "ref"), settings.grid


def test_husky_run_over_dds_uses_the_mount_footprint(ros_node, start_node, tmp_path):
    from rollability_ros.core.optimization import optimization_run as optimization_run

    markers = []
    ros_node.node.create_subscription(Marker, "/best_profile_marker", markers.append, MARKER_QOS)
    start_node("sim_evaluator", ros_args=ros_args({"evaluator.workers": 1}))
    optimizer = start_node("optimizer", ros_args=ros_args({
        **RUN, "optimizer.output_dir": str(tmp_path / "runs"), "run_id": "husky", "exit_on_finish": True,
        "evaluator_discovery_period_s": 0.5, "evaluator_timeout_s": 30.0}))
    expected, grid = in_process_run(tmp_path / "ref")
    assert (grid.length_m, grid.width_m) == (0.9, 0.56)
    assert optimizer.process.wait(timeout=120) == 0, optimizer.log()

    run_dir = tmp_path / "runs" / "husky"
    saved = optimization_run.read_run_config(run_dir)
    assert (saved["profile.length_m"], saved["profile.width_m"], saved["profile.rows"]) == (0.9, 0.56, 4)
    stored, screen = candidate_rows(run_dir, "husky")
    assert len(stored) >= RUN["optimizer.popsize"] * RUN["optimizer.max_generations"]
    assert (stored, screen) == expected   # same screened start, same candidates, same Husky trial outcomes
    assert len(screen["upright_probability"]) == 4 and len(set(screen["upright_probability"])) > 1
    assert len({row[3] for row in stored}) >= 2, "all candidates scored alike: a weak test"

    assert ros_node.wait_for(lambda: markers, 10), optimizer.log()
    marker = markers[-1]
    assert marker.header.frame_id == "top_plate_link" and marker.action == Marker.ADD
    assert (marker.pose.position.x, marker.pose.position.y, marker.pose.position.z) == (0.0, 0.0, 0.25873)
    assert marker.pose.orientation.w == 1.0
    xs, ys = [p.x for p in marker.points], [p.y for p in marker.points]
    assert max(xs) - min(xs) == pytest.approx(0.9) and max(ys) - min(ys) == pytest.approx(0.56)
