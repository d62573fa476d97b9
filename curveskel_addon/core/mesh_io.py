"""Reading mesh files (.obj .ply .stl .off) into arrays, for the command line and tests.

trimesh is imported lazily: inside Blender the meshes come from bpy, and trimesh is not bundled.
"""

from __future__ import annotations

import re
import struct
from pathlib import Path

import numpy as np

from .errors import CurveSkelError

__all__ = ["read_mesh", "MESH_SUFFIXES"]

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off")


def read_mesh(path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of a mesh file, vertices in the file's own order.

    Parameters
    ----------
    path : str or Path
        A .obj, .ply, .stl or .off file. Polygons are triangulated; several objects in one file
        are concatenated (each becomes a component of the skeleton).

    Returns
    -------
    V : (n, 3) float64
    F : (m, 3) int64

    Raises
    ------
    CurveSkelError
        Missing file, unsupported suffix, or a file the reader cannot parse.
    """
    path = Path(path)
    if path.is_dir():
        raise CurveSkelError(f"{path} is a directory, not a mesh file")
    if not path.is_file():
        raise CurveSkelError(f"no such mesh file: {path}")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise CurveSkelError(f"unsupported mesh format {path.suffix!r}: use one of {', '.join(MESH_SUFFIXES)}")
    try:
        if path.suffix.lower() == ".stl":
            _check_stl(path)
        elif path.suffix.lower() == ".obj":
            _check_obj(path)
    except OSError as exc:
        raise CurveSkelError(f"cannot read {path}: {exc.strerror or exc}") from exc
    try:
        import trimesh
    except ImportError as exc:  # pragma: no cover - trimesh is pinned in requirements.txt
        raise CurveSkelError("reading mesh files needs trimesh (pip install -r requirements.txt)") from exc
    try:
        # process=False and maintain_order=True keep the file's vertices and their order
        # (no merging, no splitting at texture seams): the JSON mapping is per input vertex.
        loaded = trimesh.load(str(path), process=False, force="mesh", maintain_order=True)
    except Exception as exc:  # trimesh raises many types for malformed files
        raise CurveSkelError(f"cannot read {path.name}: {exc}") from exc
    V = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    F = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64)
    if V.size == 0:
        raise CurveSkelError(f"{path.name} contains no vertices")
    return V.reshape(-1, 3), F.reshape(-1, 3)


def _check_stl(path: Path) -> None:
    """Say what is wrong with a file that is neither a complete binary STL nor ASCII STL (the
    reader's own errors for such files are unrelated, e.g. about a text-encoding module)."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(4096)
    if size >= 84:
        count = struct.unpack("<I", head[80:84])[0]
        if size == 84 + 50 * count:
            if count == 0:
                raise CurveSkelError(f"{path.name} is a binary STL with no triangles")
            return                                                  # a complete binary STL
    text = head.lstrip()
    if text[:5].lower() == b"solid":
        try:
            text.decode("ascii")
        except UnicodeDecodeError:
            pass
        else:
            if size < 84 or b"facet" in head or size > len(head):
                return                                              # ASCII STL
    if size < 84:
        raise CurveSkelError(f"{path.name} is not an STL file: {size} bytes, too short for a binary "
                             "STL (an 84-byte header) and not ASCII STL (which starts with 'solid')")
    expected = 84 + 50 * count
    how = "truncated" if size < expected else "longer than that"
    raise CurveSkelError(
        f"{path.name} is not a valid STL file: as binary STL its header announces {count} triangles "
        f"({expected} bytes) but the file has {size} bytes ({how}), and it is not ASCII STL "
        "(which starts with 'solid')")


#: A face line with a vertex index 0 (OBJ indices start at 1; 0 is not a valid index).
_OBJ_ZERO_INDEX = re.compile(rb"(?m)^[ \t]*f[ \t]+(?:[^\n]*?[ \t])?0(?=[/ \t\r\n]|$)")


def _check_obj(path: Path) -> None:
    """Refuse an OBJ file with vertex index 0: OBJ counts from 1, so the file was written with
    0-based indices and would be read with every face shifted by one vertex."""
    with open(path, "rb") as fh:
        data = fh.read()
    m = _OBJ_ZERO_INDEX.search(data)
    if m is not None:
        line = data.count(b"\n", 0, m.start()) + 1
        raise CurveSkelError(
            f"{path.name} line {line}: face uses vertex index 0, but OBJ indices start at 1; the "
            "file looks 0-based (written by a tool that forgot the +1): add 1 to every face index")
