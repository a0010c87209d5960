"""Any robot's start on the launch twin and the stroke launcher's refusal (docs/other-robots.md, "What the TurtleBot3
Waffle showed"), on two generated robots unlike the chassis, the Husky and the mast robot:

- a skid robot shaped like the TurtleBot3 Waffle: low and wide, the drive wheels near the middle, two skid casters
  (boxes) at the rear, a sensor on a fixed joint at the back of the top, the centre of mass just behind the axle.
  Its rigid body is merged from several links, so its principal axes are turned and Bullet's box of it is
  centimetres too large: placed by that box it started 42 mm above the ledge, fell onto the moving plate and was
  never launched ("the gate reads 0.000 m/s with the plate at 2.70 m/s");
- a tall robot (0.55 m, its centre of mass 0.27 m up) pushed at its feet: it tips over backwards, which no pressure
  changes, and the refusal says so;
- a car shaped like pybullet_data's racecar: four wheels, a frame without a collision shape, a sensor box in front:
  a plate half its width passed between its rear wheels and under it, so the derived plate spans the robot."""
import math

import numpy as np
import pytest

from rollability_ros.core.records import LaunchCondition
from rollability_ros.core.sim.launch.drive import launch_drive
from rollability_ros.core.sim.launch.placement import check_launcher, sized_for_robot
from rollability_ros.core.sim.launch.settings import load_launch_twin_settings
from rollability_ros.core.sim.launch.twin import simulate_launch

pybullet = pytest.importorskip("pybullet")

TWIN = ("sim", "robot", "launch_twin")


def _fixed(name, child, xyz, rpy="0 0 0"):
    return (f'<joint name="{name}" type="fixed"><parent link="base_link"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/></joint>')


def _inertial(mass_kg, ixx, iyy, izz, ixz=0.0):
    return (f'<inertial><mass value="{mass_kg}"/><inertia ixx="{ixx}" ixy="0" ixz="{ixz}" iyy="{iyy}" iyz="0" '
            f'izz="{izz}"/></inertial>')


def _wheels(radius_m, width_m, mass_kg, x_m, y_m, z_m):
    inertia = (mass_kg * (3 * radius_m ** 2 + width_m ** 2) / 12, mass_kg * radius_m ** 2 / 2)
    return "".join(
        f'<link name="wheel_{side}"><collision><geometry><cylinder radius="{radius_m}" length="{width_m}"/>'
        f'</geometry></collision>{_inertial(mass_kg, inertia[0], inertia[0], inertia[1])}</link>'
        f'<joint name="wheel_{side}_joint" type="continuous"><parent link="base_link"/><child link="wheel_{side}"/>'
        f'<origin xyz="{x_m} {sign * y_m} {z_m}" rpy="-1.5708 0 0"/><axis xyz="0 0 1"/></joint>'
        for side, sign in (("left", 1), ("right", -1)))


def skid_robot_urdf():
    """The skid robot (module docstring): base_link 1 cm above base_footprint, its 0.266 m box body reaching
    0.197 m behind the axle, skids (turned boxes, as upstream descriptions model casters) 0.177 m behind it."""
    skids = "".join(f'<link name="skid_{side}"><collision><origin xyz="0 0.001 0"/><geometry><box size="0.03 0.009 '
                    f'0.02"/></geometry></collision>{_inertial(0.005, 0.001, 0.001, 0.001)}</link>'
                    + _fixed(f"skid_{side}_joint", f"skid_{side}", f"-0.177 {y} -0.004", "-1.5708 0 0")
                    for side, y in (("left", 0.064), ("right", -0.064)))
    return f"""<?xml version="1.0"?>
<robot name="skid_bot">
  <link name="base_footprint"/>
  <joint name="base_joint" type="fixed"><parent link="base_footprint"/><child link="base_link"/>
    <origin xyz="0 0 0.01"/></joint>
  <link name="base_link"><collision><origin xyz="-0.064 0 0.047"/><geometry><box size="0.266 0.266 0.094"/>
    </geometry></collision>{_inertial(1.4, 0.0087, 0.0086, 0.0146, 0.0001)}</link>
  {_wheels(0.033, 0.018, 0.03, 0.0, 0.144, 0.023)}{skids}
  <link name="sensor"><collision><origin xyz="0.015 0 -0.0065"/><geometry><cylinder radius="0.055" length="0.0315"/>
    </geometry></collision>{_inertial(0.11, 0.001, 0.001, 0.001)}</link>
  {_fixed("sensor_joint", "sensor", "-0.064 0 0.122")}
</robot>
"""


def tall_robot_urdf():
    """The tall robot: a 0.16 x 0.2 x 0.5 m box on two wheels (r 0.05 m) behind its middle and a front skid."""
    return f"""<?xml version="1.0"?>
<robot name="tall_bot">
  <link name="base_link"><collision><geometry><box size="0.16 0.2 0.5"/></geometry></collision>
    <collision><origin xyz="0.06 0 -0.275"/><geometry><box size="0.02 0.04 0.05"/></geometry></collision>
    {_inertial(3.0, 0.07, 0.07, 0.02)}</link>
  <link name="top_plate"/>
  {_fixed("top_joint", "top_plate", "0 0 0.25")}
  {_wheels(0.05, 0.03, 0.2, -0.05, 0.12, -0.25)}
</robot>
"""


def car_urdf():
    """The car: a frame link (mass, no collision shape), rear wheels on its axle at x = 0, front wheels 0.3 m ahead,
    a 0.08 m sensor box over the front axle."""
    rear = _wheels(0.05, 0.045, 0.34, 0.0, 0.12, 0.0).replace("wheel_", "wheel_rear_")
    return f"""<?xml version="1.0"?>
<robot name="car">
  <link name="base_link">{_inertial(4.0, 0.01, 0.04, 0.04)}</link>
  {rear}{_wheels(0.05, 0.045, 0.34, 0.3, 0.12, 0.0).replace("wheel_", "wheel_front_")}
  <link name="sensor"><collision><geometry><box size="0.08 0.08 0.08"/></geometry></collision>
    {_inertial(0.2, 0.0002, 0.0002, 0.0002)}</link>
  {_fixed("sensor_joint", "sensor", "0.26 0 0.09")}
</robot>
"""


def _robot_config(folder, name, urdf, mount, footprint, extra=""):
    (folder / f"{name}.urdf").write_text(urdf, encoding="utf-8")
    length, width, offset = footprint
    path = folder / f"{name}.yaml"
    path.write_text(f"""/**:
  ros__parameters:
    urdf_robot:
      urdf_path: {folder / f"{name}.urdf"}
      mount_link: {mount}
      footprint_length_m: {length}
      footprint_width_m: {width}
      footprint_offset_m: {offset}
      wheel_link_regex: "wheel_.*"
      min_wheels_in_contact: 2
{extra}""", encoding="utf-8")
    return str(path)


@pytest.fixture(scope="module")
def skid_config(tmp_path_factory):
    return _robot_config(tmp_path_factory.mktemp("skid"), "skid_bot", skid_robot_urdf(), "base_link",
                         (0.08, 0.26, [-0.152, 0.0, 0.094]))


def test_a_merged_body_on_turned_axes_starts_resting_on_the_ledge_at_its_true_front(skid_config):
    """PyBullet's placement: the lowest point start_clearance_m above the ledge and the foremost point (which trips
    the gate) where the robot's shapes end, not where Bullet's box of its merged body does."""
    from rollability_ros.core.sim.launch import pybullet_twin
    from rollability_ros.core.sim.world import connect, disconnect

    settings, _, _ = sized_for_robot(load_launch_twin_settings(TWIN + (skid_config,)))
    model = settings.robot_model()
    shapes, com_m, _ = model.standing_shapes_m()
    client = connect()
    try:
        _, ledge_id, _ = pybullet_twin.build_launch_world(client, settings, 0.75)
        robot = model.spawn(client, None, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0, 1.0), time_step_s=None)
        lead_m = pybullet_twin.place_on_launcher(pybullet, client, robot, (0.0, 0.0, 0.0, 1.0), np.array([1.0, 0, 0]),
                                                 settings, 0.75, ledge_id)
        gap_m = min(point[8] for point in pybullet.getClosestPoints(robot.body_id, ledge_id, 1.0,
                                                                     physicsClientId=client))
        box_gap_m = min(pybullet.getAABB(robot.body_id, link, physicsClientId=client)[0][2]
                        for link in range(-1, pybullet.getNumJoints(robot.body_id, physicsClientId=client)))
        box_gap_m -= settings.twin.foam.thickness_m + 0.75
    finally:
        disconnect(client)
    assert gap_m == pytest.approx(settings.twin.launcher.start_clearance_m, abs=1e-4)   # was 42 mm
    # the robot's own shapes, its frame: Bullet's base is at the centre of mass
    assert lead_m == pytest.approx(max(points[:, 0].max() for _, points in shapes) - com_m[0], abs=0.002)  # was +34 mm
    assert box_gap_m < -0.02   # the premise: Bullet's box of the merged body reaches centimetres below it


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_the_stroke_launcher_launches_the_skid_robot_off_the_ledge(skid_config, engine):
    if engine == "mujoco":
        pytest.importorskip("mujoco")
    settings = load_launch_twin_settings(TWIN + (skid_config,), overrides={"physics.engine": engine})
    drive = launch_drive(sized_for_robot(settings)[0], 1.5)   # was refused: "the gate reads 0.000 m/s"
    # rolling freely (its wheels' rolling resistance 0.01 of its load) it leaves the plate at about the plate's speed
    assert 0.9 <= drive.speed_ratio < 1.5
    result = simulate_launch(LaunchCondition("baseline", 0.75, 1.5, 0.0), settings, seed=1)
    assert result.valid, result.invalid_reason
    assert result.measured_speed_mps == pytest.approx(result.launch_speed_mps, rel=0.15)   # the speed gate's flag


def test_a_robot_that_tips_over_under_the_push_is_refused_naming_the_cause(tmp_path):
    """Pushed at its feet (a configured plate 5-55 mm up, its centre of mass 0.27 m up) the tall robot goes over
    backwards at every plate speed: the refusal says so in one line, and does not ask for more pressure."""
    config = _robot_config(tmp_path, "tall_bot", tall_robot_urdf(), "top_plate", (0.14, 0.18, [0.0, 0.0, 0.0]),
                           "    launch_twin:\n      plate: {clearance_m: 0.005, height_m: 0.05}\n")
    settings = load_launch_twin_settings(TWIN + (config,), overrides={"physics.engine": "pybullet"})
    with pytest.raises(ValueError) as refused:
        launch_drive(sized_for_robot(settings)[0], 0.8)
    message = str(refused.value)
    assert "\n" not in message and message.startswith("the stroke launcher cannot launch this robot at 0.8 m/s")
    assert "it tips over on the launcher" in message and "tail-down" in message
    assert "no pressure changes" in message and "raise the pressure" not in message
    tilt_deg = float(message.split("it tips over on the launcher (")[1].split(" deg")[0])
    assert 30.0 <= tilt_deg <= 180.0 and not math.isnan(tilt_deg)


def test_a_plate_that_would_pass_between_a_cars_rear_wheels_spans_the_car(tmp_path):
    """Half the car's width (the chassis's rule) runs between its rear wheels and under it (it has no body low
    down): the derived plate spans the car, meets the wheels, and the stroke launcher launches it."""
    config = _robot_config(tmp_path, "car", car_urdf(), "sensor", (0.06, 0.06, [0.0, 0.0, 0.04]))
    settings = load_launch_twin_settings(TWIN + (config,), overrides={"physics.engine": "pybullet"})
    geometry = check_launcher(settings)   # refused before: "the launch twin's push plate misses the robot"
    assert geometry.plate_width_m >= 2 * (0.12 + 0.045 / 2) and "plate_width_m" in geometry.derived
    result = simulate_launch(LaunchCondition("baseline", 0.75, 1.5, 0.0), settings, seed=1)
    assert result.valid, result.invalid_reason


def test_a_plate_below_every_rear_shape_reaches_up_to_the_lowest():
    """A robot whose rear shapes all sit above the band centred on its (low) centre of mass: the derived face
    reaches 1 cm up the lowest of them, and the check that refused the band centred on the centre of mass passes."""
    from rollability_ros.core.sim.launcher_geometry import (RobotEnvelope, check_launcher_geometry,
                                                             derive_launcher_geometry, rear_shapes_met)

    def box(x, y, z):
        return np.array([[a, b, c] for a in x for b in y for c in z], dtype=np.float64)

    envelope = RobotEnvelope(shapes=(("tail", box((-0.2, -0.1), (-0.1, 0.1), (0.10, 0.20))),
                                     ("sled", box((0.0, 0.2), (-0.1, 0.1), (0.0, 0.03)))),
                             com_m=(0.1, 0.0, 0.02), mass_kg=2.0)
    geometry = derive_launcher_geometry(envelope, 0.34, 0.01)
    low_z, high_z = geometry.plate_clearance_m, geometry.plate_clearance_m + geometry.plate_height_m
    assert high_z == pytest.approx(0.11, abs=0.006) and rear_shapes_met(envelope, low_z, high_z, geometry.plate_width_m,
                                                                        0.0)
    check_launcher_geometry(envelope, geometry, 0.34)
    centred = derive_launcher_geometry(envelope, 0.34, 0.01, {"plate_height_m": 0.03})   # the band on the centre of mass
    with pytest.raises(ValueError, match="passes beneath the robot"):
        check_launcher_geometry(envelope, centred, 0.34)


def small_car_urdf(radius_m=0.033, wheel_mass_kg=0.03):
    """A small four-wheeled robot: a 0.2 x 0.14 x 0.04 m box body clear of the ground on four wheels of ``radius_m``
    (a TurtleBot3's), nothing else touching the ground."""
    front = _wheels(radius_m, 0.018, wheel_mass_kg, 0.08, 0.09, 0.0).replace("wheel_", "wheel_front_")
    rear = _wheels(radius_m, 0.018, wheel_mass_kg, -0.08, 0.09, 0.0).replace("wheel_", "wheel_rear_")
    return f"""<?xml version="1.0"?>
<robot name="small_car">
  <link name="base_link"><collision><origin xyz="0 0 0.03"/><geometry><box size="0.2 0.14 0.04"/></geometry>
    </collision>{_inertial(1.5, 0.003, 0.005, 0.007)}</link>
  {front}{rear}
</robot>
"""


def small_car(radius_m=0.033):
    """Settings overrides that make the twin launch :func:`small_car_urdf` (a footprint on its body's top)."""
    return {"urdf_robot.robot_description": small_car_urdf(radius_m), "urdf_robot.mount_link": "base_link",
            "urdf_robot.footprint_length_m": 0.1, "urdf_robot.footprint_width_m": 0.1,
            "urdf_robot.footprint_offset_m": [0.0, 0.0, 0.05], "urdf_robot.wheel_link_regex": "wheel_.*"}


@pytest.mark.parametrize("contact_model", ["per_contact", "per_body"])
@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_small_wheeled_robot_coasts_on_the_launcher_at_its_rolling_resistance_coefficient(engine, contact_model):
    """The analytic coast-down: a URDF robot rolling freely on the launcher's base plate is slowed by its wheels'
    rolling resistance, force = launch_twin.wheel_rolling_resistance x load whatever the wheels' size (each
    wheel's rolling friction is the coefficient x its radius), against its mass plus the wheels' spin inertia:
    within 10% of Crr g m / (m + 4 I / r^2) on both engines. Before, the wheels kept the trials' 0.01 m: a
    coefficient of 0.3 on these 33 mm wheels, 10 x this one. Either reading of the paper's contact values
    (sim.contact_model): under per_body Bullet added the ground's own rolling friction, 0.0035 m."""
    pytest.importorskip("mujoco")
    from test_twin_engine_fidelity import _on_foam

    crr, radius, wheel_mass = 0.03, 0.033, 0.03
    robot = {**small_car(radius), "twin.wheel_rolling_resistance": crr, "physics.contact_model": contact_model}
    mass = 1.5 + 4 * wheel_mass
    expected = crr * 9.81 * mass / (mass + 4 * wheel_mass / 2)
    velocity = _on_foam(engine, 0.0, (1.0, 0.0, 0.0), 0.35, on_ledge=True, **robot)
    dt = 1.0 / 240.0
    coasting = velocity[round(0.05 / dt):, 0]   # the wheels spun up
    deceleration = -np.polyfit(np.arange(len(coasting)) * dt, coasting, 1)[0]
    assert deceleration == pytest.approx(expected, rel=0.10)


def test_a_wheel_key_of_the_model_the_twin_does_not_use_is_refused():
    """One seam per wheel model: the robot's own wheels' rolling-resistance coefficient on the built-in chassis's
    Mecanum wheels, and a Mecanum wheel key on a URDF robot's own wheels, are refused in one line naming the key;
    at their defaults both load, and the chassis's wheels keep their Mecanum rolling friction."""
    from rollability_ros.core.config import ConfigError
    from rollability_ros.core.sim.launch.settings import twin_with_values, wheel_rolling_friction_m

    chassis = load_launch_twin_settings(TWIN)
    assert wheel_rolling_friction_m(chassis, (0.03,) * 4) == (chassis.twin.wheel_rolling_friction,) * 4
    with pytest.raises(ConfigError, match=r"^launch_twin.wheel_rolling_resistance \(0.02\) acts on the robot's own "
                                          r"wheels \(wheel_model robot\) only, and this twin gives the robot its "
                                          r"Mecanum wheels"):
        load_launch_twin_settings(TWIN, overrides={"twin.wheel_rolling_resistance": 0.02})
    car = load_launch_twin_settings(TWIN, overrides=small_car())
    assert wheel_rolling_friction_m(car, (0.033, 0.05)) == pytest.approx((0.00033, 0.0005))
    with pytest.raises(ConfigError, match=r"^launch_twin.wheel_drag_torque_nm \(0.01\) acts on the twin's Mecanum "
                                          r"wheels \(wheel_model mecanum\) only"):
        twin_with_values(car, {"launch_twin.wheel_drag_torque_nm": 0.01})


def test_the_own_wheels_rolling_resistance_is_drawn_fitted_and_varied_only_where_it_acts():
    """The coefficient is an unknown like the twin's others: the robust draw gives a URDF robot's own wheels a
    value in [wheel_rolling_resistance_min, _max] and leaves the chassis's Mecanum wheels as configured (their
    earlier draws unchanged); calibration and the sensitivity's factor refuse it on the chassis in one line."""
    from rollability_ros.core.campaign.calibration import OWN_WHEEL_KEY, CalibrationSettings, check_fittable
    from rollability_ros.core.sim.robustness import RobustSettings, draw, perturb
    from rollability_ros.core.sim.sensitivity import with_launch_factor

    chassis = load_launch_twin_settings(TWIN)
    car = load_launch_twin_settings(TWIN, overrides=small_car())
    robust = RobustSettings(enabled=True)
    draws = [draw(seed, robust, -0.015, 0.05) for seed in range(1, 9)]
    assert all(0.005 <= d.wheel_rolling_resistance <= 0.03 for d in draws)
    assert len({d.wheel_rolling_resistance for d in draws}) == len(draws)
    for drawn in draws:
        assert perturb(car, drawn).twin.wheel_rolling_resistance == drawn.wheel_rolling_resistance
        assert perturb(chassis, drawn).twin.wheel_rolling_resistance == chassis.twin.wheel_rolling_resistance
    fit = CalibrationSettings(parameters=[OWN_WHEEL_KEY], lower=[0.003], upper=[0.03], log_scale=[True])
    check_fittable(car, fit)
    with pytest.raises(ValueError, match=r"^calibration.parameters: launch_twin.wheel_rolling_resistance acts on a "
                                         r"robot's own wheels only"):
        check_fittable(chassis, fit)
    assert with_launch_factor(car, "wheel_rolling_resistance", 0.02).twin.wheel_rolling_resistance == 0.02
    with pytest.raises(ValueError, match="wheel_rolling_resistance acts on a robot's own wheels"):
        with_launch_factor(chassis, "wheel_rolling_resistance", 0.02)
