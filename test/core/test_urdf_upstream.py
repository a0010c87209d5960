"""Shapes of upstream descriptions that broke a new user's first run (docs/other-robots.md, "Upstream descriptions
tried"): a xacro that includes its own package's files by ``$(find <pkg>)`` (Clearpath Jackal, Husarion ROSbot,
iRobot Create 3, AgileX Scout) used from a clone without a ROS install, and a COLLADA ``.dae`` collision mesh
(iRobot Create 3's bumper) on the MuJoCo engines. Each robot is built here; no upstream file is copied."""
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))

from rollability_ros.core.robots.urdf_robot import UrdfRobotModel, UrdfRobotSpec  # noqa: E402

pytest.importorskip("xacro")

XACRO_ROBOT = """<?xml version="1.0"?>
<robot name="clone_bot" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:include filename="$(find clone_bot_description)/urdf/wheel.urdf.xacro"/>
  <link name="base_link">
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.3 0.2 0.1"/></geometry></collision>
    <inertial><origin xyz="0 0 0.05"/><mass value="2.0"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0"
      izz="0.02"/></inertial>
  </link>
  <xacro:wheel side="left" y="0.13"/>
  <xacro:wheel side="right" y="-0.13"/>
</robot>
"""
XACRO_WHEEL = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="wheel" params="side y">
    <link name="${side}_wheel">
      <collision><origin rpy="1.5708 0 0"/><geometry><cylinder radius="0.04" length="0.03"/></geometry></collision>
      <inertial><mass value="0.1"/><inertia ixx="5e-5" ixy="0" ixz="0" iyy="8e-5" iyz="0" izz="5e-5"/></inertial>
    </link>
    <joint name="${side}_wheel_joint" type="continuous">
      <parent link="base_link"/><child link="${side}_wheel"/><origin xyz="0 ${y} 0.0"/><axis xyz="0 1 0"/>
    </joint>
  </xacro:macro>
</robot>
"""


def _clone(folder):
    """A clone of an upstream repository: <folder>/clone_bot_description/urdf/{robot,wheel}.urdf.xacro."""
    urdf = folder / "clone_bot_description" / "urdf"
    urdf.mkdir(parents=True)
    (urdf / "robot.urdf.xacro").write_text(XACRO_ROBOT, encoding="utf-8")
    (urdf / "wheel.urdf.xacro").write_text(XACRO_WHEEL, encoding="utf-8")
    return "clone_bot_description/urdf/robot.urdf.xacro"


def _spec(**changes):
    values = dict(mount_link="base_link", footprint_length_m=0.2, footprint_width_m=0.15,
                  footprint_offset_m=(0.0, 0.0, 0.1), wheel_link_regex=".*_wheel", min_wheels_in_contact=2)
    values.update(changes)
    return UrdfRobotSpec(**values)


def test_find_of_the_descriptions_own_package_resolves_from_a_clone_on_the_search_path(tmp_path, monkeypatch):
    """Without AMENT_PREFIX_PATH xacro's $(find) raised "Environment variable 'AMENT_PREFIX_PATH' is not set",
    naming neither the package nor what to set; a relative search path must work from the working directory."""
    path = _clone(tmp_path)
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)
    monkeypatch.chdir(tmp_path)
    description = _spec(urdf_path=path, search_paths=(".",)).description()
    assert {"left_wheel", "right_wheel"} <= set(description.robot.body_of)
    monkeypatch.chdir(tmp_path / "clone_bot_description")    # the search folder named after the package works too
    assert _spec(urdf_path="urdf/robot.urdf.xacro", search_paths=(".",)).description()


def test_find_of_a_package_found_nowhere_is_refused_naming_it_and_where_it_looked(tmp_path, monkeypatch):
    path = _clone(tmp_path)
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError) as refused:
        _spec(urdf_path=path, search_paths=("elsewhere",)).description()
    message = str(refused.value)
    assert "\n" not in message and "$(find clone_bot_description): package clone_bot_description not found" in message
    assert os.path.join(str(tmp_path), "elsewhere", "clone_bot_description") in message
    assert "urdf_robot.search_paths" in message and "share/clone_bot_description on AMENT_PREFIX_PATH" in message
    assert message.count("not found") == 1                    # once, not xacro's repetition of it
    # an install prefix on AMENT_PREFIX_PATH works as before
    share = tmp_path / "install" / "share"
    share.mkdir(parents=True)
    os.symlink(tmp_path / "clone_bot_description", share / "clone_bot_description")
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path / "install"))
    assert _spec(urdf_path=path).description()


BOX_BOT = XACRO_ROBOT.replace('<xacro:include filename="$(find clone_bot_description)/urdf/wheel.urdf.xacro"/>',
                              XACRO_WHEEL.split('<robot xmlns:xacro="http://www.ros.org/wiki/xacro">')[1]
                              .replace("</robot>", ""))


def ascii_stl_text(*triangles):
    """An ASCII STL of ``triangles`` (each three (x, y, z) vertices, written as given)."""
    facets = "".join("facet normal 0 0 1\nouter loop\n" + "".join(f"vertex {x} {y} {z}\n" for x, y, z in triangle)
                     + "endloop\nendfacet\n" for triangle in triangles)
    return f"solid body\n{facets}endsolid body\n".encode()


#: Broken descriptions (their text changes from BOX_BOT, the files they name) and the refusal's words.
BROKEN = [
    # a collision mesh that is empty or truncated: "No points given", naming neither the link nor the file
    ({'<box size="0.3 0.2 0.1"/>': '<mesh filename="body.stl"/>'}, {"body.stl": b""},
     "link 'base_link' collision 0: mesh .*body.stl holds no vertices"),
    # ASCII STL (converted to binary since both engines read only that) that is no whole mesh: no facet, a word
    # where a number belongs (trimesh's parser stopped there quietly, keeping the triangles before it), a NaN
    ({'<box size="0.3 0.2 0.1"/>': '<mesh filename="body.stl"/>'}, {"body.stl": b"solid body\nendsolid body\n"},
     r"link 'base_link' collision 0: ASCII STL .*body.stl holds 0 facet\(s\) but 0 whole triangle\(s\)"),
    ({'<box size="0.3 0.2 0.1"/>': '<mesh filename="body.stl"/>'}, {"body.stl": ascii_stl_text(((0, 0, 0), (1, 0, 0),
                                                                    (0, 1, 0)), ((0, 0, 1), (1, 0, 0), (0, "x", 0)))},
     "link 'base_link' collision 0: cannot read ASCII STL .*body.stl: string or file could not be read to its end"),
    ({'<box size="0.3 0.2 0.1"/>': '<mesh filename="body.stl"/>'}, {"body.stl": ascii_stl_text(((0, 0, 0), (1, 0, 0),
                                                                    (0, 1, 0)), ((0, 0, 1), (1, 0, 0), (0, "nan", 0)))},
     "link 'base_link' collision 0: ASCII STL .*body.stl has a vertex that is not a finite number"),
    ({'<box size="0.3 0.2 0.1"/>': '<mesh filename="body.stl"/>'}, {"body.stl": b"solid body\nfacet normal 0 0 1\n"
                                                                               b"outer loop\nvertex 0 0 0\n"},
     r"link 'base_link' collision 0: ASCII STL .*body.stl holds 0 facet\(s\) but 0 whole triangle\(s\)"),
    # a flat one: Qhull's QhullError (not a ValueError: a traceback from the CLI), in several lines
    ({'<box size="0.3 0.2 0.1"/>': '<mesh filename="flat.obj"/>'}, {"flat.obj": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"},
     "link 'base_link' collision 0: mesh .*flat.obj encloses no volume"),
    # sizes <= 0: PyBullet ran them, MuJoCo refused in two lines ("Error: size 0 must be positive in geom")
    ({'<box size="0.3 0.2 0.1"/>': '<box size="-0.3 0.2 0.1"/>'}, {}, r"collision 0 box size: expected 3 number\(s\) > 0"),
    ({'radius="0.04"': 'radius="0"'}, {}, r"link 'left_wheel' collision 0 cylinder radius: expected 1 number\(s\) > 0"),
    # a moving joint's zero axis or NaN damping: the trials ran to NaN poses ("Points cannot contain NaN", or a verdict)
    ({'<axis xyz="0 1 0"/>': '<axis xyz="0 0 0"/>'}, {}, "joint 'left_wheel_joint' has axis xyz '0 0 0'"),
    ({'<axis xyz="0 1 0"/>': '<axis xyz="0 1 0"/><dynamics damping="nan"/>'}, {},
     "joint 'left_wheel_joint' dynamics damping: expected 1 numbers, got 'nan'"),
    # non-physical masses, inertias and sizes ran the physics with nonsense numbers: a 1e300 kg robot, one lighter
    # than MuJoCo's twin integrates on the foam, an inertia no 2 kg body has, a 300 m box, a mesh in millimetres
    ({'value="2.0"': 'value="1e300"'}, {}, r"robot description \(its <inertial> masses\): the robot weighs 1e\+300 kg, "
                                          r"outside 0.2-250 kg, the masses PyBullet and MuJoCo integrate stably"),
    ({'value="2.0"': 'value="0.05"', 'value="0.1"': 'value="0.001"'}, {}, "the robot weighs 0.052 kg, outside"),
    ({'ixx="0.01"': 'ixx="1e300"'}, {}, r"rigid body 'base_link' \(2 kg\): its inertia's largest moment 1e\+300 "
                                        r"kg m\^2 means a radius of gyration of 7.07107e\+149 m, over the 10 m"),
    ({'<box size="0.3 0.2 0.1"/>': '<box size="300 200 100"/>'}, {},
     "link 'base_link' collision 0: the shape spans 300 m, over the 10 m any part of a robot on the rig may$"),
    ({'<box size="0.3 0.2 0.1"/>': '<mesh filename="body.obj"/>'},
     {"body.obj": b"".join(b"v %d %d %d\n" % (x, y, z) for x in (-150, 150) for y in (-100, 100) for z in (0, 100))
      + b"f 1 2 4\nf 1 4 3\nf 5 6 8\nf 5 8 7\n"},
     r"link 'base_link' collision 0: the shape spans 300 m, .* \(a mesh in millimetres needs scale=\"0.001 0.001 "),
    # xacro's own error spans three lines ("Use of invalid name(s) ... \nwhen evaluating expression ...")
    ({'value="2.0"': 'value="${__import__(\'os\').getpid()}"'}, {}, "cannot expand xacro .*Use of invalid name"),
]


@pytest.mark.parametrize("entry", ["python:no_such_package_xyz", "python:no_such_package_xyz.sub", "python:..x"])
def test_a_search_path_of_no_installed_package_is_refused_in_one_line(entry):
    """A dotted name whose parent is not installed was a ModuleNotFoundError traceback, a relative one an
    ImportError: find_spec raises for them where it returns None for a plain missing name."""
    from rollability_ros.core.robots.urdf_description import search_folders

    with pytest.raises(ValueError, match=f"search path entry {entry}: no installed Python package"):
        search_folders([entry])


@pytest.mark.parametrize("changes, files, problem", BROKEN)
def test_a_broken_description_is_refused_in_one_line_naming_the_link_or_joint(tmp_path, changes, files, problem):
    text = BOX_BOT
    for old, new in changes.items():
        assert old in text
        text = text.replace(old, new)
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    (tmp_path / "bot.urdf.xacro").write_text(text, encoding="utf-8")
    with pytest.raises(ValueError, match=problem) as refused:
        _spec(urdf_path=str(tmp_path / "bot.urdf.xacro")).validate()
    assert "\n" not in str(refused.value)


def dae_robot(folder):
    """A two-wheeled box whose body's collision shape is a COLLADA mesh (0.3 x 0.2 x 0.1 m), file in ``folder``."""
    trimesh = pytest.importorskip("trimesh")
    pytest.importorskip("collada")
    body = trimesh.creation.box(extents=(0.3, 0.2, 0.1))
    body.export(str(folder / "body.dae"))
    text = XACRO_ROBOT.replace('<xacro:include filename="$(find clone_bot_description)/urdf/wheel.urdf.xacro"/>',
                               XACRO_WHEEL.split("<robot xmlns:xacro=\"http://www.ros.org/wiki/xacro\">")[1]
                               .replace("</robot>", ""))
    text = text.replace('<box size="0.3 0.2 0.1"/>', '<mesh filename="body.dae"/>')
    (folder / "dae_bot.urdf.xacro").write_text(text, encoding="utf-8")
    return str(folder / "dae_bot.urdf.xacro")


def test_a_collada_collision_mesh_loads_in_mujoco_as_the_hull_pybullet_collides_with(tmp_path):
    """MuJoCo decodes no .dae: the robot failed to compile ("no decoder found for mesh file"), a two-line error
    from the middle of a launch. Its hull goes to MuJoCo as an OBJ asset; PyBullet reads the file as before."""
    mujoco = pytest.importorskip("mujoco")
    from rollability_ros.core.sim.mujoco_trials import robot_spec
    from rollability_ros.core.sim.world import PhysicsParams

    model = UrdfRobotModel(_spec(urdf_path=dae_robot(tmp_path)))
    assert ".dae" in model.sim_urdf()    # PyBullet's URDF keeps the file
    compiled = robot_spec(model, None, PhysicsParams())[0].compile()
    meshes = [g for g in range(compiled.ngeom) if compiled.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH]
    assert len(meshes) == 1
    mesh = compiled.geom_dataid[meshes[0]]
    start, count = compiled.mesh_vertadr[mesh], compiled.mesh_vertnum[mesh]
    vertices = compiled.mesh_vert[start:start + count]
    # MuJoCo moves a mesh to its principal axes: the box's extents survive the hull and the OBJ
    np.testing.assert_allclose(sorted(np.ptp(vertices, axis=0)), (0.1, 0.2, 0.3), atol=1e-6)
    from rollability_ros.core.robots import mujoco_mesh_assets
    text, assets = mujoco_mesh_assets(model.sim_urdf())
    assert ".dae" not in text and len(assets) == 1


def test_an_optimizer_batch_with_a_failing_profile_raises_and_leaves_no_evaluation_running():
    """The AgileX Scout's optimize printed its error (the MuJoCo twin's launcher could not launch it) and then
    never exited: the batch's other profiles kept their threads waiting on a worker pool that had been shut down,
    and the interpreter's exit joins them. One profile's error now cancels the others."""
    import threading
    import time

    from rollability_ros.core.optimization.batch_evaluation import fidelity_batch_evaluator
    from rollability_ros.core.sim.evaluation import TrialExecutor, load_settings

    calls = []
    both_waiting = threading.Event()

    class OneFails(TrialExecutor):
        workers, in_process = 2, False

        def iter_batches(self, job, batches, should_stop):
            calls.append(threading.current_thread())
            if len(calls) == 1:
                both_waiting.wait(5.0)   # the other profile's batches are out too, as on a pool of two workers
                raise ValueError("the stroke launcher cannot launch this robot")
            both_waiting.set()
            deadline = time.monotonic() + 10.0     # a worker that never answers: only a stop ends the wait
            while not should_stop() and time.monotonic() < deadline:
                time.sleep(0.005)
            return iter(())

    evaluate = fidelity_batch_evaluator(load_settings(), OneFails(), "screen")
    with pytest.raises(ValueError, match="cannot launch this robot"):
        evaluate([np.zeros(100), np.full(100, 0.1)], 0, 4)
    assert len(calls) == 2
    for waiting in calls[1:]:      # the other profile's thread stops
        waiting.join(5.0)
        assert not waiting.is_alive()   # was: still waiting when the process wanted to exit


def test_xacro_arguments_are_passed_as_on_xacros_command_line(tmp_path, monkeypatch):
    """AgileX's limo_four_diff.xacro reads $(arg robot_namespace), declared nowhere: xacro refuses it unless the
    caller passes it, and a robot config had no way to (ROSbot's mecanum:=true, Create 3's gazebo:=ignition too)."""
    _clone(tmp_path)
    wheel = tmp_path / "clone_bot_description" / "urdf" / "wheel.urdf.xacro"
    wheel.write_text(XACRO_WHEEL.replace('radius="0.04"', 'radius="$(arg wheel_radius)"'), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    path = "clone_bot_description/urdf/robot.urdf.xacro"
    with pytest.raises(ValueError, match="Undefined substitution argument wheel_radius"):
        _spec(urdf_path=path, search_paths=(".",)).description()
    model = UrdfRobotModel(_spec(urdf_path=path, search_paths=(".",), xacro_args=("wheel_radius:=0.05",)))
    assert model.wheel_radii_m() == pytest.approx((0.05, 0.05))
    with pytest.raises(ValueError, match="xacro_args entry 'wheel_radius=0.05': expected name:=value"):
        _spec(urdf_path=path, search_paths=(".",), xacro_args=("wheel_radius=0.05",)).description()
    # a misspelt argument, one given twice, or arguments for a plain URDF: xacro expanded without them, silently
    # keeping the default (or the last value)
    with pytest.raises(ValueError, match="xacro_args 'wheel_radus': .*declares no such argument .*its arguments: "
                                         "wheel_radius"):
        _spec(urdf_path=path, search_paths=(".",), xacro_args=("wheel_radius:=0.05", "wheel_radus:=0.06")).description()
    with pytest.raises(ValueError, match="xacro_args sets 'wheel_radius' twice"):
        _spec(urdf_path=path, search_paths=(".",), xacro_args=("wheel_radius:=0.05", "wheel_radius:=0.06")).description()
    plain = tmp_path / "plain.urdf"
    plain.write_text(model.mounted.robot.original_urdf, encoding="utf-8")
    with pytest.raises(ValueError, match="xacro_args .* given, but .*plain.urdf is not a xacro"):
        _spec(urdf_path=str(plain), xacro_args=("wheel_radius:=0.05",)).description()


def stl_robots(folder):
    """``{format: UrdfRobotModel}``: BOX_BOT with its body a mesh in millimetres (an upstream habit:
    ``scale="0.001 ..."``), a box turned about z with one bottom corner moved, in ASCII and in binary STL, byte for byte the same triangles."""
    trimesh = pytest.importorskip("trimesh")
    body = trimesh.creation.box(extents=(300.0, 200.0, 100.0))
    body.apply_transform(trimesh.transformations.rotation_matrix(0.2, (0.0, 0.0, 1.0)))
    assert body.vertices[0][2] < 0
    body.vertices[0] += (7.0, -3.0, -2.0)   # a bottom corner: the top stays level for the profile
    body.vertices = body.vertices.astype(np.float32).astype(np.float64)   # what a binary STL holds
    files = {"ascii": (trimesh.exchange.stl.export_stl_ascii(body).encode(), "body_ascii.stl"),
             "binary": (trimesh.exchange.stl.export_stl(body), "body_binary.stl")}
    models = {}
    for name, (data, filename) in files.items():
        (folder / filename).write_bytes(data)
        text = BOX_BOT.replace('<box size="0.3 0.2 0.1"/>', f'<mesh filename="{filename}" scale="0.001 0.001 0.001"/>')
        (folder / f"{name}.urdf.xacro").write_text(text, encoding="utf-8")
        models[name] = UrdfRobotModel(_spec(urdf_path=str(folder / f"{name}.urdf.xacro")))
    return models


def test_an_ascii_stl_collides_in_both_engines_as_the_binary_stl_of_the_same_mesh(tmp_path, monkeypatch):
    """Many upstream descriptions ship ASCII STL, which PyBullet dropped (the link simulated without its shape) and
    MuJoCo refused; it was then refused here. It is converted to a binary STL in the mesh cache, so both engines
    load the same shape, scale and units, and the same mass properties, as from the binary STL of the same mesh."""
    mujoco = pytest.importorskip("mujoco")
    pybullet = pytest.importorskip("pybullet")
    from rollability_ros.core.robots.mesh_files import mesh_cache_folder
    from rollability_ros.core.sim.mujoco_trials import robot_spec
    from rollability_ros.core.sim.world import PhysicsParams, connect, disconnect

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    models = stl_robots(tmp_path)
    ascii_robot, binary_robot = models["ascii"].mounted.robot, models["binary"].mounted.robot
    assert ascii_robot.collision_points == binary_robot.collision_points
    cached = os.listdir(mesh_cache_folder())
    assert len(cached) == 1 and cached[0] in ascii_robot.sim_urdf and "body_ascii.stl" not in ascii_robot.sim_urdf
    assert ascii_robot.sim_urdf.replace(os.path.join(mesh_cache_folder(), cached[0]), "") == \
        binary_robot.sim_urdf.replace(str(tmp_path / "body_binary.stl"), "")

    def pybullet_body(model):
        client = connect()
        try:
            body = model.spawn(client, None, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 1.0), time_step_s=None).body_id
            return [(pybullet.getAABB(body, link, physicsClientId=client),
                     pybullet.getDynamicsInfo(body, link, physicsClientId=client)[:4])
                    for link in range(-1, pybullet.getNumJoints(body, physicsClientId=client))]
        finally:
            disconnect(client)

    ascii_links, binary_links = pybullet_body(models["ascii"]), pybullet_body(models["binary"])
    assert ascii_links == binary_links
    # the body's box in metres: 0.3 x 0.2 m turned by 0.2 rad spans more than 0.3 m in x (PyBullet had no shape)
    spans = [upper[0] - lower[0] for (lower, upper), _ in ascii_links]
    assert 0.3 < max(spans) < 0.4

    def mujoco_model(model):
        return robot_spec(model, None, PhysicsParams())[0].compile()

    ascii_model, binary_model = mujoco_model(models["ascii"]), mujoco_model(models["binary"])
    for field in ("body_mass", "body_inertia", "body_ipos", "geom_type", "geom_size", "geom_aabb", "geom_pos",
                  "geom_quat", "mesh_vert"):
        np.testing.assert_array_equal(getattr(ascii_model, field), getattr(binary_model, field), err_msg=field)
    assert sum(ascii_model.geom_type == mujoco.mjtGeom.mjGEOM_MESH) == 1
    # the cached file is reused while the ASCII file's content is unchanged
    assert stl_robots(tmp_path)["ascii"].mounted.robot.sim_urdf == ascii_robot.sim_urdf
    assert os.listdir(mesh_cache_folder()) == cached


def test_an_ascii_stl_over_the_size_converted_is_refused_in_one_line(tmp_path, monkeypatch):
    """A huge ASCII STL would take trimesh minutes and gigabytes (98 MB: 8.4 s, 0.9 GB): refused before it is read,
    naming the link, the file and the fix."""
    from rollability_ros.core.robots.mesh_files import ASCII_STL_MAX_BYTES

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    with open(tmp_path / "body.stl", "wb") as stream:
        stream.write(b"solid body\n")
        stream.truncate(ASCII_STL_MAX_BYTES + 1)   # sparse: nothing written past the header
    (tmp_path / "bot.urdf.xacro").write_text(BOX_BOT.replace('<box size="0.3 0.2 0.1"/>',
                                                             '<mesh filename="body.stl"/>'), encoding="utf-8")
    with pytest.raises(ValueError) as refused:
        _spec(urdf_path=str(tmp_path / "bot.urdf.xacro")).validate()
    message = str(refused.value)
    assert "\n" not in message and message.startswith("link 'base_link' collision 0: ASCII STL ")
    assert "body.stl is 64 MiB, over the 64 MiB converted: save it as a binary STL" in message
    assert not (tmp_path / "cache").exists()


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_robot_with_an_ascii_stl_body_launches_as_with_the_binary_stl(tmp_path, monkeypatch, engine):
    """The launch twin on both engines: the robot whose body is an ASCII STL is launched, with the very result
    of the same robot from the binary STL."""
    if engine == "mujoco":
        pytest.importorskip("mujoco")
    from rollability_ros.core.records import LaunchCondition
    from rollability_ros.core.sim.launch.settings import load_launch_twin_settings
    from rollability_ros.core.sim.launch.twin import simulate_launch

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    stl_robots(tmp_path)
    results = {}
    for name in ("ascii", "binary"):
        settings = load_launch_twin_settings(("sim", "robot", "launch_twin"), overrides={
            "physics.engine": engine, "urdf_robot.urdf_path": str(tmp_path / f"{name}.urdf.xacro"),
            "urdf_robot.mount_link": "base_link", "urdf_robot.footprint_length_m": 0.2,
            "urdf_robot.footprint_width_m": 0.15, "urdf_robot.footprint_offset_m": [0.0, 0.0, 0.1],
            "urdf_robot.wheel_link_regex": ".*_wheel", "urdf_robot.min_wheels_in_contact": 2})
        results[name] = simulate_launch(LaunchCondition("baseline", 0.75, 1.5, 0.0), settings, seed=1)
    assert results["ascii"].valid, results["ascii"].invalid_reason
    assert results["ascii"] == results["binary"]


def test_a_chassis_outside_the_masses_the_engines_integrate_is_refused(tmp_path):
    """The built-in chassis's mass (body and four wheels) from its parameter file: the same range as a URDF robot's;
    the default 1.1 kg chassis is unchanged."""
    from rollability_ros.core.config import ConfigError
    from rollability_ros.core.sim.evaluation import load_settings

    assert load_settings(["sim", "robot", "evaluator"]).robot.body_mass_kg == 0.9
    for name, values, mass in (("heavy", "body_mass_kg: 500.0", "500.2"),
                               ("light", "body_mass_kg: 0.02, wheel_mass_kg: 0.01", "0.06")):
        path = tmp_path / f"{name}.yaml"
        path.write_text(f"/**:\n  ros__parameters:\n    robot: {{{values}}}\n", encoding="utf-8")
        with pytest.raises((ConfigError, ValueError)) as refused:
            load_settings(["sim", "robot", "evaluator", str(path)])
        message = str(refused.value)
        assert "\n" not in message and f"robot.body_mass_kg + 4 x robot.wheel_mass_kg: the robot weighs {mass} kg, " \
                                      "outside 0.2-250 kg" in message
