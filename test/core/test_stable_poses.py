"""The stable-pose screen: analytic cases (cube, boxes), the chassis hull, and low-energy PyBullet drops."""
import math

import numpy as np
import pytest

from rollability_ros.core.config import check_settings
from rollability_ros.core.sim import stable_poses
from rollability_ros.core.profile.geometry import ProfileGrid, grid_xy, profile_mesh
from rollability_ros.core.robots.robot import ChassisModel, ChassisSpec
from rollability_ros.core.sim.world import PhysicsParams
from rollability_ros.core.sim.trials import TrialSettings

pytest.importorskip("trimesh")
pytest.importorskip("networkx")


def box(length_m, width_m, height_m, com_m=(0.0, 0.0, 0.0), mass_kg=1.0):
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) / 2
    return stable_poses.RigidHull.from_points(corners * [length_m, width_m, height_m], com_m, mass_kg)


def hexagonal_prism(radius_m, length_m):
    """A prism along x with a flat face down (upright) and up: a cylinder-ish shape."""
    angles = np.linspace(0.0, 2 * math.pi, 6, endpoint=False) + math.pi / 6
    ring = np.column_stack([np.zeros(6), radius_m * np.cos(angles), radius_m * np.sin(angles)])
    return stable_poses.RigidHull.from_points(np.vstack([ring - [length_m / 2, 0, 0], ring + [length_m / 2, 0, 0]]),
                                              (0.0, 0.0, 0.0), 1.0)


def ridge_profile(spec):
    """A ridge along the chassis length (the tallest grid heights next to the centre line)."""
    grid = ProfileGrid()
    across = grid_xy(grid)[:, 1] / (grid.width_m / 2)
    heights = np.where(across < 0.2, grid.height_max, 0.0)
    return ChassisModel(spec).profile_body(profile_mesh(heights, grid))


def test_cube_rests_on_each_face_equally_and_tips_over_an_edge():
    side = 0.1
    screen = stable_poses.screen_body(box(side, side, side), upright_tilt_deg=30.0)
    assert len(screen.poses) == 6
    assert [p.probability for p in screen.poses] == pytest.approx([1 / 6] * 6, abs=1e-9)
    assert screen.upright_probability == pytest.approx(1 / 6)
    # tipping over an edge lifts the COM from side/2 to side/sqrt(2)
    assert screen.worst_barrier_m == pytest.approx(side * (math.sqrt(0.5) - 0.5))
    assert screen.worst_barrier_j == pytest.approx(9.81 * side * (math.sqrt(0.5) - 0.5))
    assert all(p.barrier_m == 0.0 for p in screen.poses if p.upright)


def test_flat_box_barrier_is_the_cheapest_edge_from_the_inverted_pose():
    length, width, height = 0.2, 0.15, 0.05
    screen = stable_poses.screen_body(box(length, width, height), upright_tilt_deg=30.0)
    inverted = [p for p in screen.poses if p.tilt_deg > 170]
    assert len(inverted) == 1
    # over the long edge (along x): the COM rises to the distance from the edge, sqrt((w/2)^2 + (h/2)^2)
    assert inverted[0].barrier_m == pytest.approx(math.hypot(width / 2, height / 2) - height / 2)
    assert inverted[0].com_height_m == pytest.approx(height / 2)
    assert screen.worst_barrier_m == pytest.approx(inverted[0].barrier_m)
    assert sum(p.probability for p in screen.poses) == pytest.approx(1.0)


def test_a_lower_centre_of_mass_rests_upright_more_often():
    probabilities = [stable_poses.screen_body(box(0.1, 0.1, 0.1, (0.0, 0.0, z)), 30.0).upright_probability
                     for z in (0.02, 0.0, -0.02, -0.04)]
    assert probabilities == sorted(probabilities)
    assert probabilities[-1] > probabilities[0] + 0.3


def test_centre_of_mass_scatter_is_sampled_and_smooths_the_answer():
    body = box(0.1, 0.1, 0.1)
    scattered = stable_poses.screen_body(body, 30.0, com_sigma_m=0.01, n_samples=40, seed=3)
    assert scattered.upright_probability == pytest.approx(1 / 6, abs=0.05)
    assert scattered.upright_probability != pytest.approx(1 / 6, abs=1e-9)
    again = stable_poses.screen_body(body, 30.0, com_sigma_m=0.01, n_samples=40, seed=3)
    assert again.upright_probability == scattered.upright_probability


def test_chassis_hull_holds_wheels_profile_and_mass():
    spec = ChassisSpec()
    bare = stable_poses.robot_hull(ChassisModel(spec))
    assert bare.mass_kg == pytest.approx(spec.body_mass_kg + 4 * spec.wheel_mass_kg)
    assert bare.hull.bounds[0][2] == pytest.approx(spec.axle_offset_z_m - spec.wheel_radius_m)
    assert bare.hull.bounds[1][1] == pytest.approx(spec.track_m / 2 + spec.wheel_width_m / 2)
    ridge = ridge_profile(spec)
    with_ridge = stable_poses.robot_hull(ChassisModel(spec), ridge)
    assert with_ridge.mass_kg == pytest.approx(bare.mass_kg + ridge.mass_kg)
    assert with_ridge.com_m[2] > bare.com_m[2]
    assert with_ridge.hull.bounds[1][2] == pytest.approx(spec.body_height_m / 2 + ridge.hull_vertices_m[:, 2].max())


def test_a_ridge_lowers_the_barrier_out_of_the_inverted_pose():
    spec = ChassisSpec()
    settings = stable_poses.ScreenSettings(com_sigma_m=0.0)
    bare = stable_poses.screen_robot(ChassisModel(spec), None, settings)
    ridge = stable_poses.screen_robot(ChassisModel(spec), ridge_profile(spec), settings)
    assert ridge.worst_barrier_m < 0.5 * bare.worst_barrier_m

    def inverted(screen):
        return sum(p.probability for p in screen.poses if p.tilt_deg > 170)
    assert inverted(ridge) < 0.5 * inverted(bare)    # the ridge's narrow top rarely catches the chassis


def test_screen_heights_flags_candidates_below_the_threshold():
    from rollability_ros.core.sim.evaluation import EvaluatorSettings

    evaluator = EvaluatorSettings()
    grid = evaluator.grid
    ridge = np.where(grid_xy(grid)[:, 1] / (grid.width_m / 2) < 0.2, grid.height_max, 0.0)
    settings = stable_poses.ScreenSettings(com_sigma_m=0.0, prescreen_min_probability=0.4)
    (bare, bare_passed), (screened, ridge_passed) = stable_poses.screen_heights([None, ridge], evaluator, settings)
    assert bare_passed == (bare.upright_probability >= 0.4)
    assert ridge_passed == (screened.upright_probability >= 0.4)
    assert bare_passed != ridge_passed


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="outside the hull"):
        box(0.1, 0.1, 0.1, com_m=(0.0, 0.0, 0.2))
    with pytest.raises(ValueError, match="upright_tilt_deg"):
        stable_poses.screen_body(box(0.1, 0.1, 0.1), 95.0)
    with pytest.raises(ValueError, match="n_samples"):
        check_settings(stable_poses.ScreenSettings(n_samples=0), "stable_poses")


SHAPES = {
    "cube": lambda: (stable_poses.hull_spawner, box(0.1, 0.1, 0.1)),
    "brick 4:2:1": lambda: (stable_poses.hull_spawner, box(0.2, 0.1, 0.05)),
    "low-COM cube": lambda: (stable_poses.hull_spawner, box(0.1, 0.1, 0.1, (0.0, 0.0, -0.03))),
    "hexagonal prism": lambda: (stable_poses.hull_spawner, hexagonal_prism(0.04, 0.12)),
}


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_screen_agrees_with_low_energy_pybullet_drops(name):
    pytest.importorskip("pybullet")
    spawner, body = SHAPES[name]()
    drops = 150
    expected = stable_poses.screen_body(body, 30.0).upright_probability
    upright, settled = stable_poses.drop_trials(spawner(body, 30.0), drops, 7, PhysicsParams(), TrialSettings())
    assert settled == drops
    standard_error = math.sqrt(expected * (1 - expected) / drops)
    assert abs(upright / drops - expected) <= 3 * standard_error, (name, upright, expected)


def test_chassis_screen_agrees_with_low_energy_pybullet_drops():
    pytest.importorskip("pybullet")
    spec = ChassisSpec()
    ridge = ridge_profile(spec)
    drops = 150
    expected = stable_poses.screen_robot(ChassisModel(spec), ridge, stable_poses.ScreenSettings(com_sigma_m=0.0))
    upright, settled = stable_poses.drop_trials(stable_poses.chassis_spawner(ChassisModel(spec), ridge), drops, 7,
                                                PhysicsParams(), TrialSettings())
    assert settled == drops
    p = expected.upright_probability
    assert abs(upright / drops - p) <= 3 * math.sqrt(p * (1 - p) / drops), (upright, p)


def chassis_as_urdf_robot(tilt_rpy=None):
    """The built-in chassis described as a URDF robot; with ``tilt_rpy``, under a root frame turned by it, so that
    the chassis' up axis is no longer the root frame's z (the spec names it in the root frame instead)."""
    from rollability_ros.core.robots.urdf_description import rpy_matrix
    from rollability_ros.core.robots.urdf_robot import UrdfRobotModel, UrdfRobotSpec

    spec = ChassisSpec()
    text = ChassisModel(spec).to_urdf()
    up = (0.0, 0.0, 1.0)
    if tilt_rpy is not None:
        joint = (f'<link name="tilted_root"/><joint name="tilt" type="fixed"><parent link="tilted_root"/>'
                 f'<child link="base_link"/><origin xyz="0 0 0" rpy="{" ".join(map(str, tilt_rpy))}"/></joint>')
        text = text.replace("</robot>", joint + "</robot>")
        up = tuple(rpy_matrix(tilt_rpy) @ [0.0, 0.0, 1.0])
    return UrdfRobotModel(UrdfRobotSpec(
        robot_description=text, mount_link="base_link", footprint_length_m=spec.body_length_m,
        footprint_width_m=spec.body_width_m, footprint_offset_m=(0.0, 0.0, spec.body_height_m / 2),
        wheel_link_regex=".*_wheel", min_wheels_in_contact=spec.min_wheels_in_contact, up_axis_xyz=up,
        upright_tilt_deg=spec.upright_tilt_deg, profile_print=spec.profile_print))


def test_rotation_onto_z_turns_any_axis_up():
    for axis in ([0, 0, 1], [0, 0, -1], [1, 0, 0], [0, -1, 0], [1, 2, -3]):
        turn = stable_poses._rotation_onto_z(axis)
        assert turn @ (np.array(axis) / np.linalg.norm(axis)) == pytest.approx([0, 0, 1])
        assert turn @ turn.T == pytest.approx(np.eye(3)) and np.linalg.det(turn) == pytest.approx(1.0)


@pytest.mark.parametrize("tilt_rpy", [None, (math.pi / 2, 0.0, 0.3)])
def test_a_urdf_robot_screens_like_the_same_robot_built_in(tilt_rpy):
    """The chassis from its own URDF, also under a turned root frame, gives the built-in chassis' mass, COM height,
    hull and screen: the screen reads any robot model, not the chassis spec."""
    pytest.importorskip("pybullet")
    spec = ChassisSpec()
    settings = stable_poses.ScreenSettings(com_sigma_m=0.0)
    ridge = ridge_profile(spec)
    for profile in (None, ridge):
        built_in = stable_poses.robot_hull(ChassisModel(spec), profile)
        urdf = stable_poses.robot_hull(chassis_as_urdf_robot(tilt_rpy), profile)
        assert urdf.mass_kg == pytest.approx(built_in.mass_kg, rel=1e-4)
        # heights above the lowest point are frame-free (the URDF base sits at the COM, the chassis' at its box)
        assert urdf.com_m[2] - urdf.hull.bounds[0][2] == pytest.approx(built_in.com_m[2] - built_in.hull.bounds[0][2],
                                                                       abs=1e-4)
        assert np.ptp(urdf.hull.bounds, axis=0)[2] == pytest.approx(np.ptp(built_in.hull.bounds, axis=0)[2], abs=2e-3)
        assert urdf.hull.volume == pytest.approx(built_in.hull.volume, rel=0.03)   # PyBullet's cylinder tessellation
        expected = stable_poses.screen_body(built_in, spec.upright_tilt_deg).upright_probability
        screened = stable_poses.screen_robot(chassis_as_urdf_robot(tilt_rpy), profile, settings).upright_probability
        assert screened == pytest.approx(expected, abs=0.03)


def test_husky_screen_agrees_with_low_energy_pybullet_drops():
    """A robot nobody here wrote: the Husky's hull from its URDF collision shapes, screened, against drops."""
    pytest.importorskip("pybullet")
    from rollability_ros.core.sim.evaluation import load_settings

    model = load_settings(("sim", "robot", "evaluator", "husky")).robot_model()
    body = stable_poses.robot_hull(model)
    assert body.mass_kg == pytest.approx(model.mounted.robot.mass_kg, rel=1e-4)
    wheel_radius = max(model.wheel_radii_m())
    assert np.ptp(body.hull.bounds, axis=0)[2] > 2 * wheel_radius            # wheels and body are both in it
    expected = stable_poses.screen_body(body, model.upright_tilt_deg).upright_probability
    assert 0.05 < expected < 0.95
    drops = 150
    upright, settled = stable_poses.drop_trials(stable_poses.chassis_spawner(model, None), drops, 7,
                                                PhysicsParams(), TrialSettings())
    assert settled == drops
    assert abs(upright / drops - expected) <= 3 * math.sqrt(expected * (1 - expected) / drops), (upright, expected)


def rests_off_the_wheels(screen):
    """The screen's resting poses that are not upright (upside down or on a side)."""
    return [pose for pose in screen.poses if not pose.upright]


def test_the_0_09_m_bound_leaves_rests_off_the_wheels_and_lowers_the_barrier_back():
    """ProfileGrid's claim: at the paper's bound (0.45 units = 0.09 m) the inverted pose is not made unstable; every
    shape keeps rests off its wheels, and a dome, a flat top and a centre ridge lower the barrier back onto the
    wheels to under half the bare chassis's. Printed as config/robot.yaml says."""
    from test_physics import dome_heights

    spec, grid = ChassisSpec(), ProfileGrid()
    assert grid.height_max * grid.unit_m == pytest.approx(0.09)
    model, settings = ChassisModel(spec), stable_poses.ScreenSettings(com_sigma_m=0.0, n_samples=1)  # nominal COM
    bare = stable_poses.screen_robot(model, None, settings)
    assert any(pose.tilt_deg > 170 for pose in rests_off_the_wheels(bare))     # the bare chassis rests inverted
    across = grid_xy(grid)[:, 1] / (grid.width_m / 2)
    named = {"dome": dome_heights(grid), "flat top": np.full(grid.n_variables, grid.height_max),
             "ridge": np.where(across < 0.2, grid.height_max, 0.0)}
    rng = np.random.default_rng(40)
    shapes = dict(named, **{f"random {i}": rng.uniform(grid.height_min, grid.height_max, grid.n_variables)
                            for i in range(4)})
    for name, heights in shapes.items():
        screen = stable_poses.screen_robot(model, model.profile_body(profile_mesh(heights, grid)), settings)
        assert rests_off_the_wheels(screen), f"{name}: no rest off the wheels"
        assert max(pose.tilt_deg for pose in rests_off_the_wheels(screen)) > 90, name
        if name in named:
            assert screen.worst_barrier_m < bare.worst_barrier_m / 2, name
