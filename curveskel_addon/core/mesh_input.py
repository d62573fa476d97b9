"""Checking and cleaning the input mesh before any stage runs.

Nothing here changes the caller's arrays: a cleaned copy (the "working mesh") is returned with
the map from each input vertex to its working vertex, so results come back in input order.

Every tolerance is relative to the size ``D`` of the mesh (the diagonal of the bounding box of
the vertices the faces use), never absolute, so scaling or moving a mesh cleans it the same way:

* vertices at one position are merged; where the surface has open edges (a triangle soup, a
  crack) vertices on them closer than ``_CFG.merge_tolerance * D`` are merged too;
* faces with a repeated vertex, repeated faces, and faces thinner than the merge tolerance
  (zero-area slivers) are dropped;
* face winding is made consistent across every manifold edge and each connected part is turned
  to face outwards (positive signed volume), so inverted normals do not matter;
* holes are capped (a fan from each loop of open edges to its mean), so every part has an
  inside: an open bowl becomes a half-ball;
* debris is dropped, judged per part: a part smaller than the *Detail Size* of its nearest
  neighbour (its enclosing ball's radius below ``detail`` times the neighbour's) is below the
  resolution the neighbour is skeletonized at (:func:`_debris`); equal parts never are, so
  200 equal spheres stay 200 parts. Optionally also parts with less than
  ``min_component_area`` of the total area;
* a mesh flat to within the tolerance (no volume at all) is refused.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .config import CONFIG
from .errors import CurveSkelError
from .geometry.mesh_graph import components
from .geometry.rows import col_max, col_min, next_corners, row_sumsq, rows_differ, take_rows

__all__ = ["CleanMesh", "clean_mesh", "triangulate"]

_CFG = CONFIG.input


@dataclass
class CleanMesh:
    """A triangle mesh ready for skeletonization.

    Attributes
    ----------
    V : (w, 3) float
        Working vertices: duplicate positions merged, unreferenced vertices dropped.
    F : (m, 3) int
        Triangles on V, none with a repeated index.
    work_index : (n,) int
        For each input vertex its working vertex, or -1 if no face uses it (isolated).
    info : dict
        What was repaired: merged duplicates, dropped degenerate faces, isolated vertices,
        faces turned over, small parts dropped (see :func:`clean_mesh`).
    components : (k, labels) or None
        The connected components of the working mesh, as
        :func:`.mesh_graph.components` returns them (computed here anyway).
    edge_matrix : scipy.sparse.csr_matrix or None
        The edge census of the working triangles (row a, column b > a: the sides a->b plus the
        sides b->a << 32), when no repair changed them after it (else None): see
        :meth:`edge_table`.
    """

    V: np.ndarray
    F: np.ndarray
    work_index: np.ndarray
    info: dict = field(default_factory=dict)
    components: tuple | None = None
    edge_matrix: object = None

    def edge_table(self):
        """:func:`.mesh_graph.edge_table` of (V, F) from the census (the same arrays), or None
        if the census no longer describes F."""
        A = self.edge_matrix
        if A is None:
            return None
        rows = np.repeat(np.arange(A.shape[0], dtype=np.int64), np.diff(A.indptr))
        E = np.stack([rows, A.indices.astype(np.int64)], axis=1)
        return E, ((A.data & 0xFFFFFFFF) + (A.data >> 32)).astype(np.int64)


def triangulate(faces) -> np.ndarray:
    """Fan-triangulate polygons.

    Parameters
    ----------
    faces : (m, k) int array, k >= 3, or a sequence of index sequences of any lengths >= 3

    Returns
    -------
    (p, 3) int64 triangles

    Examples
    --------
    >>> triangulate([[0, 1, 2, 3]]).tolist()
    [[0, 1, 2], [0, 2, 3]]
    """
    if isinstance(faces, np.ndarray) and faces.ndim == 2:
        polys = [faces]
    else:
        if isinstance(faces, np.ndarray) and faces.ndim != 2:
            raise CurveSkelError(f"faces must have shape (m, 3) (or be a list of index lists), "
                                 f"got an array of shape {faces.shape}")
        try:
            faces = list(faces)
        except TypeError:
            raise CurveSkelError(f"faces must be an (m, 3) array or a list of index lists, got "
                                 f"{type(faces).__name__} {faces!r}") from None
        if not faces:
            return np.zeros((0, 3), np.int64)
        by_len: dict[int, list] = {}
        for f in faces:
            if isinstance(f, (str, bytes)) or not hasattr(f, "__len__"):
                raise CurveSkelError("faces must be index lists (each face a sequence of vertex "
                                     f"indices), got a face {f!r}")
            by_len.setdefault(len(f), []).append(f)
        polys = [np.asarray(v) for v in by_len.values()]
    out = []
    for P in polys:
        if P.ndim != 2 or P.shape[1] < 3:
            raise CurveSkelError(f"faces need at least 3 vertices each, got shape {P.shape}")
        P = _as_index_array(P)
        k = P.shape[1]
        # Fan: (0, i, i+1) for i in 1..k-2 — vectorised over all faces of this length.
        tris = np.stack([np.repeat(P[:, :1], k - 2, axis=1), P[:, 1:-1], P[:, 2:]], axis=2)
        out.append(tris.reshape(-1, 3))
    return np.concatenate(out) if out else np.zeros((0, 3), np.int64)


def _as_index_array(P) -> np.ndarray:
    P = np.asarray(P)
    if P.dtype.kind in "iu":
        return P.astype(np.int64)
    if P.dtype.kind == "f":
        if not np.all(np.isfinite(P)) or np.any(P != np.round(P)):
            raise CurveSkelError("face indices must be integers")
        return P.astype(np.int64)
    raise CurveSkelError(f"face indices must be integers, got dtype {P.dtype}")


def _merge_identical(V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique rows of V and, per row, the index of its unique row (first occurrence order kept).

    A lexsort over the three columns: np.unique(axis=0) gives the same answer but compares
    structured rows and is about 10x slower on a million vertices.
    """
    order = np.lexsort((V[:, 2], V[:, 1], V[:, 0]))
    Vs = take_rows(V, order)
    starts = np.ones(len(V), bool)
    starts[1:] = rows_differ(Vs[1:], Vs[:-1])
    if starts.all():                  # no two alike (the usual case): what the rest would give
        return V.copy(), np.arange(len(V), dtype=np.int64)
    group = np.cumsum(starts) - 1                       # group id in sorted order
    # Number groups by their first input index so the working mesh keeps the input's order.
    first_min = np.minimum.reduceat(order, np.flatnonzero(starts))
    by_first = np.argsort(first_min, kind="stable")
    rank = np.empty(len(first_min), np.int64)
    rank[by_first] = np.arange(len(first_min))
    inverse = np.empty(len(V), np.int64)
    inverse[order] = rank[group]
    return take_rows(V, first_min[by_first]), inverse



def _edge_census(F: np.ndarray, n: int):
    """Per undirected edge of the triangles: how many sides run a->b (a < b) and b->a.

    Returns (boundary, nonmanifold, inconsistent) edge counts and the (n, n) sparse edge matrix
    (its connected components are the mesh's). A sparse matrix sums the two directions in one
    pass (as :func:`.mesh_graph.edge_table`, no sort of the 3m sides)."""

    a = F.ravel()
    b = next_corners(F).ravel()
    fwd = a < b
    lo, hi = np.where(fwd, a, b), np.where(fwd, b, a)
    idx = np.int32 if n < 2**31 - 1 else np.int64
    data = np.where(fwd, np.int64(1), np.int64(1) << 32)
    A = sp.coo_matrix((data, (lo.astype(idx), hi.astype(idx))), shape=(n, n)).tocsr()
    A.sum_duplicates()
    f, r = A.data & 0xFFFFFFFF, A.data >> 32
    c = f + r
    return (int(np.count_nonzero(c == 1)), int(np.count_nonzero(c > 2)),
            int(np.count_nonzero((c == 2) & (f != 1))), A)


def _open_edge_vertices(F: np.ndarray, n: int) -> np.ndarray:
    """Indices of the vertices on edges used by one face only."""
    a = F.ravel()
    b = next_corners(F).ravel()
    key = np.minimum(a, b) * np.int64(n) + np.maximum(a, b)
    k, cnt = np.unique(key, return_counts=True)
    k = k[cnt == 1]
    return np.unique(np.concatenate([k // n, k % n]))


def _merge_close(V: np.ndarray, inverse: np.ndarray, candidates: np.ndarray, tol: float):
    """Merge the ``candidates`` (indices into V) lying within ``tol`` of each other (chains
    included); each cluster takes the position and the place of its first member (so vertices
    of a clean part never move). Returns (V, inverse, merged count)."""

    if len(candidates) < 2:
        return V, inverse, 0
    pairs = cKDTree(V[candidates]).query_pairs(tol, output_type="ndarray")
    if len(pairs) == 0:
        return V, inverse, 0
    pairs = candidates[pairs]
    n = len(V)
    G = coo_matrix((np.ones(len(pairs), np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    k, lab = connected_components(G, directed=False)
    # Number clusters by their first vertex so the working mesh keeps the input's order.
    first = np.full(k, n, np.int64)
    np.minimum.at(first, lab, np.arange(n))
    order = np.argsort(first, kind="stable")
    rank = np.empty(k, np.int64)
    rank[order] = np.arange(k)
    new = rank[lab]
    return V[first[order]], new[inverse], n - k


def _drop_repeated_index(F: np.ndarray) -> tuple[np.ndarray, int]:
    ok = (F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])
    dropped = int(len(F) - np.count_nonzero(ok))
    return (F[ok] if dropped else F), dropped


def _drop_repeated_faces(F: np.ndarray, n: int) -> tuple[np.ndarray, int]:
    """Faces on the same three vertices (either winding) after the first are dropped."""
    S = np.sort(F, axis=1)
    order = np.lexsort((S[:, 2], S[:, 1], S[:, 0]))
    Ss = S[order]
    dup = np.zeros(len(F), bool)
    dup[order[1:]] = np.all(Ss[1:] == Ss[:-1], axis=1)
    # keep the first occurrence in input order: among equal rows lexsort is stable, so the
    # first of each run is the lowest input index
    k = int(np.count_nonzero(dup))
    return (F[~dup] if k else F), k


def _consistent_winding(F: np.ndarray, n: int, weight: np.ndarray):
    """Flip faces so neighbours across every manifold edge agree (an edge run in opposite
    directions by its two faces). Within each connected patch the winding of the larger share
    of ``weight`` (face area) is kept. Returns (flip mask (m,), patch label per face,
    number of non-orientable patches, left as they are)."""

    m = len(F)
    a = F.ravel()
    b = next_corners(F).ravel()
    face = np.repeat(np.arange(m), 3)
    key = np.minimum(a, b) * np.int64(n) + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    starts = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    counts = np.diff(np.r_[starts, len(ks)])
    s2 = starts[counts == 2]
    h1, h2 = order[s2], order[s2 + 1]
    f, g = face[h1], face[h2]
    same = (a[h1] < b[h1]) == (a[h2] < b[h2])          # same direction: one of them must flip
    keep = f != g
    f, g, same = f[keep], g[keep], same[keep]
    k, patch = connected_components(coo_matrix((np.ones(len(f), np.int8), (f, g)), shape=(m, m)),
                                    directed=False)
    # Two copies of every face (as is / flipped); an edge joins the copies that agree there.
    p = same.astype(np.int64)
    rows = np.concatenate([f, f + m])
    cols = np.concatenate([g + p * m, g + (1 - p) * m])
    _, side = connected_components(coo_matrix((np.ones(len(rows), np.int8), (rows, cols)),
                                              shape=(2 * m, 2 * m)), directed=False)
    root = np.full(k, m, np.int64)
    np.minimum.at(root, patch, np.arange(m))
    flip = side[:m] != side[root[patch]]
    bad = np.zeros(k, bool)
    bad[patch[side[:m] == side[m:]]] = True              # a face agrees with its own flip
    flip &= ~bad[patch]
    # Keep the winding most of each patch's area already had.
    flipped_w = np.bincount(patch, weights=weight * flip, minlength=k)
    total_w = np.bincount(patch, weights=weight, minlength=k)
    invert = (flipped_w > 0.5 * total_w) & ~bad
    flip ^= invert[patch]
    return flip, patch, int(bad.sum())


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product (several times faster than np.cross on (m, 3) arrays)."""
    c = np.empty_like(a)
    c[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    c[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    c[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return c


def _cap_holes(V: np.ndarray, F: np.ndarray, labels: np.ndarray):
    """Close every hole: each loop of open edges gets a fan of triangles to a new vertex at the
    loop's mean, wound to match its neighbours (an open edge a->b gets the cap b->a->centre).

    The method needs an inside (contours, inside tests); a capped bowl is a half-ball, an open
    tube a closed one. Returns (V, F, labels, holes, cap area)."""

    n = len(V)
    a = F.ravel()
    b = next_corners(F).ravel()
    key = np.minimum(a, b) * np.int64(n) + np.maximum(a, b)
    _, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
    one = cnt[inv] == 1
    ea, eb = a[one], b[one]
    if len(ea) == 0:
        return V, F, labels, 0, 0.0
    _, lab = connected_components(coo_matrix((np.ones(len(ea), np.int8), (ea, eb)), shape=(n, n)),
                                  directed=False)
    bv = np.unique(np.concatenate([ea, eb]))
    loops, loop_of = np.unique(lab[bv], return_inverse=True)
    h = len(loops)
    cnt_l = np.bincount(loop_of, minlength=h).astype(np.float64)
    centre = np.stack([np.bincount(loop_of, weights=V[bv, j], minlength=h) for j in range(3)],
                      axis=1) / cnt_l[:, None]
    first = np.full(h, n, np.int64)
    np.minimum.at(first, loop_of, bv)
    caps = np.stack([eb, ea, n + np.searchsorted(loops, lab[ea])], axis=1)
    V2 = np.vstack([V, centre])
    T = V2[caps]
    area = float(np.linalg.norm(_cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1).sum() / 2)
    return V2, np.vstack([F, caps]), np.concatenate([labels, labels[first]]), h, area


def _boundary_vertices(A) -> np.ndarray:
    """Vertices on edges used by one face, from the edge matrix of :func:`_edge_census`."""
    c = (A.data & 0xFFFFFFFF) + (A.data >> 32)
    rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    one = c == 1
    return np.concatenate([rows[one], A.indices[one]])


def _flat_components(V: np.ndarray, labels: np.ndarray, k: int, centre=None) -> np.ndarray:
    """(k,) bool: the components whose vertices lie in one plane (RMS distance from their plane
    of best fit at most ``_CFG.merge_tolerance`` of their RMS radius)."""
    if k == 1:
        centre = V.mean(axis=0) if centre is None else centre     # (V's mean, if at hand)
        size = float(np.sqrt(row_sumsq(V - centre).mean()))
        return np.array([_thickness(V, centre) <= _CFG.merge_tolerance * size])
    cnt = np.maximum(np.bincount(labels, minlength=k), 1).astype(np.float64)
    mean = np.stack([np.bincount(labels, weights=V[:, j], minlength=k) for j in range(3)], 1) / cnt[:, None]
    X = V - mean[labels]
    C = np.empty((k, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            C[:, i, j] = C[:, j, i] = np.bincount(labels, weights=X[:, i] * X[:, j], minlength=k) / cnt
    lam = np.linalg.eigvalsh(C)                       # ascending
    return np.sqrt(np.maximum(lam[:, 0], 0.0)) <= _CFG.merge_tolerance * np.sqrt(np.maximum(lam.sum(axis=1), 0.0))


def _thickness(V: np.ndarray, centre=None) -> float:
    """Extent of V across its plane of best fit (0 for a flat point set).

    The plane comes from the covariance of at most ~20k evenly spaced vertices (exact when the
    set is flat, as long as they span the plane), the extent is measured on every vertex.
    ``centre``: V's mean, if at hand."""
    centre = V.mean(axis=0) if centre is None else centre
    step = max(1, len(V) // 20000)
    for sample in (V[::step], V) if step > 1 else (V,):
        X = sample - centre
        _, sv, vt = np.linalg.svd(X.T @ X)
        if sv[1] > 1e-12 * sv[0]:        # the sample spans a plane: its normal is reliable
            break
    return float(np.ptp((V - centre) @ vt[-1]))


def _debris(V: np.ndarray, labels: np.ndarray, k: int, usable: np.ndarray,
            detail: float) -> np.ndarray:
    """(k,) bool: the usable parts below the *Detail Size* of their nearest usable neighbour.

    Each part is taken as the ball about its vertices' mean through its farthest vertex (no
    rotation, move or renumbering changes it). A part's nearest neighbour is the one whose ball
    comes closest to (or reaches deepest into) its own; the part is debris when its radius is
    below ``detail`` times the neighbour's: a speck the neighbour's first approximation (its
    contours ``detail`` of its size apart) could not resolve. The largest part never is.
    Pairs are compared in blocks (``CONFIG.numerics.block`` at a time).

    Parameters
    ----------
    V : (n, 3) float
    labels : (n,) int
        Part of every vertex.
    k : int
        Number of parts.
    usable : (k,) bool
        Parts to judge and to compare with (flat parts and open fragments are not).
    detail : float
        The *Detail Size*: a share of a part's size.

    Returns
    -------
    (k,) bool
    """
    out = np.zeros(k, bool)
    ids = np.flatnonzero(usable)
    if detail <= 0 or len(ids) < 2:
        return out
    cnt = np.maximum(np.bincount(labels, minlength=k), 1).astype(np.float64)
    centre = np.stack([np.bincount(labels, weights=V[:, j], minlength=k) for j in range(3)],
                      axis=1) / cnt[:, None]
    radius = np.zeros(k)
    np.maximum.at(radius, labels, np.sqrt(row_sumsq(V - centre[labels])))
    C, R = centre[ids], radius[ids]
    step = max(1, CONFIG.numerics.block // len(ids))
    for s in range(0, len(ids), step):
        e = min(s + step, len(ids))
        gap = np.sqrt(np.maximum(row_sumsq((C[s:e, None, :] - C[None, :, :]).reshape(-1, 3)), 0.0))
        gap = gap.reshape(e - s, -1) - R[s:e, None] - R[None, :]
        gap[np.arange(e - s), np.arange(s, e)] = np.inf          # not its own neighbour
        out[ids[s:e]] = R[s:e] < detail * R[np.argmin(gap, axis=1)]
    return out


def clean_mesh(V, F, *, min_component_area: float = 0.0, detail: float = 0.0) -> CleanMesh:
    """Validate a mesh and return its working copy.

    Raises :class:`CurveSkelError` for: no vertices, vertices not of shape (n, 3), NaN or inf
    coordinates, no faces, non-integer or out-of-range face indices, a mesh with no face of
    non-zero area, and a flat mesh (every vertex in one plane: no volume to skeletonize).

    Repairs (and counts in ``info``): polygons (triangulated), duplicate vertex positions
    (merged; on open edges within ``_CFG.merge_tolerance`` of the size), faces with a repeated vertex
    or repeated faces (dropped), zero-area faces (dropped), inconsistent or inward winding
    (turned over: ``flipped_faces``), debris (parts below the *Detail Size* ``detail`` of their
    nearest neighbour, :func:`_debris`; 0 keeps all) and connected parts with less than
    ``min_component_area`` of the total area (dropped; 0 keeps all; the largest part is always
    kept): ``small_components_dropped``, holes (capped with a
    fan to a new working vertex: ``holes_capped``), isolated vertices.
    Vertices left out of the working mesh have ``work_index`` -1 (mapped to the skeleton
    afterwards by the nearest working vertex).
    """

    V = np.asarray(V)
    if V.size == 0:
        raise CurveSkelError("the mesh has no vertices")
    if V.ndim != 2 or V.shape[1] != 3:
        raise CurveSkelError(f"vertices must have shape (n, 3), got {V.shape}")
    if V.dtype.kind not in "fiu":
        raise CurveSkelError(f"vertex coordinates must be numbers, got dtype {V.dtype}")
    V = V.astype(np.float64)
    finite = np.isfinite(V)
    if not finite.all():
        bad = ~np.all(finite, axis=1)
        raise CurveSkelError(
            f"{int(bad.sum())} vertices have NaN or infinite coordinates (first: {int(np.argmax(bad))})")
    n = len(V)
    if F is None or (hasattr(F, "__len__") and len(F) == 0):
        raise CurveSkelError("the mesh has no faces: curveskel needs a surface, not a point cloud")
    F = triangulate(F)
    if F.size and (F.min() < 0 or F.max() >= n):
        raise CurveSkelError(
            f"face indices out of range: they must lie in [0, {n - 1}], found {int(F.min())}..{int(F.max())}")
    try:
        min_component_area = float(min_component_area)
    except (TypeError, ValueError):
        min_component_area = float("nan")
    if not 0.0 <= min_component_area < 1.0:
        raise CurveSkelError(f"min_component_area must be >= 0 and < 1, got {min_component_area!r}")
    try:
        detail = float(detail)
    except (TypeError, ValueError):
        detail = float("nan")
    if not 0.0 <= detail < 1.0:
        raise CurveSkelError(f"detail must be >= 0 and < 1, got {detail!r}")

    # Merge vertices at identical positions (STL soup, seams) so connectivity is real.
    uniq, inverse = _merge_identical(V)
    merged = n - len(uniq)
    Fm = inverse[F] if merged else F
    Fm, dropped = _drop_repeated_index(Fm)
    if len(Fm) == 0:
        raise CurveSkelError("every face is degenerate (repeated vertices): nothing to skeletonize")
    used = np.bincount(Fm.ravel(), minlength=len(uniq)) > 0
    Vu = uniq[used]
    size = float(np.linalg.norm(col_max(Vu) - col_min(Vu)))
    if size == 0.0:
        raise CurveSkelError("every face has zero area (all vertices at one point): nothing to skeletonize")
    tol = _CFG.merge_tolerance * size

    boundary, nonmanifold, inconsistent, edges = _edge_census(Fm, len(uniq))
    merged_close = 0
    if boundary:
        # Open edges: a soup or a crack. Vertices on them within the tolerance are one vertex.
        cand = _open_edge_vertices(Fm, len(uniq))
        uniq, inverse, merged_close = _merge_close(uniq, inverse, cand, tol)
        if merged_close:
            Fm = inverse[F]
            Fm, dropped = _drop_repeated_index(Fm)
            if len(Fm) == 0:
                raise CurveSkelError("every face is degenerate (repeated vertices): nothing to skeletonize")
            boundary, nonmanifold, inconsistent, edges = _edge_census(Fm, len(uniq))
    repeated_faces = 0
    if nonmanifold or inconsistent:
        Fm, repeated_faces = _drop_repeated_faces(Fm, len(uniq))
        if repeated_faces:
            boundary, nonmanifold, inconsistent, edges = _edge_census(Fm, len(uniq))

    T0 = take_rows(uniq, Fm[:, 0])
    e1, e2 = take_rows(uniq, Fm[:, 1]) - T0, take_rows(uniq, Fm[:, 2]) - T0
    cross = _cross(e1, e2)
    dbl_area = np.sqrt(np.einsum("ij,ij->i", cross, cross))
    e3 = e2 - e1
    longest2 = np.maximum(np.maximum(np.einsum("ij,ij->i", e1, e1), np.einsum("ij,ij->i", e2, e2)),
                          np.einsum("ij,ij->i", e3, e3))
    # Height over the longest side no more than the tolerance: a sliver with no area.
    thin = dbl_area * dbl_area <= (tol * tol) * longest2
    if np.all(thin):
        raise CurveSkelError("every face has zero area: nothing to skeletonize")

    flip = np.zeros(len(Fm), bool)
    patch = None
    non_orientable = 0
    if inconsistent:
        # Made consistent with the zero-area faces still in place: they may close a crack.
        flip, patch, non_orientable = _consistent_winding(Fm, len(uniq), dbl_area)

    ok = ~thin
    degenerate_area = int(np.count_nonzero(thin))
    if degenerate_area:
        Fm, cross, dbl_area, flip, T0 = Fm[ok], cross[ok], dbl_area[ok], flip[ok], T0[ok]
        if patch is not None:
            patch = patch[ok]

    # Keep referenced vertices only; renumber. Clean meshes (the common case) skip the copies.
    used = np.bincount(Fm.ravel(), minlength=len(uniq)) > 0
    n_used = int(np.count_nonzero(used))
    if n_used == len(uniq):
        Vw, Fw = uniq, Fm
        work_index = inverse
    else:
        new_id = np.full(len(uniq), -1, np.int64)
        new_id[used] = np.arange(n_used)
        Vw = uniq[used]
        Fw = new_id[Fm]
        work_index = new_id[inverse]
    isolated = int(len(uniq) - n_used)

    reuse_edges = degenerate_area == 0 and isolated == 0
    if reuse_edges:
        # The working mesh is the one of the last census: its edge matrix gives the components
        # (the same labels as mesh_graph.components: both number them by their first vertex).

        k, labels = connected_components(edges, directed=False)
    else:
        k, labels = components(len(Vw), Fw)
    face_comp = labels[Fw[:, 0]]
    # Outward: each part (a patch of consistent winding, or a connected component) turned so
    # its signed volume is positive; about the part's centroid, for precision far from 0.
    group = patch if patch is not None else face_comp
    ng = int(group.max()) + 1
    if ng == 1:
        gc = Vw.mean(axis=0)[None, :]
    elif patch is None:          # per component: the mean of its vertices
        cnt = np.bincount(labels, minlength=ng).astype(np.float64)
        gc = np.stack([np.bincount(labels, weights=Vw[:, j], minlength=ng) for j in range(3)],
                      axis=1) / np.maximum(cnt, 1.0)[:, None]
    else:                        # per patch: the area-weighted mean of its faces' first corners
        gw = np.maximum(np.bincount(group, weights=dbl_area, minlength=ng), 1e-300)
        gc = np.stack([np.bincount(group, weights=dbl_area * T0[:, j], minlength=ng)
                       for j in range(3)], axis=1) / gw[:, None]
    term = np.einsum("ij,ij->i", T0 - gc[group] if ng > 1 else T0 - gc[0], cross)
    if flip.any():
        term[flip] = -term[flip]
    vol = np.bincount(group, weights=term, minlength=ng)
    absvol = np.bincount(group, weights=np.abs(term), minlength=ng)
    inward = vol < -_CFG.orient_margin * absvol
    if inward.any():
        flip ^= inward[group]
    reoriented = int(np.count_nonzero(inward))
    flipped_faces = int(np.count_nonzero(flip))
    if flipped_faces:
        Fw = Fw.copy()
        Fw[flip] = Fw[flip][:, ::-1]

    # Parts with no inside have no curve-skeleton: flat parts (every vertex in one plane) and
    # open fragments (loose triangles, strips: no vertex surrounded by faces) are left out; if
    # nothing else is left the mesh is refused. Then scan debris: parts with a tiny share of
    # the total area (the largest part is always kept).
    # (one group: gc is Vw's mean, which the flatness test of one component needs too)
    flat = _flat_components(Vw, labels, k, centre=gc[0] if ng == 1 else None)
    fragment = np.zeros(k, bool)
    if boundary or degenerate_area or merged_close or repeated_faces:
        A = edges if reuse_edges else _edge_census(Fw, len(Vw))[3]
        interior = np.ones(len(Vw), bool)
        interior[_boundary_vertices(A)] = False
        fragment = np.bincount(labels, weights=interior, minlength=k) == 0
    unusable = flat | fragment
    if unusable.all():
        if flat.all():
            where = ("every vertex lies in one plane" if k == 1 else
                     f"each of its {k} parts lies in a plane; a triangle soup whose corners are "
                     "not shared?")
            raise CurveSkelError(
                f"the mesh is flat ({where}): a curve-skeleton needs a shape with volume; give "
                "the surface a thickness (e.g. a Solidify modifier) first")
        raise CurveSkelError(
            f"no part of the mesh encloses a volume: its {k} part(s) are flat or loose triangles "
            "and open strips (no vertex surrounded by faces); is it a triangle soup whose corners "
            "are not shared, or an unfinished surface?")
    carea = np.bincount(face_comp, weights=dbl_area, minlength=k)
    small = np.zeros(k, bool)
    if min_component_area > 0 and k > 1:
        usable_area = carea[~unusable]
        small = ~unusable & (carea < min_component_area * float(usable_area.sum()))
        small[np.flatnonzero(~unusable)[int(np.argmax(usable_area))]] = False
    if detail > 0 and k > 1:
        small |= _debris(Vw, labels, k, ~unusable, detail)
    drop = unusable | small
    small_vertices = 0
    if drop.any():
        keep_v = ~drop[labels]
        small_vertices = int(np.count_nonzero(~keep_v & small[labels]))
        new_id = np.full(len(Vw), -1, np.int64)
        new_id[keep_v] = np.arange(int(keep_v.sum()))
        Fw = new_id[Fw[~drop[face_comp]]]
        Vw = Vw[keep_v]
        wi = work_index.copy()
        ok_wi = wi >= 0
        wi[ok_wi] = new_id[wi[ok_wi]]
        work_index = wi
        kept = np.flatnonzero(~drop)
        relabel = np.full(k, -1, np.int64)
        relabel[kept] = np.arange(len(kept))
        labels = relabel[labels[keep_v]]
        k = len(kept)
    small_dropped = int(small.sum())
    small_share = float(carea[small].sum() / carea.sum()) if small_dropped else 0.0

    # Holes are closed (the working mesh only: every input vertex keeps its place).
    holes, cap_area = 0, 0.0
    if boundary or degenerate_area or merged_close or repeated_faces:
        Vw, Fw, labels, holes, cap_area = _cap_holes(Vw, Fw, labels)

    info = {
        "input_vertices": n,
        "input_faces": int(len(F)),
        "merged_duplicates": int(merged + merged_close),
        "merge_tolerance": tol,
        "degenerate_faces_dropped": int(dropped + repeated_faces + degenerate_area),
        "isolated_vertices": isolated,
        "flipped_faces": flipped_faces,
        "reoriented_components": reoriented,
    }
    if merged_close:
        info["merged_within_tolerance"] = int(merged_close)
    if non_orientable:
        info["non_orientable_parts"] = non_orientable
    if holes:
        info["holes_capped"] = int(holes)
        info["cap_area_share"] = cap_area / max(float(carea[~drop].sum()), 1e-300)
    info["min_component_area"] = min_component_area
    if detail > 0:
        info["detail"] = float(detail)
    if flat.any():
        info["flat_components_dropped"] = int(flat.sum())
    if (fragment & ~flat).any():
        info["open_fragments_dropped"] = int((fragment & ~flat).sum())
    if small_dropped:
        info["small_components_dropped"] = small_dropped
        info["small_components_vertices"] = small_vertices
        info["small_components_area_share"] = small_share
    # the census still describes the working triangles: no face or vertex dropped or added
    # since (turning a face over keeps its edges)
    same_edges = reuse_edges and not drop.any() and not holes
    return CleanMesh(Vw, Fw, work_index, info, components=(int(k), labels),
                     edge_matrix=edges if same_edges else None)
