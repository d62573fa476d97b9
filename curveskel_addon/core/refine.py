"""Adaptive refinement: split the bones that leave the mesh, re-solve (issue 5).

A straight bone between two joints inside the mesh can still cut a corner: at a bent elbow,
along a curved tail, round a handle. The containment term of the solver (:mod:`.solvers.lm`)
samples only a few points per bone and is soft, so such bones survive it. This stage tests
points along every bone with the exact inside test (ray parity, :class:`.quality.InsideTest`),
splits each bone that has points outside at its worst point and re-optimises; a few rounds, up
to a joint budget.

The new joint starts where the shape is: at the weighted centroid of the bone's points mapped
near the split (a cross-section of the part the bone explains, whose centre is inside even when
the bone's own point is not), with their mean distance as its radius. The mapping of the split
bone's points is carried over exactly (sigma is unchanged where the joint is interpolated) and
then re-fitted by the solver.

Finally, joints still outside (tips of thin parts whose balls have shrunk to nothing, where the
solver puts the joint on the surface) are moved along their bone towards the neighbouring joint
until they are inside: the only stage that moves a joint without re-solving, by at most the
part of the bone that is outside.

Examples
--------
>>> pr2, log = refine(pr, V, F, solve)       # doctest: +SKIP
>>> log["split"], log["outside_before"], log["outside_after"]    # doctest: +SKIP
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .problem import FitProblem
from .quality import InsideTest, bone_points

__all__ = ["refine", "outside_samples", "split_bones", "pull_in_leaves"]

#: Points tested per bone, at t = (k + 1/2) / PER_BONE (the quality measure uses 10).
PER_BONE = 16
#: Half-width (in t) of the band of points that places a new joint.
BAND = 0.1


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


def split_bones(pr: FitProblem, split: np.ndarray, t_split: np.ndarray) -> FitProblem:
    """Split bones at parameters, each with a new joint placed from the points it explains.

    Parameters
    ----------
    pr : FitProblem
    split : (k,) int
        Bones to split (distinct).
    t_split : (k,) float in (0, 1)
        Where: the new joint of bone (i, j) is at the points mapped near ``t x_i + (1-t) x_j``.

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
    ok = cnt >= 4
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


def pull_in_leaves(joints, bones, inside: InsideTest, *, steps: int = 8) -> tuple[np.ndarray, int]:
    """Move joints of degree 1 that are outside the mesh towards their neighbour until inside.

    Tries ``lam = 1/2^steps ... 1/2`` of the way along the bone (the smallest move first); a
    joint whose neighbour is outside too stays where it is. Returns (joints, moved).
    """
    joints = np.array(joints, np.float64)
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    deg = np.bincount(bones.ravel(), minlength=len(joints))
    out = ~inside(joints[:, :3])
    leaves = np.flatnonzero(out & (deg == 1))
    if not leaves.size:
        return joints, 0
    # The neighbour of each leaf: the other end of its single bone.
    at0 = np.isin(bones[:, 0], leaves)
    at1 = np.isin(bones[:, 1], leaves)
    L = np.concatenate([bones[at0, 0], bones[at1, 1]])
    N = np.concatenate([bones[at0, 1], bones[at1, 0]])
    lams = 0.5 ** np.arange(steps, 0, -1)                    # 1/256 ... 1/2
    X = joints[L, None, :3] + lams[None, :, None] * (joints[N, None, :3] - joints[L, None, :3])
    ins = inside(X.reshape(-1, 3)).reshape(len(L), steps)
    first = np.where(ins.any(axis=1), ins.argmax(axis=1), -1)
    moved = first >= 0
    joints[L[moved], :3] = X[moved, first[moved]]
    return joints, int(moved.sum())


def refine(pr: FitProblem, V, F, solve: Callable[[FitProblem], FitProblem], *,
           max_joints: int = 300, rounds: int = 3, per_bone: int = PER_BONE) -> tuple[FitProblem, dict]:
    """Split bones with points outside the mesh and re-solve, ``rounds`` times at most.

    Parameters
    ----------
    pr : FitProblem
        A solved problem (not modified).
    V, F : the closed surface the skeleton must stay inside.
    solve : callable(FitProblem) -> FitProblem
        Re-optimises (the pipeline's solver settings).
    max_joints : int
        No split beyond this many joints.
    rounds : int

    Returns
    -------
    FitProblem, dict
        The log holds ``outside_before`` / ``outside_after`` (fractions of the tested points),
        ``split`` (bones split per round) and ``pulled_in`` (leaf joints moved).
    """
    pr = pr.copy()
    inside = InsideTest(V, F)
    log = {"split": [], "kept": []}
    t, out, _ = outside_samples(pr.joints, pr.bones, inside, per_bone=per_bone)
    log["outside_before"] = frac = float(out.mean()) if out.size else 0.0
    for _ in range(rounds):
        # Bones with points outside away from their ends (outside at an end is that joint's
        # business); split at the mean parameter of the outside points.
        cand = np.flatnonzero(out[:, 1:-1].any(axis=1))
        budget = max_joints - len(pr.joints)
        if not cand.size or budget <= 0:
            break
        cand = cand[np.argsort(-out[cand].sum(axis=1), kind="stable")][:budget]
        tt = (out[cand] * t).sum(axis=1) / out[cand].sum(axis=1)
        tt = np.clip(tt, t[1], t[-2])
        trial = solve(split_bones(pr, cand, tt))
        t, out_new, _ = outside_samples(trial.joints, trial.bones, inside, per_bone=per_bone)
        frac_new = float(out_new.mean()) if out_new.size else 0.0
        log["split"].append(int(len(cand)))
        # Keep a round only if less of the skeleton is outside (the solver's containment term
        # approximates the surface and can be wrong in parts thinner than its blending radius).
        keep = frac_new < frac
        log["kept"].append(bool(keep))
        if not keep:
            break
        pr, out, frac = trial, out_new, frac_new
    joints, moved = pull_in_leaves(pr.joints, pr.bones, inside)
    pr.joints = joints
    log["pulled_in"] = moved
    _, out, _ = outside_samples(pr.joints, pr.bones, inside, per_bone=per_bone)
    log["outside_after"] = float(out.mean()) if out.size else 0.0
    return pr, log
