"""The two geometric traits the paper's discussion ties to rollability, measured on a profile's hull.

* **Maximum height** ``max_height_mm`` (mm): the tallest point of the profile solid above the chassis top,
  ``max(heights) * unit_m``. Range: 0 to ``height_max * unit_m`` (0 to 90 mm on the paper's grid).
* **Sharpness** ``sharpness_deg`` (degrees): how abruptly the rolling surface turns from one facet to the next,
  measured as the length-weighted mean dihedral angle of the hull's *ridges*. A ridge is an edge between two
  facets that are not the base (the face on the chassis top) and that meet at more than
  :data:`RIDGE_MIN_ANGLE_DEG` (edges that only split a plane into triangles are not ridges). The dihedral angle
  is the angle between the two facets' outward normals: 0 for a flat continuation, 90 for a box edge. Each ridge
  weighs with its length, so one long sharp ridge counts more than a short one. Range: 0 to 180 in principle; a
  smooth dome measures about 25, a random height field 30 to 70, a box or wedge 70 to 90.

Both are pure functions of the heights and the grid (deterministic), so an optimizer can compute them for every
candidate without a simulation; they are the behaviour descriptors of the quality-diversity archive
(``core/optimization/quality_diversity.py``) and the axes of the report's map.
"""
import dataclasses
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core.profile import geometry

#: Facets meeting at this angle or less (deg) lie in one plane for the purpose of sharpness: not a ridge.
RIDGE_MIN_ANGLE_DEG = 2.0
#: A facet whose outward normal's z is below this is the base (the face lying on the chassis top).
BASE_NORMAL_Z = -0.999


@dataclasses.dataclass(frozen=True)
class ProfileDescriptors:
    """The profile's maximum height (mm) and sharpness (deg, length-weighted mean ridge angle); 0 and 0 for the
    baseline (no profile)."""

    max_height_mm: float
    sharpness_deg: float

    def as_tuple(self) -> typing.Tuple[float, float]:
        """``(max_height_mm, sharpness_deg)``, the archive's measure order."""
        return (self.max_height_mm, self.sharpness_deg)


def mesh_descriptors(mesh: typing.Optional[geometry.Mesh]) -> ProfileDescriptors:
    """Measure a profile solid (``trimesh.Trimesh`` in metres, base on z = 0; None = the baseline)."""
    if mesh is None:
        return ProfileDescriptors(0.0, 0.0)
    normals = mesh.face_normals
    pairs = mesh.face_adjacency                      # (e, 2) faces sharing an edge
    angles_deg = np.degrees(mesh.face_adjacency_angles)
    base = normals[:, 2] < BASE_NORMAL_Z
    ends = mesh.vertices[mesh.face_adjacency_edges]  # (e, 2, 3) the shared edge's end points
    lengths_m = np.linalg.norm(ends[:, 0] - ends[:, 1], axis=1)
    ridge = ~(base[pairs[:, 0]] | base[pairs[:, 1]]) & (angles_deg > RIDGE_MIN_ANGLE_DEG)
    total_m = float(lengths_m[ridge].sum())
    sharpness = float((angles_deg[ridge] * lengths_m[ridge]).sum() / total_m) if total_m > 0 else 0.0
    return ProfileDescriptors(max_height_mm=float(mesh.bounds[1][2]) * 1000.0, sharpness_deg=sharpness)


def profile_descriptors(heights: npt.ArrayLike, grid: geometry.ProfileGrid) -> ProfileDescriptors:
    """Measure the profile of half-grid ``heights`` ``(grid.n_variables,)`` (simulation units) on ``grid``; a profile
    too flat to be a solid (within ``grid.flat_tolerance``) counts as the baseline."""
    try:
        return mesh_descriptors(geometry.profile_mesh(heights, grid))
    except ValueError:
        geometry.check_heights(heights, grid)        # invalid heights still raise; a flat profile is the baseline
        return ProfileDescriptors(0.0, 0.0)


def height_bound_mm(grid: geometry.ProfileGrid) -> float:
    """The tallest profile the grid allows, mm: the height descriptor's upper end."""
    return grid.height_max * grid.unit_m * 1000.0
