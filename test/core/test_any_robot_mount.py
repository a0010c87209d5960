"""The mount of any robot (issue 28): the whole footprint against every collision shape above the mount surface
(a sensor mast, a spinning lidar), an up axis that is not the robot's, the printer checked before any simulation,
and a robot config alone running on the shipped optimiser defaults; on the Husky and on a generated robot with a
tall sensor mast and a high underside."""
import os
import sys

import pytest

from rollability_ros.cli import main
from rollability_ros.core.config import ConfigError, load_parameters
from rollability_ros.core.optimization import optimization_run
from rollability_ros.core.robots.urdf_robot import UrdfRobotSpec
from rollability_ros.core.sim import evaluation

sys.path.insert(0, os.path.dirname(__file__))
from mast_robot import mast_robot_config, mast_robot_urdf  # noqa: E402

pytest.importorskip("pybullet")


@pytest.fixture
def mast_urdf(tmp_path):
    path = tmp_path / "mast_bot.urdf"
    path.write_text(mast_robot_urdf(), encoding="utf-8")
    return str(path)


def _mast_spec(urdf_path, **changes):
    fields = dict(urdf_path=urdf_path, mount_link="top_plate", footprint_length_m=0.16, footprint_width_m=0.2,
                  footprint_offset_m=(0.06, 0.0, 0.0), wheel_link_regex="(left|right)_wheel", min_wheels_in_contact=2)
    fields.update(changes)
    return UrdfRobotSpec(**fields)


def _husky_spec(**changes):
    fields = dict(urdf_path="husky/husky.urdf", search_paths=("python:pybullet_data",), mount_link="top_plate_link",
                  footprint_length_m=0.9, footprint_width_m=0.56, footprint_offset_m=(0.0, 0.0, 0.25873),
                  wheel_link_regex=".*_wheel_link", min_wheels_in_contact=3)
    fields.update(changes)
    return UrdfRobotSpec(**fields)


def test_the_documented_mounts_of_both_robots_are_accepted(mast_urdf):
    _mast_spec(mast_urdf).validate()
    _husky_spec().validate()


def test_a_footprint_over_the_sensor_mast_is_refused_naming_the_mast(mast_urdf):
    """Over the mast at the body's rear the profile would swallow it: the error names the mast, not "set z to the
    top of the hull" (which put the profile on the lidar, its corners 4 cm above the body)."""
    with pytest.raises(ValueError, match=r"link 'mast_link' rises 0.35\d* m above the footprint plane inside the "
                                         r"footprint .*clear of 'mast_link'"):
        _mast_spec(mast_urdf, footprint_offset_m=(0.0, 0.0, 0.0), footprint_length_m=0.28).validate()
    # the mast is thinner than the footprint's sampling grid: found by its shape's own points inside the footprint
    with pytest.raises(ValueError, match="link 'mast_link' rises"):
        _mast_spec(mast_urdf, footprint_offset_m=(-0.1, 0.0, 0.0), footprint_length_m=0.06,
                   footprint_width_m=0.06).validate()


def test_a_sensor_on_its_own_moving_joint_is_found_too(tmp_path, mast_urdf):
    """A lidar cantilevered over the mount on a continuous joint (another rigid body than the mount's)."""
    text = mast_robot_urdf().replace('<origin xyz="0 0 0.38"/><axis xyz="0 0 1"/>',
                                     '<origin xyz="0.16 0 0.1"/><axis xyz="0 0 1"/>')
    path = tmp_path / "low_lidar.urdf"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ValueError, match="link 'lidar_link' rises"):
        _mast_spec(str(path)).validate()


def test_the_husky_profile_may_not_swallow_an_antenna(tmp_path):
    """The Husky with a GPS antenna on its top plate: a footprint over it is refused, one beside it accepted."""
    import pybullet_data

    with open(os.path.join(pybullet_data.getDataPath(), "husky", "husky.urdf"), encoding="utf-8") as stream:
        text = stream.read()
    antenna = ('<link name="gps_antenna"><collision><origin xyz="0 0 0.05"/><geometry><cylinder radius="0.04" '
               'length="0.1"/></geometry></collision><inertial><mass value="0.2"/><inertia ixx="0.001" ixy="0" '
               'ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link><joint name="gps_joint" type="fixed">'
               '<parent link="base_link"/><child link="gps_antenna"/><origin xyz="-0.4 0 0.25873"/></joint></robot>')
    path = tmp_path / "husky_gps.urdf"
    path.write_text(text.replace("</robot>", antenna), encoding="utf-8")
    search = (os.path.join(pybullet_data.getDataPath(), "husky"), "python:pybullet_data")
    with pytest.raises(ValueError, match="link 'gps_antenna' rises 0.1000 m above the footprint plane"):
        _husky_spec(urdf_path=str(path), search_paths=search).validate()
    _husky_spec(urdf_path=str(path), search_paths=search, footprint_length_m=0.5,
                footprint_offset_m=(0.2, 0.0, 0.25873)).validate()


def test_a_footprint_whose_corners_float_is_refused(tmp_path):
    """A stepped deck: the centre sits on the high step, two corners over the low one 4 cm below."""
    deck = ('<robot name="stepped"><link name="deck"><inertial><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" '
            'iyy="0.1" iyz="0" izz="0.1"/></inertial>'
            '<collision><origin xyz="0.05 0 0.05"/><geometry><box size="0.3 0.3 0.1"/></geometry></collision>'
            '<collision><origin xyz="-0.15 0 0.03"/><geometry><box size="0.1 0.3 0.06"/></geometry></collision>'
            '</link></robot>')
    (tmp_path / "stepped.urdf").write_text(deck, encoding="utf-8")
    spec = UrdfRobotSpec(urdf_path=str(tmp_path / "stepped.urdf"), mount_link="deck", footprint_length_m=0.36,
                         footprint_width_m=0.2, footprint_offset_m=(0.0, 0.0, 0.1), upright_tilt_deg=30.0)
    with pytest.raises(ValueError, match=r"0.0400 m above the top of mount link 'deck''s collision shapes at the "
                                         r"footprint's corner \[-0.18, -0.1\] m .*where the surface is level"):
        spec.validate()


@pytest.mark.parametrize("robot", ["husky", "mast"])
def test_an_up_axis_that_is_not_the_robots_up_is_refused(robot, mast_urdf):
    spec = (_husky_spec if robot == "husky" else lambda **c: _mast_spec(mast_urdf, **c))
    with pytest.raises(ValueError, match=r"up_axis_xyz \[1.0, 0.0, 0.0\] is 90 deg from the root link's z.*never "
                                         r"count as upright"):
        spec(up_axis_xyz=(1.0, 0.0, 0.0)).validate()
    spec(up_axis_xyz=(0.0, 0.1, 1.0)).validate()        # 6 deg off: still the robot's up


def _robot_config(tmp_path, robot, extra=""):
    if robot == "husky":
        path = tmp_path / "husky_extra.yaml"
        path.write_text("/**:\n  ros__parameters:\n" + extra, encoding="utf-8")
        return ["husky", str(path)]
    (tmp_path / "mast_bot.urdf").write_text(mast_robot_urdf(), encoding="utf-8")
    path = tmp_path / "mast_bot.yaml"
    path.write_text(mast_robot_config(str(tmp_path / "mast_bot.urdf"), extra=extra), encoding="utf-8")
    return [str(path)]


@pytest.mark.parametrize("robot", ["husky", "mast"])
def test_the_printer_is_checked_before_any_simulation(tmp_path, robot, monkeypatch):
    configs = _robot_config(tmp_path, robot, "    printer:\n      bed_x_m: 0.05\n      bed_y_m: 0.05\n"
                                             "      bed_z_m: 0.05\n")
    parameters = optimization_run.load_run_parameters(configs)
    assert parameters["optimizer.initial_mean_screen"] > 0       # the start-point screen would run first

    def no_simulation(*args, **kwargs):
        raise AssertionError("simulated before the printer check")

    with pytest.raises(ValueError, match="cannot optimize: .*bed"):
        optimization_run.OptimizationRun(tmp_path / "run", optimization_run.run_config(parameters),
                                         evaluation.settings_from_parameters(parameters).grid, no_simulation,
                                         screen_profiles=no_simulation)
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("robot", ["husky", "mast"])
def test_a_robot_config_alone_runs_on_the_shipped_optimizer_defaults(tmp_path, robot):
    configs = _robot_config(tmp_path, robot)
    alone = optimization_run.load_run_parameters(configs)
    explicit = optimization_run.load_run_parameters(["optimizer"] + configs)
    assert alone == explicit
    shipped = load_parameters(["optimizer"])
    assert alone["optimizer.method"] == shipped["optimizer.method"] and alone["selection.count"] == 3
    assert alone["optimizer.initial_mean_screen"] == shipped["optimizer.initial_mean_screen"]
    if robot == "husky":   # the robot config's own optimizer keys still win
        assert alone["optimizer.popsize"] == 8
    paper = optimization_run.load_run_parameters(["paper"] + configs)
    assert paper["optimizer.method"] == load_parameters(["paper"])["optimizer.method"]
    with pytest.raises(ConfigError, match="config file not found: nowhere.yaml"):
        optimization_run.load_run_parameters(["nowhere.yaml"])


def test_cli_optimize_with_a_bad_up_axis_fails_in_one_line(tmp_path, capsys):
    (config,) = _robot_config(tmp_path, "mast")
    text = open(config, encoding="utf-8").read()
    with open(config, "w", encoding="utf-8") as stream:
        stream.write(text.replace("up_axis_xyz: [0.0, 0.0, 1.0]", "up_axis_xyz: [1.0, 0.0, 0.0]"))
    assert main(["optimize", "--config", config, "--run-id", "x"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "up_axis_xyz [1.0, 0.0, 0.0] is 90 deg from the root link's z" in err[0]


#: An upstream description as published: the TurtleBot3 Burger's xacro, visual meshes package://turtlebot3_description.
BURGER = os.path.join(os.path.dirname(__file__), "..", "resources", "turtlebot3_burger.urdf")
#: The walk-through's mount (docs/other-robots.md): on the lidar housing's top, the only free top surface.
BURGER_MOUNT = dict(urdf_path=BURGER, mount_link="base_scan", footprint_length_m=0.07, footprint_width_m=0.07,
                    footprint_offset_m=(0.015, 0.0, 0.00925), wheel_link_regex="wheel_(left|right)_link",
                    min_wheels_in_contact=2)


def test_upstream_xacro_with_missing_visual_meshes_says_what_to_do(monkeypatch):
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)
    with pytest.raises(ValueError) as refused:
        UrdfRobotSpec(**BURGER_MOUNT).validate()
    message = str(refused.value)
    assert "\n" not in message and message.startswith(
        "visual mesh package://turtlebot3_description/meshes/bases/burger_base.stl not found")
    assert "AMENT_PREFIX_PATH" in message and "ignore_visual_meshes: true" in message
    spec = UrdfRobotSpec(**BURGER_MOUNT, ignore_visual_meshes=True)
    spec.validate()
    assert "<visual>" not in spec.description().robot.original_urdf


def test_upstream_meshes_found_through_ament_prefix_path(tmp_path, monkeypatch):
    trimesh = pytest.importorskip("trimesh")
    share = tmp_path / "prefix" / "share" / "turtlebot3_description" / "meshes"
    for name in ("bases/burger_base.stl", "wheels/left_tire.stl", "wheels/right_tire.stl", "sensors/lds.stl"):
        (share / name).parent.mkdir(parents=True, exist_ok=True)
        trimesh.creation.box((10.0, 10.0, 10.0)).export(str(share / name))
    monkeypatch.setenv("AMENT_PREFIX_PATH", f"{tmp_path / 'elsewhere'}{os.pathsep}{tmp_path / 'prefix'}")
    UrdfRobotSpec(**BURGER_MOUNT).validate()    # found in the second prefix's share/ (the first has none)


def test_upstream_robot_profile_over_its_lidar_is_refused_naming_it():
    spec = UrdfRobotSpec(**{**BURGER_MOUNT, "mount_link": "base_link", "footprint_length_m": 0.12,
                            "footprint_width_m": 0.12, "footprint_offset_m": (-0.032, 0.0, 0.1415)},
                         ignore_visual_meshes=True)
    with pytest.raises(ValueError, match="link 'base_scan' rises 0.0397 m above the footprint plane"):
        spec.validate()
