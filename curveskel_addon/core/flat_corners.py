"""Corners of flat parts: a chain's end bent into a corner of a plate or board is cut back.

Why: the Reeb graph's poles are the two vertices farthest apart, and on a board or a plate
those are corners, so a chain starts in a corner and runs along its bisector to the middle:
a board 6 x 2 x 0.4 came out as a Z, the plate with three holes kept a tail 0.66-0.81 long
into each pole's corner (issue 10). In 3-D such a tail is as much a part as a finger (its
length is 3-4 of its radius, the plate's half thickness); what says it is none is its flat
footprint: in the plate's plane it is a wedge whose width grows with the distance from its
tip, the corner branch of the footprint's 2-D medial axis, which curve skeletons leave out
(mean-curvature flow pulls a corner in; the analytic curves of ``tests/meshes.py`` end half a
width short of a board's end).

A chain end is a flat corner as far as, walking in from its tip, the cross-sections across the
chain are flat (width at least ``corner_flat`` (``edit.EDIT_CONSTANTS``) times their thickness,
by their second moments: :func:`.cross_section.section_shapes`) and hold the tip: the tip lies
within ``corner_hold`` half-widths of the section's point (a wedge of full angle above 2 atan(2 / 3)
= 67 degrees: a right-angled corner holds its tip at every section, a pointed ear of 60
degrees does not, nor a board's straight part farther than ``corner_hold`` half-widths from its
end). Sections closer to the tip than their thickness are skipped (the tip's own cap). Then

* a leaf held up to a junction on a loop is removed, if its width grows with the distance from
  its tip (``corner_wedge``): the corner of a plate outside the loop round its hole (a frame's,
  a washer's). Off a loop a leaf held whole is a stump as wide as it is long, a tab on a board
  or the board's end beyond it, and a part;
* else the held end is cut where it leaves the chain's line (the line inward of the held run)
  by more than ``corner_bend`` half-widths, if it leaves it by more than ``corner_turned``
  somewhere (a straight end is the part's own), and the tip is put on the line as far out as it
  was (a board's corner end then reaches as far as its straight end);

either only when the part cut off and the part the chain goes on into are one sheet: the same
thickness within ``corner_sheet_ratio``, the same thin direction within ``corner_sheet_angle``.
An ear or a lever meets a thicker head or hub; a round limb's sections are never flat, and
walking in stops at the first that is not, so a finger next to a flat palm is not reached. On
the 28 shared and held-out meshes this touches the stuffed toy's flat paw alone.

Examples
--------
>>> joints, bones, bone_map = trim_flat_corners(V, F, joints, bones)    # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np

from .cross_section import section_shapes
from .edit import EDIT_CONSTANTS, chains, compact, cycle_bones

__all__ = ["trim_flat_corners", "flat_ends"]

#: The constants: EDIT_CONSTANTS["corner_*"] (the edit operators' one place), with their reasons.
_C = EDIT_CONSTANTS


def flat_ends(V, F, joints, bones, *, face_of=None, vertex_edge=None):
    """The chain ends that are flat corners.

    Returns
    -------
    list of (path, path_bones, cut, i, f, whole, tip): ``path`` (k,) the chain's joints from
    its tip, ``path_bones`` (k - 1,) the bones between them; the end is cut at ``cut`` (x, y,
    z, r), the point a fraction ``f`` of the way along ``path_bones[i]``; ``whole``: the leaf
    is held up to its junction and goes; ``tip``: where the tip goes on the chain's line
    (None: the cut is the tip).
    """
    J = np.asarray(joints, np.float64)
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    deg = np.bincount(bones.ravel(), minlength=len(J))
    loop = np.zeros(len(J), bool)                     # joints on a cycle
    loop[bones[cycle_bones(len(J), bones)].ravel()] = True
    tails = []
    for js, bs in chains(len(J), bones):
        js, bs = np.asarray(js, np.int64), np.asarray(bs, np.int64)
        if len(js) < 2 or js[0] == js[-1]:
            continue
        ends = [e for e in (0, len(js) - 1) if deg[js[e]] == 1]
        for e in ends:
            p, b = (js, bs) if e == 0 else (js[::-1], bs[::-1])
            tails.append(_Tail(J[p], p, b, two=len(ends) == 2, loop=bool(loop[p[-1]])))
    size = float(np.linalg.norm(np.ptp(V, axis=0))) if len(V) else 0.0

    def shapes(X, T, near=None):
        # a held section reaches at least dist / corner_hold, and may reach across the whole mesh (a
        # section along a board's end runs the board's length): looked for near first (a
        # limb's section is found there, for a fraction of the cost), then across the mesh
        reach = np.full(len(X), size) if near is None else np.minimum(near, size)
        w, th, thin = section_shapes(V, F, X, T, reach, face_of=face_of,
                                     vertex_edge=vertex_edge)[3:]
        if near is not None:
            again = np.flatnonzero(w == 0)
            if len(again):
                w[again], th[again], thin[again] = shapes(X[again], T[again])
        return w, th, thin

    # walk in from every tip at once: one batch of sections per step
    active = list(tails)
    while active:
        X = np.array([t.point()[:3] for t in active])
        T = np.array([t.direction() for t in active])
        near = np.array([4.0 * (t.dist() + t.radius()) for t in active])
        for t, *shape in zip(active, *shapes(X, T, near)):
            t.record(*shape)
        active = [t for t in active if t.going() and t.advance()]
    # a whole leaf's sheet goes on into its junction's other bones: their middles' sections
    ask = [(t, k) for t in tails if t.whole()
           for k in np.flatnonzero((bones == t.path[-1]).any(axis=1)) if k != t.bones[-1]]
    if ask:
        A, B = J[bones[[k for _, k in ask], 0], :3], J[bones[[k for _, k in ask], 1], :3]
        T = B - A
        n = np.linalg.norm(T, axis=1, keepdims=True)
        w, th, thin = shapes((A + B) / 2, np.divide(T, n, out=np.zeros_like(T), where=n > 0))
        for (t, _), wk, tk, nk in zip(ask, w, th, thin):
            t.beyond.append((wk, tk, nk))
    out = []
    for t in tails:
        cut = t.cut()
        if cut is not None:
            out.append((t.path, t.bones) + cut)
    return out


class _Tail:
    """One chain end walked in from its tip: samples at every bone's middle and far joint."""

    def __init__(self, P, path, bones, two, loop):
        self.P, self.path, self.bones, self.two, self.loop = P, path, bones, two, loop
        d = P[1:, :3] - P[:-1, :3]
        self.L = np.linalg.norm(d, axis=1)
        self.u = np.divide(d, self.L[:, None], out=np.zeros_like(d), where=self.L[:, None] > 0)
        self.s = np.r_[0.0, np.cumsum(self.L)]
        self.k = 0            # sample k: bone k // 2, at its middle (even) or far end (odd)
        self.samples = []     # (k, dist, width, thickness, thin, held) walking in
        self.beyond = []      # (width, thickness, thin) of sections past the held run

    def _at(self, k):
        return k // 2, 0.5 if k % 2 == 0 else 1.0

    def point(self):
        i, f = self._at(self.k)
        return self.P[i] + f * (self.P[i + 1] - self.P[i])

    def direction(self):
        i, f = self._at(self.k)
        t = self.u[i] + (self.u[i + 1] if f == 1.0 and i + 1 < len(self.u) else 0.0)
        n = np.linalg.norm(t)
        return t / n if n > 0 else t

    def dist(self):
        return float(np.linalg.norm(self.point()[:3] - self.P[0, :3]))

    def radius(self):
        return abs(float(self.point()[3]))

    def record(self, w, th, thin):
        dist = self.dist()
        if w > 0 and dist < th:
            held = None                                   # the tip's own cap: no say
        else:
            held = bool(w > 0 and w >= _C["corner_flat"] * th and dist <= _C["corner_hold"] * w / 2)
        self.samples.append((self.k, dist, w, th, thin, held))

    def going(self):
        if self.samples[-1][5] is False:
            self.beyond.append(self.samples[-1][2:5])     # the section that ended the walk
            return False
        return True

    def advance(self):
        self.k += 1
        i, f = self._at(self.k)
        if i >= len(self.L):
            return False
        # a chain with two tips: each end walks at most half of it
        return not (self.two and self.s[i] + f * self.L[i] > self.s[-1] / 2)

    def _held(self):
        return [x for x in self.samples if x[5]]

    def whole(self):
        h = self._held()
        return (self.loop and bool(h) and h[-1][0] == 2 * len(self.L) - 1
                and self.samples[-1][5] is not False)

    def cut(self):
        """(cut point, bone index, fraction, whole, tip) or None: a straight end (the part's
        own), no wedge cut off, or no sheet going on."""
        held = self._held()
        if not held:
            return None
        if self.whole():
            return self._checked(held, held, self.P[-1].copy(), len(self.L) - 1, 1.0, True, None)
        i, f = self._at(held[-1][0])
        width = held[-1][2]
        # the chain's line inward of the held run: the main direction of the held point and
        # the joints within a width inward of it (two joints alone tilt it by the chain's
        # wiggle), in the sheet's plane (a wiggle across the thickness must not send the tip
        # out of the board's face)
        x = self.P[i] + f * (self.P[i + 1] - self.P[i])
        inner = i + 1 if f < 1.0 else i + 2
        if inner >= len(self.P):
            return None
        sx = self.s[i] + f * self.L[i]
        near = np.flatnonzero((np.arange(len(self.P)) >= inner) & (self.s <= sx + width))
        Q = np.vstack([x[:3], self.P[near if len(near) else [inner], :3]])
        n = held[-1][4]
        u = Q[0] - Q[1:].mean(axis=0)
        if len(Q) > 2:
            d = np.linalg.svd(Q - Q.mean(axis=0), full_matrices=False)[2][0]
            u = d if d @ u > 0 else -d
        u = u - (u @ n) * n
        nu = np.linalg.norm(u)
        if nu == 0:
            return None
        u /= nu
        # walking out from the held point, the last joint still on that line is the cut
        H = self.P[: i + 1, :3] - x[:3]
        off = np.linalg.norm(H - np.outer(H @ u, u), axis=1)
        if off.max() <= _C["corner_turned"] * width / 2:
            return None
        away = np.flatnonzero(off > _C["corner_bend"] * width / 2)
        j = int(away.max()) + 1                       # first joint (from the tip) back on the line
        c, i, f = (x, i, f) if j > i else (self.P[j].copy(), j - 1, 1.0)
        # the tip goes onto the line as far out as it was (a board's straight end runs as far)
        tip = x[:3] + max(float((self.P[0, :3] - x[:3]) @ u), 0.0) * u
        # the samples cut off, and those the chain keeps (its sheet goes on there)
        end = 2 * i + (1 if f == 1.0 else 0)
        off_part = [x for x in held if x[0] <= end]
        self.beyond.extend(x[2:5] for x in held if x[0] > end)
        return self._checked(held, off_part, c, i, f, False,
                             tip if (tip - c[:3]) @ u > 0 else None)

    def _checked(self, held, off_part, c, i, f, whole, tip):
        """The cut if the part cut off is a wedge of one sheet with what the chain goes on
        into; else None."""
        if len(off_part) < 2 or not self.beyond:
            return None
        d = np.array([x[1] for x in off_part])
        w = np.array([x[2] for x in off_part])
        if whole and w[-1] / d[-1] < _C["corner_wedge"] * w[0] / d[0]:
            return None
        th = np.array([x[3] for x in off_part] + [b[1] for b in self.beyond])
        thin = np.array([x[4] for x in off_part] + [b[2] for b in self.beyond])
        if not (th.min() > 0 and th.max() <= _C["corner_sheet_ratio"] * th.min()):
            return None
        if np.abs(thin @ thin[0]).min() < np.cos(np.radians(_C["corner_sheet_angle"])):
            return None
        return c, i, f, whole, tip


def trim_flat_corners(V, F, joints, bones, *, inside=None, face_of=None, vertex_edge=None):
    """Every chain end that is a flat corner (:func:`flat_ends`) cut back to its innermost
    held section, a leaf held up to its junction removed.

    Parameters
    ----------
    V, F : the mesh
    joints : (J, 4) float
    bones : (B, 2) int
    inside : callable (k, 3) -> (k,) bool, optional
        The mesh's inside test: a tip whose place on the line is outside stays at the cut.
    face_of, vertex_edge : optional
        As :func:`.cross_section.section_loops`, if at hand.

    Returns
    -------
    joints, bones, bone_map : the new graph, and ``old bone -> new bone`` (a removed bone's
        vertices go to the kept bone at its cut, or at its junction).
    """
    joints = np.asarray(joints, np.float64)
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    inside = inside or (lambda X: np.ones(len(X), bool))
    ends = flat_ends(V, F, joints, bones, face_of=face_of, vertex_edge=vertex_edge)
    if not ends:
        return joints, bones, np.arange(len(bones))
    J = joints.copy()
    nb = [bones.copy()]
    n_bones = len(bones)
    removed = np.zeros(len(bones), bool)
    to = np.full(len(bones), -1, np.int64)        # a removed bone's vertices: to this bone
    deg = np.bincount(bones.ravel(), minlength=len(J))
    for p, b, cut, i, f, whole, tip in ends:
        if whole:
            if deg[p[-1]] <= 2:
                continue
            deg[p[-1]] -= 1
            removed[b] = True
            keep = np.flatnonzero(((bones == p[-1]).any(axis=1)) & ~removed)
            to[b] = keep[0] if len(keep) else -1
            continue
        if tip is not None:
            # as far out along the line as the mesh goes (a tilted line leaves it early)
            q = cut[:3] + np.linspace(1.0, 0.0, 11)[:, None] * (tip - cut[:3])
            ok = np.flatnonzero(inside(q))
            tip = q[ok[0]] if len(ok) and ok[0] < 10 else None
        if f < 1.0:
            # the cut on bone b[i]: a new joint there ends the kept part of the bone
            J = np.vstack([J, cut[None]])
            c = len(J) - 1
            nb[0][b[i]] = np.where(nb[0][b[i]] == p[i], c, nb[0][b[i]])
            gone = b[:i]
        else:
            c, gone = p[i + 1], b[: i + 1]
        removed[gone] = True
        if tip is None:
            # the cut is the new tip; the removed bones' vertices go to the bone it ends
            k = b[i] if f < 1.0 else (b[i + 1] if i + 1 < len(b) else -1)
            to[gone] = k
        else:
            # the tip, moved onto the chain's line, joined to the cut by one new bone
            J[p[0], :3] = tip
            nb.append(np.array([[p[0], c]]))
            to[gone] = n_bones
            n_bones += 1
    nb = np.vstack(nb)
    alive = np.r_[~removed, np.ones(len(nb) - len(bones), bool)]
    keep = np.flatnonzero(alive)
    m = np.full(len(nb), -1, np.int64)
    m[keep] = np.arange(len(keep))
    bone_map = np.where(removed, m[np.maximum(to, 0)], m[: len(bones)])
    bone_map[removed & (to < 0)] = 0
    J2, B2, _ = compact(J, nb[keep], None)
    return J2, B2, bone_map
