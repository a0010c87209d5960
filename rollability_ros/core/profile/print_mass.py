"""The profile's mass, centre of mass and inertia from its mesh and how it is made (``profile_print``).

An FDM print is a shell of solid walls around sparse infill. With the shell's outer solid ``O`` (the mesh) and
its inner solid ``I`` (the mesh moved inwards by the shell), material density ``rho`` and infill fraction ``f``::

    m = rho * (V_O - V_I) + rho * f * V_I = rho * V_O - rho * (1 - f) * V_I

and the centre of mass and inertia are those of ``O`` at density ``rho`` minus ``I`` at ``rho * (1 - f)``
(parallel-axis theorem about the combined centre of mass). Infill is smeared uniformly over ``I``, unless
``gradual_infill_steps`` N > 0 (Ultimaker Cura's "gradual infill": the density is ``f`` in the ``step_height`` just
under a top surface and halves with every further ``step_height`` down, N times, so most of ``I`` holds ``f / 2^N``).
Then ``I`` is at ``f / 2^N`` and each band ``k < N`` below the inner solid's top (points of ``I`` whose depth under
its top surface, straight up, is in ``[k h, (k + 1) h)``) adds ``f / 2^k - f / 2^N``; the bands' mass properties are
integrated over vertical columns of ``I`` (:func:`top_bands`, exact for a box).

The inner solid of a convex mesh is exact: the intersection of the mesh's face half-spaces, each moved inwards
by that face's shell thickness. A slicer lays walls (perimeters) of ``wall_thickness_m`` horizontally in each layer
and top/bottom skins of ``skin_thickness_m`` vertically, so a face whose unit outward normal is ``n`` gets
``max(wall * sqrt(1 - n_z^2), skin * |n_z|)`` of solid across it: ``wall`` on a vertical face, ``skin`` on the flat
base, the thicker of the two projections on a slope. When the moved half-spaces leave no room (walls thicker than
half the solid's smallest width) the print is solid.

Defaults and their sources (``docs/optimization.md``, "Profile mass"): PLA at 1240 kg/m^3 (NatureWorks Ingeo 4043D
technical data sheet: specific gravity 1.24); two 0.4 mm perimeters (0.8 mm wall), 0.8 mm top/bottom skin and 20 %
infill (Ultimaker Cura's default print settings: ``wall_thickness`` 0.8, ``top_bottom_thickness`` 0.8,
``infill_sparse_density`` 20). ``model: solid`` is the explicit alternative for a profile that is one uniform
material throughout (cut foam, cast rubber): its mass is ``solid_density_kgpm3`` times the mesh volume.

trimesh and scipy are imported inside the functions that need them.
"""
import dataclasses
import typing

import numpy as np

from rollability_ros.core import config
from rollability_ros.core.optional import require
from rollability_ros.core.profile.geometry import Mesh

#: ``profile_print.model`` values: a printed shell with infill, or one uniform solid material.
PRINT_MODELS = ("shell", "solid")

#: A shell's inner solid thinner than this (m, the largest sphere it holds) is no inner solid: the print is solid.
MIN_INNER_RADIUS_M = 1e-7


@dataclasses.dataclass
class ProfilePrintSpec:
    """How the profile is made (``robot.profile_print`` / ``urdf_robot.profile_print``; module docstring).

    ``model: shell`` (default): an FDM print, walls ``wall_thickness_m``, top/bottom skin ``skin_thickness_m``,
    sparse infill ``infill_fraction`` of ``material_density_kgpm3``. ``model: solid``: one uniform material of
    ``solid_density_kgpm3`` (e.g. an EPS foam block); that density is refused with ``model: shell`` and required
    with ``model: solid``, so a setting is never silently ignored.
    """

    model: str = dataclasses.field(default="shell", metadata={
        "description": "how the profile is made: shell (an FDM print: solid walls and skins around sparse infill) or "
                       "solid (one uniform material throughout, e.g. cut foam; uses solid_density_kgpm3)"})
    material_density_kgpm3: float = dataclasses.field(default=1240.0, metadata={
        "description": "density of the printed material, kg/m^3 (PLA 1240: NatureWorks Ingeo 4043D data sheet; PETG "
                       "about 1270, ABS about 1040)", "range": (0.0, 100000.0), "exclusive": "low"})
    wall_thickness_m: float = dataclasses.field(default=0.0008, metadata={
        "description": "solid wall (perimeters) across the side faces, horizontal, m (0.8 mm: Cura's default "
                       "wall_thickness, two 0.4 mm lines)", "range": (0.0, 1.0), "exclusive": "low"})
    skin_thickness_m: float = dataclasses.field(default=0.0008, metadata={
        "description": "solid top and bottom skin, vertical, m (0.8 mm: Cura's default top_bottom_thickness)",
        "range": (0.0, 1.0), "exclusive": "low"})
    infill_fraction: float = dataclasses.field(default=0.2, metadata={
        "description": "sparse infill inside the shell as a fraction of solid (0 = hollow, 1 = solid; 0.2: Cura's "
                       "default infill_sparse_density 20 %)", "range": (0.0, 1.0)})
    gradual_infill_steps: int = dataclasses.field(default=0, metadata={
        "description": "times the infill density halves going down from under a top surface (Cura's "
                       "gradual_infill_steps; 0 = uniform infill, Cura's default)", "range": (0, 10)})
    gradual_infill_step_height_m: float = dataclasses.field(default=0.0015, metadata={
        "description": "height of each density step of gradual infill, m (1.5 mm: Cura's default "
                       "gradual_infill_step_height)", "range": (0.0, 1.0), "exclusive": "low"})
    solid_density_kgpm3: float = dataclasses.field(default=0.0, metadata={
        "description": "density of a solid profile (model: solid only; 0 = unset), kg/m^3, e.g. EPS foam about 20",
        "range": (0.0, 100000.0)})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable or inconsistent field."""
        if self.model not in PRINT_MODELS:
            raise ValueError(f"profile_print.model must be one of {', '.join(PRINT_MODELS)}, got {self.model!r}")
        if self.model == "solid":
            if not self.solid_density_kgpm3 > 0:
                raise ValueError("profile_print.model: solid needs profile_print.solid_density_kgpm3 > 0, got "
                                 f"{self.solid_density_kgpm3}")
            return
        if self.solid_density_kgpm3 != 0:
            raise ValueError(f"profile_print.solid_density_kgpm3 ({self.solid_density_kgpm3}) is only used with "
                             "profile_print.model: solid; the shell model weighs the print from material_density_kgpm3, "
                             "wall_thickness_m, skin_thickness_m and infill_fraction (set model: solid, or remove it)")


@dataclasses.dataclass(frozen=True)
class MassProperties:
    """A body's mass (kg), centre of mass ``com_m`` (3,) and inertia ``inertia_kgm2`` (3, 3) about that centre, in
    the mesh's frame (m, kg m^2)."""

    mass_kg: float
    com_m: np.ndarray
    inertia_kgm2: np.ndarray

    def scaled(self, factor: float) -> "MassProperties":
        """The same body with mass and inertia times ``factor`` (the centre of mass unchanged)."""
        return MassProperties(self.mass_kg * factor, self.com_m, self.inertia_kgm2 * factor)


def _unit_solid(triangles: np.ndarray) -> MassProperties:
    """Mass properties of the closed, outward-wound ``triangles`` (k, 3, 3) as a solid of density 1 (mass = volume,
    m^3)."""
    trimesh = require("trimesh", feature="profile meshes")
    properties = trimesh.triangles.mass_properties(triangles, density=1.0)
    return MassProperties(float(properties["volume"]), np.asarray(properties["center_mass"], dtype=np.float64),
                          np.asarray(properties["inertia"], dtype=np.float64))


def combine(parts: typing.Sequence[typing.Tuple[MassProperties, float]]) -> MassProperties:
    """The union of ``(unit-density solid, density)`` parts (a negative density subtracts a part): mass, centre of
    mass, and inertia about it by the parallel-axis theorem."""
    mass = sum(part.mass_kg * density for part, density in parts)
    if not mass > 0:
        raise ValueError(f"the parts weigh {mass} kg: nothing to build a body from")
    com = np.sum([part.com_m * part.mass_kg * density for part, density in parts], axis=0) / mass
    inertia = np.zeros((3, 3))
    for part, density in parts:
        offset = part.com_m - com
        inertia += density * (part.inertia_kgm2 + part.mass_kg * (offset @ offset * np.eye(3) - np.outer(offset, offset)))
    return MassProperties(float(mass), com, inertia)


def check_solid_mesh(mesh: Mesh) -> None:
    """Raise ``ValueError`` unless ``mesh`` is a closed, consistently wound solid of positive, finite volume."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if len(mesh.faces) < 4 or not np.all(np.isfinite(vertices)):
        raise ValueError(f"the profile mesh is degenerate ({len(mesh.faces)} faces, finite vertices: "
                         f"{bool(np.all(np.isfinite(vertices)))}): it has no mass to compute")
    if not mesh.is_watertight:
        raise ValueError("the profile mesh is not watertight (it has open edges): its volume, mass and inertia are "
                         "undefined; repair it or export it closed")
    if not mesh.is_winding_consistent or not mesh.volume > 0:
        raise ValueError(f"the profile mesh encloses no positive volume ({mesh.volume:g} m^3; faces inconsistently "
                         "wound or inside out): its mass is undefined")


def face_planes(mesh: Mesh) -> typing.Tuple[np.ndarray, np.ndarray]:
    """The distinct planes of ``mesh``'s faces of non-zero area: unit outward normals (p, 3) and offsets (p,) m, so
    that the solid is ``normals @ x <= offsets`` when it is convex."""
    triangles = np.asarray(mesh.triangles, dtype=np.float64)
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    length = np.linalg.norm(normals, axis=1)
    keep = length > 1e-12 * max(1.0, float(np.ptp(triangles.reshape(-1, 3), axis=0).max()) ** 2)
    normals = normals[keep] / length[keep, None]
    offsets = np.einsum("ij,ij->i", normals, triangles[keep].mean(axis=1))
    planes = np.unique(np.round(np.column_stack([normals, offsets]), 12), axis=0)
    return planes[:, :3] / np.linalg.norm(planes[:, :3], axis=1, keepdims=True), planes[:, 3]


def is_convex(mesh: Mesh, normals: np.ndarray, offsets: np.ndarray) -> bool:
    """True when every vertex of the closed, outward-wound ``mesh`` lies inside every face plane ``normals`` (F, 3)
    . x <= ``offsets`` (F,) (to 1e-6 of its size): the mesh is convex."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    tolerance = 1e-6 * float(np.ptp(vertices, axis=0).max())
    return bool((vertices @ normals.T - offsets).max() <= tolerance)


def shell_limits(normals: np.ndarray, offsets: np.ndarray, wall_thickness_m: float,
                 skin_thickness_m: float) -> np.ndarray:
    """The offsets (p,) of the face planes moved inwards by the shell (module docstring): the inner solid is
    ``normals @ x <= shell_limits(...)``."""
    vertical = np.abs(normals[:, 2])
    return offsets - np.maximum(wall_thickness_m * np.sqrt(np.clip(1 - vertical ** 2, 0.0, 1.0)),
                                skin_thickness_m * vertical)


def inner_solid(normals: np.ndarray, offsets: np.ndarray, wall_thickness_m: float, skin_thickness_m: float,
                guess_m: np.ndarray) -> typing.Optional[np.ndarray]:
    """The convex solid ``normals @ x <= offsets`` moved inwards by the shell (module docstring) as outward-wound
    triangles (k, 3, 3), or None when nothing is left inside; ``guess_m`` (3,) is tried first as its interior
    point (the outer solid's centroid)."""
    scipy_spatial = require("scipy.spatial", feature="the printed profile's mass")
    limits = shell_limits(normals, offsets, wall_thickness_m, skin_thickness_m)
    inside = np.asarray(guess_m, dtype=np.float64)
    if not (limits - normals @ inside).min() > MIN_INNER_RADIUS_M * 10:
        # Chebyshev centre: the largest ball inside every moved half-space n.x <= limit (maximise its radius r)
        scipy_optimize = require("scipy.optimize", feature="the printed profile's mass")
        found = scipy_optimize.linprog(c=[0.0, 0.0, 0.0, -1.0], A_ub=np.column_stack([normals, np.ones(len(normals))]),
                                       b_ub=limits, bounds=[(None, None)] * 3 + [(0.0, None)], method="highs")
        if found.status != 0 or found.x[3] <= MIN_INNER_RADIUS_M:
            return None
        inside = found.x[:3]
    corners = scipy_spatial.HalfspaceIntersection(np.column_stack([normals, -limits]), inside).intersections
    hull = scipy_spatial.ConvexHull(corners)
    triangles = corners[hull.simplices]
    outward = np.einsum("ij,ij->i", np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]),
                        triangles[:, 0] - inside)
    triangles[outward < 0] = triangles[outward < 0][:, ::-1]
    return triangles if hull.volume > 0 else None


#: Columns across the inner solid's footprint for the gradual-infill bands (:func:`top_bands`): about this many.
BAND_COLUMNS = 40000


def top_bands(normals: np.ndarray, limits: np.ndarray, corners: np.ndarray, step_m: float,
              steps: int) -> typing.List[MassProperties]:
    """Unit-density mass properties of the ``steps`` bands under the top of the convex solid ``normals @ x <=
    limits`` (corners ``corners`` (k, 3)): band ``k`` holds the points whose depth under the solid's top surface,
    straight up, is in ``[k step_m, (k + 1) step_m)``. Integrated over vertical columns on a grid of about
    :data:`BAND_COLUMNS` cells across the footprint, exactly in z; a band that is empty gets zero mass."""
    low, high = corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)
    cell = max(float(np.sqrt(np.prod(high - low) / BAND_COLUMNS)), 1e-9)
    counts = np.maximum(np.ceil((high - low) / cell).astype(int), 1)
    size = (high - low) / counts
    x, y = np.meshgrid(*(low[i] + (np.arange(counts[i]) + 0.5) * size[i] for i in range(2)), indexing="ij")
    x, y = x.ravel(), y.ravel()
    reach = limits[None, :] - x[:, None] * normals[None, :, 0] - y[:, None] * normals[None, :, 1]   # n_z z <= reach
    n_z = normals[:, 2]
    up, down, flat = n_z > 1e-9, n_z < -1e-9, np.abs(n_z) <= 1e-9
    top = (reach[:, up] / n_z[up]).min(axis=1) if up.any() else np.full(len(x), np.inf)
    bottom = (reach[:, down] / n_z[down]).max(axis=1) if down.any() else np.full(len(x), -np.inf)
    inside = (reach[:, flat] >= 0).all(axis=1) & (top > bottom) & np.isfinite(top) & np.isfinite(bottom)
    x, y, top, bottom = x[inside], y[inside], top[inside], bottom[inside]
    area = float(size[0] * size[1])
    bands = []
    for k in range(steps):
        z1 = top - k * step_m
        z0 = np.maximum(bottom, top - (k + 1) * step_m)
        length = np.clip(z1 - z0, 0.0, None)
        z0 = np.minimum(z0, z1)
        volume = area * float(length.sum())
        if not volume > 0:
            bands.append(MassProperties(0.0, np.zeros(3), np.zeros((3, 3))))
            continue
        # integrals over each column: of 1, x, y, z, x^2, y^2, z^2, xy, xz, yz (the cell's own spread in x, y added)
        s_z, s_zz = (z1 ** 2 - z0 ** 2) / 2, (z1 ** 3 - z0 ** 3) / 3
        com = area * np.array([(x * length).sum(), (y * length).sum(), s_z.sum()]) / volume
        xx = area * ((x ** 2 + size[0] ** 2 / 12) * length).sum()
        yy = area * ((y ** 2 + size[1] ** 2 / 12) * length).sum()
        zz, xy = area * s_zz.sum(), area * (x * y * length).sum()
        xz, yz = area * (x * s_z).sum(), area * (y * s_z).sum()
        second = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) - volume * np.outer(com, com)   # about com
        bands.append(MassProperties(volume, com, np.trace(second) * np.eye(3) - second))
    return bands


def print_mass_properties(mesh: Mesh, spec: ProfilePrintSpec, mass_scale: float = 1.0) -> MassProperties:
    """Mass, centre of mass and inertia of ``mesh`` (a watertight trimesh, metres) made as ``spec`` says (a
    :class:`ProfilePrintSpec`), mass and inertia times ``mass_scale`` (the unknown ``profile_mass_scale``).

    ``ValueError`` for an unusable spec or mesh (degenerate, not watertight, no volume; a non-convex mesh under the
    shell model, whose inward offset is not computed here).
    """
    config.check_settings(spec, "profile_print")
    if not mass_scale > 0:
        raise ValueError(f"profile_mass_scale must be > 0, got {mass_scale}")
    check_solid_mesh(mesh)
    outer = _unit_solid(np.asarray(mesh.triangles, dtype=np.float64))
    if spec.model == "solid":
        return combine([(outer, spec.solid_density_kgpm3)]).scaled(mass_scale)
    normals, offsets = face_planes(mesh)
    if not is_convex(mesh, normals, offsets):
        raise ValueError("profile_print.model: shell needs a convex profile mesh (the designs are convex hulls); for "
                         "another solid use profile_print.model: solid with its effective density")
    rho = spec.material_density_kgpm3
    inner = inner_solid(normals, offsets, spec.wall_thickness_m, spec.skin_thickness_m, outer.com_m)
    if inner is None or spec.infill_fraction >= 1:
        return combine([(outer, rho)]).scaled(mass_scale)
    steps, fill = spec.gradual_infill_steps, spec.infill_fraction
    lowest = fill / 2 ** steps
    parts = [(outer, rho), (_unit_solid(inner), -rho * (1 - lowest))]
    if steps and fill > 0:
        limits = shell_limits(normals, offsets, spec.wall_thickness_m, spec.skin_thickness_m)
        bands = top_bands(normals, limits, inner.reshape(-1, 3), spec.gradual_infill_step_height_m, steps)
        parts += [(band, rho * (fill / 2 ** k - lowest)) for k, band in enumerate(bands) if band.mass_kg > 0]
    return combine(parts).scaled(mass_scale)
