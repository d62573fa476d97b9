"""Centre the Reeb graph's curve on the medial axis: an elastic fit of the medial points.

Why: the first approximation has the right structure (one branch per part, the mesh's cycles,
no fold: each contour is one point, in order along its branch) but its joints sit at the centres
of the contours' enclosing balls. A contour of a bent or flattened part is a slanted loop whose
ball centre is off the part's axis, and a Reeb region between two far-apart contours (a handle
around a hole, a long limb between sparse levels) is one straight bone that cuts through the
hole. Re-fitting sigma freely to E (earlier rounds) fixed the fit but let bones sweep across
any part whose cross-section is not round: E rewards a curve that fills the volume.

Formulation. Every vertex v has a medial point m(v), the centre of the largest inscribed ball
touching the surface at v (shrinking ball, :class:`.medial.MedialBalls`): on the axis of a tube,
on the mid-sheet of a plate. The curve is the graph of the Reeb skeleton, bones split into
pieces no longer than ``h``, with joint positions X minimising

    sum_v w_v |m(v) - sigma(v)|^2  +  lam * sum_j mass_j |X_j - (X_a + X_b) / 2|^2

where sigma(v) is the closest point to m(v) on the bones of v's own Reeb region (the topology
of the first approximation is never left), the second sum runs over the chain joints (degree 2,
neighbours a and b) and ``mass_j`` is the weight of the points joint j explains (so ``lam`` is
scale-free: 1 means a joint's smoothness counts as much as its data). With sigma fixed the
problem is linear least squares in X (a sparse J x J system, three right-hand sides);
it can be alternated with the closest-point step, as a principal curve or an elastic principal
graph is fitted -- stable only with ``lam > 0`` (without it zig-zag modes cost nothing and the
alternation drifts), and on a part whose medial set is a sheet even then free to wander: the
pipeline takes one round from the Reeb sigma. ``w_v`` is the vertex area times the medial
radius: the balls of surface noise are small and sit off the axis, the part's own balls are
large.

Examples
--------
>>> X = fit_centreline(M, w, joints, bones, bone_region, region)     # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from .mapping import closest_on_bones
from .rows import mul_rows, row_norm, take_rows

__all__ = ["split_long_bones", "region_candidates", "fit_centreline", "fit_radii", "medial_samples",
           "chain_smoothness_rows", "chain_neighbours", "joint_adjacency", "centre_stage",
           "fit_radii_surface", "smooth_chains"]


def split_long_bones(joints, bones, bone_region, h, only=None):
    """Split every bone longer than ``h`` into equal pieces (new joints on the segment).

    Parameters
    ----------
    joints : (J, 4) float
    bones : (B, 2) int
    bone_region : (B,) int
    h : float > 0, or (B,) float (a length per bone)
    only : (B,) bool, optional
        Split only these bones.

    Returns
    -------
    joints : (J', 4) float, the first J rows unchanged
    bones : (B', 2) int
    bone_region : (B',) int
    owner : (B',) int, the original bone of each piece
    """
    joints = np.asarray(joints, np.float64)
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    L = np.linalg.norm(joints[bones[:, 0], :3] - joints[bones[:, 1], :3], axis=1)
    k = np.maximum(1, np.ceil(L / np.maximum(h, 1e-300) - 1e-9).astype(np.int64))  # pieces per bone
    if only is not None:
        k[~np.asarray(only, bool)] = 1
    if np.all(k == 1):
        return joints, bones, np.asarray(bone_region, np.int64), np.arange(len(bones))
    J = len(joints)
    nb = int(k.sum())
    owner = np.repeat(np.arange(len(bones)), k)                  # piece -> original bone
    first = np.concatenate([[0], np.cumsum(k)[:-1]])
    piece = np.arange(nb) - np.repeat(first, k)                  # 0..k-1 along the bone
    # new joints: interior points u = p / k, p = 1..k-1
    inner = piece > 0
    u = piece[inner] / k[owner[inner]]
    bi, bj = bones[owner[inner], 0], bones[owner[inner], 1]
    new = joints[bi] + u[:, None] * (joints[bj] - joints[bi])
    new_id = np.full(nb, -1, np.int64)
    new_id[inner] = J + np.arange(inner.sum())
    # piece p runs from joint (p == 0 ? bi : new p) to (p == k-1 ? bj : new p+1)
    start = np.where(piece == 0, bones[owner, 0], new_id)
    nxt = np.roll(new_id, -1)
    end = np.where(piece == k[owner] - 1, bones[owner, 1], nxt)
    return (np.concatenate([joints, new]), np.stack([start, end], axis=1),
            np.asarray(bone_region, np.int64)[owner], owner)


def region_candidates(region, bone_region):
    """CSR (indptr, bone ids): the bones of each vertex's own Reeb region.

    Parameters
    ----------
    region : (n,) int
    bone_region : (B,) int

    Returns
    -------
    (indptr (n + 1,), ids (p,)) for :func:`.mapping.closest_on_bones`.
    """
    from .state import candidates_from_pairs
    region = np.asarray(region, np.int64)
    bone_region = np.asarray(bone_region, np.int64)
    R = int(max(region.max(initial=-1), bone_region.max(initial=-1))) + 1
    pairs = np.stack([bone_region, np.arange(len(bone_region))], axis=1)
    return candidates_from_pairs(pairs, region, R)


def _hat_matrix(bones, bone, t, J, sw):
    """Sparse (n x J): row v interpolates sigma(v) = t x_i + (1 - t) x_j, times sqrt(w_v)."""
    n = len(bone)
    rows = np.r_[np.arange(n), np.arange(n)]
    cols = np.r_[bones[bone, 0], bones[bone, 1]]
    vals = np.r_[sw * t, sw * (1.0 - t)]
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, J))


def joint_adjacency(n_joints, bones):
    """The skeleton's neighbours, CSR: (indptr, neighbour joint, bone id); joint j's
    neighbours are ``nbr[indptr[j]:indptr[j + 1]]`` (in bone order)."""
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    ends = np.r_[bones[:, 0], bones[:, 1]]
    other = np.r_[bones[:, 1], bones[:, 0]]
    bid = np.r_[np.arange(len(bones)), np.arange(len(bones))]
    o = np.argsort(ends, kind="stable")
    indptr = np.concatenate([[0], np.cumsum(np.bincount(ends, minlength=n_joints))])
    return indptr, other[o], bid[o]


def chain_neighbours(bones, J):
    """The joints of degree 2 and their two neighbours, without a Python loop.

    Returns
    -------
    chain, a, b : (c,) int
    """
    indptr, nbr, _ = joint_adjacency(J, bones)
    chain = np.flatnonzero(np.diff(indptr) == 2)
    return chain, nbr[indptr[chain]], nbr[indptr[chain] + 1]


def chain_smoothness_rows(bones, J):
    """Sparse (c x J) rows ``x_j - (x_a + x_b) / 2`` for every joint j of degree 2, and the js.

    Parameters
    ----------
    bones : (B, 2) int
    J : int

    Returns
    -------
    S : scipy.sparse.csr_matrix (c, J)
    chain : (c,) int, the joints of degree 2
    """
    chain, a, b = chain_neighbours(bones, J)
    c = len(chain)
    rows = np.repeat(np.arange(c), 3)
    cols = np.stack([chain, a, b], axis=1).ravel()
    vals = np.tile([1.0, -0.5, -0.5], c)
    return sp.csr_matrix((vals, (rows, cols)), shape=(c, J)), chain


def fit_centreline(M, w, joints, bones, cand, *, smooth=1.0, anchor=None, anchor_weight=0.0,
                   rounds=6, map_points=None, depth=None, depth_gain=0.05):
    """Joint positions of the elastic curve through the medial points (module docstring).

    Parameters
    ----------
    M : (n, 3) float
        Medial point of every vertex.
    w : (n,) float >= 0
        Weights.
    joints : (J, 3 or 4) float
        Start positions (and the graph's joints).
    bones : (B, 2) int
    cand : (indptr, ids)
        Candidate bones of each point (its Reeb region's, :func:`region_candidates`).
    smooth : float
        ``lam``: weight of the chain smoothness relative to the data, per joint.
    anchor : (J, 3) float, optional
        Positions the joints are held towards with ``anchor_weight`` (relative, per joint).
    rounds : int
        Alternations of closest-point mapping and linear solve.
    map_points : (n, 3) float, optional
        Points mapped to the bones instead of ``M`` (the vertices whose medial points M are).
    depth : callable (k, 3) -> (k,), optional
        Distance of points from the surface. When given, each joint goes to the centroid of
        the medial points it explains only if that lies deeper than where the joint is (by
        ``depth_gain`` of its depth), else it stays: on a tube the centroid is on the axis,
        deeper than an off-axis contour centre; on a plate every point of the mid-sheet is
        medial and the contour's own centre is kept.

    Returns
    -------
    X : (J, 3) float
    bone : (n,) int, t : (n,) float
        The mapping of the medial points at the end.
    """
    X = np.asarray(joints, np.float64)[:, :3].copy()
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    J = len(X)
    sw = np.sqrt(np.asarray(w, np.float64))
    S, chain = chain_smoothness_rows(bones, J)
    bone = t = None
    P = M if map_points is None else map_points
    for _ in range(max(rounds, 1)):
        bone, t, _ = closest_on_bones(P, X, bones, cand)
        A = _hat_matrix(bones, bone, t, J, sw)
        AtA = (A.T @ A).tocsr()
        rhs = A.T @ (sw[:, None] * M)
        mass = np.asarray(AtA.sum(axis=1)).ravel()
        floor = 0.05 * float(np.median(mass[mass > 0])) if np.any(mass > 0) else 1.0
        mass = np.maximum(mass, floor)
        lam = smooth * mass[chain]
        if depth is not None:
            has = np.asarray(AtA.sum(axis=1)).ravel() > 0
            B = np.where(has[:, None], rhs / np.maximum(np.asarray(AtA.sum(axis=1)), 1e-300), X)
            dX = depth(X)
            deeper = depth(B) > np.where(dX > 0, (1.0 + depth_gain) * dX, dX)
            target = np.where((deeper & has)[:, None], B, X)
            H = sp.diags(mass) + S.T @ sp.diags(lam) @ S
            rhs = mass[:, None] * target
            X = np.column_stack([spsolve(H.tocsc(), rhs[:, k]) for k in range(3)])
            continue
        H = AtA + S.T @ sp.diags(lam) @ S
        if anchor is not None and anchor_weight > 0:
            aw = anchor_weight * mass
            H = H + sp.diags(aw)
            rhs = rhs + aw[:, None] * anchor
        # joints no point maps to and no smoothness holds (isolated leaves): keep them still
        free = np.asarray(H.diagonal()).ravel()
        pin = floor * 1e-3 * (free <= 0)
        H = (H + sp.diags(pin + 1e-12 * floor)).tocsc()
        rhs = rhs + (pin + 1e-12 * floor)[:, None] * X
        X = np.column_stack([spsolve(H, rhs[:, k]) for k in range(3)])
    bone, t, _ = closest_on_bones(P, X, bones, cand)
    return X, bone, t


def fit_radii(V, w, X, bones, bone, t, *, smooth=0.01):
    """Radii of linear-radius bones best fitting each vertex's distance to sigma(v).

    Least squares of ``r(sigma(v)) - |v - sigma(v)|`` (weights w) with a light chain
    smoothness; linear in the radii. Radii are clipped at 0.

    Returns
    -------
    r : (J,) float
    """
    X = np.asarray(X, np.float64)[:, :3]
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    i, j = bones[bone, 0], bones[bone, 1]
    sig = mul_rows(t, take_rows(X, i)) + mul_rows(1.0 - t, take_rows(X, j))
    d = row_norm(V - sig)
    return _radii_for_distances(d, w, len(X), bones, bone, t, smooth)


def _radii_for_distances(d, w, J, bones, bone, t, smooth):
    """fit_radii's solve for given distances ``d``: the normal equations A^T W A r = A^T W d of
    the hat matrix A (row v: t at joint i, 1 - t at joint j of its bone) summed per bone
    (three weighted sums of the points of each bone, O(n) by bincount) instead of building
    the sparse n x J matrix: the same system up to the order of the sums."""
    B = len(bones)
    w = np.asarray(w, np.float64)
    tw = w * t
    uw = w * (1.0 - t)
    Stt = np.bincount(bone, weights=tw * t, minlength=B)
    Stu = np.bincount(bone, weights=tw * (1.0 - t), minlength=B)
    Suu = np.bincount(bone, weights=uw * (1.0 - t), minlength=B)
    bi, bj = bones[:, 0], bones[:, 1]
    AtA = sp.csr_matrix((np.r_[Stt, Suu, Stu, Stu], (np.r_[bi, bj, bi, bj], np.r_[bi, bj, bj, bi])),
                        shape=(J, J))
    AtA.eliminate_zeros()
    rhs = (np.bincount(bi, weights=np.bincount(bone, weights=tw * d, minlength=B), minlength=J)
           + np.bincount(bj, weights=np.bincount(bone, weights=uw * d, minlength=B), minlength=J))
    mass = np.asarray(AtA.sum(axis=1)).ravel()
    floor = 0.05 * float(np.median(mass[mass > 0])) if np.any(mass > 0) else 1.0
    S, chain = chain_smoothness_rows(bones, J)
    if J <= DENSE_RADII_JOINTS:
        return _radii_dense(AtA, rhs, S, chain, smooth * np.maximum(mass, floor)[chain], floor,
                            bones, J)
    H = AtA + S.T @ sp.diags(smooth * np.maximum(mass, floor)[chain]) @ S
    # every joint gets at least a weak pull to its neighbours' mean radius (joints without data)
    nb = sp.coo_matrix((np.ones(2 * len(bones)), (np.r_[bones[:, 0], bones[:, 1]],
                                                   np.r_[bones[:, 1], bones[:, 0]])), shape=(J, J)).tocsr()
    deg = np.maximum(np.asarray(nb.sum(axis=1)).ravel(), 1)
    Lp = sp.eye(J) - sp.diags(1.0 / deg) @ nb
    H = H + 1e-3 * floor * (Lp.T @ Lp) + sp.eye(J) * 1e-12 * floor
    r = spsolve(H.tocsc(), rhs)
    return np.maximum(r, 0.0)


#: Up to this many joints the radius fit's J x J system is solved dense: the sparse products
#: and their set-up cost more than the solve (a third of the radius fits on the 87k star).
DENSE_RADII_JOINTS = 400


def _radii_dense(AtA, rhs, S, chain, c, floor, bones, J):
    """:func:`_radii_for_distances`'s system, assembled and solved as dense J x J arrays:
    H = A^T W A + S^T diag(c) S + 1e-3 floor Lp^T Lp + 1e-12 floor I, r = H^-1 rhs, clipped
    at 0 (Lp = I - D^-1 N: each joint against its neighbours' mean)."""
    H = AtA.toarray()
    Sd = S.toarray()
    H += (Sd * c[:, None]).T @ Sd
    N = np.zeros((J, J))
    np.add.at(N, (np.r_[bones[:, 0], bones[:, 1]], np.r_[bones[:, 1], bones[:, 0]]), 1.0)
    deg = np.maximum(N.sum(axis=1), 1)
    Lp = np.eye(J) - N / deg[:, None]
    H += 1e-3 * floor * (Lp.T @ Lp)
    H[np.diag_indices(J)] += 1e-12 * floor
    return np.maximum(np.linalg.solve(H, rhs), 0.0)


def _signed_depth(tree, inside, V=None, F=None, k: int = 8, ids=None, face_of=None):
    """Distance to the surface, negative outside the mesh: the centroid of a curved medial set
    (a ring's arc) can fall in the hole, far from the surface but not in the shape.

    The distance is to the triangles around the ``k`` nearest vertices (``tree``: a KD-tree of
    the vertices), not to the nearest vertex: a point lying on a large face is ~0 deep, so
    whether the ray-parity test calls it inside or outside (a matter of the last bits there)
    cannot change a decision that compares depths (the octopus scaled by 1e6: 0.011 D).
    ``ids``: the vertex of each point of ``tree``, if it holds a subset of the vertices.
    ``face_of``: the faces around each vertex (:func:`.mesh_graph.faces_around`), if at hand."""
    from .mesh_graph import faces_around
    from .quality import point_triangle_distance

    csr = [face_of]                 # the faces around each vertex, built on first use

    def around(v):
        """(point, face) pairs: every face holding one of the vertices ``v`` (p, k)."""
        if csr[0] is None:
            csr[0] = faces_around(F, len(V))
        starts, face = csr[0]
        lo, cnt = starts[v.ravel()], np.diff(starts)[v.ravel()]
        pi = np.repeat(np.repeat(np.arange(len(v)), v.shape[1]), cnt)
        fi = face[np.repeat(lo, cnt) + np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)]
        return pi, fi

    def depth(P):
        P = np.asarray(P, np.float64).reshape(-1, 3)
        d, nn = tree.query(P, k=min(k, tree.n))
        d, nn = d.reshape(len(P), -1), nn.reshape(len(P), -1)
        d = d[:, 0]
        if F is not None and len(P):
            pi, fi = around(nn if ids is None else ids[nn])
            T = V[F[fi]]
            best = np.full(len(P), np.inf)
            np.minimum.at(best, pi, point_triangle_distance(P[pi], T[:, 0], T[:, 1], T[:, 2]))
            d = np.minimum(best, d)
        return np.where(inside(P), d, -d)
    return depth


def medial_samples(V, F, fa_joints, fa_bones, bone, t, k, seed=0, key=None, weights=None,
                   face_cross=None):
    """Medial points of (at most) k area-weighted vertex samples.

    ``key`` (n,): the quantity of the shape the draw reads (:func:`.state.canonical_subset`;
    the vertex numbers if None); ``weights`` (n,): the vertices' areas if already known (any
    scale); ``face_cross``: that of :func:`.vertex_area.face_cross` (V, F), if at hand.

    Returns
    -------
    idx : (k,) int   the sampled vertices
    M : (k, 3) float their medial points
    rho : (k,) float their medial radii
    balls : MedialBalls, with its KD-tree of the surface vertices (reusable)
    """
    from .medial import MedialBalls
    from .state import canonical_subset
    from .vertex_area import vertex_areas
    n = len(V)
    subsample = n > MEDIAL_TREE_POINTS             # the balls' points too (see below)
    key = np.arange(n) if key is None else key
    drawn = n > k or subsample
    a = vertex_areas(V, F, face_cross) if weights is None and drawn else weights
    idx = np.arange(n) if n <= k else canonical_subset(key, k, seed, p=a)
    X = np.asarray(fa_joints)[:, :3]
    i, j = fa_bones[bone[idx], 0], fa_bones[bone[idx], 1]
    sig = t[idx, None] * X[i] + (1.0 - t[idx, None]) * X[j]
    d = row_norm(V[idx] - sig)
    points = None
    if subsample:
        # The balls shrink against an area-weighted subsample of the surface (the samples
        # included): on a huge mesh the k-NN queries of balls centred on an axis visit the
        # whole ring of vertices around it, and vertices this dense add nothing measurable
        # (a ball can bulge through the subsample's gaps by their sagitta, ~gap^2 / radius).
        keep = canonical_subset(key, MEDIAL_TREE_POINTS, seed + 1, p=a)
        points = np.union1d(keep, idx)
    balls = MedialBalls(V, F, points=points, face_cross=face_cross)
    q = idx if points is None else np.searchsorted(points, idx)
    M, rho = balls.at(q, rho0=2.0 * d)          # (floored at 1e-12 of the size inside: no unit)
    return idx, M, rho, balls


#: Move a joint to the medial centroid only where that is deeper inside (see fit_centreline).
DEPTH_SELECT = True
#: Rounds of the elastic fit (closest point, then linear solve).
CENTRE_ROUNDS = 1
#: Map the vertices (True) or their medial points (False) to the bones in the closest-point step.
MAP_VERTICES = True
#: Medial samples used for centring (area-weighted vertices; their average is what counts).
MEDIAL_SAMPLES = 3000
#: Surface points the medial balls shrink against, at most (an area-weighted subsample above).
#: 50k: a ball bulges through the subsample's gaps by their sagitta (gap^2 / 8r); on the 100k
#: capsule and torus the joints move by 6e-5 and 2e-5 of the skeleton's extent against the
#: full 100k points, and the centring takes 0.06 s less. Every shared mesh has fewer vertices.
MEDIAL_TREE_POINTS = 50_000
#: Bones of branching regions are split into pieces of this many contour spacings before
#: centring, so a limb's bone that starts at the centre of the body can bend into the limb.
JUNCTION_SPLIT = 2.0
#: Bones shorter than this many contour spacings (region joints next to their loop's joint)
#: are contracted before centring: their direction is noise.
COLLAPSE_SPACINGS = 0.5


def centre_stage(state, spacing_abs, *, smooth, seed=0):
    """Centre the state's first-approximation skeleton on the medial points (in place).

    Parameters
    ----------
    state : PipelineState
        Holding the first approximation (joints, bones, sigma, region, pairs).
    spacing_abs : (B,) float
        Contour spacing (absolute length) of the component of every bone.
    smooth : float
        Chain smoothness (``lam`` of :func:`fit_centreline`).
    """
    from .edit import collapse_short_bones
    V, F = state.V, state.F
    idx, M, rho, balls = medial_samples(V, F, state.joints, state.bones, state.bone, state.t,
                                        MEDIAL_SAMPLES, seed=seed, key=state.key,
                                        weights=state.areas,
                                        face_cross=state.face_cross)
    state.face_cross = None                          # (only the surface normals needed it)
    state.medial = (M, rho)
    state.medial_points = int(len(balls.pts))       # the surface points the balls shrank against
    # contract the tiny bones (direction noise), then split the bones of branching regions
    joints, bones, bmap = collapse_short_bones(state.joints, state.bones,
                                               COLLAPSE_SPACINGS * spacing_abs)
    state.joints, state.bones = joints, bones
    state.apply_bone_map(bmap)
    per_region = np.bincount(state.pairs[:, 0], minlength=state.n_regions)
    sp_new = np.zeros(len(bones))
    np.maximum.at(sp_new, bmap, spacing_abs)
    junction = np.zeros(len(bones), bool)
    junction[state.pairs[per_region[state.pairs[:, 0]] >= 3, 1]] = True
    h = JUNCTION_SPLIT * np.where(sp_new > 0, sp_new, np.median(spacing_abs))
    joints, bones, _, owner = split_long_bones(joints, bones, np.zeros(len(bones), np.int64), h,
                                               only=junction)
    state.joints, state.bones = joints, bones
    # each piece explains its bone's regions
    o = np.argsort(owner, kind="stable")
    st = np.concatenate([[0], np.cumsum(np.bincount(owner, minlength=int(owner.max()) + 1))])
    cnt = st[state.pairs[:, 1] + 1] - st[state.pairs[:, 1]]
    reg = np.repeat(state.pairs[:, 0], cnt)
    local = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    state.pairs = np.unique(np.stack([reg, o[np.repeat(st[state.pairs[:, 1]], cnt) + local]], 1), axis=0)
    depth = (_signed_depth(balls.tree, state.inside, V, F, ids=balls.ids,
                           face_of=state.faces_around) if DEPTH_SELECT else None)
    X, _, _ = fit_centreline(M, rho, joints, bones, state.candidates(idx), smooth=smooth,
                             rounds=CENTRE_ROUNDS, map_points=V[idx] if MAP_VERTICES else None,
                             depth=depth)
    state.joints = np.column_stack([X, joints[:, 3]])
    state.remap()
    state.joints[:, 3] = fit_radii(V, state.weights, X, bones, state.bone, state.t)


#: Reweighting rounds of :func:`fit_radii_surface` (least absolute deviations by IRLS).
SURFACE_RADII_ROUNDS = 5


def fit_radii_surface(V, w, joints, bones, cand=None, *, rounds=SURFACE_RADII_ROUNDS):
    """Radii that make the silhouette follow the surface, the curve held fixed.

    Each vertex is mapped to its closest point on any bone (the silhouette's nearest part:
    what ``recon`` compares the surface with; mapping it to its Reeb region's bones instead
    costs 20-50 % of recon on the shared meshes), and the radii minimise the weighted sum of
    ``| |v - sigma(v)| - r(sigma(v)) |`` -- the distance from the surface to the silhouette
    that ``recon`` measures -- by iteratively reweighted least squares. Least absolute
    deviations rather than squares: where a cross-section is not round (a torso) the squares
    inflate the ball towards the far side and the silhouette bulges out of the near one.
    The positions are not touched, so this cannot make the curve zig-zag or fill the volume.

    Returns
    -------
    r : (J,) float
    bone : (n,) int, t : (n,) float   the mapping the radii were fitted with
    """
    from .mapping import closest_on_bones
    X = np.asarray(joints, np.float64)[:, :3]
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    bone, t, _ = closest_on_bones(V, X, bones, cand)
    i, j = bones[bone, 0], bones[bone, 1]
    d = row_norm(V - (mul_rows(t, take_rows(X, i)) + mul_rows(1.0 - t, take_rows(X, j))))
    r = _radii_for_distances(d, w, len(X), bones, bone, t, 0.01)
    for _ in range(rounds):
        res = np.abs(d - (t * r[i] + (1.0 - t) * r[j]))
        floor = 1e-3 * max(float(np.median(res)), 1e-300)
        r = _radii_for_distances(d, w / np.maximum(res, floor), len(X), bones, bone, t, 0.01)
    return r, bone, t


def smooth_chains(X, bones, lam):
    """Positions near ``X`` with smoother chains: argmin |Y - X|^2 + lam |Y_j - (Y_a + Y_b)/2|^2
    over the chain joints (junctions and leaves are held by the first term alone).

    Returns
    -------
    Y : (J, 3) float
    """
    X = np.asarray(X, np.float64)[:, :3]
    J = len(X)
    S, chain = chain_smoothness_rows(bones, J)
    if lam <= 0 or chain.size == 0:
        return X.copy()
    H = (sp.eye(J) + lam * (S.T @ S)).tocsc()
    return np.column_stack([spsolve(H, X[:, k]) for k in range(3)])
