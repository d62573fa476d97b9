"""Outside skeletons for issue 33's tests and figures: a Rigify human metarig placed on a
T-posed character as a rigger places one, and the hand's CGAL skeleton without a finger.

Rigify's metarig stands Z up, facing -Y, its arms hanging at about 30 degrees; a rigger scales it
to the character's height, moves it onto the character and raises its arms to the character's
T-pose, then adjusts the bones one by one. :func:`place_metarig` does the first three steps
(what the refinement then improves is the fourth): a uniform scale to the mesh's height, a move
putting the point between its hip joints in the middle of the mesh's section there, and each
arm chain rotated in the frontal plane about the shoulder joint until it runs level.

``tests/data/rigify_basic_human.json`` holds Rigify's *Basic Human* metarig as Blender 5.0.1
makes it (bone names, parents, connected flags, heads and tails), so the benchmark and the core
tests need no Blender; the Blender tests make the metarig with Rigify itself.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from curveskel_addon.core.geometry.segments import closest_on_bones
from curveskel_addon.core.graph import SkeletonGraph
from curveskel_addon.core.moves.topology import leaf_chains
from curveskel_addon.mesh_files import read_mesh

__all__ = ["load_metarig", "place_metarig", "obj_to_blender", "blender_to_obj", "METARIG",
           "hand_without_a_finger"]

METARIG = Path(__file__).resolve().parent / "data" / "rigify_basic_human.json"
SHARED = Path(__file__).resolve().parents[2] / "shared"


def load_metarig(path=METARIG):
    """(names, parent (nb,) int, connected (nb,) bool, heads (nb, 3), tails (nb, 3))."""
    bones = json.loads(Path(path).read_text())["bones"]
    names = [b["name"] for b in bones]
    index = {n: i for i, n in enumerate(names)}
    parent = np.array([index[b["parent"]] if b["parent"] else -1 for b in bones])
    connected = np.array([b["connected"] for b in bones])
    heads = np.array([b["head"] for b in bones], float)
    tails = np.array([b["tail"] for b in bones], float)
    return names, parent, connected, heads, tails


def obj_to_blender(P):
    """An OBJ file's Y-up coordinates as Blender's importer places them (90 degrees about X)."""
    P = np.asarray(P, float)
    return np.stack([P[:, 0], -P[:, 2], P[:, 1]], 1)


def blender_to_obj(P):
    P = np.asarray(P, float)
    return np.stack([P[:, 0], P[:, 2], -P[:, 1]], 1)


def _descendants(parent, b):
    out, todo = [], [b]
    while todo:
        c = todo.pop()
        out.append(c)
        todo += list(np.flatnonzero(parent == c))
    return out


def place_metarig(names, parent, heads, tails, V):
    """The metarig on a T-posed character standing Z up, facing -Y (module doc).

    Parameters
    ----------
    names : list of str
    parent : (nb,) int
    heads, tails : (nb, 3) float
        The metarig's bones in its own space.
    V : (n, 3) float
        The character's vertices in the same (world) space.

    Returns
    -------
    scale : float
        The uniform scale of the metarig's space.
    offset : (3,) float
        Where its origin goes: world = scale * local + offset.
    heads, tails : (nb, 3) float
        The bones in the metarig's own space with the arms raised (world through scale and
        offset).
    """
    H, T = np.array(heads, float), np.array(tails, float)
    index = {n: i for i, n in enumerate(names)}
    top = max(H[:, 2].max(), T[:, 2].max())
    scale = float((V[:, 2].max() - V[:, 2].min()) / top)
    hips = 0.5 * (H[index["thigh.L"]] + H[index["thigh.R"]])      # between the hip joints
    level = V[:, 2].min() + scale * hips[2]
    near = np.abs(V[:, 2] - level) < 0.02 * (V[:, 2].max() - V[:, 2].min())
    middle = 0.5 * (V[near].min(0) + V[near].max(0))
    offset = np.array([middle[0] - scale * hips[0], middle[1] - scale * hips[1], V[:, 2].min()])
    for side, sign in (("L", 1.0), ("R", -1.0)):
        arm, hand = index[f"upper_arm.{side}"], index[f"hand.{side}"]
        pivot = H[arm].copy()
        d = T[hand] - pivot
        angle = np.arctan2(d[2], sign * d[0])          # below the horizontal: negative
        c, s = np.cos(-angle), np.sin(-angle)
        # a rotation about the forward axis (y) that lifts the chain by -angle on this side
        R = np.array([[c, 0, -sign * s], [0, 1, 0], [sign * s, 0, c]])
        chain = _descendants(parent, arm)
        H[chain] = (H[chain] - pivot) @ R.T + pivot
        T[chain] = (T[chain] - pivot) @ R.T + pivot
    return scale, offset, H, T


def hand_without_a_finger():
    """The shared hand, CGAL's skeleton of it without the finger whose tip is highest (joints
    only: radii fitted, as for an armature), the whole skeleton, and which vertices that
    finger's bones explained (the nearest bone of the whole skeleton is one of them).

    Returns
    -------
    V, F, (joints, bones) without the finger, (joints, bones) whole, finger (n,) bool
    """
    V, F = read_mesh(SHARED / "meshes" / "hand.off")
    ref = json.loads((SHARED / "reference" / "hand.json").read_text())
    J, B = np.array(ref["joints"])[:, :3], np.array(ref["bones"])
    graph = SkeletonGraph(np.c_[J, np.ones(len(J))], B, np.zeros((0, 2)))
    fingers = [c for c in leaf_chains(graph) if c[2] >= 0]
    js, bs, _ = max(fingers, key=lambda c: J[c[0][0], 1])
    keep_j = np.setdiff1d(np.arange(len(J)), js)
    keep_b = np.setdiff1d(np.arange(len(B)), bs)
    renumber = np.full(len(J), -1)
    renumber[keep_j] = np.arange(len(keep_j))
    nearest, _, _ = closest_on_bones(V, J, B)
    return V, F, (J[keep_j], renumber[B[keep_b]]), (J, B), np.isin(nearest, bs)
