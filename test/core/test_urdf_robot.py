"""A robot from its URDF: the Husky inside the pybullet wheel, a URDF written by the chassis, bad descriptions."""
import os
import pickle
import shutil
import xml.etree.ElementTree as ElementTree

import numpy as np
import pytest
import yaml

pybullet = pytest.importorskip("pybullet")
pybullet_data = pytest.importorskip("pybullet_data")

from rollability_ros.core.config import ConfigError, load_parameters  # noqa: E402
from rollability_ros.core.sim.evaluation import (EvaluatorSettings, evaluate_profile, load_settings,  # noqa: E402
                                             settings_from_parameters)
from rollability_ros.core.profile.geometry import export_mesh, load_profile_mesh, profile_mesh  # noqa: E402
from rollability_ros.core.robots.robot import ChassisModel, ChassisSpec  # noqa: E402
from rollability_ros.core.sim.world import PhysicsParams, connect, disconnect, reset_world  # noqa: E402
from rollability_ros.core.robots.urdf_description import BASE_LINK, PROFILE_LINK  # noqa: E402
from rollability_ros.core.robots.urdf_robot import UrdfRobotModel, UrdfRobotSpec, footprint_corners  # noqa: E402

HUSKY_DIR = os.path.join(pybullet_data.getDataPath(), "husky")
HUSKY_MASS_KG = 33.455 + 4 * 2.637  # base_link + four wheels; every other link is a massless frame
FIXTURE = os.path.join(os.path.dirname(__file__), "..", "resources", "husky_optimized_profile.yaml")
HUSKY_CONFIGS = ("sim", "robot", "evaluator", "husky")


@pytest.fixture(scope="module")
def husky():
    return load_settings(HUSKY_CONFIGS)


@pytest.fixture
def client():
    client = connect()
    yield client
    disconnect(client)


def husky_spec(**changes):
    values = dict(urdf_path=os.path.join(HUSKY_DIR, "husky.urdf"), mount_link="top_plate_link",
                  footprint_length_m=0.9, footprint_width_m=0.56, footprint_offset_m=(0.0, 0.0, 0.25873),
                  wheel_link_regex=".*_wheel_link", min_wheels_in_contact=3)
    values.update(changes)
    spec = UrdfRobotSpec(**values)
    spec.validate()
    return spec


def husky_copy(folder, text_changes=()):
    """A copy of the Husky URDF in ``folder`` (meshes linked); returns its path."""
    with open(os.path.join(HUSKY_DIR, "husky.urdf"), encoding="utf-8") as stream:
        text = stream.read()
    for old, new in text_changes:
        assert old in text
        text = text.replace(old, new)
    os.symlink(os.path.join(HUSKY_DIR, "meshes"), os.path.join(folder, "meshes"))
    path = os.path.join(folder, "husky.urdf")
    with open(path, "w", encoding="utf-8") as stream:
        stream.write(text)
    return path


def test_husky_config_selects_the_urdf_robot_and_footprint_sets_the_grid(husky):
    assert isinstance(husky.robot_model(), UrdfRobotModel)
    assert (husky.grid.length_m, husky.grid.width_m) == (0.9, 0.56)
    made = husky.urdf_robot.profile_print
    assert (made.model, made.solid_density_kgpm3) == ("solid", 20.0)
    default = load_settings()
    assert isinstance(default.robot_model(), ChassisModel) and default.grid.length_m == 0.18
    assert default.robot.profile_print == ChassisSpec().profile_print and default.robot.profile_print.model == "shell"


def test_masses_and_inertias_come_from_the_urdf(client):
    model = UrdfRobotModel(husky_spec())
    robot = model.spawn(client, None, (0, 0, 1), (0, 0, 0, 1), time_step_s=None)
    body = robot.body_id
    names = {pybullet.getJointInfo(body, j, physicsClientId=client)[12].decode(): j
             for j in range(pybullet.getNumJoints(body, physicsClientId=client))}
    # massless frames (imu, top plate, rails, bumpers) are not bodies of their own
    assert set(names) == {"base_footprint", "front_left_wheel_link", "front_right_wheel_link", "rear_left_wheel_link",
                          "rear_right_wheel_link"}
    masses = [pybullet.getDynamicsInfo(body, j, physicsClientId=client)[0] for j in [-1, *names.values()]]
    assert sum(masses) == pytest.approx(HUSKY_MASS_KG, rel=2e-6)
    base = pybullet.getDynamicsInfo(body, names["base_footprint"], physicsClientId=client)
    urdf_inertia = np.array([[0.6022, -0.02364, -0.1197], [-0.02364, 1.7386, -0.001544], [-0.1197, -0.001544, 2.0296]])
    assert sorted(base[2]) == pytest.approx(sorted(np.linalg.eigvalsh(urdf_inertia)), rel=1e-5)
    assert base[3] == pytest.approx((-0.08748, -0.00085, 0.14493 + 0.09947))  # base_link com, via the fixed joint
    wheel = pybullet.getDynamicsInfo(body, names["front_left_wheel_link"], physicsClientId=client)
    assert wheel[0] == 2.637 and wheel[2] == pytest.approx((0.02467, 0.02467, 0.04411))
    # PyBullet's base is a frame at the robot's centre of mass with the root link's axes
    position, orientation = pybullet.getBasePositionAndOrientation(body, physicsClientId=client)
    assert position == pytest.approx((0, 0, 1)) and orientation == pytest.approx((0, 0, 0, 1))
    assert model.mounted.robot.mass_kg == pytest.approx(HUSKY_MASS_KG)


def test_frame_base_moves_like_the_root_body_as_base(client, tmp_path):
    """The base frame link changes nothing physical: spun up and tumbling freely, the robot turns exactly as the
    same URDF with its root body as PyBullet's base (wheels braked so it is one rigid body)."""
    model = UrdfRobotModel(husky_spec())
    plain = model.sim_urdf().split(f'<link name="{BASE_LINK}">')[0] + model.sim_urdf().split("</joint>\n", 1)[1]
    rates = []
    for text, start in ((model.sim_urdf(), model.mounted.robot.com_m), (plain, (0, 0, 0))):
        pybullet.resetSimulation(physicsClientId=client)  # no gravity, no ground
        path = tmp_path / "robot.urdf"
        path.write_text(text, encoding="utf-8")
        body = pybullet.loadURDF(str(path), list(start), [0, 0, 0, 1], flags=pybullet.URDF_USE_INERTIA_FROM_FILE,
                                 physicsClientId=client)
        for joint in range(pybullet.getNumJoints(body, physicsClientId=client)):
            pybullet.setJointMotorControl2(body, joint, pybullet.VELOCITY_CONTROL, force=1000.0, physicsClientId=client)
        for step in range(480):
            if step < 12:
                pybullet.applyExternalTorque(body, -1, [30, 20, 10], pybullet.WORLD_FRAME, physicsClientId=client)
            pybullet.stepSimulation(physicsClientId=client)
            rates.append(pybullet.getBaseVelocity(body, physicsClientId=client)[1])
    turning, plain_turning = np.array(rates[:480]), np.array(rates[480:])
    assert np.linalg.norm(turning[-1]) > 0.5  # it does tumble (rad/s)
    assert np.abs(turning - plain_turning).max() < 1e-5


def test_profile_is_fixed_rigidly_to_the_mount(client, husky):
    heights = np.full(husky.grid.n_variables, 0.2)
    profile = husky.profile_body(profile_mesh(heights, husky.grid))
    model = husky.robot_model()
    reset_world(client, husky.physics)
    robot = model.spawn(client, profile, (0, 0, 1.5), pybullet.getQuaternionFromEuler([2.5, 0.4, 0.3]),
                        time_step_s=husky.physics.time_step_s)
    body = robot.body_id
    links = {pybullet.getJointInfo(body, j, physicsClientId=client)[12].decode(): j
             for j in range(pybullet.getNumJoints(body, physicsClientId=client))}
    assert pybullet.getDynamicsInfo(body, links[PROFILE_LINK], physicsClientId=client)[0] == pytest.approx(
        profile.mass_kg)

    def profile_in_mount():
        mount = pybullet.getLinkState(body, links["base_footprint"], physicsClientId=client)[4:6]
        prof = pybullet.getLinkState(body, links[PROFILE_LINK], physicsClientId=client)[4:6]
        return pybullet.multiplyTransforms(*pybullet.invertTransform(*mount), *prof)

    for _ in range(600):  # falls and tumbles on the ground
        pybullet.stepSimulation(physicsClientId=client)
    position, orientation = profile_in_mount()
    assert position == pytest.approx((0, 0, 0.14493 + 0.25873), abs=1e-6)  # top plate frame + footprint offset
    assert orientation == pytest.approx((0, 0, 0, 1), abs=1e-6)


def test_same_robot_from_a_string_a_package_uri_and_after_pickling(tmp_path, client):
    from_file = UrdfRobotModel(husky_spec())
    with open(os.path.join(HUSKY_DIR, "husky.urdf"), encoding="utf-8") as stream:
        text = stream.read()
    from_string = UrdfRobotModel(husky_spec(urdf_path="", robot_description=text, search_paths=(HUSKY_DIR,)))
    assert from_string.sim_urdf() == from_file.sim_urdf()
    package = tmp_path / "share" / "husky_description"
    package.mkdir(parents=True)
    shutil.copytree(os.path.join(HUSKY_DIR, "meshes"), package / "meshes")
    packaged = text.replace('filename="meshes/', 'filename="package://husky_description/meshes/')
    spec = husky_spec(urdf_path="", robot_description=packaged, search_paths=(str(tmp_path / "share"),))
    assert "package://" not in spec.description().robot.sim_urdf
    settings = EvaluatorSettings(urdf_robot=spec)
    restored = pickle.loads(pickle.dumps(settings))
    shutil.rmtree(tmp_path / "share")  # a worker never reads the description's files again
    robot = restored.robot_model().spawn(client, None, (0, 0, 1), (0, 0, 0, 1), time_step_s=None)
    assert len(robot.wheel_links) == 4


def _bad(tmp_path, **changes):
    with pytest.raises(ValueError) as error:
        husky_spec(**changes)
    return str(error.value)


@pytest.mark.parametrize("text_changes, expected", [
    ((("<mass value=\"33.455\"/>", "<mass value=\"0\"/>"),), "link 'base_link' has mass 0"),
    ((("<mass value=\"2.637\"/>", "<mass value=\"-2.637\"/>"),), "link 'front_left_wheel_link' has mass -2.637"),
    ((('filename="meshes/wheel.stl"', 'filename="package://nowhere/wheel.stl"'),), "mesh package://nowhere/wheel.stl"),
    ((('<link name="base_footprint"/>', '<link name="base_footprint">'),), "not valid XML"),
    ((("<mass value=\"2.637\"/>\n      <origin xyz=\"0 0 0\"/>\n      <inertia ixx=\"0.02467\" ixy=\"0\" ixz=\"0\" "
       "iyy=\"0.02467\" iyz=\"0\" izz=\"0.04411\"/>", ""),), "needs <mass> and <inertia>"),
])
def test_bad_descriptions_are_refused_naming_the_problem(tmp_path, text_changes, expected):
    path = husky_copy(str(tmp_path), text_changes)
    assert expected in _bad(tmp_path, urdf_path=path)


def test_bad_mounts_and_wheels_are_refused(tmp_path):
    assert "URDF file not found: missing.urdf" in _bad(tmp_path, urdf_path="missing.urdf")
    assert "unknown link 'roof_link'" in _bad(tmp_path, mount_link="roof_link")
    message = _bad(tmp_path, footprint_length_m=1.2)
    assert "outside mount link 'top_plate_link'" in message and "x [-0.5037, 0.5037]" in message
    assert "outside mount link" in _bad(tmp_path, footprint_yaw_deg=90.0)
    assert "matches no link" in _bad(tmp_path, wheel_link_regex="caster.*")
    assert "exceeds the 4 wheel bodies" in _bad(tmp_path, min_wheels_in_contact=5)
    assert "unknown link 'track_link'" in _bad(tmp_path, wheel_links=("track_link",))
    assert "either urdf_path or robot_description" in _bad(tmp_path, robot_description="<robot/>")
    with pytest.raises(ConfigError, match="urdf_robot: .*mount link 'top_plate_link'"):
        settings_from_parameters({**load_parameters(list(HUSKY_CONFIGS)), "urdf_robot.footprint_width_m": 0.8})


def test_the_profile_must_sit_on_the_mount_surface(tmp_path):
    """A footprint 0.6 m above the Husky's top, or down at its wheels, was accepted and scored."""
    floating = _bad(tmp_path, footprint_offset_m=(0.0, 0.0, 0.25873 + 0.6))
    assert "0.6000 m above the top of mount link 'top_plate_link'" in floating and "set footprint_offset_m[2] to " \
        "0.25873" in floating
    assert "m below the top" in _bad(tmp_path, footprint_offset_m=(0.0, 0.0, -0.1))
    assert "forward_axis must be one of x, y, -x, -y" in _bad(tmp_path, forward_axis="z")


def test_the_outline_of_the_shapes_counts_not_their_bounding_box(tmp_path):
    """A triangular deck: the footprint fits its bounding box but not the triangle."""
    deck = ('<robot name="wedge"><link name="deck"><inertial><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" '
            'iyy="0.1" iyz="0" izz="0.1"/></inertial><collision><geometry><mesh filename="wedge.obj"/></geometry>'
            '</collision></link></robot>')
    (tmp_path / "wedge.obj").write_text("".join(f"v {x} {y} {z}\n" for x, y in ((-0.3, -0.2), (0.3, -0.2), (-0.3, 0.2))
                                                for z in (0.0, 0.05)) +
                                        "f 1 2 3\nf 4 6 5\nf 1 4 5\nf 1 5 2\nf 2 5 6\nf 2 6 3\nf 3 6 4\nf 3 4 1\n")
    (tmp_path / "wedge.urdf").write_text(deck)
    spec = dict(urdf_path=str(tmp_path / "wedge.urdf"), mount_link="deck", footprint_offset_m=(0.0, 0.0, 0.05),
                upright_tilt_deg=30.0)
    message = _bad(tmp_path, **spec, footprint_length_m=0.5, footprint_width_m=0.3)
    assert "corner(s) [[0.25, -0.15], [0.25, 0.15]] m lie outside mount link 'deck'" in message
    UrdfRobotSpec(**{**spec, "footprint_offset_m": (-0.15, -0.05, 0.05)}, footprint_length_m=0.2,
                  footprint_width_m=0.1).validate()    # in the right-angled corner: on the deck


def test_xacro_is_expanded_and_an_unexpanded_one_refused(tmp_path, client):
    with open(os.path.join(HUSKY_DIR, "husky.urdf"), encoding="utf-8") as stream:
        text = stream.read()
    # the Husky as a xacro: a property for the base mass and a macro for its wheels' inertia
    wheel_inertial = ("<inertial>\n      <mass value=\"2.637\"/>\n      <origin xyz=\"0 0 0\"/>\n      <inertia "
                      "ixx=\"0.02467\" ixy=\"0\" ixz=\"0\" iyy=\"0.02467\" iyz=\"0\" izz=\"0.04411\"/>\n    </inertial>")
    assert text.count(wheel_inertial) == 4
    root = '<robot name="husky_robot" xmlns:xacro="http://ros.org/wiki/xacro">'
    xacro_text = (text.replace(root, root.replace("http://ros.org", "http://www.ros.org"))
                  .replace('<mass value="33.455"/>', '<mass value="${base_mass}"/>')
                  .replace(wheel_inertial, '<xacro:wheel_inertial/>'))
    macros = ('<xacro:property name="base_mass" value="33.455"/><xacro:macro name="wheel_inertial">'
              + wheel_inertial + '</xacro:macro>')
    xacro_text = xacro_text.replace('/wiki/xacro">', '/wiki/xacro">' + macros, 1)
    assert root in text and "${base_mass}" in xacro_text
    path = tmp_path / "husky.urdf.xacro"
    path.write_text(xacro_text)
    os.symlink(os.path.join(HUSKY_DIR, "meshes"), tmp_path / "meshes")
    expanded = UrdfRobotModel(husky_spec(urdf_path=str(path)))
    def canonical(urdf):
        return ElementTree.canonicalize(urdf.split("?>", 1)[-1], strip_text=True)

    assert canonical(expanded.sim_urdf()) == canonical(UrdfRobotModel(husky_spec()).sim_urdf())
    unexpanded = tmp_path / "husky_unexpanded.urdf"
    unexpanded.write_text(text.replace('<link name="base_link">', '<link name="${prefix}base_link">'))
    assert "unexpanded xacro expression" in _bad(tmp_path, urdf_path=str(unexpanded))
    broken = tmp_path / "broken.urdf.xacro"
    broken.write_text(xacro_text.replace("${base_mass}", "${no_such_property}"))
    assert "cannot expand xacro" in _bad(tmp_path, urdf_path=str(broken))


def test_forward_axis_turns_the_robot_to_face_world_x(client):
    pybullet = pytest.importorskip("pybullet")
    facing = {}
    for axis in ("x", "y"):
        robot = UrdfRobotModel(husky_spec(forward_axis=axis)).spawn(client, None, (0, 0, 1), (0, 0, 0, 1),
                                                                    time_step_s=None)
        _, orientation = pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)
        facing[axis] = np.asarray(pybullet.getMatrixFromQuaternion(orientation)).reshape(3, 3)
    np.testing.assert_allclose(facing["x"][:, 0], [1, 0, 0], atol=1e-9)    # REP 103: root x = world x
    np.testing.assert_allclose(facing["y"][:, 1], [1, 0, 0], atol=1e-9)    # root y now faces world x
    np.testing.assert_allclose(facing["y"][:, 2], [0, 0, 1], atol=1e-9)    # still upright


def test_moving_link_without_mass_is_refused(tmp_path):
    massless_wheel = ("<inertial>\n      <mass value=\"2.637\"/>\n      <origin xyz=\"0 0 0\"/>\n      <inertia "
                      "ixx=\"0.02467\" ixy=\"0\" ixz=\"0\" iyy=\"0.02467\" iyz=\"0\" izz=\"0.04411\"/>\n    </inertial>")
    path = husky_copy(str(tmp_path), ((massless_wheel, ""),))
    assert "link 'front_left_wheel_link' moves on joint 'front_left_wheel' but has no mass" in _bad(
        tmp_path, urdf_path=path)


def test_any_urdf_from_config_alone(client):
    """A URDF nobody wrote for this module (the chassis's own export) works with a wheel list and another mount."""
    chassis = ChassisSpec()
    text = ChassisModel(chassis).to_urdf()
    spec = UrdfRobotSpec(robot_description=text, mount_link="base_link", footprint_length_m=0.18,
                         footprint_width_m=0.14, footprint_offset_m=(0.0, 0.0, chassis.body_height_m / 2),
                         wheel_links=("front_left_wheel", "front_right_wheel", "rear_left_wheel", "rear_right_wheel"),
                         min_wheels_in_contact=3, contact_tolerance_m=0.003)
    spec.validate()
    model = UrdfRobotModel(spec)
    ground = reset_world(client, PhysicsParams())
    for orientation, upright in (((0, 0, 0, 1), True), (pybullet.getQuaternionFromEuler([np.pi, 0, 0]), False)):
        robot = model.spawn(client, None, (0, 0, 0.2), orientation, time_step_s=PhysicsParams().time_step_s)
        for _ in range(480):
            pybullet.stepSimulation(physicsClientId=client)
        assert model.is_upright(client, robot, ground)[0] is upright
        pybullet.removeBody(robot.body_id, physicsClientId=client)


def test_bare_husky_stays_inverted(husky):
    result = evaluate_profile(None, 30, 2024, husky)
    assert result.successes == 0
    assert all(outcome.settled and outcome.tilt_deg > 150 for outcome in result.trial_results)


def test_optimized_profile_beats_the_bare_husky(husky):
    with open(FIXTURE, encoding="utf-8") as stream:
        heights = yaml.safe_load(stream)["heights"]
    bare = evaluate_profile(None, 30, 2025, husky)
    optimized = evaluate_profile(heights, 30, 2025, husky)
    assert optimized.ci_low > bare.ci_high, (bare, optimized)


def test_exported_stl_and_urdf_fit_the_mount_footprint(tmp_path, husky):
    with open(FIXTURE, encoding="utf-8") as stream:
        heights = yaml.safe_load(stream)["heights"]
    path = tmp_path / "husky_profile.stl"
    export_mesh(profile_mesh(heights, husky.grid), path)
    mesh = load_profile_mesh(path)
    spec = husky.urdf_robot
    assert mesh.bounds[0][:2] == pytest.approx(footprint_corners(spec)[:, :2].min(axis=0), abs=1e-6)  # float32 STL
    assert mesh.bounds[1][:2] == pytest.approx(footprint_corners(spec)[:, :2].max(axis=0), abs=1e-6)
    profile = husky.profile_body(mesh)
    document = ElementTree.fromstring(husky.robot_model().to_urdf("husky_profile.stl", profile))
    (joint,) = [j for j in document.findall("joint") if j.find("child").get("link") == PROFILE_LINK]
    assert joint.find("parent").get("link") == "top_plate_link"
    assert [float(v) for v in joint.find("origin").get("xyz").split()] == pytest.approx([0, 0, 0.25873])
    assert float(document.find(f"link[@name='{PROFILE_LINK}']/inertial/mass").get("value")) == pytest.approx(
        profile.mass_kg)


def test_package_uris_resolve_through_ament_prefix_path(tmp_path, monkeypatch):
    share = tmp_path / "install" / "share" / "husky_description"
    share.mkdir(parents=True)
    shutil.copytree(os.path.join(HUSKY_DIR, "meshes"), share / "meshes")
    with open(os.path.join(HUSKY_DIR, "husky.urdf"), encoding="utf-8") as stream:
        packaged = stream.read().replace('filename="meshes/', 'filename="package://husky_description/meshes/')
    monkeypatch.setenv("AMENT_PREFIX_PATH", os.pathsep.join([str(tmp_path / "elsewhere"), str(tmp_path / "install")]))
    spec = husky_spec(urdf_path="", robot_description=packaged, search_paths=())
    assert "package://" not in spec.description().robot.sim_urdf     # found under the second prefix
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path / "elsewhere"))
    assert "package://husky_description" in _bad(tmp_path, urdf_path="", robot_description=packaged, search_paths=())


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_compliant_mount_on_a_urdf_robot_deflects_by_the_profile_weight(husky, engine):
    """The Husky with its optimized profile on a spring: the profile joint slides along the mount's normal,
    carries no drive drag, and rests at -m g / k."""
    import mujoco

    from rollability_ros.core.robots.robot import ProfileMountSpec
    from rollability_ros.core.robots.urdf_robot import PROFILE_JOINT
    from rollability_ros.core.sim.mujoco_trials import MujocoTrialWorld
    from rollability_ros.core.sim.trials import TrialSettings, place_on_ground

    with open(FIXTURE, encoding="utf-8") as stream:
        heights = yaml.safe_load(stream)["heights"]
    profile = husky.profile_body(profile_mesh(heights, husky.grid))
    stiffness = 20000.0
    model = UrdfRobotModel(husky_spec(joint_drag_torque_nm=5.0, profile_mount=ProfileMountSpec(
        stiffness_npm=stiffness, damping_nspm=2 * (stiffness * profile.mass_kg) ** 0.5, travel_m=0.01)))
    physics = PhysicsParams()
    trace = []
    if engine == "pybullet":
        client = connect()
        try:
            reset_world(client, physics)
            robot = model.spawn(client, profile, (0, 0, 1), (0, 0, 0, 1), time_step_s=physics.time_step_s)
            place_on_ground(client, robot.body_id, (0, 0, 0, 1), 0.0)
            info = pybullet.getJointInfo(robot.body_id, robot.mount_spring.joint, physicsClientId=client)
            assert info[1].decode() == PROFILE_JOINT and info[2] == pybullet.JOINT_PRISMATIC
            for _ in range(480):
                robot.before_step()
                pybullet.stepSimulation(physicsClientId=client)
                trace.append(robot.mount_spring.position_m())
        finally:
            disconnect(client)
    else:
        world = MujocoTrialWorld(model, profile, TrialSettings(), physics)
        world.place((0, 0, 0, 1), 0.0)
        joint = world.model.joint(PROFILE_JOINT)
        assert world.model.dof_frictionloss[world.model.jnt_dofadr[joint.id]] == 0.0  # no drive drag on the mount
        for _ in range(480):
            mujoco.mj_step(world.model, world.data)
            trace.append(float(world.data.qpos[world.model.jnt_qposadr[joint.id]]))
    assert np.mean(trace[-60:]) == pytest.approx(-profile.mass_kg * 9.81 / stiffness, rel=0.03)


def test_a_constraint_held_profile_would_stretch_and_be_left_behind_where_a_fixed_link_does_not(client):
    """urdf_robot's reason for a fixed-joint profile link: a body held by createConstraint(JOINT_FIXED) stretches
    away from its mount under an impact and stays put when the robot's base is reset; a link on a fixed joint does
    neither."""
    pybullet.setGravity(0, 0, 0, physicsClientId=client)
    box = pybullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=[0.05, 0.05, 0.02], physicsClientId=client)
    offset = np.array([0.0, 0.0, 0.1])

    def profile_offset(base, profile_position):
        """Where the profile is in its mount's frame (m)."""
        position, orientation = pybullet.getBasePositionAndOrientation(base, physicsClientId=client)
        turn = np.asarray(pybullet.getMatrixFromQuaternion(orientation)).reshape(3, 3)
        return turn.T @ np.subtract(profile_position(), position)

    held = pybullet.createMultiBody(1.0, box, basePosition=[0, 0, 1], physicsClientId=client)
    loose = pybullet.createMultiBody(0.3, box, basePosition=list(offset + [0, 0, 1]), physicsClientId=client)
    pybullet.createConstraint(held, -1, loose, -1, pybullet.JOINT_FIXED, [0, 0, 0], list(offset), [0, 0, 0],
                              physicsClientId=client)
    linked = pybullet.createMultiBody(1.0, box, basePosition=[2, 0, 1], linkMasses=[0.3],
                                      linkCollisionShapeIndices=[box], linkVisualShapeIndices=[-1],
                                      linkPositions=[list(offset)], linkOrientations=[[0, 0, 0, 1]],
                                      linkInertialFramePositions=[[0, 0, 0]],
                                      linkInertialFrameOrientations=[[0, 0, 0, 1]], linkParentIndices=[0],
                                      linkJointTypes=[pybullet.JOINT_FIXED], linkJointAxis=[[0, 0, 0]],
                                      physicsClientId=client)
    on_constraint = lambda: pybullet.getBasePositionAndOrientation(loose, physicsClientId=client)[0]  # noqa: E731
    on_link = lambda: pybullet.getLinkState(linked, 0, computeForwardKinematics=True,  # noqa: E731
                                            physicsClientId=client)[4]
    for body, index in ((loose, -1), (linked, 0)):   # an impact on the profile: 2 kN for one step
        position = on_constraint() if index < 0 else on_link()
        pybullet.applyExternalForce(body, index, [2000.0, 0.0, 0.0], position, pybullet.WORLD_FRAME,
                                    physicsClientId=client)
    pybullet.stepSimulation(physicsClientId=client)
    assert np.linalg.norm(profile_offset(held, on_constraint) - offset) > 0.001
    assert profile_offset(linked, on_link) == pytest.approx(offset, abs=1e-6)
    for base in (held, linked):
        pybullet.resetBasePositionAndOrientation(base, [5, 5, 5], [0, 0, 0, 1], physicsClientId=client)
    assert np.linalg.norm(profile_offset(held, on_constraint)) > 5
    assert profile_offset(linked, on_link) == pytest.approx(offset, abs=1e-6)


def test_pybullets_loader_gives_a_massless_frame_1_kg_and_the_description_drops_it(client, tmp_path):
    """urdf_description's reason to drop links that carry nothing: PyBullet's loader gives such a link 1 kg and a
    1 kg m^2 inertia (with URDF_USE_INERTIA_FROM_FILE, as the robots are loaded)."""
    from rollability_ros.core.robots.urdf_description import describe

    text = ('<robot name="r"><link name="box"><inertial><mass value="2"/><inertia ixx="0.1" iyy="0.1" izz="0.1" '
            'ixy="0" ixz="0" iyz="0"/></inertial><collision><geometry><box size="0.1 0.1 0.1"/></geometry>'
            '</collision></link><link name="imu_link"/><joint name="imu_joint" type="fixed"><parent link="box"/>'
            '<child link="imu_link"/></joint></robot>')
    path = tmp_path / "frame.urdf"
    path.write_text(text)
    body = pybullet.loadURDF(str(path), flags=pybullet.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
    mass, _, inertia = pybullet.getDynamicsInfo(body, 0, physicsClientId=client)[:3]
    assert (mass, inertia) == (1.0, (1.0, 1.0, 1.0))
    assert "imu_link" not in describe(text).sim_urdf
