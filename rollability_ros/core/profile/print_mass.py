"""The profile's mass, centre of mass and inertia from its mesh and how it is made (``profile_print``).

An FDM print is a shell of solid walls around sparse infill. With the shell's outer solid ``O`` (the mesh) and
its inner solid ``I`` (the mesh moved inwards by the shell), material density ``rho`` and infill fraction ``f``::

    m = rho * (V_O - V_I) + rho * f * V_I = rho * V_O - rho * (1 - f) * V_I

and the centre of mass and inertia are those of ``O`` at density ``rho`` minus ``I`` at ``rho * (1 - f)``
(parallel-axis theorem about the combined centre of mass). Infill is smeared uniformly over ``I``.

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


def inner_solid(normals: np.ndarray, offsets: np.ndarray, wall_thickness_m: float, skin_thickness_m: float,
                guess_m: np.ndarray) -> typing.Optional[np.ndarray]:
    """The convex solid ``normals @ x <= offsets`` moved inwards by the shell (module docstring) as outward-wound
    triangles (k, 3, 3), or None when nothing is left inside; ``guess_m`` (3,) is tried first as its interior
    point (the outer solid's centroid)."""
    scipy_spatial = require("scipy.spatial", feature="the printed profile's mass")
    vertical = np.abs(normals[:, 2])
    shell = np.maximum(wall_thickness_m * np.sqrt(np.clip(1 - vertical ** 2, 0.0, 1.0)), skin_thickness_m * vertical)
    limits = offsets - shell
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
    return combine([(outer, rho), (_unit_solid(inner), -rho * (1 - spec.infill_fraction))]).scaled(mass_scale)
