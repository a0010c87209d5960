"""The geometry of a spawned PyBullet body: hull points, mass and centre of mass of every link (m, kg), and points on
a sphere; shared by the stable-pose screen, the trials' early decision and the MuJoCo models (no other sim module
imported here, so none of them depends on another for it).
"""
import math

import numpy as np
import typing

from rollability_ros.core.optional import require


def sphere_points(radius_m: float, sections: int) -> np.ndarray:
    """About ``sections ** 2 / 2`` points on a sphere of ``radius_m`` (a Fibonacci lattice), (k, 3) m."""
    count = max(8, sections * sections // 2)
    index = np.arange(count) + 0.5
    z = 1 - 2 * index / count
    angle = math.pi * (1 + math.sqrt(5)) * index
    ring = np.sqrt(1 - z * z)
    return radius_m * np.column_stack([ring * np.cos(angle), ring * np.sin(angle), z])


def _shape_points(pybullet, client, body_id, link, index, shape, sections):
    """Points ``(k, 3)`` whose hull is one collision shape of a spawned body, in its link's inertial frame (m).

    ``shape`` is a row of ``getCollisionShapeData``: primitives are built from their dimensions in the shape's
    local frame (cylinders and capsules along local z, ``sections`` points per rim); meshes come from
    ``getMeshData``, which already gives them in the link's inertial frame.
    """
    kind, dimensions, local_position, local_orientation = shape[2], shape[3], shape[5], shape[6]
    if kind == pybullet.GEOM_MESH:
        _, vertices = pybullet.getMeshData(body_id, link, collisionShapeIndex=index, physicsClientId=client)
        return np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    if kind == pybullet.GEOM_BOX:
        half = np.asarray(dimensions, dtype=np.float64) / 2
        local = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    elif kind == pybullet.GEOM_SPHERE:
        local = sphere_points(dimensions[0], sections)
    elif kind in (pybullet.GEOM_CYLINDER, pybullet.GEOM_CAPSULE):
        length, radius = dimensions[0], dimensions[1]
        angles = np.linspace(0.0, 2 * math.pi, sections, endpoint=False)
        rim = np.column_stack([radius * np.cos(angles), radius * np.sin(angles), np.zeros(sections)])
        if kind == pybullet.GEOM_CYLINDER:
            local = np.vstack([rim + [0.0, 0.0, side * length / 2] for side in (-1, 1)])
        else:
            ball = sphere_points(radius, sections)
            local = np.vstack([ball + [0.0, 0.0, side * length / 2] for side in (-1, 1)])
    else:
        raise ValueError(f"link {link}: collision geometry type {kind} has no hull (box, sphere, cylinder, capsule "
                         "and mesh do)")
    rotation = np.asarray(pybullet.getMatrixFromQuaternion(local_orientation)).reshape(3, 3)
    return local @ rotation.T + np.asarray(local_position)


def link_points(client: int, body_id: int, sections: int = 24) -> typing.Tuple[dict, dict, dict]:
    """Hull points, mass and COM of every link of a spawned body as it stands now, in the world frame.

    Returns three dicts keyed by link index (-1 = base): points (k, 3) m whose hull is the link's collision
    geometry (primitives sampled, round ones with ``sections`` points per rim, meshes by their vertices), mass
    kg and COM position (3,) m.
    """
    pybullet = require("pybullet", feature="the hull of a simulated body")
    points, masses, centres = {}, {}, {}
    for link in range(-1, pybullet.getNumJoints(body_id, physicsClientId=client)):
        if link < 0:
            position, orientation = pybullet.getBasePositionAndOrientation(body_id, physicsClientId=client)
        else:
            position, orientation = pybullet.getLinkState(body_id, link, computeForwardKinematics=True,
                                                          physicsClientId=client)[:2]
        rotation = np.asarray(pybullet.getMatrixFromQuaternion(orientation)).reshape(3, 3)
        masses[link] = pybullet.getDynamicsInfo(body_id, link, physicsClientId=client)[0]
        centres[link] = np.asarray(position, dtype=np.float64)
        shapes = pybullet.getCollisionShapeData(body_id, link, physicsClientId=client)
        if shapes:
            points[link] = np.vstack([_shape_points(pybullet, client, body_id, link, index, shape, sections)
                                      for index, shape in enumerate(shapes)]) @ rotation.T + centres[link]
    return points, masses, centres
