"""The skeleton as the search holds it: joints, bones, the Reeb regions each bone explains, and
the thickness of the part each bone lies in.

A :class:`SkeletonGraph` is an immutable value: the continuous minimisation returns a new one
with moved joints, a topology move returns a new one with its bone map. ``pairs`` lists
``(region, bone)``: the surface of a Reeb region of the first approximation maps onto those
bones (the output mapping of the input vertices, the paper's sigma); ``thick`` is each bone's
part's thickness, the centring's unit of length there. Both are attributes of the bones, set by
the first approximation and carried through every move by its bone map (a bone made of others
takes their mean thickness): J then depends on the graph alone, never on which samples happen
to be nearest a bone (a sample equidistant from two bones would otherwise make J jump).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

__all__ = ["SkeletonGraph", "rewrite_pairs", "carry_thickness", "candidates_from_pairs"]


def _frozen(a, dtype, cols):
    a = np.array(a, dtype=dtype).reshape(-1, cols)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class SkeletonGraph:
    """Joints (J, 4) x, y, z, r; bones (B, 2); pairs (P, 2) (region, bone); thick (B,) or None."""

    joints: np.ndarray
    bones: np.ndarray
    pairs: np.ndarray
    thick: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "joints", _frozen(self.joints, np.float64, 4))
        object.__setattr__(self, "bones", _frozen(self.bones, np.int64, 2))
        object.__setattr__(self, "pairs", _frozen(self.pairs, np.int64, 2))
        if self.thick is not None:
            t = np.array(self.thick, np.float64).ravel()
            t.flags.writeable = False
            object.__setattr__(self, "thick", t)

    def with_thickness(self, thick) -> "SkeletonGraph":
        return SkeletonGraph(self.joints, self.bones, self.pairs, thick)

    def with_joints(self, joints) -> "SkeletonGraph":
        g = SkeletonGraph(joints, self.bones, self.pairs, self.thick)
        for name in ("degree",):          # topology caches carry over
            if name in self.__dict__:
                g.__dict__[name] = self.__dict__[name]
        return g

    @property
    def n_joints(self) -> int:
        return len(self.joints)

    @cached_property
    def degree(self) -> np.ndarray:
        return np.bincount(self.bones.ravel(), minlength=len(self.joints))

    @property
    def n_leaves(self) -> int:
        return int(np.count_nonzero(self.degree == 1))


def carry_thickness(thick, old_lengths, bone_map, n_new):
    """Each new bone's thickness after a move: the length-weighted mean of the old bones that map
    to it (``bone_map`` rows ``(old, new)``); the median of all where none does."""
    if thick is None:
        return None
    bm = np.asarray(bone_map, np.int64).reshape(-1, 2)
    w = np.maximum(np.asarray(old_lengths, np.float64)[bm[:, 0]], 1e-300)
    W = np.bincount(bm[:, 1], w, n_new)
    T = np.bincount(bm[:, 1], w * thick[bm[:, 0]], n_new)
    return np.where(W > 0, T / np.maximum(W, 1e-300), float(np.median(thick)) if len(thick) else 1.0)


def rewrite_pairs(pairs, bone_map) -> np.ndarray:
    """``(region, bone)`` pairs after a move: ``bone_map`` rows ``(old bone, new bone)`` (an old
    bone may have several new ones, or none: its regions then map to no bone of it)."""
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    bm = np.asarray(bone_map, np.int64).reshape(-1, 2)
    o = np.argsort(bm[:, 0], kind="stable")
    bm = bm[o]
    start = np.searchsorted(bm[:, 0], pairs[:, 1], side="left")
    stop = np.searchsorted(bm[:, 0], pairs[:, 1], side="right")
    cnt = stop - start
    reg = np.repeat(pairs[:, 0], cnt)
    idx = np.repeat(start, cnt) + (np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt))
    return np.unique(np.stack([reg, bm[idx, 1]], 1), axis=0) if len(reg) else np.zeros((0, 2), np.int64)


def candidates_from_pairs(pairs, region, n_regions):
    """CSR (indptr, bone ids) of each point's candidate bones: the bones of its region.

    Parameters
    ----------
    pairs : (P, 2) int
        (region, bone) rows, unique.
    region : (n,) int
        Region of each point.
    n_regions : int

    Returns
    -------
    (indptr (n + 1,), ids (p,)) as :func:`.mapping.closest_on_bones` takes them.
    """
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    o = np.argsort(pairs[:, 0], kind="stable")
    st = np.concatenate([[0], np.cumsum(np.bincount(pairs[:, 0], minlength=n_regions))])
    cnt = np.diff(st)[region]
    indptr = np.concatenate([[0], np.cumsum(cnt)])
    local = np.arange(indptr[-1]) - np.repeat(indptr[:-1], cnt)
    return indptr, pairs[o, 1][np.repeat(st[region], cnt) + local]
