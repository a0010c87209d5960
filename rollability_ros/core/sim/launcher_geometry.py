"""The launch twin's launcher sized for the robot: push plate and ledge from the robot's collision geometry.

Engine-free (numpy only), shared by every launch twin. The robot is described by
:meth:`~rollability_ros.core.robots.robot.RobotModel.standing_shapes_m`: its bare collision shapes standing level
on its wheels, facing +x, joints at zero. :func:`robot_envelope` puts them in the launch frame: x forward along the
push, y left, z up from the robot's lowest point (the launcher's base plate), metres.

Derived values (:func:`derive_launcher_geometry`; a config value of 0 means "derive", any other value is used as
given, and :func:`check_launcher_geometry` checks either before a campaign)
    ``plate.clearance_m``   min(5 mm, a quarter of the centre of mass's height): the gap under the plate;
    ``plate.height_m``      the face runs from the clearance up to twice the centre of mass's height above it, so
                            the push's line of action passes through the centre of mass (no pitching moment);
                            never above the robot's top; rounded to 1 cm (at least 1 cm); when that face meets
                            none of the robot's rear shapes (:func:`rear_shapes`: all higher), it reaches 1 cm up
                            the lowest of them, as a lab sets the plate to push the robot's body;
    ``plate.width_m``       half the robot's width, rounded to 1 cm (at least 2 cm): centred on the robot's path;
                            when that passes between the robot's rear shapes (a car's rear wheels), the robot's
                            width about the plate's centre line, rounded up to 1 cm;
    ``plate.max_force_n``   the robot's mass times :data:`PLATE_ACCELERATION_MPS2` (the paper rig's 200 N on the
                            1.1 kg chassis), rounded to 10 N: a heavier robot gets a bigger cylinder, so it reaches
                            the launch speed as early in the run as the chassis does;
    ``launcher.bore_m``     the stroke cylinder's bore: the paper's :data:`PAPER_BORE_M` on the built-in chassis's
                            :data:`CHASSIS_MASS_KG`, times the square root of a heavier robot's mass over it (the
                            same force per kilogram at the same pressure), rounded to 1 mm; never smaller;
    ``launcher.ledge_depth_m``  the run, the robot's diagonal (any yaw), the plate and 0.1 m, rounded up to 0.1 m;
    ``launcher.ledge_width_m``  room for a start turned by :data:`LEDGE_ANGLE_DEG` either way: twice (run + the
                            diagonal / cos) x sin + the diagonal, plus 0.2 m, rounded up to 0.1 m.
On the built-in chassis these give the shipped twin's plate (0.10 x 0.05 m at 5 mm, 200 N) and ledge depth (0.8 m).
"""
import dataclasses
import math
import typing

import numpy as np

if typing.TYPE_CHECKING:  # annotations only
    from rollability_ros.core.robots import RobotModel

#: Gap under the push plate unless the robot's centre of mass is lower than four times it (m).
PLATE_CLEARANCE_M = 0.005
#: Most acceleration the cylinder gives the robot (m/s^2): 200 N on the built-in chassis's 1.1 kg.
PLATE_ACCELERATION_MPS2 = 200.0 / 1.1
#: The paper's cylinder bore (m, section 2.2: MAL 25 x 150) and the mass of the chassis it launched (kg: the
#: built-in chassis of config/robot.yaml, body 0.9 + four 0.05 kg wheels).
PAPER_BORE_M = 0.025
CHASSIS_MASS_KG = 1.1
#: Largest start angle the derived ledge width holds (deg): the paper's mounting holes reach +-60 deg.
LEDGE_ANGLE_DEG = 60.0
#: Margins and rounding of the derived sizes (m).
LEDGE_MARGIN_M = 0.1
ROUND_PLATE_M = 0.01
ROUND_LEDGE_M = 0.1


@dataclasses.dataclass(frozen=True)
class RobotEnvelope:
    """The bare robot on the launcher (launch frame, m): ``shapes`` ``[(link, points (k, 3))]``, ``com_m`` (3,)
    and its mass (kg)."""

    shapes: tuple
    com_m: tuple
    mass_kg: float

    def points(self) -> np.ndarray:
        """Every shape's points stacked, ``(n, 3)`` (m)."""
        return np.vstack([points for _, points in self.shapes])

    @property
    def length_m(self) -> float:
        points = self.points()
        return float(np.ptp(points[:, 0]))

    @property
    def width_m(self) -> float:
        points = self.points()
        return float(np.ptp(points[:, 1]))

    @property
    def height_m(self) -> float:
        return float(self.points()[:, 2].max())

    @property
    def com_height_m(self) -> float:
        return float(self.com_m[2])

    @property
    def diagonal_m(self) -> float:
        return math.hypot(self.length_m, self.width_m)


def robot_envelope(robot_model: "RobotModel") -> RobotEnvelope:
    """The :class:`RobotEnvelope` of a :class:`~rollability_ros.core.robots.robot.RobotModel` (bare robot)."""
    shapes, com, mass_kg = robot_model.standing_shapes_m()
    lowest = min(float(np.asarray(points)[:, 2].min()) for _, points in shapes)
    shift = np.array([0.0, 0.0, lowest])
    return RobotEnvelope(shapes=tuple((link, np.asarray(points, dtype=np.float64) - shift) for link, points in shapes),
                         com_m=tuple(float(v) for v in np.asarray(com, dtype=np.float64) - shift),
                         mass_kg=float(mass_kg))


@dataclasses.dataclass(frozen=True)
class LauncherGeometry:
    """The launcher's robot-dependent sizes (m); ``derived`` names the fields taken from the robot."""

    plate_width_m: float
    plate_height_m: float
    plate_clearance_m: float
    plate_max_force_n: float
    ledge_depth_m: float
    ledge_width_m: float
    cylinder_bore_m: float = PAPER_BORE_M
    derived: tuple = ()


def _round(value_m, step_m, up=False):
    steps = value_m / step_m
    return (math.ceil(steps - 1e-9) if up else round(steps)) * step_m


def derive_launcher_geometry(envelope: RobotEnvelope, run_length_m: float, plate_thickness_m: float,
                             configured: typing.Optional[typing.Mapping[str, float]] = None,
                             plate_offset_m: float = 0.0) -> "LauncherGeometry":
    """The :class:`LauncherGeometry` for ``envelope`` (module docstring); ``configured`` maps field names of
    :class:`LauncherGeometry` to config values, and a non-zero one replaces the derived value; ``plate_offset_m``
    the plate's configured sideways offset (m, + = left of the centre of mass)."""
    configured = configured or {}
    com_z = max(envelope.com_height_m, 1e-3)
    clearance = min(PLATE_CLEARANCE_M, com_z / 4)
    if configured.get("plate_clearance_m"):
        clearance = configured["plate_clearance_m"]
    top = min(2 * com_z - clearance, envelope.height_m)
    height = max(ROUND_PLATE_M, _round(top - clearance, ROUND_PLATE_M))
    width = max(2 * ROUND_PLATE_M, _round(envelope.width_m / 2, ROUND_PLATE_M))
    centre_y = envelope.com_m[1] + plate_offset_m
    if not configured.get("plate_width_m") and not rear_shapes_met(envelope, clearance, clearance + height, width,
                                                                   centre_y):
        # half the width passes between its rear shapes (a car's rear wheels): the lab's plate spans the robot
        width = _round(2 * max(abs(float(v) - centre_y) for v in envelope.points()[:, 1]), ROUND_PLATE_M, up=True)
    rear = rear_shapes(envelope, width, centre_y)
    if not configured.get("plate_height_m") and rear and all(points[:, 2].min() >= clearance + height
                                                             for points in rear):
        # its rear face is all above the band centred on the centre of mass: the lab's plate reaches up to it
        top = min(envelope.height_m, min(float(points[:, 2].min()) for points in rear) + ROUND_PLATE_M)
        height = max(ROUND_PLATE_M, _round(top - clearance, ROUND_PLATE_M, up=True))
    diagonal = envelope.diagonal_m
    depth = _round(run_length_m + diagonal + plate_thickness_m + LEDGE_MARGIN_M, ROUND_LEDGE_M, up=True)
    angle = math.radians(LEDGE_ANGLE_DEG)
    side = (run_length_m + diagonal / math.cos(angle)) * math.sin(angle) + diagonal
    ledge_width = _round(2 * side + 2 * LEDGE_MARGIN_M, ROUND_LEDGE_M, up=True)
    values = {"plate_width_m": round(width, 4), "plate_height_m": round(height, 4),
              "plate_clearance_m": round(clearance, 4),
              "plate_max_force_n": float(_round(envelope.mass_kg * PLATE_ACCELERATION_MPS2, 10.0)),
              "ledge_depth_m": round(depth, 3),
              "ledge_width_m": round(ledge_width, 3),
              "cylinder_bore_m": round(PAPER_BORE_M * math.sqrt(max(1.0, envelope.mass_kg / CHASSIS_MASS_KG)), 3)}
    derived = tuple(name for name in values if not configured.get(name))
    values.update({name: float(value) for name, value in configured.items() if value})
    return LauncherGeometry(**{name: float(value) for name, value in values.items()}, derived=derived)


def rear_shapes(envelope: RobotEnvelope, width_m: float, centre_y_m: float) -> typing.List[np.ndarray]:
    """The points ``(k, 3)`` of each collision shape a plate ``width_m`` wide centred at ``centre_y_m`` can reach
    from behind: across the plate's width, its rear in the robot's rear half (a plate meeting only a front caster
    has passed beneath the robot)."""
    everything = envelope.points()
    middle_x = (everything[:, 0].min() + everything[:, 0].max()) / 2
    return [points for _, points in envelope.shapes
            if points[:, 1].max() > centre_y_m - width_m / 2 and points[:, 1].min() < centre_y_m + width_m / 2
            and points[:, 0].min() < middle_x]


def rear_shapes_met(envelope: RobotEnvelope, low_z: float, high_z: float, width_m: float, centre_y_m: float) -> bool:
    """True when a plate face from ``low_z`` to ``high_z`` above the launcher (m), ``width_m`` wide centred at
    ``centre_y_m``, meets one of :func:`rear_shapes`."""
    return any(points[:, 2].max() > low_z and points[:, 2].min() < high_z
               for points in rear_shapes(envelope, width_m, centre_y_m))


#: Where each :class:`LauncherGeometry` field is set (``launch_twin.`` parameter names).
PARAMETERS = {"plate_width_m": "launch_twin.plate.width_m", "plate_height_m": "launch_twin.plate.height_m",
              "plate_clearance_m": "launch_twin.plate.clearance_m", "plate_max_force_n": "launch_twin.plate.max_force_n",
              "ledge_depth_m": "launch_twin.launcher.ledge_depth_m",
              "ledge_width_m": "launch_twin.launcher.ledge_width_m", "cylinder_bore_m": "launch_twin.launcher.bore_m"}


def check_launcher_geometry(envelope: RobotEnvelope, geometry: "LauncherGeometry", run_length_m: float,
                            plate_offset_m: float = 0.0) -> None:
    """Raise ``ValueError`` (one line, naming the settings) when the push plate would miss the robot or the robot
    would not stand on the ledge at its start (straight push): the plate's face, ``plate_clearance_m`` to
    ``plate_clearance_m + plate_height_m`` above the base plate and ``plate_width_m`` wide centred
    ``plate_offset_m`` left of the centre of mass, must overlap in height and across some collision shape whose
    rear lies in the robot's rear half (a plate meeting only a front caster has passed beneath the robot)."""
    low_z = geometry.plate_clearance_m
    high_z = low_z + geometry.plate_height_m
    centre_y = envelope.com_m[1] + plate_offset_m
    across = rear_shapes(envelope, geometry.plate_width_m, centre_y)
    if not rear_shapes_met(envelope, low_z, high_z, geometry.plate_width_m, centre_y):
        where = "passes beneath" if across and all(points[:, 2].min() >= high_z for points in across) else "misses"
        raise ValueError(
            f"the launch twin's push plate {where} the robot: its face spans {low_z:.3f}-{high_z:.3f} m above the "
            f"launcher and {geometry.plate_width_m:.3f} m across, but no collision shape of the robot (centre of mass "
            f"{envelope.com_height_m:.3f} m up) lies there; set {PARAMETERS['plate_height_m']} and "
            f"{PARAMETERS['plate_clearance_m']} to 0 (derived from the robot) or to values that reach it")
    needed_depth = run_length_m + envelope.length_m + 0.01
    if geometry.ledge_depth_m < needed_depth:
        raise ValueError(f"the robot ({envelope.length_m:.3f} m long) does not fit on the launcher: "
                         f"{PARAMETERS['ledge_depth_m']} = {geometry.ledge_depth_m} m is less than the run "
                         f"({run_length_m} m) plus the robot and the plate ({needed_depth:.2f} m); set it to 0 "
                         "(derived from the robot) or larger")
    if geometry.ledge_width_m < envelope.width_m:
        raise ValueError(f"the robot ({envelope.width_m:.3f} m wide) does not fit on the launcher: "
                         f"{PARAMETERS['ledge_width_m']} = {geometry.ledge_width_m} m; set it to 0 (derived from "
                         "the robot) or wider")
