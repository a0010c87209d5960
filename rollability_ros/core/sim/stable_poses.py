"""Analytic stable-pose screen: how likely a rigid convex body comes to rest upright, and how deep it can be stuck.

Model (quasi-static, no momentum)
    The body is its convex hull with its centre of mass (COM). Dropped in a uniformly random orientation onto a
    plane, it lands on the hull face its downward direction points through (as seen from the COM) and topples
    face to face, always downhill, until the COM projects inside the face it rests on.
    ``trimesh.poses.compute_stable_poses`` computes those resting poses and their probabilities; with
    ``com_sigma_m`` > 0 it averages over ``n_samples`` COM positions drawn around the nominal one (trimesh's
    ``sigma`` argument is the variance of each coordinate, ``com_sigma_m ** 2``), which smooths the answer for a
    COM that is only known to a few millimetres. A pose is *upright* when the body's +z axis is within
    ``upright_tilt_deg`` of world up (the robot model's tilt test; on a hull the wheels of a pose that tilted
    are always on the ground).
Barrier back to upright
    Tipping from resting face f to an adjacent face g over their shared edge lifts the COM to its distance from
    that edge (the COM passes over it); within one flat facet the COM stays at the facet's height. The barrier
    of a resting pose is the lowest possible highest COM height over all face-to-face paths to an upright face,
    minus its resting COM height (a minimax path, found with Dijkstra's algorithm on the hull's face adjacency),
    in metres and as potential energy ``mass * g * height`` in joules. ``worst_barrier_m`` is the largest over
    the non-upright resting poses: the energy a disturbance must supply to right the body from its worst
    resting pose, the quantity the paper's profiles are designed to make small.
Use
    :func:`screen_body` on any hull; :func:`robot_hull` builds the hull of any robot model (the built-in chassis
    or a URDF robot) with its profile, from the collision shapes PyBullet spawns; :func:`screen_robot` screens
    one; :func:`screen_heights` screens candidate profiles, and :func:`profile_screener` binds it for the
    optimization run, which starts from the best of several random means by the screen when
    ``optimizer.initial_mean_screen`` > 0 (see ``docs/calibration.md``: it ranks starting points, it never stands
    in for a simulated fitness); :func:`drop_trials` runs the low-energy PyBullet drops the screen is
    cross-checked against.

Frames and units: the body frame is the robot's base frame turned so that its up axis is +z (for the built-in
chassis, the chassis frame: x forward, y left, z up = upright); metres, kilograms, joules.
trimesh, networkx (trimesh's pose graph), scipy and pybullet are imported inside the functions that use them.
"""
import dataclasses
import heapq
import math
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core import config
from rollability_ros.core.optional import require
from rollability_ros.core.profile import Mesh
from rollability_ros.core.sim._body_points import link_points

if typing.TYPE_CHECKING:  # annotations only
    from rollability_ros.core.robots import ProfileBody, RobotModel
    from rollability_ros.core.sim.evaluation import EvaluatorSettings
    from rollability_ros.core.sim.trials import TrialSettings
    from rollability_ros.core.sim.world import PhysicsParams

#: Standard gravity for the barrier energy, m/s^2.
GRAVITY_MPS2 = 9.81


@dataclasses.dataclass
class ScreenSettings:
    """The screen's own parameters (``config/calibration.yaml``, namespace ``stable_poses``)."""

    com_sigma_m: float = dataclasses.field(default=0.003, metadata={
        "description": "standard deviation of each centre-of-mass coordinate in the stable-pose screen, m",
        "range": (0.0, 0.05), "exclusive": "high"})
    n_samples: int = dataclasses.field(default=16, metadata={
        "description": "centre-of-mass samples of the stable-pose screen (count)", "range": (1, 1000000)})
    seed: int = dataclasses.field(default=1, metadata={
        "description": "seed of the centre-of-mass samples (integer)", "range": (0, 2147483647)})
    wheel_sections: int = dataclasses.field(default=24, metadata={
        "description": "points per rim of each round collision shape such as a wheel (count)", "range": (6, 100000)})
    prescreen_min_probability: float = dataclasses.field(default=0.0, metadata={
        "description": "candidates below this quasi-static P(upright) are flagged (0 = off)", "range": (0.0, 1.0)})


@dataclasses.dataclass(frozen=True)
class RigidHull:
    """A rigid body for the screen: its convex hull (trimesh, metres, body frame), COM (3,) m, mass kg."""

    hull: Mesh
    com_m: np.ndarray
    mass_kg: float

    @classmethod
    def from_points(cls, points_m: npt.ArrayLike, com_m: npt.ArrayLike, mass_kg: float) -> "RigidHull":
        """The hull of ``points_m`` (k, 3) with ``com_m`` (3,) inside it; ``ValueError`` if degenerate or outside."""
        trimesh = require("trimesh", feature="the stable-pose screen")
        points = np.asanyarray(points_m, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3 or len(points) < 4:
            raise ValueError(f"points_m must be (k >= 4, 3), got shape {points.shape}")
        com = np.asanyarray(com_m, dtype=np.float64)
        if com.shape != (3,):
            raise ValueError(f"com_m must be (3,), got shape {com.shape}")
        if not mass_kg > 0:
            raise ValueError(f"mass_kg must be > 0, got {mass_kg}")
        hull = trimesh.convex.convex_hull(points)
        if hull.volume <= 0:
            raise ValueError("the hull of the points has no volume")
        if np.any(np.einsum("ij,ij->i", com - hull.triangles_center, hull.face_normals) >= 0):
            raise ValueError(f"centre of mass {com.tolist()} lies outside the hull")
        return cls(hull=hull, com_m=com, mass_kg=float(mass_kg))


def _rotation_onto_z(axis):
    """The rotation matrix (3, 3) turning unit vector ``axis`` onto +z by the shortest arc."""
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    cross, cos = np.cross(axis, [0.0, 0.0, 1.0]), float(axis[2])
    if np.linalg.norm(cross) < 1e-12:
        return np.eye(3) if cos > 0 else np.diag([1.0, -1.0, -1.0])
    skew = np.array([[0.0, -cross[2], cross[1]], [cross[2], 0.0, -cross[0]], [-cross[1], cross[0], 0.0]])
    return np.eye(3) + skew + skew @ skew / (1 + cos)


def robot_hull(robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]" = None,
               sections: int = 24) -> RigidHull:
    """The :class:`RigidHull` of any :class:`~rollability_ros.core.robots.robot.RobotModel` with ``profile`` on its mount.

    The robot is spawned, as the trials spawn it, in a private PyBullet client at the origin with its base frame
    unrotated and every joint at zero; the hull is that of all its collision shapes (primitives sampled, round
    ones with ``sections`` points per rim, meshes by their vertices) and the COM and mass are PyBullet's, summed
    over its links. The result is turned so that the model's up axis is +z, as :func:`screen_body` expects.
    """
    require("pybullet", feature="the stable-pose screen of a robot")
    from rollability_ros.core.sim.world import connect, disconnect

    client = connect()
    try:
        # geometry only: this world is never stepped
        robot = robot_model.spawn(client, profile, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), time_step_s=None)
        points_by_link, mass_by_link, centre_by_link = link_points(client, robot.body_id, sections)
        points = list(points_by_link.values())
        masses, centres = list(mass_by_link.values()), list(centre_by_link.values())
        up = robot_model.up_axis(client, robot)
    finally:
        disconnect(client)
    if not points:
        raise ValueError("the robot has no collision shape to rest on")
    mass = float(sum(masses))
    com = sum(m * c for m, c in zip(masses, centres)) / mass
    turn = _rotation_onto_z(up)
    return RigidHull.from_points(np.vstack(points) @ turn.T, turn @ com, mass)


@dataclasses.dataclass(frozen=True)
class RestingPose:
    """One stable resting pose: ``transform`` (4, 4) puts the body at rest on z = 0 (trimesh's convention),
    ``probability`` of ending in it, body tilt (deg), COM height (m), upright or not, barrier back to upright (m;
    0 for an upright pose, inf when no upright face is reachable)."""

    transform: np.ndarray
    probability: float
    tilt_deg: float
    com_height_m: float
    upright: bool
    barrier_m: float


@dataclasses.dataclass(frozen=True)
class StableScreen:
    """The screen of one body: P(rest upright), resting poses (most probable first), worst barrier (m, J)."""

    upright_probability: float
    poses: tuple
    worst_barrier_m: float
    worst_barrier_j: float

    def row(self) -> typing.Dict[str, float]:
        """Flat dict for a CSV table or a printout."""
        return {"upright_probability": self.upright_probability, "resting_poses": len(self.poses),
                "worst_barrier_m": self.worst_barrier_m, "worst_barrier_j": self.worst_barrier_j}


def _minimax_heights(hull, com, upright_faces):
    """Per hull face, the lowest possible highest COM height (m) on a face-to-face path to an upright face."""
    plane_height = -np.einsum("ij,ij->i", com - hull.triangles_center, hull.face_normals)
    pairs = hull.face_adjacency
    edges = hull.vertices[hull.face_adjacency_edges]               # (p, 2, 3): the shared edge of each pair
    along = edges[:, 1] - edges[:, 0]
    t = np.clip(np.einsum("ij,ij->i", com - edges[:, 0], along) / np.einsum("ij,ij->i", along, along), 0.0, 1.0)
    over_edge = np.linalg.norm(com - (edges[:, 0] + t[:, None] * along), axis=1)
    coplanar = hull.face_adjacency_angles < 1e-6
    pass_height = np.where(coplanar, plane_height[pairs].max(axis=1), over_edge)
    neighbours: typing.List[typing.List[typing.Tuple[int, float]]] = [[] for _ in range(len(hull.faces))]
    for (a, b), height in zip(pairs, pass_height):
        neighbours[a].append((b, height))
        neighbours[b].append((a, height))
    best = np.full(len(hull.faces), np.inf)
    queue = [(plane_height[face], int(face)) for face in upright_faces]
    for height, face in queue:
        best[face] = height
    heapq.heapify(queue)
    while queue:
        height, face = heapq.heappop(queue)
        if height > best[face]:
            continue
        for other, step in neighbours[face]:
            through = max(height, step, plane_height[other])
            if through < best[other]:
                best[other] = through
                heapq.heappush(queue, (through, other))
    return best, plane_height


#: A :func:`drop_trials` spawner: ``spawn(client, time_step_s) -> (body_id, upright(ground_id) -> bool)``.
Spawner = typing.Callable[[int, typing.Optional[float]], typing.Tuple[int, typing.Callable[[int], bool]]]


def screen_body(body: RigidHull, upright_tilt_deg: float, com_sigma_m: float = 0.0, n_samples: int = 1,
                seed: int = 1) -> StableScreen:
    """Screen ``body`` (a :class:`RigidHull`): resting poses with probabilities and barriers (module docstring).

    Parameters
    ----------
    body : RigidHull
    upright_tilt_deg : float
        Largest tilt of the body's +z from world up that counts as upright, in (0, 90) deg.
    com_sigma_m : float
        Standard deviation of each COM coordinate (m); 0 = the nominal COM only.
    n_samples : int
        COM samples when ``com_sigma_m`` > 0.
    seed : int
        Seed of trimesh's COM samples.
    """
    trimesh = require("trimesh", feature="the stable-pose screen")
    require("networkx", feature="the stable-pose screen (trimesh's topple graph)")
    if not 0 < upright_tilt_deg < 90:
        raise ValueError(f"upright_tilt_deg must be in (0, 90), got {upright_tilt_deg}")
    if com_sigma_m < 0 or n_samples < 1:
        raise ValueError(f"need com_sigma_m >= 0 and n_samples >= 1, got {com_sigma_m}, {n_samples}")
    hull, com = body.hull, body.com_m
    transforms, probabilities = trimesh.poses.compute_stable_poses(
        hull, center_mass=com, sigma=com_sigma_m ** 2, n_samples=n_samples if com_sigma_m > 0 else 1, seed=seed)
    cos_upright = math.cos(math.radians(upright_tilt_deg))
    upright_faces = np.flatnonzero(-hull.face_normals[:, 2] >= cos_upright)
    if not len(upright_faces):
        raise ValueError("the hull has no face the body can stand upright on")
    minimax, plane_height = _minimax_heights(hull, com, upright_faces)
    poses = []
    for transform, probability in zip(transforms, probabilities):
        down = -transform[2, :3]                                   # the resting face's outward normal, body frame
        faces = np.flatnonzero(hull.face_normals @ down > 1 - 1e-6)
        up_z = float(transform[2, 2])                              # world z of the body's +z axis
        upright = up_z >= cos_upright
        face = faces[np.argmin(minimax[faces] - plane_height[faces])] if len(faces) else None
        barrier = 0.0 if upright or face is None else float(minimax[face] - plane_height[face])
        poses.append(RestingPose(transform=np.asarray(transform), probability=float(probability),
                                 tilt_deg=math.degrees(math.acos(max(-1.0, min(1.0, up_z)))),
                                 com_height_m=float(transform[2, :3] @ com + transform[2, 3]),
                                 upright=bool(upright), barrier_m=barrier))
    worst = max((pose.barrier_m for pose in poses if not pose.upright), default=0.0)
    return StableScreen(upright_probability=float(sum(p.probability for p in poses if p.upright)),
                        poses=tuple(poses), worst_barrier_m=worst,
                        worst_barrier_j=body.mass_kg * GRAVITY_MPS2 * worst)


def screen_robot(robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]",
                 settings: ScreenSettings) -> StableScreen:
    """Screen ``robot_model`` (any RobotModel) with ``profile`` (ProfileBody or None) under :class:`ScreenSettings`,
    upright by the model's own tilt threshold."""
    body = robot_hull(robot_model, profile, settings.wheel_sections)
    return screen_body(body, robot_model.upright_tilt_deg, settings.com_sigma_m, settings.n_samples, settings.seed)


def screen_heights(heights_list: typing.Sequence[npt.ArrayLike], evaluator_settings: "EvaluatorSettings",
                   settings: ScreenSettings) -> typing.List[typing.Tuple[StableScreen, bool]]:
    """Screen candidate profiles (half-grid heights ``(grid.n_variables,)``, simulation units) for the optimizer.

    Returns ``[(StableScreen, passed)]`` in the order given; ``passed`` is ``upright_probability >=
    settings.prescreen_min_probability``. Meant for choosing or ranking initial means and for flagging
    hopeless candidates before spending trials on them; it never replaces a candidate's simulated fitness.
    """
    from rollability_ros.core.sim.evaluation import profile_job

    robot_model = evaluator_settings.robot_model()
    out = []
    for heights in heights_list:
        result = screen_robot(robot_model, profile_job(heights, evaluator_settings).profile, settings)
        out.append((result, result.upright_probability >= settings.prescreen_min_probability))
    return out


def profile_screener(evaluator_settings: "EvaluatorSettings", settings: ScreenSettings
                     ) -> typing.Callable[[typing.Sequence[npt.ArrayLike]], typing.List[StableScreen]]:
    """``screen_profiles(heights_list) -> [StableScreen, ...]`` (each heights ``(grid.n_variables,)``, simulation
    units) on the robot of ``evaluator_settings`` under :class:`ScreenSettings` ``settings``: the screen an :class:`~rollability_ros.core.optimization.optimization_run.OptimizationRun`
    ranks its initial means with."""
    config.check_settings(settings, "stable_poses")
    return lambda heights_list: [screen for screen, _ in screen_heights(heights_list, evaluator_settings, settings)]


def random_orientation(rng: np.random.Generator) -> typing.Tuple[float, ...]:
    """A uniformly random orientation (x, y, z, w) from numpy Generator ``rng`` (normalised 4-d Gaussian)."""
    quaternion = rng.standard_normal(4)
    return tuple(quaternion / np.linalg.norm(quaternion))


def hull_spawner(body: RigidHull, upright_tilt_deg: float) -> Spawner:
    """A :func:`drop_trials` spawner for a :class:`RigidHull`: one convex mesh body, upright by tilt alone."""
    pybullet = require("pybullet", feature="low-energy drop trials")
    cos_upright = math.cos(math.radians(upright_tilt_deg))

    def spawn(client: int, time_step_s: typing.Optional[float]) -> typing.Tuple[int, typing.Callable[[int], bool]]:
        # a rigid hull: nothing in it depends on the step
        shape = pybullet.createCollisionShape(pybullet.GEOM_MESH, vertices=body.hull.vertices.tolist(),
                                              physicsClientId=client)
        body_id = pybullet.createMultiBody(baseMass=body.mass_kg, baseCollisionShapeIndex=shape,
                                           baseInertialFramePosition=body.com_m.tolist(), physicsClientId=client)

        def upright(ground_id: int) -> bool:
            _, orientation = pybullet.getBasePositionAndOrientation(body_id, physicsClientId=client)
            return pybullet.getMatrixFromQuaternion(orientation)[8] >= cos_upright
        return body_id, upright
    return spawn


def chassis_spawner(robot_model: "RobotModel", profile: "typing.Optional[ProfileBody]") -> Spawner:
    """A :func:`drop_trials` spawner for a robot model with ``profile``; upright by the model's own test."""
    def spawn(client: int, time_step_s: typing.Optional[float]) -> typing.Tuple[int, typing.Callable[[int], bool]]:
        robot = robot_model.spawn(client, profile, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 1.0), time_step_s=time_step_s)
        return robot.body_id, lambda ground_id: robot_model.is_upright(client, robot, ground_id)[0]
    return spawn


def drop_trials(spawn: Spawner, trials: int, seed: int, physics: "PhysicsParams", trial_settings: "TrialSettings",
                clearance_m: float = 0.001) -> typing.Tuple[int, int]:
    """Low-energy PyBullet drops: ``trials`` uniformly random orientations released at rest ``clearance_m``
    above the ground; count how many come to rest upright (the quasi-static screen's experiment).

    Parameters
    ----------
    spawn : callable(client, time_step_s) -> (body_id, upright(ground_id) -> bool)
        :func:`hull_spawner` or :func:`chassis_spawner`, called with ``physics.time_step_s``; the body gets
        ``physics``' body contact.
    trials, seed : int
        Number of drops; seed of the orientations.
    physics : rollability_ros.core.sim.world.PhysicsParams
    trial_settings : rollability_ros.core.sim.trials.TrialSettings
        Rest detection and time cap (as in the disturbance trials).

    Returns
    -------
    (upright, settled) : (int, int)
        Drops that ended upright, and drops that came to rest before the time cap.
    """
    pybullet = require("pybullet", feature="low-energy drop trials")
    from rollability_ros.core.sim.world import connect, disconnect, reset_world, set_contact
    from rollability_ros.core.sim.trials import RestDetector, place_on_ground

    rng = np.random.default_rng(seed)
    dt = physics.time_step_s
    cap = round(trial_settings.time_cap_s / dt)
    upright_count = settled_count = 0
    client = connect()
    try:
        ground = reset_world(client, physics)
        body_id, upright = spawn(client, physics.time_step_s)
        set_contact(client, body_id, physics.body_contact())
        saved = pybullet.saveState(physicsClientId=client)
        for _ in range(trials):
            pybullet.restoreState(saved, physicsClientId=client)
            place_on_ground(client, body_id, random_orientation(rng), clearance_m)
            rest = RestDetector(trial_settings, dt)
            for steps in range(1, cap + 1):
                pybullet.stepSimulation(physicsClientId=client)
                if rest.settled(client, body_id, steps):
                    settled_count += 1
                    break
            upright_count += bool(upright(ground))
    finally:
        disconnect(client)
    return upright_count, settled_count
