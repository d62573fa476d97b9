"""Evaluate and refine real outside skeletons (issue 33): CGAL's curve skeletons of the shared
meshes, and the hand's with one finger taken away (the heat map's case)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from curveskel_addon.core import evaluate, load_outside_skeleton, refine
from curveskel_addon.core.geometry.segments import closest_on_bones
from curveskel_addon.core.graph import SkeletonGraph
from curveskel_addon.core.moves.topology import leaf_chains
from curveskel_addon.measure.evaluation import HEAT_RANGE
from curveskel_addon.mesh_files import read_mesh

from conftest import SHARED_MESHES

REFERENCE = SHARED_MESHES.parent / "reference"
MESHES = ["armadillo.obj", "horse.off", "elephant.obj", "hand.off", "homer.obj", "spot.obj",
          "octopus.off", "rocker-arm.obj", "3holes.off", "fertility.off"]


def hand_without_a_finger():
    """The hand, CGAL's skeleton without the finger whose tip is highest (joints only: radii
    fitted, as for an armature), and which vertices that finger's bones explained."""
    V, F = read_mesh(SHARED_MESHES / "hand.off")
    ref = json.loads((REFERENCE / "hand.json").read_text())
    J, B = np.array(ref["joints"])[:, :3], np.array(ref["bones"])
    fingers = [c for c in leaf_chains(SkeletonGraph(np.c_[J, np.ones(len(J))], B, np.zeros((0, 2))))
               if c[2] >= 0]
    js, bs, _ = max(fingers, key=lambda c: J[c[0][0], 1])
    keep_j = np.setdiff1d(np.arange(len(J)), js)
    keep_b = np.setdiff1d(np.arange(len(B)), bs)
    renumber = np.full(len(J), -1)
    renumber[keep_j] = np.arange(len(keep_j))
    nearest, _, _ = closest_on_bones(V, J, B)
    return V, F, (J[keep_j], renumber[B[keep_b]]), (J, B), np.isin(nearest, bs)


def test_the_missing_finger_is_where_the_skeleton_fits_badly():
    V, F, without, whole, finger = hand_without_a_finger()
    rep = evaluate(V, F, without)
    red = np.abs(rep.vertex_residual) / rep.D >= HEAT_RANGE      # full red on the heat map
    assert red[finger].mean() > 0.7
    assert red[~finger].mean() < 0.05
    # the whole skeleton explains the finger: no red there, and J is lower
    full = evaluate(V, F, whole)
    assert (np.abs(full.vertex_residual[finger]) / full.D >= HEAT_RANGE).mean() == 0
    assert full.J < rep.J
