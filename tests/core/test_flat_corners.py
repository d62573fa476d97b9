"""Corners of flat parts (:mod:`curveskel_addon.core.flat_corners`) and the section shapes they
read (:func:`curveskel_addon.core.cross_section.section_shapes`).

The operator is tested on skeletons drawn by hand on analytic meshes (what it must cut and what
it must leave), the pipeline on boards (a straight middle line, not a Z from corner to corner)
and on a board with a tab (a part as wide as it is long keeps its bone)."""

from __future__ import annotations

import numpy as np
import pytest

from curveskel_addon.core.cross_section import section_shapes
from curveskel_addon.core.flat_corners import trim_flat_corners
from curveskel_addon.core.pipeline import skeletonize
from curveskel_addon.core.quality import InsideTest, bbox_diagonal, curve_measures
from tests.meshes import (BOARD, PLATE, board, board_with_tab, box_bar, capsule, plate_hole_rings,
                          plate_with_holes, polyline)


# -- section shapes ------------------------------------------------------------------------------
def test_section_shape_of_a_box_is_its_rectangle():
    V, F = box_bar((4.0, 3.0, 0.5))
    X = np.array([[0.3, 0.2, 0.05], [1.0, -0.4, 0.0]])
    T = np.array([[1.0, 0, 0], [1.0, 0, 0]])
    *_, w, t, thin = section_shapes(V, F, X, T, [5.0, 5.0])
    assert np.allclose(w, 3.0, atol=1e-9) and np.allclose(t, 0.5, atol=1e-9)
    assert np.allclose(np.abs(thin), [0, 0, 1], atol=1e-9)


def test_section_shape_of_a_round_tube_is_square_root_3_radii_both_ways():
    V, F = capsule()                       # radius 1 along z
    *_, w, t, _ = section_shapes(V, F, [[0.0, 0, 3.0]], [[0.0, 0, 1]], [3.0])
    # a 32-gon's second moments: within a percent of the disc's sqrt(3) r
    assert w[0] == pytest.approx(np.sqrt(3), rel=0.02)
    assert t[0] == pytest.approx(np.sqrt(3), rel=0.02)
    assert w[0] / t[0] == pytest.approx(1.0, abs=1e-6)


def test_section_shape_where_no_loop_is_found_is_zero():
    V, F = box_bar((4.0, 3.0, 0.5))
    *_, w, t, thin = section_shapes(V, F, [[0.0, 0, 5.0]], [[1.0, 0, 0]], [5.0])   # outside
    assert w[0] == 0 and t[0] == 0 and not thin[0].any()


# -- the operator on hand-drawn skeletons ------------------------------------------------------
def _inside(V, F):
    return InsideTest(V, F)


def _as_joints(P, r=0.2):
    P = np.asarray(P, float)
    return np.column_stack([P, np.full(len(P), r)])


def test_a_chain_bent_into_a_board_corner_is_cut_back_onto_its_line():
    V, F = board()
    L, W, _ = BOARD["size"]
    # along the middle line from the right end, then off into the (-3, 1) corner
    P = [[2.8, 0, 0], [1.6, 0, 0], [0.4, 0, 0], [-0.8, 0, 0], [-1.8, 0, 0], [-2.3, 0.4, 0],
         [-2.6, 0.7, 0], [-2.85, 0.85, 0]]
    X, B = polyline(P)
    J2, B2, bone_map = trim_flat_corners(V, F, _as_joints(X), B, inside=_inside(V, F))
    assert np.abs(J2[:, 1]).max() < 0.05 * W, J2[:, :3].round(2)
    # the tip put on the line as far out as it was, not dropped at the cut
    assert J2[:, 0].min() < -2.5
    assert J2[:, 0].max() == pytest.approx(2.8)
    deg = np.bincount(B2.ravel(), minlength=len(J2))
    assert deg.max() <= 2 and (deg == 1).sum() == 2
    # every old bone's vertices go to a bone of the new graph
    assert bone_map.min() >= 0 and bone_map.max() < len(B2)


def test_a_straight_chain_end_on_a_board_is_left_as_it_is():
    V, F = board()
    X, B = polyline([[2.8, 0, 0], [1.0, 0, 0], [-1.0, 0, 0], [-2.8, 0.1, 0]])
    J = _as_joints(X)
    J2, B2, bone_map = trim_flat_corners(V, F, J, B, inside=_inside(V, F))
    assert np.array_equal(J2, J) and np.array_equal(B2, B)
    assert np.array_equal(bone_map, np.arange(len(B)))


def _ring_with_corner_leaf(k=20):
    """The plate's left ring (its analytic loop round the hole at x = -2, every k-th point)
    with a leaf into the (-3, 1) corner from where the pipeline's junction was, (-2.54, 0.39):
    0.6 long, where the plate is 0.4 thick."""
    R, RB = plate_hole_rings()
    n = len(R) // len(PLATE["hole_x"])
    ring = R[:n:k]                                   # the first ring: round x = -2
    corner = np.array([-3.0, 1.0, 0.0])
    a = int(np.argmin(np.linalg.norm(ring - [-2.54, 0.39, 0.0], axis=1)))
    leaf = ring[a] + np.linspace(0, 1, 5)[1:, None] * (corner + [0.12, -0.12, 0] - ring[a])
    X = np.vstack([ring, leaf])
    m = len(ring)
    B = np.vstack([np.stack([np.arange(m), (np.arange(m) + 1) % m], 1),
                   [[a, m], [m, m + 1], [m + 1, m + 2], [m + 2, m + 3]]])
    return X, B, m


def test_a_leaf_into_a_plate_corner_off_a_loop_is_removed():
    V, F = plate_with_holes()
    X, B, m = _ring_with_corner_leaf()
    J2, B2, bone_map = trim_flat_corners(V, F, _as_joints(X), B, inside=_inside(V, F))
    deg = np.bincount(B2.ravel(), minlength=len(J2))
    assert len(J2) == m and (deg == 2).all()         # the loop alone
    assert bone_map.min() >= 0 and bone_map.max() < len(B2)


def test_a_leaf_along_a_round_limb_is_not_a_corner():
    # a capsule's axis with a bent end: round sections are never flat
    V, F = capsule()
    X, B = polyline([[0, 0, 0.5], [0, 0, 2.0], [0, 0, 4.0], [0.4, 0, 5.5]])
    J = _as_joints(X, 1.0)
    J2, B2, _ = trim_flat_corners(V, F, J, B, inside=_inside(V, F))
    assert np.array_equal(J2, J) and np.array_equal(B2, B)


# -- the pipeline ----------------------------------------------------------------------------------
@pytest.mark.parametrize("size", [(6.0, 2.0, 0.4), (4.0, 2.0, 0.3), (5.0, 3.0, 0.3)])
def test_a_board_gives_one_straight_chain_along_its_middle_line(size):
    # the Reeb graph's poles are two opposite corners: the chain ran from corner to corner
    # through the middle (a Z, joints up to 0.47 W off the middle line) before the corner rule
    V, F = board(size)
    L, W, t = size
    sk = skeletonize(V, F)
    J = sk.joints
    deg = np.bincount(sk.bones.ravel(), minlength=len(J))
    assert deg.max() <= 2 and (deg == 1).sum() == 2 and len(sk.bones) == len(J) - 1
    assert np.abs(J[:, 1]).max() <= 0.05 * W, J[:, :3].round(2)
    assert np.abs(J[:, 2]).max() <= 0.25 * t
    # it runs at least over the footprint's medial axis (half a width short of each end)
    assert J[:, 0].min() <= -(L / 2 - W / 2) + 0.1 * W and J[:, 0].max() >= L / 2 - W / 2 - 0.1 * W
    m = curve_measures(J, sk.bones, bbox_diagonal(V, F))
    assert m["zigzag"] == 0 and m["folds"] == 0


def test_a_square_tab_on_a_board_keeps_its_bone():
    # as wide as it is long and in the board's sheet: every section across it holds its tip,
    # but it hangs off no loop and is no wedge (a corner's width grows from its tip)
    V, F = board_with_tab()
    sk = skeletonize(V, F)
    J = sk.joints
    deg = np.bincount(sk.bones.ravel(), minlength=len(J))
    tips = J[deg == 1, :3]
    # a tip in the tab (y from 1 to 1.8), near its middle line x = 0.5
    inside_tab = (tips[:, 1] > 1.2) & (np.abs(tips[:, 0] - 0.5) < 0.25)
    assert inside_tab.any(), tips.round(2)
    # and the board's two ends on its middle line, none in a corner
    ends = tips[tips[:, 1] < 1.0]
    assert len(ends) == 2 and np.abs(ends[:, 1]).max() < 0.1, tips.round(2)
