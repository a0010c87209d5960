"""A robot description's mesh files in the forms both engines read: an ASCII STL becomes a binary STL.

PyBullet's URDF loader reads only binary STL (an ASCII one is dropped with a warning and the link simulated without
its shape) and MuJoCo refuses ASCII STL; many upstream descriptions ship ASCII STL. :func:`binary_stl_file` reads
one with trimesh's ASCII STL parser (plain text to numbers: nothing in the file is executed) and writes the same
triangles as a binary STL into the converted-mesh cache, named by the SHA-256 of the ASCII file's bytes, so both
engines, and the collision hull the checks read, load one file with the geometry, scale and units a binary STL of
the same mesh has (float32 coordinates, as any binary STL). A converted file is written once (temp file + rename,
so concurrent workers never read half a file) and reused while the ASCII file's content is unchanged.

The cache folder is ``$XDG_CACHE_HOME/rollability/meshes`` (else ``~/.cache/rollability/meshes``).
"""
import hashlib
import io
import os
import tempfile
import warnings

import numpy as np

#: Largest ASCII STL converted, bytes. trimesh parsed a 98 MB one (327,680 triangles, 299 bytes each) in 8.4 s
#: with a 0.9 GB peak (a 2-core machine under load); 64 MiB (about 225,000 triangles) keeps a conversion within
#: about 5 s and 0.6 GB. A larger mesh is refused with the fix: save it as a binary STL (a sixth of the size) or
#: decimate it (the engines collide with its convex hull only).
ASCII_STL_MAX_BYTES = 64 * 2 ** 20


def is_ascii_stl(path: str) -> bool:
    """True for an STL file in the ASCII format: not the size a binary STL's triangle count gives (84 bytes of
    header and count, 50 a triangle), and starting with ``solid`` (a binary header may start so too)."""
    if not path.lower().endswith(".stl"):
        return False
    try:
        with open(path, "rb") as stream:
            head = stream.read(84)
        size = os.path.getsize(path)
    except OSError:
        return False   # the mesh's reader names the file
    binary = len(head) == 84 and size == 84 + 50 * int.from_bytes(head[80:84], "little")
    return not binary and head.lstrip().startswith(b"solid")


def mesh_cache_folder() -> str:
    """The converted-mesh cache: ``$XDG_CACHE_HOME/rollability/meshes``, else ``~/.cache/rollability/meshes``."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "rollability", "meshes")


def _ascii_triangles(data: bytes, path: str, where: str) -> np.ndarray:
    """The triangles ``(n, 3, 3)`` of ASCII STL ``data`` (the file's units); ``ValueError`` in one line naming
    ``where`` and ``path`` for text that is not a whole ASCII STL (trimesh's parser stops quietly at the first
    word that is not a number: a facet count that disagrees with the triangles read is refused), no triangle, or
    a coordinate that is not a finite number."""
    from rollability_ros.core.optional import require

    stl = require("trimesh.exchange.stl", feature="ASCII STL collision meshes")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")   # numpy's "string or file could not be read to its end": garbage
            loaded = stl.load_stl_ascii(io.BytesIO(data))
        triangles = (np.asarray(loaded["vertices"], dtype=np.float64)[np.asarray(loaded["faces"])]
                     if "vertices" in loaded else np.zeros((0, 3, 3)))   # no solid held a vertex
    except Exception as exc:  # trimesh and numpy raise assorted errors on text that is no STL
        raise ValueError(f"{where}: cannot read ASCII STL {path}: {' '.join(str(exc).split()) or type(exc).__name__}"
                         ) from exc
    facets = data.lower().count(b"endfacet")
    if not len(triangles) or len(triangles) != facets:
        raise ValueError(f"{where}: ASCII STL {path} holds {facets} facet(s) but {len(triangles)} whole triangle(s) "
                         "were read: an empty, truncated or damaged file?")
    if not np.all(np.isfinite(triangles)):
        raise ValueError(f"{where}: ASCII STL {path} has a vertex that is not a finite number")
    return triangles


def _binary_stl(triangles: np.ndarray) -> bytes:
    """A binary STL of ``triangles`` ``(n, 3, 3)``: trimesh's writer (normals from the winding, float32)."""
    from rollability_ros.core.optional import require

    trimesh = require("trimesh", feature="ASCII STL collision meshes")
    mesh = trimesh.Trimesh(vertices=triangles.reshape(-1, 3), faces=np.arange(len(triangles) * 3).reshape(-1, 3),
                           process=False)
    return trimesh.exchange.stl.export_stl(mesh)


def binary_stl_file(path: str, where: str) -> str:
    """The binary STL in the cache holding the triangles of the ASCII STL ``path`` (converted on first use,
    see the module docstring). ``ValueError`` in one line naming ``where`` and ``path`` for a file that cannot be
    read, is larger than :data:`ASCII_STL_MAX_BYTES`, or is no whole ASCII STL (:func:`_ascii_triangles`), and
    for a cache folder that cannot be written."""
    try:
        size = os.path.getsize(path)
        if size > ASCII_STL_MAX_BYTES:
            raise ValueError(f"{where}: ASCII STL {path} is {size / 2 ** 20:.0f} MiB, over the "
                             f"{ASCII_STL_MAX_BYTES // 2 ** 20} MiB converted: save it as a binary STL, or decimate it")
        with open(path, "rb") as stream:
            data = stream.read(ASCII_STL_MAX_BYTES + 1)
    except OSError as exc:
        raise ValueError(f"{where}: cannot read mesh {path}: {exc.strerror or exc}") from exc
    folder = mesh_cache_folder()
    target = os.path.join(folder, f"{hashlib.sha256(data).hexdigest()}.stl")
    if os.path.isfile(target):
        return target
    converted = _binary_stl(_ascii_triangles(data, path, where))
    try:
        os.makedirs(folder, exist_ok=True)
        handle, partial = tempfile.mkstemp(dir=folder, suffix=".partial")
        with os.fdopen(handle, "wb") as stream:
            stream.write(converted)
        os.replace(partial, target)
    except OSError as exc:
        raise ValueError(f"{where}: cannot write the binary STL of {path} into the mesh cache {folder}: "
                         f"{exc.strerror or exc} (set XDG_CACHE_HOME to a writable folder)") from exc
    return target


def collision_mesh_file(path: str, where: str) -> str:
    """``path``, or for an ASCII STL its binary STL in the cache (:func:`binary_stl_file`): the file both engines
    load for a collision mesh."""
    return binary_stl_file(path, where) if is_ascii_stl(path) else path

