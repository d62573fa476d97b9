"""First approximation: a discrete Reeb graph of the geodesic distance, embedded with MEBs.

The paper (section 4.1, eqs. 21-23) grows contour lines as sets of *vertices*. Taken literally
that depends on how uniform the mesh is (a long edge skips a contour) and is not well defined
where the level set splits. We implement this discrete version instead:

1. **f and levels.** f is the graph-geodesic distance from the pole (:mod:`pole`, which also
   explains how the pole is kept at the tip of an extremity). On a surface with handles the
   graph also runs through the inside (:mod:`interior`), so a cycle goes round its hole
   instead of closing across it. Levels are c_k = k * s,
   k = 1..K, c_K < max f, with s = spacing * (the diameter of the component's minimum
   enclosing ball: a size no rotation changes, :func:`.meb.size_of`), but at least 6 and at most
   400 levels (1600 after refinement). A vertex is *above* level c iff f >= c (this breaks ties
   of vertices lying exactly on a level); its *band* is the number of levels <= f.
2. **Contour loops.** Every mesh edge (a, b) with f_a < c <= f_b gets a crossing point at the
   linear interpolation; an edge may cross many levels (all crossings are generated at once with
   ``np.repeat``). A triangle crossed by level c has exactly two crossing sides: a segment.
   Connected components of segments are the contour loops (open paths on a mesh with boundary).
   Loop points are exact points of the piecewise-linear iso-line, so joints do not depend on
   how uniform the mesh is.
3. **Regions** (the parts between consecutive levels). A triangle spans bands
   band(min f)..band(max f); each (triangle, band) is a convex, hence connected, *piece*. Pieces
   sharing a mesh edge whose f-range meets their band are joined; connected components are the
   regions. A region may hold no vertex at all (inside long edges), which is why regions are
   built from pieces. To stay fast on million-face meshes the components are found in two
   passes: vertices joined by edges lying inside one band ("blobs", a sort-free sparse graph),
   then a small graph of blobs and the pieces of multi-band triangles only (a one-band
   triangle's piece adds nothing its three vertices do not). Each corner of a multi-band
   triangle joins its vertex's blob to the triangle's piece of that band, which also keeps a
   non-manifold (pinched) vertex connected; triangles sharing an edge that spans >= 3 bands join
   their pieces of the inner bands (non-manifold edges: consecutive triangles of the edge).
4. **Reeb graph.** Nodes are regions, each loop is an edge between the region below and above
   it. Its cycle count b1 = L - R + C must equal the genus g of a closed component
   (g = (2 - chi) / 2); a loop with the same region on both sides is not counted, since the
   skeleton cannot show that cycle. When b1 < g a handle fell inside one region: s is halved and everything
   rebuilt (at most 3 times; ``meta["refinements"]``).
5. **Noise caps.** Local maxima of a graph-geodesic f (noise, and the uneven last band) make
   small cap regions bounded by one loop below them: spurious branch tips. A cap whose height
   (max f in it minus its loop's level) is below ``cap_fraction * s`` is merged into the region
   below it and its loop disappears. Caps are chosen on the original regions in one pass, so
   merging never cascades into a genuine short branch; the cap at the pole and a cap whose
   removal would leave no loop are kept. b1 does not change (one region and one loop go).
6. **Embedding** (paper eqs. 12-13). Every loop is a joint at the centre of the MEB of its
   points, r = the MEB radius. A region with exactly 2 loops becomes a bone between their joints.
   A region with 1 loop (a tip) or >= 3 loops (a branching) gets its own joint at the MEB centre
   of its vertices and its loops' points, with r = mean distance of its vertices to that centre
   (the MEB radius overestimates a tip's thickness; the optimiser refines r anyway), and a bone
   to each of its loops' joints. A second region joining the same two loops (possible only in
   degenerate configurations) also gets its own joint, so no bone is duplicated. A bone that
   would have zero length has its region joint nudged by 1e-6 of the diagonal towards the
   region's vertex centroid (or along +x), so every bone has a direction.
7. **Mapping** (:mod:`mapping`, paper eqs. 18-19): each vertex maps to the closest point of the
   bones of its own region. The region is where the Reeb graph puts the vertex, so sigma
   respects the topology (a fingertip never maps to the neighbouring finger however close it
   is), and the closest point gives a continuous t along the bone rather than the paper's
   constant per contour.

Cost: everything is vectorised over vertices, edges, faces and crossings; Python loops run over
loops and regions only (one MEB each). Two Dijkstra runs dominate (see :mod:`pole`).
Timings per stage are returned in ``meta["timings"]``.

A component too small for levels (fewer than 3 vertices, or all vertices at one position) gets
one bone along its principal axis, so every vertex still has a bone.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..config import CONFIG
from ..errors import CurveSkelError
from ..geometry.segments import closest_on_bones
from .interior import InteriorGrid
from ..geometry.meb import min_enclosing_ball, size_of
from ..geometry.mesh_graph import edge_csr, edge_ids, edge_lengths, edge_table
from .pole import find_pole
from ..geometry.rows import next_corners

__all__ = ["FirstApproximation", "first_approximation"]

_CFG = CONFIG.initial


@dataclass
class FirstApproximation:
    """The first approximation of one connected component.

    Attributes
    ----------
    joints : (J, 4) float
        x, y, z, r.
    bones : (B, 2) int
        Joint indices.
    bone : (n,) int
        Bone of each vertex of the component.
    t : (n,) float
        In [0, 1]: sigma = t * x_i + (1 - t) * x_j for bone (i, j) (paper eq. 19).
    meta : dict
        ``"timings"`` {stage: seconds} for "pole", "contours", "reeb", "meb", "mapping"; and
        "pole", "size" (the component's diameter, :func:`.meb.size_of`: the unit of the
        spacing), "spacing_used", "levels", "cycles", "expected_cycles", "noise_caps_removed",
        "refinements", "regions", "loops", "interior_paths" (f also ran through the inside).
    region : (n,) int or None
        Reeb region of each vertex (None for the single-bone fallback).
    bone_region : (B,) int or None
        Reeb region each bone explains: a vertex's sigma stays on the bones of its region.
    f : (n,) float or None
        The geodesic distance from the pole: an order of the vertices that does not depend on
        their numbering (the pipeline draws its samples in this order).
    """

    joints: np.ndarray
    bones: np.ndarray
    bone: np.ndarray
    t: np.ndarray
    meta: dict = field(default_factory=dict)
    region: np.ndarray | None = None
    bone_region: np.ndarray | None = None
    f: np.ndarray | None = None
    pieces: tuple | None = None  # (levels, face -> multi-band index or -1, pstart, bmin, bmax, label)

    def region_of(self, F, face, bary) -> np.ndarray:
        """Reeb region of the surface points ``bary`` (barycentric) on faces ``face`` of this
        component's triangles ``F``: a point inside a face that several levels cross lies in
        the region of its (face, band) piece, which need not hold any vertex."""
        F = np.asarray(F, np.int64)
        reg = self.region[F[face, 0]]
        if self.pieces is None:
            return reg
        levels, mt_of, pstart, bmin, bmax, label = self.pieces
        q = mt_of[face]
        multi = np.flatnonzero(q >= 0)
        if len(multi):
            fs = np.einsum("ij,ij->i", bary[multi], self.f[F[face[multi]]])
            qm = q[multi]
            band = np.clip(np.searchsorted(levels, fs, side="right"), bmin[qm], bmax[qm])
            reg[multi] = label[pstart[qm] + band - bmin[qm]]
        return reg


# ------------------------------------------------------------------------------------------------
# contours


@dataclass
class _Contours:
    levels: np.ndarray      # (K,) level values c_1..c_K
    band: np.ndarray        # (n,) band of each vertex
    cnt: np.ndarray         # (e,) number of levels each edge crosses
    mt: np.ndarray          # (q,) multi-band triangles (crossed by at least one level)
    FEm: np.ndarray         # (q, 3) their side edges, side s = corners (s, s+1 mod 3)
    tbm: np.ndarray         # (q, 3) band of their corners
    P: np.ndarray           # (C, 3) crossing points
    x_level: np.ndarray     # (C,) level index k (1..K) of each crossing
    x_loop: np.ndarray      # (C,) loop of each crossing
    n_loops: int
    loop_level: np.ndarray  # (L,) level index of each loop
    seg_tri: np.ndarray     # (S,) index into mt of each segment's triangle
    seg_level: np.ndarray   # (S,) level index of each segment
    seg_loop: np.ndarray    # (S,) loop of each segment


# side s of a triangle joins corners (s, s+1 mod 3); _SIDE[i, j] is the side joining corners i, j
_SIDE = np.array([[-1, 0, 2], [0, -1, 1], [2, 1, -1]])


def _contours(V, F, E, f, s, K) -> _Contours:
    levels = s * np.arange(1, K + 1)
    band = np.searchsorted(levels, f, side="right").astype(np.int64)
    # crossings: edge (lo, hi) oriented by f crosses levels band[lo]+1 .. band[hi]
    a, b = E[:, 0], E[:, 1]
    swap = f[a] > f[b]
    lo = np.where(swap, b, a)
    hi = np.where(swap, a, b)
    bl, bh = band[lo], band[hi]
    cnt = bh - bl
    ce = np.flatnonzero(cnt > 0)
    cc = cnt[ce]
    cstart = np.zeros(len(E), np.int64)
    cstart[ce] = np.cumsum(cc) - cc
    C = int(cc.sum())
    x_edge = np.repeat(ce, cc)
    x_level = bl[x_edge] + 1 + (np.arange(C) - np.repeat(cstart[ce], cc))
    xlo, xhi = lo[x_edge], hi[x_edge]
    flo = f[xlo]
    w = (levels[x_level - 1] - flo) / (f[xhi] - flo)
    Vlo = V[xlo]
    P = Vlo + w[:, None] * (V[xhi] - Vlo)

    # segments: triangle T crosses levels bmin+1..bmax; sides (o0,o2) and (o0,o1) or (o1,o2)
    b0, b1, b2 = band[F[:, 0]], band[F[:, 1]], band[F[:, 2]]
    mt = np.flatnonzero((b0 != b1) | (b1 != b2))
    Fm = F[mt]
    tbm = np.stack([b0[mt], b1[mt], b2[mt]], axis=1)
    FEm = edge_ids(E, Fm.ravel(), next_corners(Fm).ravel()).reshape(-1, 3)
    order = np.argsort(tbm, axis=1, kind="stable")
    ob = np.take_along_axis(tbm, order, axis=1)
    ns = ob[:, 2] - ob[:, 0]
    S = int(ns.sum())
    seg_tri = np.repeat(np.arange(len(mt)), ns)
    seg_level = ob[seg_tri, 0] + 1 + (np.arange(S) - np.repeat(np.cumsum(ns) - ns, ns))
    r = np.arange(len(mt))
    e02 = FEm[r, _SIDE[order[:, 0], order[:, 2]]]
    e01 = FEm[r, _SIDE[order[:, 0], order[:, 1]]]
    e12 = FEm[r, _SIDE[order[:, 1], order[:, 2]]]
    ea = e02[seg_tri]
    eb = np.where(seg_level <= ob[seg_tri, 1], e01[seg_tri], e12[seg_tri])
    xa = cstart[ea] + seg_level - bl[ea] - 1
    xb = cstart[eb] + seg_level - bl[eb] - 1
    G = sp.coo_matrix((np.ones(S, np.int8), (xa, xb)), shape=(C, C)).tocsr()
    n_loops, x_loop = connected_components(G, directed=False)
    loop_level = np.zeros(n_loops, np.int64)
    loop_level[x_loop] = x_level
    return _Contours(levels, band, cnt, mt, FEm, tbm, P, x_level, x_loop, int(n_loops), loop_level,
                     seg_tri, seg_level, x_loop[xa])


# ------------------------------------------------------------------------------------------------
# regions and the Reeb graph


@dataclass
class _Reeb:
    n_regions: int
    reg_v: np.ndarray       # (n,) region of each vertex
    below: np.ndarray       # (L,) region below each loop
    above: np.ndarray       # (L,) region above each loop
    cycles: int
    pieces: tuple = ()      # (pstart, bmin, bmax, label): region of (multi-band triangle, band)


def _regions(n, E, F, ct: _Contours) -> _Reeb:
    """Regions in two passes: vertices joined by one-band edges ("blobs", a sort-free CSR on the
    big vertex graph), then blobs and the pieces of multi-band triangles (a small graph)."""
    same = ct.cnt == 0
    G1 = edge_csr(n, E[same], np.ones(int(same.sum()), np.int8))
    n_blob, blob = connected_components(G1, directed=False)
    tb = ct.tbm
    bmin = tb.min(axis=1)
    npc = tb.max(axis=1) - bmin + 1
    pstart = n_blob + np.cumsum(npc) - npc          # node id of piece (T, bmin[T])
    n_nodes = n_blob + int(npc.sum())
    # each corner of a multi-band triangle joins its vertex's blob to the piece of its band
    rows = [blob[F[ct.mt]].ravel()]
    cols = [(pstart[:, None] + tb - bmin[:, None]).ravel()]
    # triangles sharing an edge that spans >= 3 bands: join their pieces of the inner bands
    side_e = ct.FEm.ravel()
    long_side = np.flatnonzero(ct.cnt[side_e] >= 2)
    if len(long_side):
        le = side_e[long_side]
        srt = np.argsort(le, kind="stable")
        le, ltri = le[srt], long_side[srt] // 3
        pair = np.flatnonzero(le[1:] == le[:-1])        # consecutive faces of the same edge
        if len(pair):
            e = le[pair]
            t1, t2 = ltri[pair], ltri[pair + 1]
            k_in = ct.cnt[e] - 1                          # inner bands bl+1 .. bh-1
            bl = ct.band[E[e]].min(axis=1)
            r = np.repeat(np.arange(len(pair)), k_in)
            k = bl[r] + 1 + (np.arange(len(r)) - np.repeat(np.cumsum(k_in) - k_in, k_in))
            rows.append(pstart[t1[r]] + k - bmin[t1[r]])
            cols.append(pstart[t2[r]] + k - bmin[t2[r]])
    rows = np.concatenate(rows)
    cols = np.concatenate(cols)
    G = sp.coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(n_nodes, n_nodes)).tocsr()
    n_reg, lab = connected_components(G, directed=False)
    # loop -> regions below/above, read off one segment (T, k) of the loop: pieces (T, k-1), (T, k)
    first = np.zeros(ct.n_loops, np.int64)
    first[ct.seg_loop[::-1]] = np.arange(len(ct.seg_loop))[::-1]
    T, k = ct.seg_tri[first], ct.seg_level[first]
    below = lab[pstart[T] + k - 1 - bmin[T]]
    above = lab[pstart[T] + k - bmin[T]]
    reg_v = lab[blob]
    return _Reeb(int(n_reg), reg_v, below, above, _cycles(int(n_reg), below, above),
                 (pstart, bmin, tb.max(axis=1), lab))


def _cycles(n_reg, below, above) -> int:
    """b1 = L - R + C of the Reeb graph, not counting a loop with the same region on both sides
    (the skeleton cannot represent that cycle, so it must trigger a refinement)."""
    if n_reg == 0:
        return 0
    ok = below != above
    G = sp.coo_matrix((np.ones(int(ok.sum())), (below[ok], above[ok])), shape=(n_reg, n_reg))
    nc, _ = connected_components(G, directed=False)
    return int(ok.sum() - n_reg + nc)


def _remove_noise_caps(rb: _Reeb, ct: _Contours, f, pole, s) -> tuple[_Reeb, np.ndarray, int]:
    """Merge small top caps into the region below; returns (reeb, kept loop ids, count).

    A cap lower than ``cap_fraction`` of the spacing lies below the level set's resolution:
    where the last level falls under a tip is chance (of the triangulation too). Such a cap is
    merged into the region below it, its loop dropped; the cap at the pole and a cap whose
    removal would leave no loop are kept. Whether a real branch is worth its joints is J's
    decision (the price of a branch), not this one's: this only removes what the levels cannot
    resolve."""
    R, L = rb.n_regions, len(rb.below)
    deg = np.bincount(rb.below, minlength=R) + np.bincount(rb.above, minlength=R)
    top = np.full(R, -1, np.int64)                  # the loop below a region (for deg-1 regions)
    top[rb.above] = np.arange(L)
    maxf = np.full(R, -np.inf)
    np.maximum.at(maxf, rb.reg_v, f)
    cand = np.flatnonzero((deg == 1) & (top >= 0))
    cand = cand[cand != rb.reg_v[pole]]
    lp = top[cand]
    height = maxf[cand] - ct.levels[ct.loop_level[lp] - 1]
    under = rb.below[lp]
    noise = (height < _CFG.cap_fraction * s) & (deg[under] >= 2)
    caps, lp, under = cand[noise], lp[noise], under[noise]
    if len(caps) == 0:
        return rb, np.arange(L), 0
    regmap = np.arange(R)
    regmap[caps] = under
    keep = np.ones(L, bool)
    keep[lp] = False
    kept = np.flatnonzero(keep)
    uniq, new = np.unique(regmap, return_inverse=True)
    below = new[rb.below[kept]]
    above = new[rb.above[kept]]
    nr = len(uniq)
    pstart, bmin, bmax, lab = rb.pieces
    return (_Reeb(nr, new[rb.reg_v], below, above, _cycles(nr, below, above),
                  (pstart, bmin, bmax, new[lab])), kept, len(caps))


# ------------------------------------------------------------------------------------------------
# embedding


def _group(labels, count):
    """(order, starts): items of group g are order[starts[g]:starts[g + 1]]."""
    order = np.argsort(labels, kind="stable")
    starts = np.concatenate([[0], np.cumsum(np.bincount(labels, minlength=count))])
    return order, starts


def _embed(V, diag, ct: _Contours, rb: _Reeb, kept):
    """Joints, bones and each region's bones (CSR) from the Reeb graph."""
    L, R = len(kept), rb.n_regions
    # loop joints: MEB of the loop's points
    new_loop = np.full(ct.n_loops, -1, np.int64)
    new_loop[kept] = np.arange(L)
    xl = new_loop[ct.x_loop]
    xs = np.flatnonzero(xl >= 0)
    xorder, xstarts = _group(xl[xs], L)
    xorder = xs[xorder]
    joints = np.zeros((L, 4))
    for l in range(L):
        c, r = min_enclosing_ball(ct.P[xorder[xstarts[l]:xstarts[l + 1]]])
        joints[l, :3], joints[l, 3] = c, r
    # loops of each region
    reg = np.concatenate([rb.below, rb.above])
    lid = np.concatenate([np.arange(L), np.arange(L)])
    lorder, lstarts = _group(reg, R)
    deg = np.diff(lstarts)
    two = np.flatnonzero(deg == 2)
    pairs = np.sort(lid[lorder][lstarts[two][:, None] + np.arange(2)], axis=1)
    if len(pairs):
        _, first = np.unique(pairs, axis=0, return_index=True)
        dup = np.ones(len(two), bool)
        dup[first] = False
        dup |= pairs[:, 0] == pairs[:, 1]
    else:
        dup = np.zeros(0, bool)
    simple = np.zeros(R, bool)
    simple[two[~dup]] = True
    own = np.flatnonzero(~simple)
    vorder, vstarts = _group(rb.reg_v, R)
    new_joints, bones, bone_reg = [], [], []
    for b_reg, (i, j) in zip(two[~dup], pairs[~dup]):
        bones.append((i, j)); bone_reg.append(b_reg)
    for g in own:
        vs = vorder[vstarts[g]:vstarts[g + 1]]
        ls = np.unique(lid[lorder[lstarts[g]:lstarts[g + 1]]])    # a loop may bound g twice
        pts = [V[vs]] + [ct.P[xorder[xstarts[l]:xstarts[l + 1]]] for l in ls]
        c, r = min_enclosing_ball(np.concatenate(pts))
        if len(vs):
            r = float(np.mean(np.linalg.norm(V[vs] - c, axis=1)))
        jid = L + len(new_joints)
        new_joints.append(np.r_[c, r])
        for l in ls:
            bones.append((jid, int(l))); bone_reg.append(g)
    if new_joints:
        joints = np.concatenate([joints, np.array(new_joints)])
    bones = np.array(bones, np.int64).reshape(-1, 2)
    bone_reg = np.array(bone_reg, np.int64)
    _nudge_zero_bones(joints, bones, bone_reg, V, vorder, vstarts, diag, L)
    border, bstarts = _group(bone_reg, R)
    return joints, bones, border, bstarts, bone_reg


def _nudge_zero_bones(joints, bones, bone_reg, V, vorder, vstarts, diag, n_loop_joints):
    """Give every zero-length bone a length: move its region joint (or 2nd joint) a little."""
    eps = _CFG.tie * max(diag, 1e-300)
    for _ in range(3):
        ln = np.linalg.norm(joints[bones[:, 0], :3] - joints[bones[:, 1], :3], axis=1)
        bad = np.flatnonzero(ln < 0.5 * eps)
        if len(bad) == 0:
            return
        for b in bad:
            i, j = bones[b]
            mv = i if i >= n_loop_joints else j
            other = j if mv == i else i
            g = bone_reg[b]
            vs = vorder[vstarts[g]:vstarts[g + 1]]
            d = (V[vs].mean(axis=0) - joints[other, :3]) if len(vs) else np.zeros(3)
            nd = np.linalg.norm(d)
            d = d / nd if nd > 0 else np.array([1.0, 0.0, 0.0])
            joints[mv, :3] = joints[other, :3] + eps * d


def _single_bone(V, diag):
    """One bone along the principal axis through the centroid (tiny or degenerate components)."""
    c = V.mean(axis=0)
    Q = V - c
    if len(V) >= 2 and np.any(Q):
        axis = np.linalg.svd(Q, full_matrices=False)[2][0]
    else:
        axis = np.array([1.0, 0.0, 0.0])
    proj = Q @ axis
    lo, hi = float(proj.min()), float(proj.max())
    if hi - lo < _CFG.tie * max(diag, 1e-300):
        h = max(_CFG.tie * max(diag, 1e-300), 1e-12)
        lo, hi = -h, h
    radial = np.linalg.norm(Q - proj[:, None] * axis, axis=1)
    r = float(radial.mean())
    joints = np.array([np.r_[c + hi * axis, r], np.r_[c + lo * axis, r]])
    return joints, np.array([[0, 1]], np.int64)


# ------------------------------------------------------------------------------------------------


def _expected_cycles(n, E, ecount, m):
    """Genus of a closed edge-manifold component (every edge in exactly two faces), else None."""
    if len(E) == 0 or np.any(ecount != 2):
        return None
    chi = n - len(E) + m
    if chi % 2:
        return None
    return max((2 - chi) // 2, 0)


def first_approximation(V, F, *, spacing: float, seed: int, inside=None,
                        edges=None) -> FirstApproximation:
    """First approximation of the curve-skeleton of ONE connected component (paper 4.1).

    Parameters
    ----------
    V : (n, 3) float
        Vertices of the component.
    F : (m, 3) int
        Its triangles: every vertex referenced, no triangle with a repeated index. The surface
        may be open or non-manifold.
    spacing : float
        Distance between contour levels as a fraction of the component's size (diameter of its
        minimum enclosing ball)
        (adjusted to 6..400 levels, halved where a handle would be lost).
    seed : int
        Seed of the pole search (reproducible).
    inside : callable, optional
        Returns an exact inside test of (V, F) (:class:`.quality.InsideTest`) when called:
        where one is built anyway, a surface with handles whose joints are all inside skips
        the coarse grid that looks for joints in its holes.
    edges : (E (e, 2), count (e,)), optional
        :func:`.mesh_graph.edge_table` of (V, F), if at hand (the cleaning's edge census).

    Returns
    -------
    FirstApproximation
        Joints (J, 4), bones (B, 2), each vertex's bone and t, and meta (see the class).

    Raises
    ------
    CurveSkelError
        For malformed input (shapes, indices, non-finite values, spacing <= 0).

    Examples
    --------
    >>> from tests.meshes import capsule                    # doctest: +SKIP
    >>> fa = first_approximation(*capsule(), spacing=0.04, seed=0)   # doctest: +SKIP
    >>> fa.joints.shape[1], fa.bones.shape[1]               # doctest: +SKIP
    (4, 2)
    """
    V, F = _check(V, F, spacing)
    n, m = len(V), len(F)
    timings = {}
    t0 = time.perf_counter()
    E, ecount = edge_table(F, n) if edges is None else edges
    expected = _expected_cycles(n, E, ecount, m)
    fa = _approximate(V, F, E, expected, spacing, seed, None, timings, t0)
    if expected and fa.region is not None:
        # With handles, a cycle may close across its hole instead of round it: its contour
        # lines' centres then lie in the hole, outside the shape. If any joint does, f is
        # computed again through the inside as well (:mod:`.interior`), and the result with
        # fewer joints outside is kept. (Not on shapes without holes: there the surface
        # distance separates limbs better.)
        t0 = time.perf_counter()          # (counted in "pole": the cost of f)
        if inside is not None and inside()(fa.joints[:, :3]).all():
            outside = 0                   # in the shape, so in no hole: the grid is not needed
        else:
            grid = InteriorGrid(V, F)
            outside = int(np.count_nonzero(~grid.contains(fa.joints[:, :3])))
        fa.meta["outside_joints"] = outside
        if outside:
            # its own pole search (the surface f's pole, reused, left a plate's first loop
            # across its hole: inside 0.92, zig-zag 0.18)
            fb = _approximate(V, F, E, expected, spacing, seed, grid.graph(), timings, t0)
            fb.meta["outside_joints"] = int(np.count_nonzero(~grid.contains(fb.joints[:, :3])))
            if fb.meta["outside_joints"] < outside and fb.meta["cycles"] >= fa.meta["cycles"]:
                fb.meta["interior_paths"] = True
                fb.meta["outside_joints_surface_f"] = outside
                fa = fb
        else:
            timings["pole"] += time.perf_counter() - t0
    fa.meta["timings"] = timings
    return fa


def _approximate(V, F, E, expected, spacing, seed, extra, timings, t0) -> FirstApproximation:
    """The first approximation with f over the edge graph, plus the ``extra`` paths if given."""
    n = len(V)
    # (shapes with handles: the default pole, see pole.py)
    pole, f = find_pole(V, E, edge_lengths(V, E), seed, extra=extra, mirror=expected == 0)
    timings["pole"] = timings.get("pole", 0.0) + time.perf_counter() - t0
    diag = size_of(V)      # rotation-free size (the spacing's unit)
    f = np.where(np.isfinite(f), f, 0.0)
    maxf = float(f.max())
    meta = {"pole": int(pole), "size": diag, "timings": timings, "expected_cycles": None,
            "cycles": 0, "noise_caps_removed": 0, "refinements": 0, "interior_paths": False}
    if n < 3 or diag <= 0 or maxf <= 0:
        joints, bones = _single_bone(V, diag)
        return _finish(V, joints, bones, None, meta | {"spacing_used": 1.0, "levels": 0,
                                                       "regions": 1, "loops": 0}, timings)
    s = min(spacing * diag, maxf / (_CFG.min_levels + 1))
    cap = _CFG.max_levels
    refined = 4 * _CFG.max_levels           # levels at most once refined
    for attempt in range(_CFG.max_refinements + 1):
        s = max(s, maxf / (cap + 1))
        K = max(int(np.ceil(maxf / s)) - 1, 1)     # levels c_1..c_K < max f
        t0 = time.perf_counter()
        ct = _contours(V, F, E, f, s, K)
        timings["contours"] = timings.get("contours", 0.0) + time.perf_counter() - t0
        t0 = time.perf_counter()
        rb = _regions(n, E, F, ct)
        timings["reeb"] = timings.get("reeb", 0.0) + time.perf_counter() - t0
        if expected is None or rb.cycles >= expected or attempt == _CFG.max_refinements:
            break
        if s <= maxf / (refined + 1) * 1.0000001:
            break
        s, cap = s / 2, refined
        meta["refinements"] = attempt + 1
    t0 = time.perf_counter()
    rb, kept, removed = _remove_noise_caps(rb, ct, f, pole, s)
    timings["reeb"] += time.perf_counter() - t0
    meta.update(spacing_used=s / diag if diag > 0 else 1.0, levels=int(K), cycles=int(rb.cycles),
                expected_cycles=expected, noise_caps_removed=int(removed),
                regions=int(rb.n_regions), loops=int(len(kept)))
    t0 = time.perf_counter()
    if len(kept) == 0:
        joints, bones = _single_bone(V, diag)
        region_bones = None
    else:
        joints, bones, border, bstarts, bone_reg = _embed(V, diag, ct, rb, kept)
        region_bones = (rb.reg_v, border, bstarts)
    timings["meb"] = timings.get("meb", 0.0) + time.perf_counter() - t0
    fa = _finish(V, joints, bones, region_bones, meta, timings)
    if region_bones is not None:
        fa.region, fa.bone_region = rb.reg_v.astype(np.int64), bone_reg
        mt_of = np.full(len(F), -1, np.int64)
        mt_of[ct.mt] = np.arange(len(ct.mt))
        pstart, bmin, bmax, label = rb.pieces
        fa.pieces = (ct.levels, mt_of, pstart, bmin, bmax, label.astype(np.int64))
    fa.f = f
    return _canonical_order(fa)


def _canonical_order(fa: FirstApproximation) -> FirstApproximation:
    """Joints and bones renumbered in an order of the shape, not of the vertices.

    Regions and loops are numbered by connected-component labels, which follow the vertex
    numbering; the edit stage walks chains in joint order and merges one joint at a time, so a
    permuted or rotated copy of the mesh could be edited differently (issue 12: the torus had
    27-30 joints under rotation, scaling or a move, now 28 each time; a rotated mesh moved by
    5.2e-4 of its size, now 2.5e-6).
    Joints are sorted by the mean f of the vertices on their bones (the lowest of their bones),
    then radius, then position (only exact ties reach it); each bone runs from its lower joint
    number, bones sorted by their joints."""
    if fa.f is None or len(fa.bones) == 0:
        return fa
    J, B = len(fa.joints), len(fa.bones)
    cnt = np.bincount(fa.bone, minlength=B)
    fb = np.bincount(fa.bone, weights=fa.f, minlength=B) / np.maximum(cnt, 1)
    fb[cnt == 0] = np.inf
    key = np.full(J, np.inf)
    np.minimum.at(key, fa.bones[:, 0], fb)
    np.minimum.at(key, fa.bones[:, 1], fb)
    X = fa.joints
    order = np.lexsort((X[:, 2], X[:, 1], X[:, 0], X[:, 3], key))
    new = np.empty(J, np.int64)
    new[order] = np.arange(J)
    bones = new[fa.bones]
    swap = bones[:, 0] > bones[:, 1]
    bones[swap] = bones[swap][:, ::-1]
    border = np.lexsort((bones[:, 1], bones[:, 0]))
    bnew = np.empty(B, np.int64)
    bnew[border] = np.arange(B)
    t = np.where(swap[fa.bone], 1.0 - fa.t, fa.t)
    fa.joints, fa.bones, fa.bone, fa.t = X[order], bones[border], bnew[fa.bone], t
    if fa.bone_region is not None:
        fa.bone_region = fa.bone_region[border]
    return fa


def _finish(V, joints, bones, region_bones, meta, timings) -> FirstApproximation:
    t0 = time.perf_counter()
    if region_bones is None:
        cand = None
    else:
        reg_v, border, bstarts = region_bones
        cnt = np.diff(bstarts)[reg_v]
        indptr = np.concatenate([[0], np.cumsum(cnt)])
        local = np.arange(indptr[-1]) - np.repeat(indptr[:-1], cnt)
        cand = (indptr, border[np.repeat(bstarts[reg_v], cnt) + local])
    bone, t, _ = closest_on_bones(V, joints, bones, cand)
    timings["mapping"] = timings.get("mapping", 0.0) + time.perf_counter() - t0
    for k in ("pole", "contours", "reeb", "meb", "mapping"):
        timings.setdefault(k, 0.0)
    meta["timings"] = timings
    return FirstApproximation(joints, bones, bone, t, meta)


def _check(V, F, spacing):
    V = np.asarray(V, dtype=np.float64)
    if V.ndim != 2 or V.shape[1] != 3 or len(V) == 0:
        raise CurveSkelError(f"first_approximation: vertices must be (n, 3) with n >= 1, got {V.shape}")
    if not np.all(np.isfinite(V)):
        raise CurveSkelError("first_approximation: vertex coordinates must be finite")
    F = np.asarray(F)
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
        raise CurveSkelError(f"first_approximation: faces must be (m, 3) with m >= 1, got {F.shape}")
    if F.dtype.kind not in "iu":
        raise CurveSkelError(f"first_approximation: face indices must be integers, got {F.dtype}")
    F = F.astype(np.int64)
    if F.min() < 0 or F.max() >= len(V):
        raise CurveSkelError("first_approximation: face index out of range")
    if np.any((F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])):
        raise CurveSkelError("first_approximation: a face repeats a vertex (clean the mesh first)")
    if not (np.isfinite(spacing) and spacing > 0):
        raise CurveSkelError(f"first_approximation: spacing must be > 0, got {spacing}")
    return V, F
