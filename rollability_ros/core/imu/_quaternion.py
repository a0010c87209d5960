"""Quaternion maths on plain tuples: ``(x, y, z, w)`` (ROS order), Hamilton product, ROS roll/pitch/yaw.

Pure Python on 3-vectors and 4-tuples (it runs per IMU sample on a robot computer); angles in rad unless a name
says deg.
"""
import math
import typing

#: A rotation (x, y, z, w), unit norm where a function says so.
Quaternion = typing.Tuple[float, float, float, float]
#: A 3-vector (x, y, z).
Vector3 = typing.Tuple[float, float, float]
#: The identity rotation (x, y, z, w).
IDENTITY = (0.0, 0.0, 0.0, 1.0)


def vector3(value: typing.Iterable[float], name: str) -> Vector3:
    """``value`` as 3 finite floats; ``ValueError`` naming ``name`` otherwise."""
    try:
        x, y, z = (float(c) for c in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be 3 numbers, got {value!r}") from None
    if not all(math.isfinite(c) for c in (x, y, z)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return x, y, z


def normalize_quaternion(q: typing.Iterable[float]) -> Quaternion:
    """Return ``q`` = (x, y, z, w) scaled to unit norm; ``ValueError`` for a zero or non-finite quaternion."""
    try:
        x, y, z, w = (float(c) for c in q)
    except (TypeError, ValueError):
        raise ValueError(f"quaternion must be 4 numbers (x, y, z, w), got {q!r}") from None
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(norm) or norm < 1e-9:
        raise ValueError(f"quaternion must be finite and non-zero, got {q!r}")
    return (x / norm, y / norm, z / norm, w / norm)


def quaternion_multiply(a: typing.Sequence[float], b: typing.Sequence[float]) -> Quaternion:
    """Hamilton product ``a * b`` (rotate by ``b``, then by ``a``)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def quaternion_conjugate(q: typing.Sequence[float]) -> Quaternion:
    """The inverse rotation of a unit quaternion."""
    return (-q[0], -q[1], -q[2], q[3])


def rotate_vector(q: typing.Sequence[float], v: typing.Sequence[float]) -> Vector3:
    """Rotate the 3-vector ``v`` by the unit quaternion ``q``."""
    qx, qy, qz, qw = q
    vx, vy, vz = v
    # t = 2 q_xyz x v ; v' = v + w t + q_xyz x t
    tx, ty, tz = 2 * (qy * vz - qz * vy), 2 * (qz * vx - qx * vz), 2 * (qx * vy - qy * vx)
    return (vx + qw * tx + qy * tz - qz * ty,
            vy + qw * ty + qz * tx - qx * tz,
            vz + qw * tz + qx * ty - qy * tx)


def quaternion_from_axis_angle(axis: typing.Iterable[float], angle_rad: float) -> Quaternion:
    """Rotation by ``angle_rad`` (rad) about ``axis`` (3-vector, any non-zero length)."""
    ax, ay, az = vector3(axis, "axis")
    norm = math.sqrt(ax * ax + ay * ay + az * az)
    if norm < 1e-12:
        raise ValueError("rotation axis must be non-zero")
    s = math.sin(angle_rad / 2) / norm
    return (ax * s, ay * s, az * s, math.cos(angle_rad / 2))


def quaternion_from_rpy_deg(roll_deg: float, pitch_deg: float, yaw_deg: float) -> Quaternion:
    """Rotation from ROS roll, pitch, yaw (deg; about fixed x, then y, then z)."""
    return quaternion_multiply(quaternion_from_axis_angle((0, 0, 1), math.radians(yaw_deg)),
                               quaternion_multiply(quaternion_from_axis_angle((0, 1, 0), math.radians(pitch_deg)),
                                                   quaternion_from_axis_angle((1, 0, 0), math.radians(roll_deg))))


def rpy_deg_from_quaternion(q: typing.Iterable[float]) -> typing.List[float]:
    """Roll, pitch, yaw (deg; fixed axes x, y, z) of the rotation ``q`` = (x, y, z, w)."""
    x, y, z, w = normalize_quaternion(q)
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return [math.degrees(roll), math.degrees(pitch), math.degrees(yaw)]
