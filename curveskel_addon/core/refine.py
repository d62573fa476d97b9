"""Adaptive refinement: split the bones that leave the mesh, re-solve (issue 5).

A straight bone between two joints inside the mesh can still cut a corner: at a bent elbow,
along a curved tail, round a handle. The containment term of the solver (:mod:`.solvers.lm`)
samples only a few points per bone and is soft, so such bones survive it. This stage tests
points along every bone with the exact inside test (ray parity, :class:`.quality.InsideTest`),
splits each bone that has points outside at its worst point and re-optimises, only while more
than ``SOLVE_ABOVE`` of the points are outside, up to a joint budget. The same solve also
serves the fit: the bones that hold the most of E are split in the middle (the new joint on the
bone, so E starts unchanged) and bend where their part does. A solved round is kept if less is
outside afterwards, or, failing that, if after the local repair below it has no more outside
and a lower E than its start would have.

The new joint starts where the shape is: at the weighted centroid of the bone's points mapped
near the split (a cross-section of the part the bone explains, whose centre is inside even when
the bone's own point is not), with their mean distance as its radius. The mapping of the split
bone's points is carried over exactly (sigma is unchanged where the joint is interpolated) and
then re-fitted by the solver.

Then, without re-solving: joints still outside (tips of thin parts whose balls have shrunk to
nothing, where the solver puts the joint on the surface) are moved towards their neighbours
until inside, bones still cutting corners are split again, the new joint placed where its
two bones have the fewest points outside among points on the line through the cross-section's
centre and the medial balls (:mod:`.medial`) touching the surface nearest the bone's outside
points, and joints of bones still outside are relocated (:func:`relocate_joints`). These local
rounds leave the rest of the skeleton as the solver put it. Last, short reversals (a chain
turning back by more than 154 degrees with a bone shorter than two radii, typically at a
junction) are merged away when that leaves no more outside.

Examples
--------
>>> pr2, log = refine(pr, V, F, solve)       # doctest: +SKIP
>>> log["split"], log["outside_before"], log["outside_after"]    # doctest: +SKIP
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .energy import energy, sigma_terms
from .problem import FitProblem
from .medial import MedialBalls
from .postprocess import FOLD_MIN_LENGTH, unfold_chains
from .quality import InsideTest, bone_points

__all__ = ["refine", "outside_samples", "split_bones", "pull_in_joints", "relocate_joints"]

#: Points tested per bone, at t = (k + 1/2) / PER_BONE (the quality measure uses 10).
PER_BONE = 16
#: Half-width (in t) of the band of points that places a new joint.
BAND = 0.1
#: Solved rounds only while more than this fraction of the tested points is outside: with a
#: few bones out, re-solving everything for them moved the rest more than it helped (the round
#: was rejected on spot, hand and homer at 0.6-1.6 % outside); the local rounds repair them.
SOLVE_ABOVE = 0.02
#: Fraction of the bones, those explaining the most of E, split too in a solved round.
FIT_SPLIT = 0.4
#: Rounds of splitting without re-solving, after the solved rounds.
LOCAL_ROUNDS = 6


def outside_samples(joints, bones, inside: InsideTest, *, per_bone: int = PER_BONE):
    """Which points along each bone are outside the mesh.

    Parameters
    ----------
    joints : (J, 4) float
    bones : (B, 2) int
    inside : InsideTest
        Of the closed mesh.
    per_bone : int

    Returns
    -------
    t : (per_bone,) float
        Sample parameters (sigma = t x_i + (1 - t) x_j).
    out : (B, per_bone) bool
    joint_out : (J,) bool
    """
    joints = np.asarray(joints, np.float64)
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    t = (np.arange(per_bone) + 0.5) / per_bone
    nb = len(bones) * per_bone
    ins = inside(np.concatenate([bone_points(joints, bones, per_bone)[:nb], joints[:, :3]]))
    return t, ~ins[:nb].reshape(len(bones), per_bone), ~ins[nb:]


def _segment_points(A, B, u):
    """``u A + (1 - u) B`` for every ``u``: points (..., len(u), 3) on segments A -> B (..., 3)."""
    return u[:, None] * A[..., None, :] + (1 - u)[:, None] * B[..., None, :]


def _neighbour_mean(joints, bones):
    """(J, 3) mean position of every joint's neighbours (0 for a joint without bones) and the
    degrees (J,), from the bone list in both directions."""
    J = len(joints)
    ends, other = bones.ravel(), bones[:, ::-1].ravel()
    deg = np.bincount(ends, minlength=J)
    T = np.stack([np.bincount(ends, weights=joints[other, a], minlength=J) for a in range(3)], 1)
    return T / np.maximum(deg, 1)[:, None], deg


def split_bones(pr: FitProblem, split: np.ndarray, t_split: np.ndarray,
                centroid=True) -> FitProblem:
    """Split bones at parameters, each with a new joint placed from the points it explains.

    Parameters
    ----------
    pr : FitProblem
    split : (k,) int
        Bones to split (distinct).
    t_split : (k,) float in (0, 1)
        Where: the new joint of bone (i, j) is at the points mapped near ``t x_i + (1-t) x_j``.
    centroid : bool or (k,) bool
        False: the new joint is that interpolated point and radius instead (sigma and E are
        then exactly unchanged, so a solve can only improve on the unsplit skeleton).

    Returns
    -------
    FitProblem
        ``k`` more joints and bones; bone ``b = (i, j)`` becomes ``(i, new)`` and a bone
        ``(new, j)`` is appended; points keep their sigma up to the new joint's offset.
    """
    split = np.asarray(split, np.int64)
    ts = np.asarray(t_split, np.float64)
    J, Bn = len(pr.joints), len(pr.bones)
    k = len(split)
    new_ids = J + np.arange(k)
    i, j = pr.bones[split, 0], pr.bones[split, 1]
    interp = ts[:, None] * pr.joints[i] + (1.0 - ts[:, None]) * pr.joints[j]
    # The cross-section near the split: points of the bone with |t - t*| < BAND.
    slot = np.full(Bn, -1, np.int64)
    slot[split] = np.arange(k)
    s = slot[pr.bone]
    on = s >= 0
    near = on.copy()
    near[on] = np.abs(pr.t[on] - ts[s[on]]) < BAND
    w = pr.weights[near]
    W = np.bincount(s[near], weights=w, minlength=k)
    C = np.stack([np.bincount(s[near], weights=w * pr.points[near, a], minlength=k)
                  for a in range(3)], axis=1) / np.maximum(W, 1e-300)[:, None]
    R = np.bincount(s[near], weights=w * np.linalg.norm(pr.points[near] - C[s[near]], axis=1),
                    minlength=k) / np.maximum(W, 1e-300)
    cnt = np.bincount(s[near], minlength=k)
    ok = (cnt >= 4) & np.broadcast_to(np.asarray(centroid, bool), (k,))
    new_joints = interp.copy()
    new_joints[ok, :3] = C[ok]
    new_joints[ok, 3] = R[ok]
    joints = np.concatenate([pr.joints, new_joints])
    bones = pr.bones.copy()
    bones[split, 1] = new_ids
    bones = np.concatenate([bones, np.stack([new_ids, j], axis=1)])
    bone, t = pr.bone.copy(), pr.t.copy()
    # t >= t*: on (i, new) with t' = 1 - (1 - t) / (1 - t*); t < t*: on (new, j) with t / t*.
    hi = on.copy()
    hi[on] = pr.t[on] >= ts[s[on]]
    lo = on & ~hi
    t[hi] = 1.0 - (1.0 - pr.t[hi]) / (1.0 - ts[s[hi]])
    t[lo] = pr.t[lo] / ts[s[lo]]
    bone[lo] = Bn + s[lo]
    return FitProblem(pr.points, pr.weights, joints, bones, bone, np.clip(t, 0.0, 1.0), dict(pr.meta))


def pull_in_joints(joints, bones, inside: InsideTest, *, steps: int = 8) -> tuple[np.ndarray, int]:
    """Move joints that are outside the mesh towards their neighbours until inside.

    The target of a joint is the mean of its neighbours (a leaf's: its one neighbour); the
    smallest move of ``lam = 1/2^steps ... 1/2`` of the way (and, for a joint with two or more
    neighbours, 3/4 and all the way: the chord between them) that puts it inside is taken. A
    joint no such move brings inside stays. Returns (joints, moved).
    """
    joints = np.array(joints, np.float64)
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    out = ~inside(joints[:, :3])
    T, deg = _neighbour_mean(joints, bones)
    L = np.flatnonzero(out & (deg > 0))
    if not L.size:
        return joints, 0
    T = T[L]
    lams = np.concatenate([0.5 ** np.arange(steps, 0, -1), [0.75, 1.0]])
    X = joints[L, None, :3] + lams[None, :, None] * (T[:, None, :] - joints[L, None, :3])
    ins = inside(X.reshape(-1, 3)).reshape(len(L), len(lams))
    ins[deg[L] == 1, steps:] = False                       # a leaf does not reach its neighbour
    first = np.where(ins.any(axis=1), ins.argmax(axis=1), -1)
    moved = first >= 0
    joints[L[moved], :3] = X[moved, first[moved]]
    return joints, int(moved.sum())


def relocate_joints(joints, bones, inside: InsideTest, balls: MedialBalls | None = None, *,
                    per_bone: int = PER_BONE) -> tuple[np.ndarray, int]:
    """Move joints of bones that leave the mesh to where their bones have the fewest points
    outside (a local descent on the exact outside count, no solver).

    Candidates for a joint: ``x + lam (T - x)`` with T the mean of its neighbours, lam = 1/8 ...
    1 (a leaf's: at most 1/2), and, with ``balls``, the medial balls touching the surface
    nearest the outside points of its bones (then the ball's radius too). A joint inside with
    all its bones where both ends are inside can still be the trouble: the middle joint of a
    chain that jumps between two parts (octopus: a joint of radius 0 between two tentacles).
    Joints sharing a bone do not move in the same call (each is scored with its neighbours
    fixed), worst first.

    Returns
    -------
    joints : (J, 4) float, moved : int
    """
    joints = np.array(joints, np.float64)
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    J, Bn = len(joints), len(bones)
    if not Bn:
        return joints, 0
    t, out, _ = outside_samples(joints, bones, inside, per_bone=per_bone)
    bad = out.sum(axis=1)
    cand = np.unique(bones[bad > 0].ravel())
    if not cand.size:
        return joints, 0
    T, deg = _neighbour_mean(joints, bones)
    ends, other = bones.ravel(), bones[:, ::-1].ravel()
    inc_bone = np.repeat(np.arange(Bn), 2)
    lams = np.array([0.125, 0.25, 0.5, 0.75, 1.0])
    u = (np.arange(per_bone) + 0.5) / per_bone
    P_all, R_all, S_all, meta = [], [], [], []
    for j in cand:
        inc = np.flatnonzero(ends == j)
        lj = lams[lams <= 0.5] if deg[j] == 1 else lams
        P = joints[j, :3] + lj[:, None] * (T[j] - joints[j, :3])
        R = np.full(len(P), joints[j, 3])
        if balls is not None:
            b_in = inc_bone[inc]
            Q = _segment_points(joints[bones[b_in, 0], :3], joints[bones[b_in, 1], :3], t)[out[b_in]]
            if len(Q):
                pick = np.linspace(0, len(Q) - 1, min(len(Q), per_bone)).astype(int)
                mc, mr = balls.at_nearest(Q[pick])
                P, R = np.concatenate([P, mc]), np.concatenate([R, mr])
        P = np.concatenate([joints[j:j + 1, :3], P])            # first: stay
        R = np.concatenate([joints[j:j + 1, 3], R])
        O = joints[other[inc], :3]                              # the far ends of its bones
        S = _segment_points(P[:, None, :], O[None, :, :], u)        # (candidates, bones, n, 3)
        P_all.append(P), R_all.append(R), S_all.append(S.reshape(-1, 3))
        meta.append((j, len(P), len(inc)))
    ins = inside(np.concatenate(S_all))
    scores, off = [], 0
    for (j, L, d), S in zip(meta, S_all):
        scores.append((~ins[off:off + len(S)]).reshape(L, d * per_bone).sum(axis=1))
        off += len(S)
    order = np.argsort([-sc[0] for sc in scores], kind="stable")
    blocked = np.zeros(J, bool)
    moved = 0
    for k in order:
        j = meta[k][0]
        best = int(np.argmin(scores[k]))
        if blocked[j] or not scores[k][best] < scores[k][0]:
            continue
        joints[j, :3], joints[j, 3] = P_all[k][best], R_all[k][best]
        blocked[other[ends == j]] = True
        blocked[j] = True
        moved += 1
    return joints, moved


def worst_fitting_bones(pr: FitProblem, fraction: float, exclude=()) -> np.ndarray:
    """The ``fraction`` of the bones with the largest share of E (worst first), but ``exclude``.

    A bone's share is the weighted sum of ``e_v^2`` over the points mapped to it: a long bone
    whose linear radius cannot follow its part (a torso, a thigh) holds much of E, and the
    solver cannot bend it; split in the middle and re-solved, it can (armadillo: 40 % of the
    bones split, E / 4.5 in one solved round, recon 0.0063 -> 0.0047 D).
    """
    e = sigma_terms(pr)[2]
    Eb = np.bincount(pr.bone, weights=pr.weights * e * e, minlength=len(pr.bones))
    Eb[np.asarray(exclude, np.int64)] = -1.0
    k = int(np.floor(fraction * len(pr.bones) + 0.5))
    order = np.argsort(-Eb, kind="stable")[:k]
    return order[Eb[order] > 0]


def _split_outside(pr, t, out, budget, inside: InsideTest | None = None, per_bone: int = PER_BONE,
                   balls: MedialBalls | None = None, fit: float = 0.0):
    """Split every bone with points outside away from its ends (outside at an end is that
    joint's business) at the mean parameter of its outside points, worst first, at most
    ``budget``. Returns (problem, bones split).

    The new joint starts at the centre of the cross-section it explains (:func:`split_bones`).
    With ``inside`` (when no solver follows) it is placed instead on the line from the bone's
    own point there through that centre, where the two new bones have the fewest points
    outside: the centre of a curved part's cross-section can lie off to one side, the bone's
    own point is outside. With ``balls`` the medial balls touching the surface nearest the
    centre and nearest each outside point of the bone are candidates too (centre and radius):
    in a thin part the bone explains too few points for a centroid. A bone is split only if its halves have fewer points outside than
    it had. Without ``inside`` (a solve follows), also the ``fit`` fraction of the bones that
    explain the most of E (:func:`worst_fitting_bones`), in the middle.
    """
    cand = np.flatnonzero(out[:, 1:-1].any(axis=1))
    cand = cand[np.argsort(-out[cand].sum(axis=1), kind="stable")][:max(budget, 0)]
    if not cand.size:
        return pr, 0
    ts = np.clip((out[cand] * t).sum(axis=1) / out[cand].sum(axis=1), t[1], t[-2])
    at_centroid = np.ones(len(cand), bool)
    if inside is None and fit > 0:
        # In the middle, the new joint on the bone: E is unchanged until the solver bends it.
        extra = worst_fitting_bones(pr, fit, exclude=cand)[:max(budget - len(cand), 0)]
        cand, ts = np.concatenate([cand, extra]), np.concatenate([ts, np.full(len(extra), 0.5)])
        at_centroid = np.concatenate([at_centroid, np.zeros(len(extra), bool)])
    sp = split_bones(pr, cand, ts, at_centroid)
    if inside is None:
        return sp, int(len(cand))
    k, J0 = len(cand), len(pr.joints)
    i, j = pr.bones[cand, 0], pr.bones[cand, 1]
    X0 = ts[:, None] * pr.joints[i, :3] + (1.0 - ts[:, None]) * pr.joints[j, :3]
    C = sp.joints[J0:, :3]
    lam = np.linspace(0.0, 1.5, 7)
    P = X0[:, None, :] + lam[None, :, None] * (C - X0)[:, None, :]          # (k, L, 3)
    radius = np.repeat(sp.joints[J0:, 3:4], len(lam), axis=1)              # (k, L)
    if balls is not None:
        # Medial balls at the surface nearest the centroid and nearest every outside point of
        # the bone (the bone's own point at t* stands in for its inside points).
        Pb = _segment_points(pr.joints[i, :3], pr.joints[j, :3], t)
        Pb = np.where(out[cand][:, :, None], Pb, X0[:, None, :])
        mc, mr = balls.at_nearest(np.concatenate([C, Pb.reshape(-1, 3)]))
        P = np.concatenate([P, mc[:k, None], mc[k:].reshape(k, -1, 3)], axis=1)
        radius = np.concatenate([radius, mr[:k, None], mr[k:].reshape(k, -1)], axis=1)
    u = (np.arange(per_bone) + 0.5) / per_bone
    # Points of the halves (i, new) and (new, j) for every candidate position: (k, L, 2, n, 3).
    Xi = np.broadcast_to(pr.joints[i, None, :3], P.shape)
    Xj = np.broadcast_to(pr.joints[j, None, :3], P.shape)
    S = np.stack([_segment_points(Xi, P, u), _segment_points(P, Xj, u)], axis=2)
    bad = (~inside(S.reshape(-1, 3))).reshape(k, P.shape[1], -1).sum(axis=2)
    best = bad.argmin(axis=1)                      # first minimum: the smallest move
    better = bad[np.arange(k), best] < out[cand].sum(axis=1)
    if not better.all():
        if not better.any():
            return pr, 0
        cand, ts, best = cand[better], ts[better], best[better]
        sp = split_bones(pr, cand, ts)
    rows = np.flatnonzero(better)
    sp.joints[J0:, :3] = P[rows, best]
    sp.joints[J0:, 3] = radius[rows, best]
    return sp, int(len(cand))


def refine(pr: FitProblem, V, F, solve: Callable[[FitProblem], FitProblem], *,
           max_joints: int = 300, rounds: int = 3, local_rounds: int = LOCAL_ROUNDS,
           per_bone: int = PER_BONE, solved: bool = True,
           fit: float = FIT_SPLIT) -> tuple[FitProblem, dict]:
    """Split bones with points outside the mesh and re-solve, ``rounds`` times at most; then
    move outside joints in, split and relocate joints without re-solving, ``local_rounds``
    times.

    A solved round is kept if less of the skeleton is outside afterwards, or else if after the
    local repair it has no more outside and a lower E than its start would have (the solver's
    containment term approximates the surface and can be wrong in parts thinner than its
    blending radius). The rounds without a solve keep the rest of the skeleton as it is and
    place each new joint from the points it explains: they finish the corners the solver
    leaves cut.

    Parameters
    ----------
    pr : FitProblem
        A solved problem, unless ``solved`` is False (not modified).
    V, F : the closed surface the skeleton must stay inside.
    solve : callable(FitProblem) -> FitProblem
        Re-optimises (the pipeline's solver settings).
    max_joints : int
        No split beyond this many joints.
    rounds, local_rounds : int
    solved : bool
        False if ``pr`` still needs a solve (the pipeline's unfolding changed it): the first
        solved round serves, and ``pr`` is solved alone only if no round is kept.

    Returns
    -------
    FitProblem, dict
        The log holds ``outside_before`` / ``outside_after`` (fractions of the tested points),
        ``split`` and ``kept`` (bones split per round, whether the round was kept; solved
        rounds first), ``local`` (how many of the rounds did not re-solve) and ``pulled_in``
        (joints moved per local round: outside joints pulled in, joints relocated by
        :func:`relocate_joints`), ``energy`` (E at the start, then after each solved round),
        ``reversals`` (short reversals merged at the end).
    """
    pr = pr.copy()
    inside = InsideTest(V, F)
    balls = MedialBalls(V, F)
    log = {"split": [], "kept": [], "local": 0, "pulled_in": [],
           "energy": [energy(pr)]}           # E at the start (before any solve), per solved round
    t, out, _ = outside_samples(pr.joints, pr.bones, inside, per_bone=per_bone)
    log["outside_before"] = frac = float(out.mean()) if out.size else 0.0

    def fraction(q):
        o = outside_samples(q.joints, q.bones, inside, per_bone=per_bone)[1]
        return o, (float(o.mean()) if o.size else 0.0)

    def repaired(q, o_f=None):
        o, f = fraction(q) if o_f is None else o_f
        return _local_rounds(q, o, f, t, inside, balls, fraction, max_joints, local_rounds, per_bone)

    best = None                   # (outside after repair, E, problem, local log) of the choice
    for _ in range(rounds):                     # split, re-solve
        if frac <= SOLVE_ABOVE:
            break
        trial, n = _split_outside(pr, t, out, max_joints - len(pr.joints), fit=fit)
        if not n:
            break
        trial = solve(trial)
        log["split"].append(n)
        log["energy"].append(energy(trial))
        out_t, frac_t = fraction(trial)
        cand = repaired(trial, (out_t, frac_t))
        e_cand = energy(cand[0])
        if frac_t < frac:
            keep = True                   # less outside even before the repair
        else:
            # Judged after the local repair both would get: the solver may leave a few more
            # points outside than it started with and still fit far better (more joints where
            # E was). An unsolved start (unfolded) is judged by what is outside only: its E is
            # not comparable, and solving it just to compare would cost a solve.
            if best is None:
                base = repaired(pr)
                best = (base[1], energy(base[0]) if solved else np.inf, base[0], base[2])
            keep = (cand[1], e_cand) <= best[:2]
        log["kept"].append(bool(keep))
        if not keep:
            break
        best = (cand[1], e_cand, cand[0], cand[2])
        pr, solved, out, frac = trial, True, out_t, frac_t
    if best is None or not solved:
        if not solved:
            pr = solve(pr)
        res = repaired(pr)
        best = (res[1], energy(res[0]), res[0], res[2])
    frac_end, _, pr, local = best
    # Last, short reversals: a chain joint where the chain turns back (> 154 degrees) with a
    # bone too short for the fold rule (inside the joint's ball, e.g. at a junction); E does
    # not mind, a rigger sees a bone pointing backwards. (Long zig-zags across a flat part
    # stay: they explain it.) Merged if no more is then outside.
    q, n_rev = unfold_chains(pr, min_length=0.0, overlap=False, short=FOLD_MIN_LENGTH)
    frac_q = fraction(q)[1] if n_rev else np.inf
    if frac_q <= frac_end:
        pr, frac_end = q, frac_q
    else:
        n_rev = 0
    log["reversals"] = n_rev
    log["local"] = len(local["split"])
    log["split"] += local["split"]
    log["kept"] += [True] * len(local["split"])
    log["pulled_in"] = local["pulled_in"]
    log["outside_after"] = frac_end
    return pr, log


def _local_rounds(pr, out, frac, t, inside, balls, fraction, max_joints, rounds, per_bone):
    """Up to ``rounds`` rounds without a solve: outside joints pulled in, bones split (new
    joints pulled in), joints relocated; a round is kept only if less is outside.
    Returns (problem, outside fraction, {"split": [...], "pulled_in": [...]})."""
    log = {"split": [], "pulled_in": []}
    for _ in range(rounds):
        a = pr.copy()
        a.joints, moved = pull_in_joints(pr.joints, pr.bones, inside)
        out_a, frac_a = fraction(a)
        b, n = _split_outside(a, t, out_a, max_joints - len(pr.joints), inside, per_bone, balls)
        if n:
            b.joints, moved_b = pull_in_joints(b.joints, b.bones, inside)
            out_b, frac_b = fraction(b)
        if n and frac_b < frac_a:
            a, out_a, frac_a, moved = b, out_b, frac_b, moved + moved_b
        else:
            n = 0
        c = a.copy()
        c.joints, moved_c = relocate_joints(a.joints, a.bones, inside, balls, per_bone=per_bone)
        if moved_c:
            out_c, frac_c = fraction(c)
            if frac_c < frac_a:
                a, out_a, frac_a, moved = c, out_c, frac_c, moved + moved_c
        if not frac_a < frac:
            break
        log["split"].append(n)
        log["pulled_in"].append(moved)
        pr, out, frac = a, out_a, frac_a
    return pr, frac, log
