"""Which robot masses do PyBullet and MuJoCo integrate stably on the launch twin? (robot.ROBOT_MASS_RANGE_KG)

    nice python bench/bench_mass_range.py [--engines pybullet,mujoco] [--scales 1e-4,1e-3,...]

Launches a small four-wheeled robot (a 0.2 x 0.14 x 0.04 m body on four 33 mm wheels, 1.62 kg) off the twin's
0.75 m ledge at 1.5 m/s, launch angles 0 and 30 deg, seed 1, at the default 1/240 s step with the 0.3 kg push
plate and the 20 kN/m foam, with every mass and inertia of its URDF times each scale (its shape unchanged; the
launcher is sized for the robot, its force with the mass). Prints per scale and engine each launch's validity,
gate speed and verdict, or the error that ended it (the launcher's refusal, or the twin's instability). All
numbers are simulated. The robot check's mass range (the bound this bench measures) is opened for the run.
"""
import argparse
import os
import re
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

from rollability_ros.core.records import LaunchCondition  # noqa: E402
from rollability_ros.core.robots import robot as robot_module  # noqa: E402
from rollability_ros.core.sim.launch.settings import load_launch_twin_settings  # noqa: E402
from rollability_ros.core.sim.launch.twin import simulate_launch  # noqa: E402

#: Mass of the robot at scale 1, kg: the body's 1.5 and four 0.03 kg wheels.
ROBOT_MASS_KG = 1.62
SCALES = (1e-4, 1e-3, 1e-2, 0.03, 0.05, 0.06, 0.1, 1.0, 10.0, 100.0, 120.0, 200.0, 300.0, 600.0, 1e3, 1e4, 1e5, 1e6)


def robot_urdf(scale: float) -> str:
    """The robot's URDF with every mass and inertia times ``scale``."""
    inertial = ('<inertial><mass value="{m!r}"/><inertia ixx="{a!r}" ixy="0" ixz="0" iyy="{b!r}" iyz="0" izz="{c!r}"/>'
                '</inertial>')
    wheel = (3 * 0.033 ** 2 + 0.018 ** 2) * 0.03 / 12, 0.03 * 0.033 ** 2 / 2
    wheels = "".join(
        f'<link name="wheel_{name}"><collision><geometry><cylinder radius="0.033" length="0.018"/></geometry>'
        f'</collision>{inertial.format(m=0.03 * scale, a=wheel[0] * scale, b=wheel[0] * scale, c=wheel[1] * scale)}'
        f'</link><joint name="wheel_{name}_joint" type="continuous"><parent link="base_link"/>'
        f'<child link="wheel_{name}"/><origin xyz="{x} {y} 0" rpy="-1.5708 0 0"/><axis xyz="0 0 1"/></joint>'
        for name, x, y in (("fl", 0.08, 0.09), ("fr", 0.08, -0.09), ("rl", -0.08, 0.09), ("rr", -0.08, -0.09)))
    body = inertial.format(m=1.5 * scale, a=0.003 * scale, b=0.005 * scale, c=0.007 * scale)
    text = (f'<?xml version="1.0"?><robot name="small_car"><link name="base_link"><collision><origin xyz="0 0 0.03"/>'
            f'<geometry><box size="0.2 0.14 0.04"/></geometry></collision>{body}</link>{wheels}</robot>')
    assert len(re.findall("<mass ", text)) == 5
    return text


def launches(engine: str, scale: float) -> str:
    """One line: the two launches of the robot at ``scale`` on ``engine``, or the error that ended them."""
    overrides = {"urdf_robot.robot_description": robot_urdf(scale), "urdf_robot.mount_link": "base_link",
                 "urdf_robot.footprint_length_m": 0.1, "urdf_robot.footprint_width_m": 0.1,
                 "urdf_robot.footprint_offset_m": [0.0, 0.0, 0.05], "urdf_robot.wheel_link_regex": "wheel_.*",
                 "physics.engine": engine}
    try:
        settings = load_launch_twin_settings(("sim", "robot", "launch_twin"), overrides=overrides)
        parts = []
        for angle in (0.0, 30.0):
            result = simulate_launch(LaunchCondition("baseline", 0.75, 1.5, angle), settings, seed=1)
            parts.append(f"{angle:g} deg: valid {result.valid}, gate {result.measured_speed_mps:.3f} m/s, upright "
                         f"{result.upright}{'' if result.valid else ' (' + result.invalid_reason[:60] + ')'}")
        return "; ".join(parts)
    except Exception as exc:  # the launcher's refusal or the twin's instability: what is measured here
        return "error: " + " ".join(str(exc).split())[:160]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engines", default="pybullet,mujoco", help="comma-separated engines")
    parser.add_argument("--scales", default=",".join(f"{s:g}" for s in SCALES), help="comma-separated mass scales")
    parser.add_argument("--smoke", action="store_true",
                        help="tiny sizes: each step once, in seconds; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    engines, scales = args.engines.split(","), [float(s) for s in args.scales.split(",")]
    if args.smoke:
        engines, scales = ["pybullet"], [1.0]
    checked = robot_module.ROBOT_MASS_RANGE_KG
    robot_module.ROBOT_MASS_RANGE_KG = (0.0, float("inf"))   # measure the engines, not the check built on them
    try:
        for scale in scales:
            for engine in engines:
                started = time.perf_counter()
                line = launches(engine, scale)
                print(f"robot {ROBOT_MASS_KG * scale:.3g} kg (x {scale:g}), {engine}: {line} "
                      f"({time.perf_counter() - started:.0f} s; simulated)", flush=True)
    finally:
        robot_module.ROBOT_MASS_RANGE_KG = checked
    return 0


if __name__ == "__main__":
    sys.exit(main())
