"""Profile geometry: half-grid vertex heights -> mirrored vertices -> convex-hull mesh, metrics, printability.

Frames and units
----------------
Profile frame = the chassis top-surface frame: x along the length (``length_m``), y along the width
(``width_m``), z up, origin at the centre of the top surface. Heights are design variables in *simulation
units* within ``[height_min, height_max]``; ``unit_m`` converts them to metres (paper 2.1.1 bounds the heights to
[0, 0.45] "simulation units" without stating the scale, so the scale is an explicit parameter here).

Grid layout
-----------
The full profile has ``rows`` x ``2 * cols`` vertices evenly spaced over the footprint, x from ``-length/2`` to
``+length/2`` and y from ``-width/2`` to ``+width/2`` (so no vertex lies on y = 0 and the mirror never
duplicates one). The design variables are the ``cols`` columns with y > 0, row-major: ``heights[i * cols + j]``
is the vertex at x index ``i`` and y index ``j`` (``j = 0`` next to the centre line, ``j = cols - 1`` at the
edge y = +width/2). The mirror about the x-z plane gives the y < 0 half.

The mesh is the convex hull of the 200 top vertices and the four footprint corners at z = 0, so it always sits
on the chassis top and covers the whole footprint. A top vertex lower than :data:`BASE_SNAP_M` is put on the
base plane first: an outer vertex a few nanometres above its footprint corner (CMA-ES proposes such heights next
to the lower bound) would otherwise be merged with the corner and leave the hull open. trimesh is imported
inside the functions that need it.
"""
import dataclasses
import os
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core import config
from rollability_ros.core.optional import require

if typing.TYPE_CHECKING:   # annotations only: trimesh is imported where used
    import trimesh

#: Top vertices lower than this (m) lie on the base plane in the mesh: far below print and simulation resolution,
#: far above trimesh's vertex-merge tolerance (1e-8 m).
BASE_SNAP_M = 1e-6

#: A ``trimesh.Trimesh`` in metres. trimesh is imported where used (core/optional.py); annotations name it by this
#: alias, which type checkers resolve to trimesh's own (typed) class.
Mesh: "typing.TypeAlias" = "trimesh.Trimesh"


@dataclasses.dataclass
class ProfileGrid:
    """The design grid: its size, its footprint in metres and its height bounds in simulation units.

    ``unit_m`` (metres per simulation unit) = 0.2: the paper's upper bound 0.45 becomes a 0.09 m tall profile,
    half the chassis length. That bound does not make the default chassis's inverted pose unstable: at 0.09 m a
    dome, a flat top, a centre ridge and random shapes each keep resting poses off their wheels (upside down or
    on a side), and what the profile changes is the barrier back onto the wheels (the centre-of-mass lift from the
    worst such rest), under half the bare chassis's for those three shapes (stable-pose screen, see
    test_stable_poses). Righting at this bound therefore takes the energy of the fall. ``flat_tolerance`` (simulation units): a profile whose tallest vertex is at or below it is
    treated as the baseline (no profile) by the evaluator, because a hull thinner than that is not a solid.
    """

    rows: int = dataclasses.field(default=10, metadata={
        "description": "grid vertices along the footprint length (count; paper 10)", "range": (2, 1000)})
    cols: int = dataclasses.field(default=10, metadata={
        "description": "grid vertices across the y > 0 half of the footprint (count; paper 10)", "range": (1, 1000)})
    length_m: float = dataclasses.field(default=0.18, metadata={
        "description": "footprint length along the chassis x axis that the profile covers, m",
        "range": (0.0, 100.0), "exclusive": "low"})
    width_m: float = dataclasses.field(default=0.14, metadata={
        "description": "footprint width along the chassis y axis that the profile covers, m",
        "range": (0.0, 100.0), "exclusive": "low"})
    height_min: float = dataclasses.field(default=0.0, metadata={
        "description": "lower bound of every vertex height, simulation units (paper 0)", "range": (0.0, 1000.0)})
    height_max: float = dataclasses.field(default=0.45, metadata={
        "description": "upper bound of every vertex height, simulation units (paper 0.45)", "range": (0.0, 1000.0)})
    unit_m: float = dataclasses.field(default=0.2, metadata={
        "description": "metres per simulation unit of vertex height, m (0.2: height 0.45 = 0.09 m)",
        "range": (0.0, 100.0), "exclusive": "low"})
    flat_tolerance: float = dataclasses.field(default=0.001, metadata={
        "description": "a profile whose tallest vertex is at or below this counts as the baseline (no profile), "
                       "simulation units", "range": (0.0, 100.0)})

    @property
    def n_variables(self) -> int:
        """Number of design variables (half-grid vertices)."""
        return self.rows * self.cols

    def validate(self) -> None:
        """Raise ``ValueError`` for a rule that spans fields (each number's range is declared in its metadata and
        checked by :func:`~rollability_ros.core.config.check_settings`)."""
        if not self.height_min < self.height_max:
            raise ValueError(f"need height_min < height_max, got [{self.height_min}, {self.height_max}]")
        if not self.flat_tolerance < self.height_max:
            raise ValueError(f"flat_tolerance must be below height_max {self.height_max}, got {self.flat_tolerance}")


@dataclasses.dataclass(frozen=True)
class ProfileMetrics:
    """Measured size of a profile solid (metres, profile frame); all zero for the baseline.

    ``com_shift_m`` (3,) is the centroid of the solid (uniform density) in the profile frame. The printed
    profile's own centre of mass is :func:`~rollability_ros.core.profile.print_mass.print_mass_properties`'s,
    which differs from the centroid as the print differs from a solid (it equals it for a solid or a fully
    infilled print).
    """

    length_m: float
    width_m: float
    max_height_m: float
    volume_m3: float
    com_shift_m: np.ndarray


@dataclasses.dataclass
class PrinterSpec:
    """An FDM printer's limits (``config/robot.yaml``, section ``printer``)."""

    bed_x_m: float = dataclasses.field(default=0.22, metadata={
        "description": "build plate size along the printer's x axis, m; a profile footprint must fit (turned 90 deg "
                       "allowed)", "range": (0.0, 10.0), "exclusive": "low"})
    bed_y_m: float = dataclasses.field(default=0.22, metadata={
        "description": "build plate size along the printer's y axis, m", "range": (0.0, 10.0), "exclusive": "low"})
    bed_z_m: float = dataclasses.field(default=0.25, metadata={
        "description": "largest printable part height, m; the tallest profile must fit",
        "range": (0.0, 10.0), "exclusive": "low"})
    nozzle_m: float = dataclasses.field(default=0.0004, metadata={
        "description": "nozzle diameter = one extrusion width, m; the minimum wall cannot be thinner",
        "range": (0.0, 0.1), "exclusive": "low"})
    min_wall_m: float = dataclasses.field(default=0.0008, metadata={
        "description": "thinnest solid width the printer makes reliably (e.g. two perimeters), m",
        "range": (0.0, 1.0), "exclusive": "low"})
    max_overhang_deg: float = dataclasses.field(default=45.0, metadata={
        "description": "steepest downward face printable without support, measured from vertical, deg",
        "range": (0.0, 90.0)})

    def validate(self) -> None:
        """Raise ``ValueError`` for a rule that spans fields (each number's range is declared in its metadata and
        checked by :func:`~rollability_ros.core.config.check_settings`)."""
        if self.min_wall_m < self.nozzle_m:
            raise ValueError(f"printer.min_wall_m {self.min_wall_m * 1000:.2f} mm is thinner than one extrusion of "
                             f"the printer.nozzle_m {self.nozzle_m * 1000:.2f} mm nozzle")


@dataclasses.dataclass(frozen=True)
class PrintabilityReport:
    """Result of :func:`check_printability`: verdict, the problems found, and the measured values.

    ``extents_m`` (3,) is the bounding box printed base-down; ``min_wall_m`` the thinnest width of the solid
    (smallest extent over the face-normal directions, exact for a convex solid); ``max_overhang_deg`` the
    steepest downward-facing face measured from vertical (0 = wall, 90 = ceiling), the bed face excluded.
    """

    printable: bool
    problems: typing.List[str]
    extents_m: np.ndarray
    min_wall_m: float
    max_overhang_deg: float


def check_heights(heights: npt.ArrayLike, grid: ProfileGrid) -> np.ndarray:
    """Return ``heights`` as a ``(grid.n_variables,)`` float64 array, or raise ``ValueError`` naming the problem.

    Checks, in order: one-dimensional, length ``rows * cols``, finite (NaN / inf named with their indices),
    within ``[height_min, height_max]`` (simulation units; the first offending index is named). No clamping:
    callers that want a clamp (an optimizer's bound handling) clamp before calling.
    """
    array = np.asarray(heights, dtype=np.float64)
    if array.ndim != 1:
        raise ValueError(f"heights must be a flat list of {grid.n_variables} numbers, got shape {array.shape}")
    if array.size != grid.n_variables:
        raise ValueError(f"heights has {array.size} values, the {grid.rows}x{grid.cols} grid needs {grid.n_variables}")
    bad = np.flatnonzero(~np.isfinite(array))
    if bad.size:
        raise ValueError(f"heights must be finite: NaN or inf at index {', '.join(map(str, bad[:5]))}")
    outside = np.flatnonzero((array < grid.height_min) | (array > grid.height_max))
    if outside.size:
        i = outside[0]
        raise ValueError(f"heights[{i}] = {array[i]} is outside [{grid.height_min}, {grid.height_max}] "
                         f"({outside.size} value(s) out of bounds)")
    return array


def is_baseline(heights: typing.Optional[npt.ArrayLike], tolerance: float = 0.0) -> bool:
    """True for the "no profile" configuration: ``heights`` ``(n,)`` is ``None``, empty, or every height is at most
    ``tolerance`` (simulation units)."""
    if heights is None:
        return True
    array = np.asarray(heights, dtype=np.float64).ravel()
    return array.size == 0 or bool(np.all(array <= tolerance))


def grid_xy(grid: ProfileGrid) -> np.ndarray:
    """Return the half-grid vertex positions ``(rows*cols, 2)`` in metres (x, y > 0), row-major."""
    xs = np.linspace(-grid.length_m / 2, grid.length_m / 2, grid.rows)
    ys = np.linspace(-grid.width_m / 2, grid.width_m / 2, 2 * grid.cols)[grid.cols:]
    xx, yy = np.meshgrid(xs, ys, indexing="ij")
    return np.column_stack([xx.ravel(), yy.ravel()])


#: Peak heights of :func:`simple_profiles` as fractions of the height bound: 0.2, 0.32 and 0.45 simulation units at the
#: paper's bound of 0.45 (bench/bench_shape_ceiling.py's family).
SIMPLE_PROFILE_HEIGHTS = (0.2 / 0.45, 0.32 / 0.45, 1.0)
#: Taper factors of :func:`simple_profiles` along the length (``a``) and across the width (``b``).
SIMPLE_PROFILE_TAPERS = (0.0, 0.5, 1.0)


def simple_profiles(grid: ProfileGrid) -> typing.Dict[str, np.ndarray]:
    """``{name: heights (grid.n_variables,)}``: the 27 simple parametric profiles
    ``h(x, y) = height_min + H (1 - a |x| / (L/2)) (1 - b |y| / (W/2))`` with ``H`` each of
    :data:`SIMPLE_PROFILE_HEIGHTS` times the height range and ``a``, ``b`` each of :data:`SIMPLE_PROFILE_TAPERS`:
    flat tops (a = b = 0), ridges across or along (one of them 0) and pyramids, named ``"H 0.32 a 1.0 b 0.5"`` by
    ``H`` in simulation units above ``height_min``. Simulation units, within the grid's bounds."""
    xy = grid_xy(grid)
    along, across = np.abs(xy[:, 0]) / (grid.length_m / 2), np.abs(xy[:, 1]) / (grid.width_m / 2)
    span = grid.height_max - grid.height_min
    family = {}
    for fraction in SIMPLE_PROFILE_HEIGHTS:
        for a in SIMPLE_PROFILE_TAPERS:
            for b in SIMPLE_PROFILE_TAPERS:
                peak = fraction * span
                heights = grid.height_min + peak * (1 - a * along) * (1 - b * across)
                family[f"H {peak:.2f} a {a:.1f} b {b:.1f}"] = np.clip(heights, grid.height_min, grid.height_max)
    return family


def profile_vertices(heights: npt.ArrayLike, grid: ProfileGrid) -> np.ndarray:
    """Return the mirrored top-surface vertices ``(2*rows*cols, 3)`` in metres, profile frame.

    The first ``rows*cols`` rows are the half grid (y > 0) in design-variable order, the next ``rows*cols``
    their mirror images (y -> -y) in the same order.
    """
    z = check_heights(heights, grid) * grid.unit_m
    half = np.column_stack([grid_xy(grid), z])
    mirror = half * np.array([1.0, -1.0, 1.0])
    return np.vstack([half, mirror])


def profile_mesh(heights: typing.Optional[npt.ArrayLike], grid: ProfileGrid) -> typing.Optional[Mesh]:
    """Return the profile solid of ``heights`` ``(grid.n_variables,)`` (simulation units) as a watertight convex-hull
    ``trimesh.Trimesh`` (metres), or None for the baseline.

    The hull spans the top vertices and the footprint corners at z = 0. Raises ``ValueError`` for invalid
    heights and for a profile so flat (tallest vertex within ``grid.flat_tolerance``) that it has no volume.
    """
    if heights is None or is_baseline(heights):
        return None
    top = profile_vertices(heights, grid)
    if top[:, 2].max() <= grid.flat_tolerance * grid.unit_m:
        raise ValueError(f"profile is flat: tallest vertex {top[:, 2].max() / grid.unit_m:.3g} units is within "
                         f"flat_tolerance {grid.flat_tolerance}; use the baseline instead")
    top[top[:, 2] < BASE_SNAP_M, 2] = 0.0
    half_l, half_w = grid.length_m / 2, grid.width_m / 2
    corners = np.array([[sx * half_l, sy * half_w, 0.0] for sx in (-1, 1) for sy in (-1, 1)])
    return _hull(np.vstack([top, corners]))


def _hull(points):
    """Convex hull of ``points`` (k, 3) as a watertight, outward-wound trimesh."""
    trimesh = require("trimesh", feature="profile meshes")
    mesh = trimesh.convex.convex_hull(points)
    if not mesh.is_watertight or mesh.volume <= 0:
        raise ValueError("convex hull of the profile is degenerate (no volume)")
    return mesh


def profile_metrics(heights: typing.Optional[npt.ArrayLike], grid: ProfileGrid) -> ProfileMetrics:
    """Measure the profile of ``heights`` ``(grid.n_variables,)`` (simulation units): see :class:`ProfileMetrics`
    (zeros for the baseline)."""
    return mesh_metrics(profile_mesh(heights, grid))


def mesh_metrics(mesh: typing.Optional[Mesh]) -> ProfileMetrics:
    """Measure a profile solid in the profile frame: see :class:`ProfileMetrics`; None -> all zeros."""
    if mesh is None:
        return ProfileMetrics(0.0, 0.0, 0.0, 0.0, np.zeros(3))
    extents = mesh.bounds[1] - mesh.bounds[0]
    return ProfileMetrics(length_m=float(extents[0]), width_m=float(extents[1]), max_height_m=float(mesh.bounds[1][2]),
                          volume_m3=float(mesh.volume), com_shift_m=np.asarray(mesh.center_mass, dtype=np.float64))


def design_space_printability(grid: ProfileGrid, printer: PrinterSpec) -> typing.List[str]:
    """Problems that make every profile of ``grid`` unprintable on ``printer``, found before optimizing; [] if none.

    Every profile covers the whole ``length_m`` x ``width_m`` footprint (metres), so a footprint larger than the
    bed (turning it 90 degrees about z allowed) rules out every design; a grid spacing or a tallest allowed
    profile below one nozzle width (``nozzle_m``) cannot be printed either. Each message names the limit and the
    configuration key to change.
    """
    config.check_settings(printer, "printer")
    problems: typing.List[str] = []
    length, width = grid.length_m, grid.width_m
    if not ((length <= printer.bed_x_m and width <= printer.bed_y_m)
            or (width <= printer.bed_x_m and length <= printer.bed_y_m)):
        problems.append(f"the profile footprint {length * 1000:.0f} x {width * 1000:.0f} mm does not fit the "
                        f"printer bed {printer.bed_x_m * 1000:.0f} x {printer.bed_y_m * 1000:.0f} mm "
                        f"(printer.bed_x_m / printer.bed_y_m): no design could be printed")
    tallest = grid.height_max * grid.unit_m
    if tallest < printer.nozzle_m:
        problems.append(f"the tallest allowed profile {tallest * 1000:.2f} mm (profile.height_max x unit_m) is "
                        f"below one nozzle width {printer.nozzle_m * 1000:.2f} mm (printer.nozzle_m)")
    spacing = min(length / max(grid.rows - 1, 1), width / max(2 * grid.cols - 1, 1))
    if spacing < printer.nozzle_m:
        problems.append(f"the grid spacing {spacing * 1000:.2f} mm is below the nozzle width "
                        f"{printer.nozzle_m * 1000:.2f} mm (printer.nozzle_m): reduce profile.rows / profile.cols")
    return problems


def check_printability(mesh: Mesh, printer: PrinterSpec) -> PrintabilityReport:
    """Check that ``mesh`` (metres, printed base-down on its z-min face) fits ``printer`` (a :class:`PrinterSpec`).

    Returns a :class:`PrintabilityReport`; ``problems`` names each failed check with its measured value.
    The bed check allows the part to be turned 90 degrees about z.
    """
    vertices = np.asarray(mesh.vertices)
    extents = vertices.max(axis=0) - vertices.min(axis=0)
    problems: typing.List[str] = []
    fits_flat = extents[0] <= printer.bed_x_m and extents[1] <= printer.bed_y_m
    fits_turned = extents[1] <= printer.bed_x_m and extents[0] <= printer.bed_y_m
    if not (fits_flat or fits_turned):
        problems.append(f"footprint {extents[0] * 1000:.0f} x {extents[1] * 1000:.0f} mm does not fit the printer "
                        f"bed {printer.bed_x_m * 1000:.0f} x {printer.bed_y_m * 1000:.0f} mm "
                        f"(printer.bed_x_m / bed_y_m)")
    if extents[2] > printer.bed_z_m:
        problems.append(f"height {extents[2] * 1000:.0f} mm exceeds the printer's build height "
                        f"{printer.bed_z_m * 1000:.0f} mm (printer.bed_z_m)")
    normals = np.asarray(mesh.face_normals)
    projections = vertices @ normals.T                       # (vertices, faces)
    min_wall = float((projections.max(axis=0) - projections.min(axis=0)).min())
    if min_wall < printer.min_wall_m:
        problems.append(f"thinnest width {min_wall * 1000:.2f} mm is below the minimum wall "
                        f"{printer.min_wall_m * 1000:.2f} mm (printer.min_wall_m)")
    face_z = np.asarray(mesh.triangles_center)[:, 2]
    on_bed = face_z <= vertices[:, 2].min() + 1e-6
    downward = (normals[:, 2] < -1e-9) & ~on_bed
    max_overhang = float(np.degrees(np.arcsin(np.clip(-normals[downward, 2], 0, 1))).max()) if downward.any() else 0.0
    if max_overhang > printer.max_overhang_deg:
        problems.append(f"overhang {max_overhang:.1f} deg exceeds {printer.max_overhang_deg:.1f} deg "
                        f"(printer.max_overhang_deg)")
    return PrintabilityReport(printable=not problems, problems=problems, extents_m=extents, min_wall_m=min_wall,
                              max_overhang_deg=max_overhang)


MESH_FORMATS = (".stl", ".obj", ".3mf")

#: Length units a mesh file can be written in, with metres per unit. Slicers (Cura, PrusaSlicer, Bambu Studio)
#: read STL and OBJ as millimetres, so files are written in millimetres unless metres are asked for.
MESH_UNITS = {"mm": 0.001, "m": 1.0}

#: Start of the 80-byte binary STL header written by :func:`export_mesh`; the units follow it (``units=mm``).
STL_HEADER_PREFIX = b"rollability_ros profile mesh; units="


def _mesh_format(path):
    extension = os.path.splitext(os.fspath(path))[1].lower()
    if extension not in MESH_FORMATS:
        raise ValueError(f"mesh file {path} must end in {', '.join(MESH_FORMATS)}")
    return extension[1:]


def _check_units(units):
    if units not in MESH_UNITS:
        raise ValueError(f"mesh units must be one of {', '.join(MESH_UNITS)}, got {units!r}")
    return units


def stl_header(units: str) -> bytes:
    """The 80-byte binary STL header naming ``units`` ('mm' or 'm'); it never starts with ``solid`` (ASCII STL)."""
    text = STL_HEADER_PREFIX + _check_units(units).encode("ascii") + b"; frame: base on z=0, x length, y width"
    return text[:80].ljust(80, b" ")


def export_mesh(mesh: Mesh, path: typing.Union[str, os.PathLike], units: str = "mm") -> None:
    """Write ``mesh`` (metres) to ``path`` in ``units`` ('mm', the slicers' convention, or 'm').

    Format by extension: binary STL (units in its 80-byte header, see :func:`stl_header`), OBJ (units in a
    ``# units:`` comment) or 3MF (trimesh writes the 3MF ``unit`` attribute, always millimetres, so a 3MF file is
    millimetres whatever ``units`` says). Written to a temp file then renamed.
    """
    file_type = _mesh_format(path)
    units = "mm" if file_type == "3mf" else _check_units(units)
    scaled = mesh.copy()
    scaled.apply_scale(1.0 / MESH_UNITS[units])
    if file_type == "stl":
        payload = stl_header(units) + typing.cast(bytes, scaled.export(file_type="stl"))[80:]
    elif file_type == "obj":
        payload = f"# units: {units}\n".encode("ascii") + typing.cast(str, scaled.export(file_type="obj")).encode("utf-8")
    else:
        require("lxml", feature="3MF export")
        payload = typing.cast(bytes, scaled.export(file_type="3mf"))
    temporary = f"{os.fspath(path)}.tmp"
    with open(temporary, "wb") as stream:
        stream.write(payload)
    os.replace(temporary, path)


def mesh_file_units(path: typing.Union[str, os.PathLike]) -> typing.Optional[str]:
    """The units a mesh file declares: 'mm' or 'm' from our STL header or OBJ comment, 'mm' for 3MF, else None."""
    file_type = _mesh_format(path)
    if file_type == "3mf":
        return "mm"
    with open(path, "rb") as stream:
        head = stream.read(80)
    if file_type == "stl" and head.startswith(STL_HEADER_PREFIX):
        declared = head[len(STL_HEADER_PREFIX):].split(b";")[0].strip().decode("ascii", "replace")
        return declared if declared in MESH_UNITS else None
    if file_type == "obj" and head.startswith(b"# units:"):
        declared = head[len(b"# units:"):].split(b"\n")[0].strip().decode("ascii", "replace")
        return declared if declared in MESH_UNITS else None
    return None


def load_profile_mesh(path: typing.Union[str, os.PathLike], max_size_m: float = 1.0, base_tolerance_m: float = 0.001,
                      units: typing.Optional[str] = None) -> Mesh:
    """Load a profile solid from STL/OBJ/3MF into metres, profile frame (base on z = 0).

    ``units`` ('mm' or 'm') is the file's length unit; None takes the one the file declares (our STL header,
    OBJ comment, 3MF) and metres for a file that declares none. Raises ``FileNotFoundError`` for a missing file
    and ``ValueError`` for an unreadable, non-watertight or empty mesh, one larger than ``max_size_m`` (the
    message suggests the units), or one whose base is not on z = 0 within ``base_tolerance_m``. The simulation
    collides with the mesh's convex hull.
    """
    trimesh = require("trimesh", feature="profile meshes")
    file_type = _mesh_format(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"mesh file not found: {path}")
    declared = mesh_file_units(path)
    if units is not None:
        _check_units(units)
    chosen_units = units or declared or "m"
    if file_type == "3mf":
        require("lxml", feature="3MF import")
    try:
        mesh = trimesh.load(path, file_type=file_type, force="mesh", process=True)
    except Exception as exc:  # trimesh raises assorted parser errors
        raise ValueError(f"cannot read mesh {path}: {exc}") from exc
    if len(mesh.faces) == 0 or not np.all(np.isfinite(mesh.vertices)):
        raise ValueError(f"mesh {path} has no faces or non-finite vertices")
    mesh.apply_scale(MESH_UNITS[chosen_units])
    if not mesh.is_watertight:
        raise ValueError(f"mesh {path} is not watertight (a closed solid is needed)")
    if mesh.volume <= 0:
        raise ValueError(f"mesh {path} encloses no volume (inverted or flat faces)")
    size = float(np.max(mesh.extents))
    if size > max_size_m:
        hint = " (the file declares no units; pass units='mm' / --stl-units mm if it is in millimetres)" \
            if declared is None and units is None else ""
        raise ValueError(f"mesh {path} is {size:.3g} m across read as {chosen_units} (> {max_size_m} m): "
                         f"units must be metres or millimetres as declared{hint}")
    if abs(mesh.bounds[0][2]) > base_tolerance_m:
        raise ValueError(f"mesh {path} base is at z = {mesh.bounds[0][2]:.4f} m; the profile frame puts it at 0")
    return mesh


def marker_points(mesh: Mesh) -> np.ndarray:
    """Return ``(3*faces, 3)`` float64 points, three per triangle: a ``visualization_msgs/Marker`` TRIANGLE_LIST."""
    return np.asarray(mesh.vertices, dtype=np.float64)[np.asarray(mesh.faces)].reshape(-1, 3)

