"""The profile's mass from its print (core/profile/print_mass.py): analytic shells (boxes, a turned box whose faces
slope), the solid limits, refused meshes and settings, and both engines and the stable-pose screen weighing the
profile as printed."""
import math
import re

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("scipy")

from rollability_ros.core.config import ConfigError, check_settings, from_mapping  # noqa: E402
from rollability_ros.core.profile.geometry import ProfileGrid, grid_xy, profile_mesh  # noqa: E402
from rollability_ros.core.profile.print_mass import MassProperties, ProfilePrintSpec, combine, print_mass_properties  # noqa: E402
from rollability_ros.core.robots.robot import ChassisModel, ChassisSpec, ProfileBody  # noqa: E402

PLA = 1240.0


def box_inertia(mass, a, b, c):
    """A solid box's inertia about its centre (3, 3), edges a, b, c along x, y, z."""
    return np.diag([mass * (b * b + c * c) / 12, mass * (a * a + c * c) / 12, mass * (a * a + b * b) / 12])


def shell(wall, skin, infill):
    return ProfilePrintSpec(wall_thickness_m=wall, skin_thickness_m=skin, infill_fraction=infill)


def front_heavy_heights(grid):
    """A wedge rising towards the front (+x): no symmetry about y-z, so the inertia has a product term I_xz."""
    x = grid_xy(grid)[:, 0] / grid.length_m + 0.5
    return grid.height_max * (0.2 + 0.8 * x)


def test_a_box_shell_weighs_and_turns_as_the_hand_formula():
    a, b, c, wall, skin, infill = 0.12, 0.08, 0.05, 0.002, 0.003, 0.25
    outer = trimesh.creation.box([a, b, c])
    outer.apply_translation([0.0, 0.0, c / 2])               # resting on z = 0 as a profile does
    inner = (a - 2 * wall, b - 2 * wall, c - 2 * skin)
    solid_outer, solid_inner = PLA * a * b * c, PLA * math.prod(inner)
    mass = solid_outer - (1 - infill) * solid_inner
    inertia = box_inertia(solid_outer, a, b, c) - (1 - infill) * box_inertia(solid_inner, *inner)
    got = print_mass_properties(outer, shell(wall, skin, infill))
    assert got.mass_kg == pytest.approx(mass, rel=1e-9)
    assert got.com_m == pytest.approx([0.0, 0.0, c / 2], abs=1e-12)
    assert got.inertia_kgm2 == pytest.approx(inertia, rel=1e-9, abs=1e-15)


def test_gradual_infill_in_a_box_is_the_sparsest_infill_plus_denser_slabs_under_the_top():
    """Cura's gradual infill (20 % halved 3 times, 4 mm steps) in a box: the inner box at 2.5 % plus slabs of the
    inner box's width under its top at 20 - 2.5, 10 - 2.5 and 5 - 2.5 %, each a box of its own: mass, centre of mass
    and inertia as the hand formula."""
    a, b, c, wall, skin, fill, step = 0.12, 0.08, 0.05, 0.002, 0.003, 0.2, 0.004
    outer = trimesh.creation.box([a, b, c])
    outer.apply_translation([0.0, 0.0, c / 2])
    inner = (a - 2 * wall, b - 2 * wall, c - 2 * skin)
    parts = [(MassProperties(a * b * c, np.array([0, 0, c / 2]), box_inertia(a * b * c, a, b, c)), PLA),
             (MassProperties(math.prod(inner), np.array([0, 0, c / 2]), box_inertia(math.prod(inner), *inner)),
              -PLA * (1 - fill / 8))]
    for k in range(3):
        slab = inner[0] * inner[1] * step
        parts.append((MassProperties(slab, np.array([0, 0, c - skin - (k + 0.5) * step]),
                                     box_inertia(slab, inner[0], inner[1], step)), PLA * (fill / 2 ** k - fill / 8)))
    expected = combine(parts)
    spec = ProfilePrintSpec(wall_thickness_m=wall, skin_thickness_m=skin, infill_fraction=fill, gradual_infill_steps=3,
                            gradual_infill_step_height_m=step)
    got = print_mass_properties(outer, spec)
    assert got.mass_kg == pytest.approx(expected.mass_kg, rel=1e-9)
    assert got.com_m == pytest.approx(expected.com_m, abs=1e-12)
    assert got.com_m[2] > print_mass_properties(outer, shell(wall, skin, fill / 8)).com_m[2]   # the dense part is high
    assert got.inertia_kgm2 == pytest.approx(expected.inertia_kgm2, rel=1e-9, abs=1e-15)


def test_gradual_infill_on_a_sloped_profile_lies_between_its_sparsest_and_densest_uniform_prints():
    """On the wedge (a sloped top), steps taller than the profile leave the whole inside at the top density (the
    uniform print, to the column grid's resolution); shorter steps weigh between the uniform prints at the sparsest
    and the densest density."""
    mesh = profile_mesh(front_heavy_heights(ProfileGrid()), ProfileGrid())
    uniform = print_mass_properties(mesh, shell(0.0008, 0.0008, 0.2))
    one_step = print_mass_properties(mesh, ProfilePrintSpec(gradual_infill_steps=2, gradual_infill_step_height_m=0.5))
    assert one_step.mass_kg == pytest.approx(uniform.mass_kg, rel=1e-3)
    assert one_step.com_m == pytest.approx(uniform.com_m, abs=1e-4)
    assert one_step.inertia_kgm2 == pytest.approx(uniform.inertia_kgm2, rel=1e-2, abs=1e-7)
    gradual = print_mass_properties(mesh, ProfilePrintSpec(gradual_infill_steps=5))
    sparsest = print_mass_properties(mesh, shell(0.0008, 0.0008, 0.2 / 32))
    assert sparsest.mass_kg < gradual.mass_kg < 0.5 * uniform.mass_kg
    assert gradual.com_m[2] > sparsest.com_m[2]


def test_a_sloped_face_gets_the_thicker_of_the_wall_and_skin_projections():
    # a box turned 45 deg about x: its four long faces slope at 45 deg, each gets max(wall, skin) / sqrt(2) of
    # solid across it; its two end faces are vertical and get the wall
    a, b, c, wall, skin = 0.1, 0.06, 0.04, 0.004, 0.002
    mesh = trimesh.creation.box([a, b, c])
    mesh.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 4, [1, 0, 0]))
    across = max(wall, skin) / math.sqrt(2)
    hollow = PLA * (a * b * c - (a - 2 * wall) * (b - 2 * across) * (c - 2 * across))
    assert print_mass_properties(mesh, shell(wall, skin, 0.0)).mass_kg == pytest.approx(hollow, rel=1e-9)


def test_infill_one_and_walls_past_half_the_smallest_width_both_make_the_solid():
    mesh = profile_mesh(front_heavy_heights(ProfileGrid()), ProfileGrid())
    solid = print_mass_properties(mesh, ProfilePrintSpec(model="solid", solid_density_kgpm3=PLA))
    assert solid.mass_kg == pytest.approx(PLA * mesh.volume, rel=1e-12)
    for spec in (shell(0.0008, 0.0008, 1.0), shell(0.08, 0.08, 0.0)):  # widths 0.14 m across, >= 0.018 m tall
        got = print_mass_properties(mesh, spec)
        assert got.mass_kg == pytest.approx(solid.mass_kg, rel=1e-9)
        assert got.com_m == pytest.approx(solid.com_m, abs=1e-12)
        assert got.inertia_kgm2 == pytest.approx(solid.inertia_kgm2, rel=1e-9, abs=1e-15)
    hollow = print_mass_properties(mesh, shell(0.0008, 0.0008, 0.0))
    assert 0 < hollow.mass_kg < print_mass_properties(mesh, shell(0.0008, 0.0008, 0.2)).mass_kg < solid.mass_kg


def test_the_mass_scale_multiplies_mass_and_inertia_not_the_centre_of_mass():
    mesh = profile_mesh(front_heavy_heights(ProfileGrid()), ProfileGrid())
    one, two = (print_mass_properties(mesh, ProfilePrintSpec(), scale) for scale in (1.0, 2.0))
    assert two.mass_kg == pytest.approx(2 * one.mass_kg) and two.inertia_kgm2 == pytest.approx(2 * one.inertia_kgm2)
    assert two.com_m == pytest.approx(one.com_m)
    with pytest.raises(ValueError, match="profile_mass_scale must be > 0"):
        print_mass_properties(mesh, ProfilePrintSpec(), 0.0)


def test_degenerate_open_and_non_convex_meshes_are_refused_by_name():
    box = trimesh.creation.box([0.1, 0.1, 0.1])
    opened = trimesh.Trimesh(box.vertices, box.faces[:-1], process=False)
    with pytest.raises(ValueError, match="not watertight"):
        print_mass_properties(opened, ProfilePrintSpec())
    flat = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False)
    with pytest.raises(ValueError, match="degenerate"):
        print_mass_properties(flat, ProfilePrintSpec())
    inside_out = trimesh.Trimesh(box.vertices, box.faces[:, ::-1], process=False)
    with pytest.raises(ValueError, match="no positive volume"):
        print_mass_properties(inside_out, ProfilePrintSpec())
    dented = box.vertices.copy()
    dented[np.argmax(dented.sum(axis=1))] *= 0.2                # a corner pushed in towards the centre
    dent = trimesh.Trimesh(dented, box.faces, process=False)
    assert dent.is_watertight and not dent.is_convex
    with pytest.raises(ValueError, match="needs a convex profile mesh"):
        print_mass_properties(dent, ProfilePrintSpec())
    assert print_mass_properties(dent, ProfilePrintSpec(model="solid", solid_density_kgpm3=10.0)).mass_kg == \
        pytest.approx(10.0 * dent.volume) != 10.0 * box.volume


@pytest.mark.parametrize("fields, message", [
    ({"model": "solid"}, "needs profile_print.solid_density_kgpm3"),
    ({"solid_density_kgpm3": 20.0}, "only used with profile_print.model: solid"),
    ({"model": "foam"}, "must be one of shell, solid"),
    ({"infill_fraction": 1.5}, r"infill_fraction out of range: 1.5 is not in \[0.0, 1.0\]"),
    ({"wall_thickness_m": 0.0}, r"wall_thickness_m out of range: 0.0 is not in \(0.0, 1.0\]"),
    ({"gradual_infill_steps": 11}, r"gradual_infill_steps out of range: 11 is not in \[0, 10\]"),
    ({"gradual_infill_step_height_m": 0.0}, r"gradual_infill_step_height_m out of range"),
])
def test_inconsistent_print_settings_are_refused(fields, message):
    with pytest.raises(ValueError, match=message):
        check_settings(ProfilePrintSpec(**fields), "profile_print")
    with pytest.raises(ConfigError, match=message.split()[0]):
        from_mapping(ChassisSpec, {"profile_print": fields}, "robot")


def test_the_old_density_setting_is_refused_not_ignored():
    with pytest.raises(ConfigError, match="profile_density_kgpm3"):
        from_mapping(ChassisSpec, {"profile_density_kgpm3": 150.0}, "robot")


# --- the engines and the screen weigh the profile as printed ---------------------------------------------------

def printed_profile(spec=ChassisSpec()):
    grid = ProfileGrid()
    return ChassisModel(spec).profile_body(profile_mesh(front_heavy_heights(grid), grid))


def test_the_profile_body_is_the_print_and_its_inertia_has_the_product_term():
    profile = printed_profile()
    grid = ProfileGrid()
    expected = print_mass_properties(profile_mesh(front_heavy_heights(grid), grid), ProfilePrintSpec())
    assert profile.mass_kg == pytest.approx(expected.mass_kg) and profile.inertia_kgm2 == pytest.approx(
        expected.inertia_kgm2)
    assert abs(profile.inertia_kgm2[0, 2]) > 1e-3 * profile.inertia_kgm2[0, 0]
    moments, turn = profile.principal_inertia()
    axes = trimesh.transformations.quaternion_matrix([turn[3], *turn[:3]])[:3, :3]
    assert axes @ np.diag(moments) @ axes.T == pytest.approx(profile.inertia_kgm2, rel=1e-9, abs=1e-15)


def pybullet_profile_link(model, profile):
    """(mass, centre of mass (3,), inertia (3, 3)) of the spawned profile link in PyBullet, in its link frame."""
    pybullet = pytest.importorskip("pybullet")
    from rollability_ros.core.sim import world

    client = world.connect()
    try:
        robot = model.spawn(client, profile, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 1.0), time_step_s=None)
        info = pybullet.getDynamicsInfo(robot.body_id, robot.profile_link, physicsClientId=client)
    finally:
        world.disconnect(client)
    mass, diagonal, position, orientation = info[0], info[2], info[3], info[4]
    axes = np.asarray(pybullet.getMatrixFromQuaternion(orientation)).reshape(3, 3)
    return mass, np.asarray(position), axes @ np.diag(diagonal) @ axes.T


def chassis_as_urdf_robot(spec):
    from rollability_ros.core.robots.urdf_robot import UrdfRobotModel, UrdfRobotSpec

    return UrdfRobotModel(UrdfRobotSpec(
        robot_description=ChassisModel(spec).to_urdf(), mount_link="base_link", footprint_length_m=spec.body_length_m,
        footprint_width_m=spec.body_width_m, footprint_offset_m=(0.0, 0.0, spec.body_height_m / 2),
        wheel_link_regex=".*_wheel", min_wheels_in_contact=3))


@pytest.mark.parametrize("robot", ["chassis", "urdf"])
def test_pybullet_spawns_the_printed_mass_centre_and_inertia(robot):
    spec = ChassisSpec()
    profile = printed_profile(spec)
    model = ChassisModel(spec) if robot == "chassis" else chassis_as_urdf_robot(spec)
    mass, com, inertia = pybullet_profile_link(model, profile)
    assert mass == pytest.approx(profile.mass_kg, rel=1e-6)
    assert com == pytest.approx(profile.com_m, abs=1e-6)
    assert inertia == pytest.approx(profile.inertia_kgm2, rel=1e-4, abs=1e-9)


def mujoco_body_inertial(mujoco, model, body):
    """(mass, centre of mass (3,), inertia (3, 3) about it) of compiled ``model``'s ``body``, in its frame."""
    turn = np.zeros(9)
    mujoco.mju_quat2Mat(turn, model.body_iquat[body])
    axes = turn.reshape(3, 3)
    return MassProperties(float(model.body_mass[body]), model.body_ipos[body].copy(),
                          axes @ np.diag(model.body_inertia[body]) @ axes.T)


@pytest.mark.parametrize("robot", ["chassis", "urdf"])
def test_mujoco_compiles_the_printed_mass_centre_and_inertia(robot):
    """MuJoCo fuses the profile's fixed link into its mount body: that body is the bare one plus the print."""
    mujoco = pytest.importorskip("mujoco")
    from rollability_ros.core.sim.mujoco_trials import build_model
    from rollability_ros.core.sim.world import PhysicsParams

    spec = ChassisSpec()
    profile = printed_profile(spec)
    model_of = ChassisModel(spec) if robot == "chassis" else chassis_as_urdf_robot(spec)
    bare, _, _ = build_model(model_of, None, PhysicsParams())
    mounted, _, _ = build_model(model_of, profile, PhysicsParams())
    body = int(np.argmax(mounted.body_mass - bare.body_mass))
    place = np.eye(4)  # the profile frame in the MuJoCo body it is fused into
    if robot == "chassis":
        place[:3, 3] = model_of.mount_position_m
    else:  # the URDF robot's root link at its centre of mass carries base_link on a fixed joint: fused too
        from rollability_ros.core.robots.urdf_description import rpy_matrix

        found = re.search(r'<child link="base_link"/><origin xyz="([^"]*)" rpy="([^"]*)"/>', model_of.sim_urdf())
        place[:3, :3] = rpy_matrix([float(v) for v in found.group(2).split()])
        place[:3, 3] = [float(v) for v in found.group(1).split()]
        place = place @ np.asarray(model_of.mounted.profile_in_body)
    turn = place[:3, :3]
    printed = MassProperties(profile.mass_kg, place[:3, 3] + turn @ profile.com_m, turn @ profile.inertia_kgm2 @ turn.T)
    expected = combine([(mujoco_body_inertial(mujoco, bare, body), 1.0), (printed, 1.0)])
    got = mujoco_body_inertial(mujoco, mounted, body)
    assert got.mass_kg - float(bare.body_mass[body]) == pytest.approx(profile.mass_kg, rel=1e-6)
    assert got.com_m == pytest.approx(expected.com_m, abs=1e-6)
    assert got.inertia_kgm2 == pytest.approx(expected.inertia_kgm2, rel=1e-4, abs=1e-9)


def test_the_stable_pose_screen_and_the_twin_weigh_the_print(tmp_path):
    pytest.importorskip("pybullet")
    from rollability_ros.core.sim import stable_poses
    from rollability_ros.core.sim.launch import settings as twin_settings, twin

    spec = ChassisSpec()
    profile = printed_profile(spec)
    bare = stable_poses.robot_hull(ChassisModel(spec))
    assert stable_poses.robot_hull(ChassisModel(spec), profile).mass_kg == pytest.approx(
        bare.mass_kg + profile.mass_kg, rel=1e-6)
    grid = ProfileGrid()
    path = tmp_path / "wedge.stl"
    profile_mesh(front_heavy_heights(grid), grid).export(path)
    settings = twin_settings.load_launch_twin_settings(overrides={"twin.designs.mesh_labels": ["W"],
                                                                  "twin.designs.mesh_files": [str(path)]})
    hollow = twin_settings.load_launch_twin_settings(overrides={
        "twin.designs.mesh_labels": ["W"], "twin.designs.mesh_files": [str(path)],
        "robot.profile_print.infill_fraction": 0.0, "robot.profile_mass_scale": 1.5})
    mounted = twin.profile_body("W", settings)
    assert mounted.mass_kg == pytest.approx(profile.mass_kg, rel=1e-6)
    expected = 1.5 * print_mass_properties(profile_mesh(front_heavy_heights(grid), grid), shell(0.0008, 0.0008, 0.0)
                                           ).mass_kg
    assert twin.profile_body("W", hollow).mass_kg == pytest.approx(expected, rel=1e-6)


def test_bullets_box_of_a_profile_on_turned_inertial_axes_overstates_it_and_the_points_do_not():
    """SpawnedRobot's claim: on principal axes turned off the profile frame (the wedge's, about y) Bullet's AABB of
    the profile link is far taller than the profile (up to twice), while ``profile_points_m`` placed by the link
    frame give its exact extent."""
    pybullet = pytest.importorskip("pybullet")
    from rollability_ros.core.sim import world

    profile = printed_profile()
    assert abs(profile.principal_inertia()[1][3]) < math.cos(math.radians(5) / 2)   # axes turned > 5 deg
    height = np.ptp(profile.hull_vertices_m[:, 2])
    client = world.connect()
    try:
        robot = ChassisModel(ChassisSpec()).spawn(client, profile, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 1.0),
                                                  time_step_s=None)
        low, high = pybullet.getAABB(robot.body_id, robot.profile_link, physicsClientId=client)
        position, orientation = pybullet.getLinkState(robot.body_id, robot.profile_link,
                                                      physicsClientId=client)[4:6]
    finally:
        world.disconnect(client)
    turn = np.asarray(pybullet.getMatrixFromQuaternion(orientation)).reshape(3, 3)
    placed = np.asarray(robot.profile_points_m) @ turn.T + position
    assert np.ptp(placed[:, 2]) == pytest.approx(height, abs=1e-9)
    assert 1.5 * height < high[2] - low[2] <= 2 * height + 0.01   # the AABB adds a collision margin
