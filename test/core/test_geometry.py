"""Profile geometry against known answers: analytic volumes, mirror symmetry, watertightness, bad inputs."""
import math

import numpy as np
import pytest

from rollability_ros.core.profile.geometry import (PrinterSpec, ProfileGrid, check_heights, check_printability, export_mesh,
                                           grid_xy, is_baseline, load_profile_mesh, marker_points, mesh_file_units, profile_mesh,
                                           profile_metrics, profile_vertices)

GRID = ProfileGrid()


def test_grid_defaults_match_the_paper():
    assert (GRID.rows, GRID.cols, GRID.n_variables) == (10, 10, 100)
    assert (GRID.length_m, GRID.width_m, GRID.height_min, GRID.height_max) == (0.18, 0.14, 0.0, 0.45)


def test_flat_top_profile_is_a_box_of_volume_length_width_height():
    heights = np.full(GRID.n_variables, 0.25)
    h_m = 0.25 * GRID.unit_m
    metrics = profile_metrics(heights, GRID)
    assert metrics.volume_m3 == pytest.approx(0.18 * 0.14 * h_m, rel=1e-9)
    assert (metrics.length_m, metrics.width_m, metrics.max_height_m) == pytest.approx((0.18, 0.14, h_m))
    np.testing.assert_allclose(metrics.com_shift_m, [0.0, 0.0, h_m / 2], atol=1e-12)


def test_wedge_volume_and_centroid_are_analytic():
    # heights rising linearly along x from 0 to h: a triangular prism, volume L*W*h/2, centroid at x = L/6
    rows = GRID.rows
    heights = np.repeat(np.linspace(0.0, 0.4, rows), GRID.cols)
    h_m = 0.4 * GRID.unit_m
    metrics = profile_metrics(heights, GRID)
    assert metrics.volume_m3 == pytest.approx(0.18 * 0.14 * h_m / 2, rel=1e-9)
    np.testing.assert_allclose(metrics.com_shift_m, [0.18 / 6, 0.0, h_m / 3], atol=1e-9)


def test_vertices_are_mirrored_about_the_xz_plane_with_no_duplicates():
    rng = np.random.default_rng(1)
    heights = rng.uniform(0, 0.45, GRID.n_variables)
    vertices = profile_vertices(heights, GRID)
    n = GRID.n_variables
    assert vertices.shape == (2 * n, 3)
    np.testing.assert_array_equal(vertices[n:], vertices[:n] * [1, -1, 1])
    assert np.all(vertices[:n, 1] > 0)
    assert len(np.unique(vertices[:, :2], axis=0)) == 2 * n
    # footprint spans the full profile: x and y extremes are +-length/2, +-width/2
    assert vertices[:, 0].min() == pytest.approx(-0.09) and vertices[:, 1].max() == pytest.approx(0.07)
    # design-variable order: row-major, column 0 next to the centre line
    np.testing.assert_allclose(grid_xy(GRID)[GRID.cols - 1], [-0.09, 0.07])
    np.testing.assert_allclose(vertices[:n, 2], heights * GRID.unit_m)


def test_random_profile_mesh_is_watertight_symmetric_and_contains_its_vertices():
    rng = np.random.default_rng(2)
    heights = rng.uniform(0, 0.45, GRID.n_variables)
    mesh = profile_mesh(heights, GRID)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    assert mesh.bounds[0][2] == pytest.approx(0.0)
    # every vertex is inside or on the hull: behind every face plane
    offsets = (profile_vertices(heights, GRID)[:, None, :] - mesh.triangles[None, :, 0, :])
    assert np.einsum("vfk,fk->vf", offsets, mesh.face_normals).max() < 1e-9
    assert profile_metrics(heights, GRID).com_shift_m[1] == pytest.approx(0.0, abs=1e-12)


def test_heights_a_hair_above_the_base_still_make_a_closed_mesh():
    """CMA-ES puts heights a few nanometres above the lower bound; at an outer vertex that is nearly the footprint
    corner below it (a real optimization run died on 3.7e-9 units). Fuzz such heights on random profiles."""
    grid = ProfileGrid(rows=4, cols=4, unit_m=0.2)
    corner = np.r_[0.4453, 0.2439, 0.3875, 3.67e-9, 0.2813, 0.2197, 0.3382, 0.105, 0.377, 0.2279, 0.4013, 0.1581,
                   0.1637, 0.4178, 0.4483, 0.1604]                      # the run's candidate, rounded
    meshes = [profile_mesh(corner, grid)]
    rng = np.random.default_rng(1)
    for _ in range(300):
        heights = rng.uniform(0, 0.45, grid.n_variables)
        tiny = rng.choice(grid.n_variables, rng.integers(1, 8), replace=False)
        heights[tiny] = 10.0 ** rng.uniform(-12, -2, tiny.size) / grid.unit_m
        meshes.append(profile_mesh(heights, grid))
    assert all(mesh.is_watertight and mesh.volume > 0 for mesh in meshes)


@pytest.mark.parametrize("bad, message", [
    (np.full(99, 0.1), "needs 100"),
    (np.full((10, 10), 0.1), "flat list"),
    (np.r_[np.full(99, 0.1), np.nan], "NaN or inf at index 99"),
    (np.r_[np.inf, np.full(99, 0.1)], "NaN or inf at index 0"),
    (np.r_[np.full(99, 0.1), 0.46], r"heights\[99\] = 0.46 is outside"),
    (np.r_[-0.01, np.full(99, 0.1)], r"heights\[0\] = -0.01 is outside"),
])
def test_bad_heights_are_refused_with_a_reason(bad, message):
    with pytest.raises(ValueError, match=message):
        check_heights(bad, GRID)
    with pytest.raises(ValueError, match=message):
        profile_mesh(bad, GRID)


def test_baseline_is_explicit():
    assert is_baseline(None) and is_baseline([]) and is_baseline(np.zeros(100))
    assert not is_baseline(np.r_[np.zeros(99), 0.1])
    assert is_baseline(np.full(100, 1e-4), tolerance=GRID.flat_tolerance)
    assert profile_mesh(np.zeros(100), GRID) is None
    assert profile_metrics(None, GRID).volume_m3 == 0.0
    with pytest.raises(ValueError, match="flat"):
        profile_mesh(np.full(100, 1e-4), GRID)


def test_printability_checks_bed_wall_and_overhang(tmp_path):
    tall = profile_mesh(np.full(100, 0.45), GRID)
    report = check_printability(tall, PrinterSpec())
    assert report.printable and report.problems == []
    assert report.min_wall_m == pytest.approx(0.45 * GRID.unit_m)
    small_bed = check_printability(tall, PrinterSpec(bed_x_m=0.15, bed_y_m=0.15))
    assert not small_bed.printable and "bed" in small_bed.problems[0]
    thin = check_printability(profile_mesh(np.full(100, 0.002), GRID), PrinterSpec())
    assert not thin.printable and "minimum wall" in thin.problems[0]
    assert thin.min_wall_m == pytest.approx(0.002 * GRID.unit_m)
    # upside down, the flat-top box has its top face on the bed: no overhang
    flipped = tall.copy()
    flipped.apply_transform(np.diag([1.0, -1.0, -1.0, 1.0]))
    assert check_printability(flipped, PrinterSpec()).max_overhang_deg == pytest.approx(0.0)
    # an upside-down wedge: its sloped face hangs at atan(length / height) from vertical
    wedge = profile_mesh(np.repeat(np.linspace(0.45, 0.0, GRID.rows), GRID.cols), GRID)
    wedge.apply_transform(np.diag([1.0, -1.0, -1.0, 1.0]))
    report = check_printability(wedge, PrinterSpec())
    assert report.max_overhang_deg == pytest.approx(math.degrees(math.atan2(0.18, 0.45 * GRID.unit_m)))
    assert not report.printable and "overhang" in report.problems[0]


@pytest.mark.parametrize("extension,units", [(".stl", "mm"), (".stl", "m"), (".obj", "mm"), (".obj", "m"),
                                             (".3mf", "mm")])
def test_export_and_load_round_trip(tmp_path, extension, units):
    rng = np.random.default_rng(3)
    mesh = profile_mesh(rng.uniform(0.05, 0.45, GRID.n_variables), GRID)
    path = tmp_path / f"profile{extension}"
    export_mesh(mesh, path, units)
    assert mesh_file_units(str(path)) == units
    loaded = load_profile_mesh(str(path))
    assert loaded.volume == pytest.approx(mesh.volume, rel=1e-5)
    np.testing.assert_allclose(loaded.bounds, mesh.bounds, atol=1e-6)


def test_stl_is_written_in_millimetres_with_the_unit_in_its_header(tmp_path):
    """What a slicer reads: the raw binary STL coordinates (no trimesh on the reading side)."""
    mesh = profile_mesh(np.full(GRID.n_variables, 0.3), GRID)   # 180 x 140 x 60 mm
    export_mesh(mesh, tmp_path / "a.stl")
    raw = (tmp_path / "a.stl").read_bytes()
    assert raw[:80].startswith(b"rollability_ros profile mesh; units=mm") and not raw.startswith(b"solid")
    count = int(np.frombuffer(raw[80:84], dtype="<u4")[0])
    records = np.frombuffer(raw[84:], dtype=np.dtype([("normal", "<f4", 3), ("vertices", "<f4", (3, 3)),
                                                      ("attribute", "<u2")]), count=count)
    points = records["vertices"].reshape(-1, 3)
    np.testing.assert_allclose(points.max(axis=0) - points.min(axis=0), [180.0, 140.0, 60.0], atol=1e-3)
    export_mesh(mesh, tmp_path / "m.stl", units="m")
    assert (tmp_path / "m.stl").read_bytes()[:80].startswith(b"rollability_ros profile mesh; units=m;")
    with pytest.raises(ValueError, match="mesh units"):
        export_mesh(mesh, tmp_path / "x.stl", units="inch")
    # a CAD file without our header, in millimetres: refused with the hint, read with units="mm"
    cad = mesh.copy()
    cad.apply_scale(1000.0)
    cad.export(str(tmp_path / "cad.stl"))
    with pytest.raises(ValueError, match="declares no units; pass units='mm'"):
        load_profile_mesh(str(tmp_path / "cad.stl"))
    assert load_profile_mesh(str(tmp_path / "cad.stl"), units="mm").volume == pytest.approx(mesh.volume, rel=1e-5)


def test_load_refuses_bad_meshes(tmp_path):
    mesh = profile_mesh(np.full(100, 0.3), GRID)
    with pytest.raises(ValueError, match="must end in"):
        export_mesh(mesh, tmp_path / "profile.ply")
    with pytest.raises(FileNotFoundError):
        load_profile_mesh(str(tmp_path / "missing.stl"))
    open_mesh = mesh.copy()
    open_mesh.update_faces(np.arange(len(mesh.faces)) > 0)
    export_mesh(open_mesh, tmp_path / "open.stl")
    with pytest.raises(ValueError, match="not watertight"):
        load_profile_mesh(str(tmp_path / "open.stl"))
    millimetres = mesh.copy()
    millimetres.apply_scale(1000.0)
    export_mesh(millimetres, tmp_path / "mm.stl", units="m")
    with pytest.raises(ValueError, match="units must be metres"):
        load_profile_mesh(str(tmp_path / "mm.stl"))
    lifted = mesh.copy()
    lifted.apply_translation([0, 0, 0.01])
    export_mesh(lifted, tmp_path / "lifted.stl")
    with pytest.raises(ValueError, match="base is at z"):
        load_profile_mesh(str(tmp_path / "lifted.stl"))


def test_marker_points_are_a_triangle_list():
    mesh = profile_mesh(np.full(100, 0.3), GRID)
    points = marker_points(mesh)
    assert points.shape == (3 * len(mesh.faces), 3) and points.dtype == np.float64
    first = points[:3]
    normal = np.cross(first[1] - first[0], first[2] - first[0])
    np.testing.assert_allclose(normal / np.linalg.norm(normal), mesh.face_normals[0], atol=1e-9)
