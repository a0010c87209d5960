"""Early decision: end a disturbance trial as soon as energy alone fixes whether it will end upright.

Argument (rigid body on the flat ground z = 0, no external work after the disturbance)
    Let ``d`` be the world's down direction seen in the body frame and ``h(d)`` the height of the centre of mass
    (COM) above the ground when the body touches it with down direction ``d`` (the support function of the
    body's convex hull about its COM). While the body is on or above the ground its COM height is >= ``h(d)``;
    after the disturbance only gravity and passive contacts (friction, restitution < 1, unpowered wheel drag)
    act, so ``E = z_com + KE / (m g)`` (an energy expressed as a height, m) can only fall. Hence ``d`` stays
    forever in the connected part of ``{d : h(d) <= E}`` that holds it now, and the body comes to rest in a
    resting pose inside that part. If every resting pose there is upright, the trial ends upright; if none
    is, it ends not upright.
Resting poses
    The outward normals of the hull facets the COM projects into (exact for the hull; round shapes are
    sampled polygons); upright as the robot model judges a body at rest: tilt of the up axis within
    ``upright_tilt_deg`` and at least ``min_wheels_in_contact`` wheel links within ``contact_tolerance_m`` of
    the ground.
Discretisation
    ``h`` is tabulated on a Fibonacci lattice of directions with a k-nearest-neighbour graph. The lowest
    possible highest ``h`` on a lattice path from each direction to the lattice point nearest an upright (or a
    not-upright) resting pose is a minimax ("bottleneck") distance, read off a minimum spanning tree (scipy).
    A continuous path is followed by the lattice points nearest to it, which are neighbours in the graph, and
    ``h`` changes by at most ``R * delta`` between a direction and its nearest lattice point (``R`` the hull's
    largest radius about the COM, ``delta`` the lattice's nearest-neighbour spacing, larger than its covering
    radius); the target points are grown by one ring of neighbours and every barrier is lowered by
    ``R * delta`` plus ``margin_m``, so the discrete test errs on the side of running on.
What the simulator breaks and the margin absorbs: contact penetration (mm) and solver energy injected at
impacts. ``bench/verify_early_decision.py`` runs thousands of trials with and without the early decision and
counts outcome changes (none allowed); ``test/core/test_early_decision.py`` does the same on a smaller sample.
Units: metres, kilograms, seconds; frames as stated per function.
"""
import collections
import dataclasses
import functools
import hashlib
import math
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core.optional import require

#: Standard gravity for the energy height, m/s^2 (the world's gravity is used where it is known).
GRAVITY_MPS2 = 9.81


def fibonacci_directions(count: int) -> np.ndarray:
    """``count`` nearly uniform unit vectors on the sphere (a Fibonacci lattice), (count, 3)."""
    index = np.arange(count) + 0.5
    z = 1 - 2 * index / count
    angle = math.pi * (1 + math.sqrt(5)) * index
    ring = np.sqrt(1 - z * z)
    return np.column_stack([ring * np.cos(angle), ring * np.sin(angle), z])


def _minimax_from(sources, edges_a, edges_b, edge_height, node_height):
    """Per node, the lowest possible highest node height on a graph path to any node in ``sources`` (m).

    Minimax path values equal the largest edge on the minimum spanning tree path, so a virtual node joined to
    every source by an edge of that source's height is added, the MST taken and walked breadth-first.
    """
    sparse = require("scipy.sparse", feature="the early trial decision")
    csgraph = require("scipy.sparse.csgraph", feature="the early trial decision")
    count = len(node_height)
    if not np.any(sources):
        return np.full(count, np.inf)
    source_nodes = np.flatnonzero(sources)
    # csgraph treats 0 as "no edge": shift every weight by a constant (MST and path maxima are unchanged by it)
    shift = 1.0 - min(float(node_height.min()), 0.0)
    rows = np.concatenate([edges_a, np.full(len(source_nodes), count)])
    cols = np.concatenate([edges_b, source_nodes])
    weights = np.concatenate([edge_height, node_height[source_nodes]]) + shift
    graph = sparse.coo_matrix((weights, (rows, cols)), shape=(count + 1, count + 1)).tocsr()
    tree = csgraph.minimum_spanning_tree(graph)
    tree = (tree + tree.T).tocsr()
    order, predecessors = csgraph.breadth_first_order(tree, count, directed=False, return_predecessors=True)
    children = order[1:]
    step = np.asarray(tree[predecessors[children], children]).ravel() - shift
    barrier = np.full(count + 1, np.inf)
    barrier[count] = -np.inf
    for node, parent, height in zip(children.tolist(), predecessors[children].tolist(), step.tolist()):
        barrier[node] = max(barrier[parent], height)
    return barrier[:count]


@dataclasses.dataclass(frozen=True)
class BasinMap:
    """The tabulated energy barriers of one rigid robot + profile (see the module docstring).

    ``directions`` (n, 3) unit down directions in the base frame; ``barrier_to_upright_m`` and
    ``barrier_to_not_upright_m`` (n,) the energy heights (m) needed to reach a resting pose of that outcome
    from each direction (already lowered by the discretisation and safety margins); ``upright`` (n,) marks the
    lattice directions nearest to upright resting poses; ``com_m`` (3,) the COM in the base frame (m);
    ``mass_kg``.
    """

    directions: np.ndarray
    barrier_to_upright_m: np.ndarray
    barrier_to_not_upright_m: np.ndarray
    upright: np.ndarray
    com_m: np.ndarray
    mass_kg: float
    #: the lowest COM height (m) of any upright / not-upright resting pose: the lowest the COM of a body whose
    #: outcome is decided that way can go (below it only by the ground's sinking), so an energy height E bounds
    #: its speed by sqrt(2 g (E - lowest)) (the launch twin's bound on how far a decided robot can still roll)
    lowest_upright_m: float = 0.0
    lowest_not_upright_m: float = 0.0

    def lowest_m(self, upright: bool) -> float:
        """The lowest resting COM height (m) of the outcome ``upright`` (see the fields)."""
        return self.lowest_upright_m if upright else self.lowest_not_upright_m

    def highest_barrier_m(self) -> float:
        """No decision is possible at or above this energy height (m; inf if some pose is never left)."""
        return float(np.max(np.concatenate([self.barrier_to_upright_m, self.barrier_to_not_upright_m])))

    def decide(self, down_in_base: np.ndarray, energy_height_m: float) -> typing.Optional[bool]:
        """The decided outcome (True = will end upright, False = will not) or None while still open.

        ``down_in_base`` (3,) unit world-down vector in the base frame; ``energy_height_m`` = COM height above
        the ground + kinetic energy / (m g), m.
        """
        nearest = int(np.argmax(self.directions @ down_in_base))
        if energy_height_m < self.barrier_to_not_upright_m[nearest]:
            return True
        if energy_height_m < self.barrier_to_upright_m[nearest]:
            return False
        return None


def resting_directions(relative: typing.Mapping[int, np.ndarray], wheel_links: typing.Collection[int], up: np.ndarray,
                       upright_tilt_deg: float, min_wheels: int,
                       contact_tolerance_m: float) -> typing.Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every direction the body can rest in and whether it rests upright there.

    ``relative`` maps link -> hull points (k, 3) about the COM, m. A resting direction is the outward normal of
    a hull facet that the COM projects into (a triangle of the triangulated hull holding the COM's foot);
    upright: tilt within ``upright_tilt_deg`` and ``min_wheels`` wheel links within ``contact_tolerance_m`` of
    the ground. Returns ((r, 3) unit vectors, (r,) bool upright, (r,) the COM's height above the ground resting
    there, m).
    """
    trimesh = require("trimesh", feature="the early trial decision")
    hull = trimesh.convex.convex_hull(np.vstack(list(relative.values())))
    normals = hull.face_normals
    corners = hull.triangles                                       # (f, 3, 3)
    distance = np.einsum("ij,ij->i", corners[:, 0], normals)       # COM (origin) to each face plane, m
    foot = normals * distance[:, None]
    # the COM's foot inside a triangle: all three edge cross products point along the normal
    inside = np.ones(len(normals), dtype=bool)
    for k in range(3):
        edge = corners[:, (k + 1) % 3] - corners[:, k]
        inside &= np.einsum("ij,ij->i", np.cross(edge, foot - corners[:, k]), normals) >= -1e-9
    rests = normals[inside]
    if not len(rests):
        raise ValueError("the body has no resting pose (the COM lies outside its hull)")
    tilt_ok = -(rests @ up) >= math.cos(math.radians(upright_tilt_deg))
    support = {link: (points @ rests.T).max(axis=0) for link, points in relative.items()}
    height = np.max(np.vstack(list(support.values())), axis=0)
    on_wheels = sum(((height - support[link]) <= contact_tolerance_m).astype(int) for link in wheel_links
                    if link in support) if len(wheel_links) else np.zeros(len(rests), dtype=int)
    return rests, tilt_ok & (on_wheels >= min_wheels), height


@functools.lru_cache(maxsize=4)
def _lattice_graph(directions, neighbours):
    """``(lattice, near, spacing)`` of a direction lattice, shared by every basin map of that size (read-only):
    the directions (n, 3), each one's ``neighbours`` nearest others (n, neighbours) and the covering radius."""
    spatial = require("scipy.spatial", feature="the early trial decision")
    lattice = fibonacci_directions(directions)
    _, near = spatial.cKDTree(lattice).query(lattice, k=neighbours + 1)
    near = near[:, 1:]
    # covering radius: no direction is farther than this from its nearest lattice point (half the largest gap)
    spacing = float(np.linalg.norm(lattice[near[:, 0]] - lattice, axis=1).max())
    lattice.flags.writeable = False
    near.flags.writeable = False
    return lattice, near, spacing


def hull_vertices(points: np.ndarray) -> np.ndarray:
    """The vertices of the convex hull of ``points`` (k, 3): the same support function, radius and hull as all of
    them (a profile mesh's thousands of vertices cost 0.24 s of lattice products per map); all points when they
    span no volume (qhull refuses flat or tiny sets)."""
    if len(points) <= 64:
        return points
    spatial = require("scipy.spatial", feature="the early trial decision")
    try:
        return points[spatial.ConvexHull(points).vertices]
    except spatial.QhullError:
        return points


def _frozen(array: np.ndarray) -> np.ndarray:
    """A read-only copy of ``array`` (any shape; a copy: a caller's own array, such as ``com_m``, stays writeable)."""
    copy = np.array(array)
    copy.flags.writeable = False
    return copy


#: Basin maps built in this process, newest last, by a digest of every input (see :func:`build_basin_map`).
_BUILT: "collections.OrderedDict[bytes, BasinMap]" = collections.OrderedDict()
#: How many maps :data:`_BUILT` keeps (a map is ~0.2 MB; a study's launches use one per design and robot).
_BUILT_KEPT = 16


def build_basin_map(points_by_link: typing.Mapping[int, npt.ArrayLike], wheel_links: typing.Collection[int],
                    com_m: npt.ArrayLike, mass_kg: float, up_axis: npt.ArrayLike, upright_tilt_deg: float,
                    min_wheels: int, contact_tolerance_m: float, directions: int = 4096, neighbours: int = 10,
                    margin_m: float = 0.002) -> "BasinMap":
    """The :class:`BasinMap` of a rigid body: tabulated once per process for the same inputs (every launch of one
    design rebuilds the same body, and the lattice products over the hull's vertices took about 0.2 s per map),
    kept read-only (its arrays refuse writes) because the launches that got it share it.

    The parameters are :func:`tabulate_basin_map`'s (``points_by_link`` {link: (k, 3)}, ``com_m`` and ``up_axis``
    (3,), base frame, m); the key is a digest of all of them, bytes of every array included, so a body that differs
    in any input gets its own map.
    """
    digest = hashlib.blake2b(repr((sorted(int(link) for link in wheel_links), float(mass_kg),
                                   float(upright_tilt_deg), int(min_wheels), float(contact_tolerance_m),
                                   int(directions), int(neighbours), float(margin_m))).encode())
    for array in (com_m, up_axis):
        digest.update(np.ascontiguousarray(array, dtype=np.float64).tobytes())
    for link in sorted(points_by_link):
        points = np.ascontiguousarray(points_by_link[link], dtype=np.float64)
        digest.update(repr((int(link), points.shape)).encode())
        digest.update(points.tobytes())
    key = digest.digest()
    if key in _BUILT:
        _BUILT.move_to_end(key)
        return _BUILT[key]
    basins = tabulate_basin_map(points_by_link, wheel_links, com_m, mass_kg, up_axis, upright_tilt_deg, min_wheels,
                                contact_tolerance_m, directions, neighbours, margin_m)
    basins = dataclasses.replace(basins, directions=_frozen(basins.directions), upright=_frozen(basins.upright),
                                 barrier_to_upright_m=_frozen(basins.barrier_to_upright_m),
                                 barrier_to_not_upright_m=_frozen(basins.barrier_to_not_upright_m),
                                 com_m=_frozen(basins.com_m))
    _BUILT[key] = basins
    while len(_BUILT) > _BUILT_KEPT:
        _BUILT.popitem(last=False)
    return basins


def tabulate_basin_map(points_by_link: typing.Mapping[int, npt.ArrayLike], wheel_links: typing.Collection[int],
                       com_m: npt.ArrayLike, mass_kg: float, up_axis: npt.ArrayLike, upright_tilt_deg: float,
                       min_wheels: int, contact_tolerance_m: float, directions: int = 4096, neighbours: int = 10,
                       margin_m: float = 0.002) -> "BasinMap":
    """Tabulate the :class:`BasinMap` of a rigid body (every time; :func:`build_basin_map` keeps the ones built).

    Parameters
    ----------
    points_by_link : dict int -> (k, 3) float
        Points whose hull is each link's collision geometry, base frame, m (link -1 = base).
    wheel_links : sequence of int
        The links that are wheels.
    com_m : (3,) float
        Centre of mass of the whole body, base frame, m.
    mass_kg : float
    up_axis : (3,) float
        The robot's up axis in the base frame (unit vector).
    upright_tilt_deg, min_wheels, contact_tolerance_m
        The robot model's upright test (deg, count, m).
    directions, neighbours : int
        Lattice size and graph degree.
    margin_m : float
        Safety margin subtracted from every barrier, m.
    """
    com = np.asarray(com_m, dtype=np.float64)
    lattice, near, delta = _lattice_graph(directions, neighbours)
    relative = {link: hull_vertices(np.asarray(points, dtype=np.float64) - com)
                for link, points in points_by_link.items()}
    support = {link: (points @ lattice.T).max(axis=0) for link, points in relative.items()}  # (n,) per link
    height = np.max(np.vstack(list(support.values())), axis=0)
    radius = max(float(np.linalg.norm(points, axis=1).max()) for points in relative.values())
    up = np.asarray(up_axis, dtype=np.float64) / np.linalg.norm(up_axis)
    rests, rest_upright, rest_height = resting_directions(relative, wheel_links, up, upright_tilt_deg, min_wheels,
                                                          contact_tolerance_m)
    upright = np.zeros(directions, dtype=bool)
    not_upright = np.zeros(directions, dtype=bool)
    nearest = np.argmax(rests @ lattice.T, axis=1)
    upright[nearest[rest_upright]] = True
    not_upright[nearest[~rest_upright]] = True
    edges_a = np.repeat(np.arange(directions), neighbours)
    edges_b = near.ravel()
    edge_height = np.maximum(height[edges_a], height[edges_b])

    def grown(mask: np.ndarray) -> np.ndarray:
        """``mask`` (directions,) bool and its lattice neighbours."""
        return mask | mask[near].any(axis=1)

    slack = radius * delta + margin_m
    to_upright = _minimax_from(grown(upright), edges_a, edges_b, edge_height, height) - slack
    to_not_upright = _minimax_from(grown(not_upright), edges_a, edges_b, edge_height, height) - slack
    def lowest(mask: np.ndarray) -> float:
        """The lowest resting COM height (m) among the resting directions in ``mask`` (r,) bool; inf if none."""
        return float(rest_height[mask].min()) if np.any(mask) else math.inf

    return BasinMap(directions=lattice, barrier_to_upright_m=to_upright, barrier_to_not_upright_m=to_not_upright,
                    upright=upright, com_m=com, mass_kg=float(mass_kg), lowest_upright_m=lowest(rest_upright),
                    lowest_not_upright_m=lowest(~rest_upright))
