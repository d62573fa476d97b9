"""Reading mesh files (.obj .ply .stl .off) into arrays, for the command line and tests.

trimesh is imported lazily: inside Blender the meshes come from bpy, and trimesh is not bundled.
"""

from __future__ import annotations

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
    if not path.is_file():
        raise CurveSkelError(f"no such mesh file: {path}")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise CurveSkelError(f"unsupported mesh format {path.suffix!r}: use one of {', '.join(MESH_SUFFIXES)}")
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
