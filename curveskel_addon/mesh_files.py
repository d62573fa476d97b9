"""Reading mesh files (.obj .ply .stl .off) into arrays, for the command line and tests.

Every vertex of the file is kept, in the file's order, used by a face or not: the skeleton's
mapping has one entry per file vertex. OBJ and OFF are read here (so an error names its line);
PLY and STL through trimesh, imported lazily (inside Blender the meshes come from bpy, and
trimesh is not bundled). Every error is one :class:`CurveSkelError` line naming the file.
"""

from __future__ import annotations

import re
import struct
from pathlib import Path

import numpy as np

from .core.errors import CurveSkelError
from .core.mesh_input import triangulate

__all__ = ["read_mesh", "MESH_SUFFIXES"]

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off")


def read_mesh(path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and polygons of a mesh file, vertices in the file's own order.

    Parameters
    ----------
    path : str or Path
        A .obj, .ply, .stl or .off file. Several objects in one file are concatenated (each
        becomes a component of the skeleton).

    Returns
    -------
    V : (n, 3) float64
        Every vertex of the file (STL: one per triangle corner), unused ones included.
    F : (m, 3) int64
        Triangles; polygons are split (quads as trimesh splits them, others fanned).

    Raises
    ------
    CurveSkelError
        Missing file, unsupported suffix, or a file that cannot be parsed (naming the file,
        and the line for OBJ and OFF).
    """
    path = Path(path)
    if path.is_dir():
        raise CurveSkelError(f"{path} is a directory, not a mesh file")
    if not path.is_file():
        raise CurveSkelError(f"no such mesh file: {path}")
    kind = path.suffix.lower()
    if kind not in MESH_SUFFIXES:
        raise CurveSkelError(f"unsupported mesh format {path.suffix!r}: use one of {', '.join(MESH_SUFFIXES)}")
    try:
        if kind in (".obj", ".off"):
            data = path.read_bytes()
            _check_text(path, data)
            V, F = (_read_obj if kind == ".obj" else _read_off)(path, data)
        else:
            if kind == ".stl":
                _check_stl(path)
            V, F = _read_trimesh(path)
    except OSError as exc:
        raise CurveSkelError(f"cannot read {path}: {exc.strerror or exc}") from exc
    if len(V) == 0:
        raise CurveSkelError(f"{path.name} contains no vertices")
    return V, F


def _read_trimesh(path: Path):
    try:
        import trimesh
    except ImportError as exc:  # pragma: no cover - trimesh is pinned in requirements.txt
        raise CurveSkelError("reading mesh files needs trimesh (pip install -r requirements.txt)") from exc
    try:
        # process=False and maintain_order=True keep the file's vertices and their order
        # (no merging, no splitting at texture seams): the JSON mapping is per input vertex.
        loaded = trimesh.load(str(path), process=False, force="mesh", maintain_order=True)
    except Exception as exc:  # trimesh raises many types for malformed files
        why = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise CurveSkelError(f"cannot read {path.name}: {why}") from exc
    V = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    F = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64)
    return V.reshape(-1, 3), F.reshape(-1, 3)


#: Control bytes that never occur in a text mesh file (tab, newlines, form feed, CR allowed).
_BINARY = re.compile(rb"[\x00-\x08\x0e-\x1f\x7f]")


def _check_text(path: Path, data: bytes) -> None:
    """Refuse a file that is not text (binary garbage, a binary OFF): say where it starts."""
    m = _BINARY.search(data)
    if m is not None:
        line = data.count(b"\n", 0, m.start()) + 1
        raise CurveSkelError(f"{path.name} line {line}: binary data (byte 0x{data[m.start()]:02x}), "
                             f"not a text {path.suffix.lower()[1:].upper()} file")


def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")


def _fail(path: Path, line: int, what: str):
    raise CurveSkelError(f"{path.name} line {line}: {what}")


def _floats(path, rows, numbers, width):
    """(len(rows), width) floats: the first ``width`` numbers of each row (byte strings);
    ``numbers[k]`` is row k's line number, for the error."""
    split = [r.split() for r in rows]
    if split and all(len(s) == width for s in split):
        try:
            return np.array([x for s in split for x in s], dtype=np.float64).reshape(-1, width)
        except ValueError:
            pass                                            # find the bad line below
    out = np.empty((len(rows), width))
    for k, s in enumerate(split):
        if len(s) < width:
            _fail(path, numbers[k], f"expected {width} coordinates, found {len(s)}")
        try:
            out[k] = [float(x) for x in s[:width]]
        except ValueError:
            bad = next(x for x in s[:width] if not _is_float(x))
            _fail(path, numbers[k], f"{bad.decode('latin-1')!r} is not a number")
    return out


def _is_float(x: bytes) -> bool:
    try:
        float(x)
        return True
    except ValueError:
        return False


def _triangles(P) -> np.ndarray:
    """(m, 3) int64 triangles of polygons ((m, k) array, or a list of index lists). Quads are
    split as trimesh split them, (0, 1, 2) then (2, 3, 0), every first half before every second
    (the triangles this module gave before it read OBJ itself); other polygons are fanned."""

    if isinstance(P, list):
        if not P:
            return np.zeros((0, 3), np.int64)
        if len({len(r) for r in P}) == 1:
            P = np.asarray(P, dtype=np.int64)
    if isinstance(P, np.ndarray) and P.ndim == 2 and P.shape[1] == 4:
        return np.vstack([P[:, [0, 1, 2]], P[:, [2, 3, 0]]])
    return triangulate(P)


# -- OBJ --------------------------------------------------------------------------------------------
#: The rest of each ``v`` line and of each ``f`` line (not vt, vn, ...).
_V_ROWS = re.compile(rb"(?m)^[ \t]*v[ \t]+([^\n]*)")
_F_ROWS = re.compile(rb"(?m)^[ \t]*f[ \t]+([^\n]*)")


def _read_obj(path: Path, data: bytes):
    """Wavefront OBJ: ``v`` lines (x y z, extra numbers such as w or a colour ignored) and ``f``
    lines of 1-based (or negative, relative) indices, each corner ``v``, ``v/vt``, ``v//vn`` or
    ``v/vt/vn`` (mixed freely). Other statements (vt, vn, o, g, usemtl, l, ...) are skipped.

    The usual file (rows of one width, positive indices) is read at once; any other goes line
    by line, which also says where an error is."""
    V = _obj_vertices_fast(_V_ROWS.findall(data))
    if V is not None:
        F = _obj_faces_fast(_F_ROWS.findall(data), len(V))
        if F is not None:
            return V, _triangles(F)
    return _read_obj_lines(path, data)


def _obj_vertices_fast(rows: list[bytes]):
    """(n, 3) vertices when every ``v`` row has the same count (>= 3) of numbers, else None."""
    if not rows:
        return np.zeros((0, 3))
    lens = set(map(len, map(bytes.split, rows)))
    if len(lens) != 1 or min(lens) < 3:
        return None
    try:
        return np.array(b" ".join(rows).split(), dtype=np.float64).reshape(len(rows), -1)[:, :3].copy()
    except ValueError:
        return None


def _read_obj_lines(path: Path, data: bytes):
    """:func:`_read_obj` line by line (negative indices, uneven rows, and every error)."""
    vrows, vlines = [], []
    frows, flines, fbase = [], [], []
    for no, ln in enumerate(_lines(data), 1):
        s = ln.strip()
        if len(s) < 2 or s[0] not in (0x76, 0x66) or s[1] not in (0x20, 0x09):   # "v " / "f "
            continue
        if s[0] == 0x76:
            vrows.append(s[2:])
            vlines.append(no)
        else:
            frows.append(s[2:])
            flines.append(no)
            fbase.append(len(vrows))
    V = _floats(path, vrows, vlines, 3) if vrows else np.zeros((0, 3))
    n = len(V)
    faces = []
    for rest, no, base in zip(frows, flines, fbase):
        corners = rest.split()
        if len(corners) < 3:
            _fail(path, no, f"a face needs at least 3 vertices, found {len(corners)}")
        face = []
        for c in corners:
            head = c.split(b"/", 1)[0]
            try:
                k = int(head)
            except ValueError:
                _fail(path, no, f"{c.decode('latin-1')!r} is not a vertex index")
            if k == 0:
                _fail(path, no, "face uses vertex index 0, but OBJ indices start at 1; the file "
                                "looks 0-based (written by a tool that forgot the +1): add 1 to "
                                "every face index")
            k = k - 1 if k > 0 else base + k           # negative: counted back from this line
            if not 0 <= k < n:
                _fail(path, no, f"face uses vertex {head.decode('latin-1')}, but the file has "
                                f"{n} vertices" + (f" ({base} before this line)" if k < 0 else ""))
            face.append(k)
        faces.append(face)
    return V, _triangles(faces)


def _obj_faces_fast(rows: list[bytes], n: int):
    """(m, k) faces when every face has k corners given by positive in-range indices (the
    usual file), read at once; None otherwise (the line-by-line reader then says what is wrong)."""
    if not rows:
        return np.zeros((0, 3), np.int64)
    block = b"\n".join(rows)
    if b"/" in block:
        block = _CORNER_TAIL.sub(b"", block)          # "12/3/4", "12//4", "12/3" -> "12"
    lens = set(map(len, map(bytes.split, block.split(b"\n"))))
    if len(lens) != 1 or min(lens) < 3:
        return None
    try:
        F = np.array(block.split(), dtype=np.int64).reshape(len(rows), -1)
    except ValueError:
        return None
    if F.min() < 1 or F.max() > n:
        return None
    return F - 1


#: The texture and normal indices of an OBJ face corner.
_CORNER_TAIL = re.compile(rb"/[^\s]*")

#: A face line with a vertex index 0 (OBJ indices start at 1; 0 is not a valid index).
_OBJ_ZERO_INDEX = re.compile(rb"(?m)^[ \t]*f[ \t]+(?:[^\n]*?[ \t])?0(?=[/ \t\r\n]|$)")


# -- OFF --------------------------------------------------------------------------------------------
_OFF_HEADER = re.compile(rb"^(ST)?(C)?(N)?(4)?(n)?OFF$")


def _read_off(path: Path, data: bytes):
    """Object File Format: ``OFF`` (or ``COFF``, ``NOFF`` ...), the counts ``nv nf ne``, nv
    vertex lines and nf face lines ``k i_1 .. i_k`` (0-based; a colour after them is ignored).
    ``#`` starts a comment."""
    items = []                                  # (line number, content) of non-empty lines
    for no, ln in enumerate(_lines(data), 1):
        s = ln.split(b"#", 1)[0].strip()
        if s:
            items.append((no, s))
    if not items:
        raise CurveSkelError(f"{path.name} contains no vertices")
    no, first = items[0]
    head = first.split()
    m = _OFF_HEADER.match(head[0])
    if m is not None:
        if m.group(4) or m.group(5):
            _fail(path, no, f"{head[0].decode()} (4D or n-dimensional OFF) is not supported")
        if len(head) > 1 and head[1].upper() == b"BINARY":
            _fail(path, no, "binary OFF is not supported: save it as text OFF")
        extra = m.group(1), m.group(2), m.group(3)
        rest = head[1:]
        items = items[1:]
        if not rest:
            if not items:
                raise CurveSkelError(f"{path.name} contains no vertices")
            no, counts_line = items[0]
            rest = counts_line.split()
            items = items[1:]
    else:
        extra = (None, None, None)
        rest = head
        items = items[1:]
    try:
        nv, nf = int(rest[0]), int(rest[1])
        if nv < 0 or nf < 0:
            raise ValueError
    except (ValueError, IndexError):
        _fail(path, no, "expected the counts 'vertices faces edges' after the OFF header, found "
                        f"{b' '.join(rest).decode('latin-1')!r}")
    if len(items) < nv:
        raise CurveSkelError(f"{path.name}: the header announces {nv} vertices, the file has "
                             f"{len(items)} lines after it (truncated?)")
    vitems = items[:nv]
    V = _floats(path, [s for _, s in vitems], [k for k, _ in vitems], 3) if nv else np.zeros((0, 3))
    fitems = items[nv:nv + nf]
    if len(fitems) < nf:
        raise CurveSkelError(f"{path.name}: the header announces {nf} faces, the file has "
                             f"{len(fitems)} (truncated?)")
    faces = []
    for no, s in fitems:
        tok = s.split()
        try:
            k = int(tok[0])
            idx = [int(x) for x in tok[1:k + 1]]
        except ValueError:
            _fail(path, no, f"expected 'k i_1 .. i_k' (integers), found {s.decode('latin-1')!r}")
        if k < 3:
            _fail(path, no, f"a face needs at least 3 vertices, found {k}")
        if len(idx) < k:
            _fail(path, no, f"the face announces {k} vertices but lists {len(idx)}")
        bad = [i for i in idx if not 0 <= i < nv]
        if bad:
            _fail(path, no, f"face uses vertex {bad[0]}, but the file has {nv} vertices "
                            "(OFF indices start at 0)")
        faces.append(idx)
    return V, _triangles(faces)


# -- STL --------------------------------------------------------------------------------------------
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
