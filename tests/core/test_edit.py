"""Unit tests of core/edit.py (issue 10: the topology-edit stage's operators) on small
skeletons drawn by hand, with the answer worked out on paper."""

from __future__ import annotations

import numpy as np
import pytest

from curveskel_addon.core.edit import (bridges_to_rungs, chain_turns, chains, collapse_short_bones,
                                       cycle_bones, remove_kinks,
                                       merge_chains, merge_short_bones, outside_worse, prune_leaves,
                                       put_back, remove_sharp_turns, turn_worse,
                                       zip_parallel_chains)
from curveskel_addon.core.quality import crossing_pairs


def _joints(points, r=0.5):
    """(J, 4) joints from 2-D or 3-D points and a radius (scalar or per joint)."""
    P = np.asarray(points, float)
    if P.shape[1] == 2:
        P = np.column_stack([P, np.zeros(len(P))])
    return np.column_stack([P, np.broadcast_to(np.asarray(r, float), (len(P),))])


def _path(k):
    return np.stack([np.arange(k - 1), np.arange(1, k)], 1)


def _cycles(n, bones):
    """Independent cycles B - J + C of a graph (joints without bones not counted)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    bones = np.asarray(bones).reshape(-1, 2)
    used = np.unique(bones)
    G = csr_matrix((np.ones(len(bones)), (bones[:, 0], bones[:, 1])), shape=(n, n))
    C = connected_components(G, directed=False)[0] - (n - len(used))
    return len(bones) - len(used) + C


def _check_chain_cover(n, bones, out):
    """Every bone in exactly one chain; a chain's bones join its consecutive joints."""
    seen = []
    for js, bs in out:
        assert len(js) == len(bs) + 1
        for k, b in enumerate(bs):
            assert sorted(bones[b].tolist()) == sorted([js[k], js[k + 1]])
        seen += bs
    assert sorted(seen) == list(range(len(bones)))


# -- chains -----------------------------------------------------------------------------------------
def test_chains_of_a_path():
    bones = np.array([[2, 3], [0, 1], [1, 2]])
    out = chains(4, bones)
    assert len(out) == 1
    js, bs = out[0]
    assert js in ([0, 1, 2, 3], [3, 2, 1, 0])
    _check_chain_cover(4, bones, out)


def test_chains_of_a_pure_cycle_is_one_closed_chain():
    bones = np.array([[2, 3], [0, 1], [3, 0], [1, 2]])
    out = chains(4, bones)
    assert len(out) == 1
    js, bs = out[0]
    assert js[0] == js[-1] and sorted(js[:-1]) == [0, 1, 2, 3] and len(bs) == 4
    _check_chain_cover(4, bones, out)


def test_chains_of_a_star_and_of_a_theta():
    # a star: junction 0 with three arms of two bones
    bones = np.array([[0, 1], [1, 2], [0, 3], [3, 4], [5, 0], [6, 5]])
    out = chains(7, bones)
    assert sorted((js[0], js[-1]) if js[0] == 0 else (js[-1], js[0]) for js, _ in out) == \
        [(0, 2), (0, 4), (0, 6)]
    assert all(len(bs) == 2 for _, bs in out)
    _check_chain_cover(7, bones, out)
    # a theta: two junctions (0, 2) joined by three chains, one of them a single bone
    bones = np.array([[0, 1], [1, 2], [0, 3], [3, 2], [0, 2]])
    out = chains(4, bones)
    assert len(out) == 3
    assert all({js[0], js[-1]} == {0, 2} for js, _ in out)
    assert sorted(len(bs) for _, bs in out) == [1, 2, 2]
    _check_chain_cover(4, bones, out)


# -- merge_chains -----------------------------------------------------------------------------------
def test_merge_chains_removes_collinear_joints():
    X = _joints([(x, 0) for x in range(6)])
    J, B, m = merge_chains(X, _path(6), np.full(6, 0.01))
    np.testing.assert_array_equal(J, X[[0, 5]])
    assert B.tolist() == [[0, 1]] and m.tolist() == [0] * 5


def test_merge_chains_keeps_a_corner_and_a_bend_beyond_the_tolerance():
    # an L: (1,0) and (2,1) lie on the bones through the corner (2,0), which is sqrt(2) off
    # the straight bone (0,0)-(2,2)
    X = _joints([(0, 0), (1, 0), (2, 0), (2, 1), (2, 2)])
    J, B, m = merge_chains(X, _path(5), np.full(5, 0.01))
    np.testing.assert_array_equal(J, X[[0, 2, 4]])
    assert B.tolist() == [[0, 1], [1, 2]] and m.tolist() == [0, 0, 1, 1]
    # a bend of 0.005: removed with tolerance 0.01, kept with 0.001
    X = _joints([(0, 0), (1, 0.005), (2, 0)])
    assert len(merge_chains(X, _path(3), np.full(3, 0.01))[0]) == 2
    assert len(merge_chains(X, _path(3), np.full(3, 0.001))[0]) == 3


def test_merge_chains_keeps_junctions_and_leaves_and_merges_each_arm():
    # three straight arms of 3 bones from a junction at the origin
    pts = [(0, 0)] + [(k * np.cos(a), k * np.sin(a)) for a in (0, 2.0, 4.0) for k in (1, 2, 3)]
    bones = np.array([[0, 1], [1, 2], [2, 3], [0, 4], [4, 5], [5, 6], [0, 7], [7, 8], [8, 9]])
    X = _joints(pts)
    J, B, m = merge_chains(X, bones, np.full(10, 0.01))
    np.testing.assert_allclose(J, X[[0, 3, 6, 9]])
    assert len(B) == 3 and (np.bincount(B.ravel()) == [3, 1, 1, 1]).all()
    assert m.tolist() == [0, 0, 0, 1, 1, 1, 2, 2, 2]


def test_merge_chains_respects_max_len():
    X = _joints([(x, 0) for x in range(11)])
    J, B, m = merge_chains(X, _path(11), np.full(11, 0.01), max_len=3.0)
    L = np.linalg.norm(J[B[:, 0], :3] - J[B[:, 1], :3], axis=1)
    assert L.max() <= 3.0
    assert len(B) == 4                     # the fewest bones of length <= 3 covering 10
    assert set(J[:, 0]) <= set(range(11))  # kept joints are original joints (none moved)
    # bones map in order along the chain, each new bone covering consecutive old bones
    assert (np.diff(m) >= 0).all() and m[0] == 0 and m[-1] == len(B) - 1


def _polygon(k, radius=1.0):
    th = 2 * np.pi * np.arange(k) / k
    return (np.column_stack([radius * np.cos(th), radius * np.sin(th), 0 * th, np.full(k, 0.2)]),
            np.stack([np.arange(k), (np.arange(k) + 1) % k], 1))


def test_merge_chains_keeps_a_cycle_a_cycle():
    X, bones = _polygon(12)
    J, B, m = merge_chains(X, bones, np.full(12, 10.0))      # a tolerance that would flatten it
    assert _cycles(len(J), B) == 1
    assert len(J) >= 3 and (m >= 0).all()
    # a tolerance below the loop's size and max_len: no bone longer than asked, the loop
    # keeps its shape (every kept joint an original one, on the circle)
    J, B, _ = merge_chains(X, bones, np.full(12, 0.3), max_len=0.6)
    assert _cycles(len(J), B) == 1
    assert np.linalg.norm(J[B[:, 0], :3] - J[B[:, 1], :3], axis=1).max() <= 0.6
    np.testing.assert_allclose(np.linalg.norm(J[:, :2], axis=1), 1.0)


def test_merge_chains_respects_max_len_on_a_cycle_whatever_the_tolerance():
    X, bones = _polygon(12)
    J, B, _ = merge_chains(X, bones, np.full(12, 10.0), max_len=0.6)
    assert np.linalg.norm(J[B[:, 0], :3] - J[B[:, 1], :3], axis=1).max() <= 0.6


def test_merge_chains_keeps_a_loop_free_of_zigzags():
    # a 12-gon with a huge tolerance: at least 7 joints stay, so no turn reaches 60 degrees
    X, bones = _polygon(12)
    J, B, _ = merge_chains(X, bones, np.full(12, 10.0))
    assert len(J) >= 7 and len(B) == len(J) and _cycles(len(J), B) == 1
    _, _, _, turn = chain_turns(J, B)
    assert turn.max() < 60, turn.max()


# -- remove_sharp_turns --------------------------------------------------------------------------------
def test_remove_sharp_turns_removes_a_small_zigzag():
    # along x with a back-step at (0.9, 0.1): turns of 135 and 138 deg at joints 1 and 2,
    # bones of 0.14 < the radius 0.5
    X = _joints([(0, 0), (1, 0), (0.9, 0.1), (3, 0)])
    _, _, _, turn = chain_turns(X, _path(4))
    assert turn.min() > 130
    J, B, m = remove_sharp_turns(X, _path(4), X[:, 3])
    assert len(J) == 3
    _, _, _, turn = chain_turns(J, B)
    assert turn.max() < 1e-6                                   # straight now
    assert {tuple(j) for j in J[:, :2].round(9)} <= {tuple(j) for j in X[:, :2]}
    assert _cycles(len(J), B) == 0 and (np.bincount(B.ravel()) <= 2).all()
    assert (m >= 0).all() and m.max() == len(B) - 1


def test_remove_sharp_turns_keeps_an_elbow_and_a_wide_zigzag():
    # a right angle with bones of 2 (> radius 0.5): a real bend
    X = _joints([(0, 0), (2, 0), (2, 2)])
    J, B, m = remove_sharp_turns(X, _path(3), X[:, 3])
    np.testing.assert_array_equal(J, X)
    assert B.tolist() == _path(3).tolist() and m.tolist() == [0, 1]
    # a sharp zig-zag whose replacing bone would pass 0.8 from the removed joint (> tol 0.5)
    X = _joints([(0, 0), (1, 0), (0.5, 0.8), (3, 0.8)])
    J, _, _ = remove_sharp_turns(X, _path(4), X[:, 3])
    assert len(J) == 4


def _outside_hole(P):
    """Inside test of the half-plane y >= 0 (in z = 0's neighbourhood) with a round hole of
    radius 0.2 at (0.5, 0): the material round a hole, as at rocker-arm's ring."""
    P = np.asarray(P, float)
    return (P[:, 1] >= -1e-9) & (np.hypot(P[:, 0] - 0.5, P[:, 1]) > 0.2)


def test_remove_sharp_turns_keeps_a_corner_whose_chord_crosses_a_hole():
    # a corner turning by 90 deg, bones of 0.71 < radius 1, the chord within tol of the corner:
    # a zig-zag to remove -- unless the chord (0, 0)-(1, 0) runs through the hole at (0.5, 0),
    # where 4 of its 10 samples lie outside while the corner's two bones have none
    X = _joints([(0, 0), (0.5, 0.5), (1, 0)], r=1.0)
    J, B, _ = remove_sharp_turns(X, _path(3), X[:, 3])
    assert len(J) == 2                                         # no inside test: removed
    J, B, m = remove_sharp_turns(X, _path(3), X[:, 3], inside=_outside_hole)
    np.testing.assert_array_equal(J, X)
    assert B.tolist() == _path(3).tolist() and m.tolist() == [0, 1]
    # the same corner over solid material (no hole) is still removed with the inside test
    J, _, _ = remove_sharp_turns(X, _path(3), X[:, 3], inside=lambda P: np.asarray(P)[:, 1] >= -1e-9)
    assert len(J) == 2


# -- put_back with outside_worse (the polish's inside guard) ----------------------------------------------------------------------------
def test_the_inside_guard_puts_back_a_bone_moved_across_a_hole():
    # a chain above the hole; joints 1 and 2 moved down beside it, each inside (0.25 from its
    # centre), but the bone between them now runs 0.05 from the centre: both go back; joint 0
    # moved up stays (its bone stays inside)
    before = _joints([(0, 0.5), (0.25, 0.5), (0.75, 0.5), (1, 0.5)])
    J = before.copy()
    J[0, 1] = 0.6
    J[1, :2] = (0.25, 0.05)
    J[2, :2] = (0.75, 0.05)
    assert _outside_hole(J[:, :3]).all()
    back = put_back(J, _path(4), before, outside_worse(_path(4), before, _outside_hole))
    assert back.tolist() == [False, True, True, False]
    np.testing.assert_array_equal(J[1:], before[1:])
    assert J[0, 1] == 0.6
    # nothing outside: nothing put back
    J = before.copy()
    J[1, 1] = 0.3
    assert not put_back(J, _path(4), before, outside_worse(_path(4), before, _outside_hole)).any()
    assert J[1, 1] == 0.3


# -- put_back with turn_worse (the polish's zig-zag guard) ---------------------------------------
def test_the_turn_guard_puts_back_a_joint_that_makes_a_new_zigzag():
    # a straight chain; joint 2 moved 1.0 sideways on bones of 1 turns by 90 degrees (its
    # neighbours by 45), joint 4 moved 0.2 by at most 23: joint 2 goes back (with its bones'
    # other joints, which did not move), joint 4 stays
    before = _joints([(0, 0), (1, 0), (2, 0), (3, 0), (4, 0), (5, 0)])
    J = before.copy()
    J[2, 1] = 1.0
    J[4, 1] = 0.2
    c, _, _, t = chain_turns(J, _path(6))
    assert t[c == 2][0] == pytest.approx(90.0) and (t[c != 2] < 60).all()
    back = put_back(J, _path(6), before, turn_worse(_path(6), before, 60.0))
    assert back[2] and not back[4] and not back[5]
    np.testing.assert_array_equal(J[:4], before[:4])
    assert J[4, 1] == 0.2


def test_the_turn_guard_watches_only_the_joints_it_is_given():
    before = _joints([(0, 0), (1, 0), (2, 0), (3, 0), (4, 0), (5, 0)])
    J = before.copy()
    J[2, 1] = 1.0                                         # a new 90-degree turn at joint 2
    watch = np.zeros(6, bool)
    watch[3] = True                                       # ... not watched: left
    assert not put_back(J, _path(6), before, turn_worse(_path(6), before, 60.0, watch)).any()
    watch[2] = True
    assert put_back(J, _path(6), before, turn_worse(_path(6), before, 60.0, watch))[2]


def test_the_turn_guard_leaves_a_turn_that_was_there():
    # a right-angled corner at joint 2 before and after (moved along the chain): not new
    before = _joints([(0, 0), (1, 0), (2, 0), (2, 1), (2, 2)])
    J = before.copy()
    J[3, 1] = 1.2
    assert not put_back(J, _path(5), before, turn_worse(_path(5), before, 60.0)).any()
    assert J[3, 1] == 1.2


# -- prune_leaves ------------------------------------------------------------------------------------
def test_prune_leaves_removes_a_stub_and_keeps_a_limb():
    # a trunk (0,0)-(5,0)-(10,0) of radius 1; a branch from the junction (5,0) of radius 0.8
    trunk = [(0, 0), (5, 0), (10, 0)]
    r = np.array([1, 1, 1, 0.8])
    bones = np.array([[0, 1], [1, 2], [1, 3]])
    # a stub reaching 0.2 out of the junction's ball (< its radius): a bump
    J, B, m = prune_leaves(_joints(trunk + [(5, 1.2)], r), bones, 1.0)
    np.testing.assert_array_equal(J[:, :2], np.array(trunk, float))
    assert B.tolist() == [[0, 1], [1, 2]]
    assert m[:2].tolist() == [0, 1] and m[2] in (0, 1)       # its vertices go to the junction's bones
    # a limb reaching 3 out: a part
    X = _joints(trunk + [(5, 4)], r)
    J, B, m = prune_leaves(X, bones, 1.0)
    np.testing.assert_array_equal(J, X)
    assert m.tolist() == [0, 1, 2]
    # factor 0 keeps every branch
    assert len(prune_leaves(_joints(trunk + [(5, 1.2)], r), bones, 0.0)[1]) == 3


def test_prune_leaves_leaves_a_junction_at_least_two_branches():
    # three stubs from a junction of radius 1, all within its ball's reach: two stay (a chain)
    X = _joints([(0, 0), (1.1, 0), (-1.2, 0), (0, 1.3)], np.array([1.0, 0.5, 0.5, 0.5]))
    bones = np.array([[0, 1], [0, 2], [0, 3]])
    J, B, m = prune_leaves(X, bones, 1.0)
    assert len(B) == 2 and np.bincount(B.ravel()).max() == 2
    kept = {tuple(p) for p in J[:, :2].round(9)}
    assert (1.1, 0.0) not in kept                     # the shortest is the one removed
    assert (m >= 0).all()


# -- collapse_short_bones ----------------------------------------------------------------------------
def test_collapse_short_bones_contracts_to_the_midpoint_on_a_chain():
    X = _joints([(0, 0), (1, 0), (1.01, 0), (2, 0)])
    J, B, m = collapse_short_bones(X, _path(4), np.full(3, 0.1))
    np.testing.assert_allclose(J[:, 0], [0, 1.005, 2])
    assert B.tolist() == [[0, 1], [1, 2]]
    assert m[0] == 0 and m[2] == 1 and m[1] in (0, 1)


def test_collapse_short_bones_keeps_a_junction_in_place_and_a_cycle_a_cycle():
    # junction (1,0) of degree 4 with a short bone to (1.05,0)
    X = _joints([(0, 0), (1, 0), (1.05, 0), (2, 0), (1, 1), (1, -1)])
    bones = np.array([[0, 1], [1, 2], [2, 3], [1, 4], [1, 5]])
    J, B, m = collapse_short_bones(X, bones, np.full(5, 0.1))
    assert len(J) == 5 and len(B) == 4
    assert np.bincount(B.ravel()).max() == 4
    hub = int(np.argmax(np.bincount(B.ravel())))
    np.testing.assert_allclose(J[hub, :3], [1, 0, 0])          # the junction did not move
    assert (m >= 0).all() and hub in B[m[1]]                    # the short bone -> a hub bone
    # a square loop with one short side: a triangle, still one cycle
    X = _joints([(0, 0), (1, 0), (1, 1), (0, 1.05), (0, 1)])
    sq = np.array([[0, 1], [1, 2], [2, 4], [4, 3], [3, 0]])
    J, B, m = collapse_short_bones(X, sq, np.full(5, 0.1))
    assert len(J) == 4 and len(B) == 4 and _cycles(len(J), B) == 1
    # nothing short: unchanged
    J, B, m = collapse_short_bones(X, sq, np.full(5, 0.01))
    np.testing.assert_array_equal(J, X)
    assert m.tolist() == list(range(5))


# -- zip_parallel_chains ----------------------------------------------------------------------------

def _fork(gap, r=1.0):
    """A stem s -> (-3, 0) and two chains from s = (0, 0) running side by side ``gap`` apart
    (y = +-gap/2) to x = 3, then parting to (4, +-2)."""
    h = gap / 2
    pts = [(0, 0), (-3, 0),
           (1, h), (2, h), (3, h), (4, 2),
           (1, -h), (2, -h), (3, -h), (4, -2)]
    bones = [(0, 1), (0, 2), (2, 3), (3, 4), (4, 5), (0, 6), (6, 7), (7, 8), (8, 9)]
    return _joints(pts, r), np.array(bones)


def test_zip_merges_two_chains_side_by_side_into_one_that_forks_where_they_part():
    J, B = _fork(0.4)                        # 0.4 apart, radius 1: one part's curve twice
    J2, B2, m = zip_parallel_chains(J, B, 0.5)
    deg = np.bincount(B2.ravel(), minlength=len(J2))
    # one junction where the stem meets, one where the two ends part: a single chain between
    fork = np.flatnonzero(deg == 3)
    assert len(fork) == 1
    assert np.allclose(J2[fork[0], :3], [3, 0, 0])
    assert _cycles(len(J2), B2) == 0 and len(np.flatnonzero(deg == 1)) == 3
    # the merged chain runs on the mean curve y = 0 from (0, 0) to (3, 0)
    inner = np.flatnonzero((deg == 2) & (J2[:, 0] < 3))
    assert len(inner) >= 2 and np.allclose(J2[inner, 1], 0.0)
    length = np.linalg.norm(J2[B2[:, 0], :3] - J2[B2[:, 1], :3], axis=1).sum()
    assert length == pytest.approx(3 + 3 + 2 * np.hypot(1, 2))
    assert len(crossing_pairs(J2, B2, 10.0, far=0.01)) == 0
    # every old bone has a new one; the zipped bones go to bones of the merged chain (y = 0)
    assert m.shape == (len(B),) and m.min() >= 0 and m.max() < len(B2)
    for b in (1, 2, 3, 5, 6, 7):
        assert np.allclose(J2[B2[m[b]], 1], 0.0)
    assert np.allclose(J2[B2[m[0]], 0].min(), -3)          # the stem stays the stem


def test_zip_leaves_chains_farther_apart_than_half_their_radius():
    J, B = _fork(1.4)                        # two fingers: 1.4 apart with radius 1
    J2, B2, m = zip_parallel_chains(J, B, 0.5)
    assert np.array_equal(J2, J) and np.array_equal(B2, B) and np.array_equal(m, np.arange(len(B)))


def test_zip_never_closes_a_hole():
    # two paths between the same two junctions 0.4 apart (radius 1): a loop round a thin hole;
    # zipping them would remove the cycle, so nothing changes
    pts = [(-2, 0), (0, 0), (1, 0.2), (2, 0.2), (3, 0), (1, -0.2), (2, -0.2), (5, 0)]
    B = np.array([(0, 1), (1, 2), (2, 3), (3, 4), (1, 5), (5, 6), (6, 4), (4, 7)])
    J = _joints(pts, 1.0)
    J2, B2, _ = zip_parallel_chains(J, B, 0.5)
    assert _cycles(len(J2), B2) == 1
    assert np.array_equal(J2, J) and np.array_equal(B2, B)


def test_zip_ignores_bones_within_the_junction_ball():
    # three short bones at a right angle inside the junction's ball (radius 1): close, but not
    # side by side beyond the ball
    pts = [(0, 0), (0.4, 0), (0, 0.4), (-3, 0)]
    B = np.array([(0, 1), (0, 2), (0, 3)])
    J = _joints(pts, 1.0)
    J2, B2, _ = zip_parallel_chains(J, B, 0.5)
    assert np.array_equal(B2, B)


def test_zip_joins_two_junctions_of_one_part_into_a_shared_segment():
    # the plate between two holes: the left loop's side and the right loop's side run up and
    # down side by side from two junctions joined by a short bridge; zipped they share one
    # vertical segment with a junction at each end (three junctions -> theta-like joins)
    pts = [(-0.2, 0), (0.2, 0),                        # bridge ends (junctions)
           (-0.2, 1), (-0.2, 2), (-2, 3),              # left loop up
           (0.2, 1), (0.2, 2), (2, 3),                 # right loop up
           (-0.2, -1), (-0.2, -2), (-2, -3),           # left loop down
           (0.2, -1), (0.2, -2), (2, -3),              # right loop down
           (-4, 0), (4, 0),                            # the far sides of the two loops
           (-6, 0), (6, 0)]                            # with a tail each (plate's ends)
    B = np.array([(0, 1), (0, 2), (2, 3), (3, 4), (1, 5), (5, 6), (6, 7),
                  (0, 8), (8, 9), (9, 10), (1, 11), (11, 12), (12, 13),
                  (4, 14), (14, 10), (7, 15), (15, 13), (14, 16), (15, 17)])
    J = _joints(pts, 1.0)
    assert _cycles(len(J), B) == 2
    J2, B2, m = zip_parallel_chains(J, B, 0.5)
    assert _cycles(len(J2), B2) == 2
    assert len(crossing_pairs(J2, B2, 10.0)) == 0
    # the shared segment lies on x = 0 from y = -2 to 2; the junctions at its ends
    deg = np.bincount(B2.ravel(), minlength=len(J2))
    junctions = J2[(deg == 3) & (np.abs(J2[:, 0]) < 3), :3]       # (the tails' are at x = +-4)
    assert len(junctions) == 2 and (deg == 3).sum() == 4
    assert np.allclose(np.sort(junctions[:, 1]), [-2, 2]) and np.allclose(junctions[:, 0], 0)
    # and the segment between them is one chain on x = 0
    between = (deg == 2) & (np.abs(J2[:, 1]) < 2)
    assert np.abs(J2[between, 0]).max() < 0.1


def _two_loops_through_a_web(gap=1.4):
    """Two loops from one junction (0, 0), their inner sides running up side by side ``gap``
    apart (radius 1: beyond the distance rule's half radius) to y = 2, then parting."""
    h = gap / 2
    pts = [(0, 0),
           (-h, 1), (-h, 2), (-3, 3), (-5, 0), (-3, -3),      # left loop
           (h, 1), (h, 2), (3, 3), (5, 0), (3, -3)]           # right loop
    B = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 0),
         (0, 6), (6, 7), (7, 8), (8, 9), (9, 10), (10, 0)]
    return _joints(pts, 1.0), np.array(B)


def _web(pairs):
    """A stand-in for cross_section.shared_sections_many: joints within |x| < 1 lie in one web."""
    return [np.abs(JP[:, 0]) < 1.0 for JP, JQ in pairs]


def test_zip_by_shared_sections_joins_two_loops_sides_in_one_web():
    J, B = _two_loops_through_a_web()
    assert _cycles(len(J), B) == 2
    # by distance alone (1.4 apart, radius 1) nothing is zipped, loops or not
    for loops in (False, True):
        J2, B2, _ = zip_parallel_chains(J, B, 0.5, loops=loops)
        assert np.array_equal(B2, B)
    # sharing their sections, the two sides become one strand up the web, forking at its top
    J2, B2, m = zip_parallel_chains(J, B, 0.5, loops=True, sections=_web)
    assert _cycles(len(J2), B2) == 2
    deg = np.bincount(B2.ravel(), minlength=len(J2))
    forks = J2[deg == 3, :3]
    assert len(forks) == 2
    assert np.allclose(sorted(forks[:, 1]), [0.0, 2.0]) and np.allclose(forks[:, 0], 0.0)
    assert m.shape == (len(B),) and m.min() >= 0
    # the loops' chains from a junction back to it are needed: without them nothing pairs
    J3, B3, _ = zip_parallel_chains(J, B, 0.5, loops=False, sections=_web)
    assert np.array_equal(B3, B)


def test_zip_by_shared_sections_joins_loops_met_by_a_short_bridge():
    """As above, but the right loop hangs from a second junction 0.5 below the first, joined
    to it by one bone (fertility's middle web): that bone is a bridge, yet it lies inside the
    first junction's ball (radius 1), so the two loops' sides still pair and become one strand
    up the web (they did not before: the pair was judged by distance alone)."""
    h = 0.7
    pts = [(0, 0),
           (-h, 1), (-h, 2), (-3, 3), (-5, 0), (-3, -3),      # left loop, from (0, 0)
           (0, -0.5),                                        # the second junction
           (h, 1), (h, 2), (3, 3), (5, 0), (3, -3)]           # right loop, from (0, -0.5)
    B = np.array([(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 0), (0, 6),
                  (6, 7), (7, 8), (8, 9), (9, 10), (10, 11), (11, 6)])
    J = _joints(pts, 1.0)
    assert not cycle_bones(len(J), B)[6]                 # the link (0, 6) is a bridge
    J2, B2, _ = zip_parallel_chains(J, B, 0.5, loops=True, sections=_web)
    assert _cycles(len(J2), B2) == 2
    deg = np.bincount(B2.ravel(), minlength=len(J2))
    top = J2[deg >= 3, :3]
    # one fork at the web's top, where the two sides part (x = 0, y = 2)
    assert np.any(np.all(np.abs(top - [0.0, 2.0, 0.0]) < 1e-9, axis=1)), top
    # the strand up the web: no joint of the result left on either side's old line
    used = np.unique(B2)
    assert not np.any(np.isclose(np.abs(J2[used, 0]), h) & (J2[used, 1] > 0.5))


def test_zip_by_shared_sections_leaves_limbs_alone():
    # two limbs (no cycle) 1.4 apart whose sections a test would call shared (a chest): the
    # section rule applies to loops' sides only, the distance rule leaves them apart
    J, B = _fork(1.4)
    J2, B2, _ = zip_parallel_chains(J, B, 0.5, loops=True,
                                    sections=lambda pairs: [np.ones(len(p[0]), bool) for p in pairs])
    assert np.array_equal(B2, B) and np.array_equal(J2, J)


def _two_loops_and_a_bridge():
    """Two loops (radius 0.2) either side of x = 0, their near junctions at x = -0.5 and 0.5
    joined by a bridge along x through (0.1, 0.1) (a Reeb graph's link along f through the
    web between two holes); each junction's arms leave at y = +-0.6 and -0.7."""
    pts = [(-0.5, 0.0), (-0.7, 0.6), (-1.5, 0.7), (-2.2, 0.0), (-1.5, -0.7), (-0.8, -0.7),
           (0.5, 0.0), (0.7, 0.6), (1.5, 0.7), (2.2, 0.0), (1.5, -0.7), (0.8, -0.7),
           (0.1, 0.1)]
    B = np.array([(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 0),
                  (6, 7), (7, 8), (8, 9), (9, 10), (10, 11), (11, 6), (0, 12), (12, 6)])
    return _joints(pts, 0.2), B


def _plate_web(extent):
    """A stand-in for the mesh's cross-section: across x (the bridge) a strip reaching
    ``extent``; across y (the rung) the web between the holes, centred on x = 0."""
    def section(X, T, reach):
        if abs(T[0]) > 0.9:
            return np.array([X[0], 0.0, 0.0]), extent
        return np.array([0.0, X[1], 0.0]), 0.5
    return section


def test_a_bridge_across_a_web_becomes_the_two_loops_shared_rung():
    J, B = _two_loops_and_a_bridge()
    assert not cycle_bones(len(J), B)[-2:].any()         # the link is a bridge
    J2, B2, m = bridges_to_rungs(J, B, _plate_web(1.0))
    assert _cycles(len(J2), B2) == 2
    assert cycle_bones(len(J2), B2).all()                # no bridge left: the loops share a bone
    deg = np.bincount(B2.ravel(), minlength=len(J2))
    forks = J2[deg == 3, :3]
    # across the web (the loops' middles lie on the x axis) through its centre x = 0, from
    # the higher upper arm (0.6) to the lower lower arm (-0.7)
    assert np.allclose(forks[:, 0], 0.0) and np.allclose(sorted(forks[:, 1]), [-0.7, 0.6])
    rung = J2[(deg == 2) & (np.abs(J2[:, 0]) < 1e-9), :3]
    assert len(rung) >= 1 and np.allclose(rung[:, 2], 0.0)
    assert m.shape == (len(B),) and m.min() >= 0 and m.max() < len(B2)
    # each junction joins an upper (or lower) arm of each loop and the rung
    for f in np.flatnonzero(deg == 3):
        nb = [int(p + q - f) for p, q in B2 if f in (p, q)]
        xs = sorted(np.sign(np.round(J2[nb, 0], 9)))
        assert xs == [-1, 0, 1], J2[nb]


def test_a_bridge_with_a_section_of_its_own_stays():
    """Two rings joined by a bar: the section across the bar reaches its radius, no more."""
    J, B = _two_loops_and_a_bridge()
    J2, B2, m = bridges_to_rungs(J, B, _plate_web(0.25))
    assert np.array_equal(B2, B) and np.array_equal(J2, J)
    assert np.array_equal(m, np.arange(len(B)))


def test_a_rung_that_would_leave_the_mesh_is_not_made():
    J, B = _two_loops_and_a_bridge()
    J2, B2, _ = bridges_to_rungs(J, B, _plate_web(1.0),
                                 inside=lambda P: np.abs(P[:, 1]) < 0.65)
    assert np.array_equal(B2, B)


def test_a_kink_inside_its_joints_ball_is_merged_away_a_bend_or_a_junctions_is_not():
    """A chain along x (radius 1) with a 112-degree kink on bones of 0.36 each (together 0.72
    r): the kink's joint goes, its neighbours joined. The same kink with bones of 0.6 (1.2 r,
    a bend the silhouette sees) stays, and so does a kink next to a junction."""
    def chain(h):
        return _joints([(0, 0), (2, 0), (2 + h * 2 / 3, h), (2 + h * 4 / 3, 0), (4, 0)], 1.0)
    B = np.array([(0, 1), (1, 2), (2, 3), (3, 4)])
    J2, B2, m = remove_kinks(chain(0.3), B)
    assert len(J2) == 4 and not np.any(np.all(np.isclose(J2[:, :2], [2.2, 0.3]), axis=1))
    assert _cycles(len(J2), B2) == 0 and m.min() >= 0
    ang = chain_turns(J2, B2)[3]
    assert ang.max() < 60
    J3, B3, _ = remove_kinks(chain(0.5), B)                # bones of 0.6: 1.2 r together
    assert np.array_equal(B3, B) and np.array_equal(J3, chain(0.5))
    # a branch at joint 1: the kink is next to a junction
    Jb = np.vstack([chain(0.3), [[2, -3, 0, 1.0]]])
    Bb = np.vstack([B, [(1, 5)]])
    J4, B4, _ = remove_kinks(Jb, Bb)
    assert np.array_equal(B4, Bb)


def test_rungs_and_kinks_leave_trees_and_empty_skeletons_alone():
    """No loop, no rung: a fork's bridges stay whatever the sections say; a single bone and an
    empty skeleton pass through both operators unchanged."""
    J, B = _fork(1.4)
    J2, B2, m = bridges_to_rungs(J, B, _plate_web(5.0))
    assert np.array_equal(B2, B) and np.array_equal(J2, J) and np.array_equal(m, np.arange(len(B)))
    for J, B in ((_joints([(0, 0), (1, 0)], 1.0), np.array([(0, 1)])),
                 (np.zeros((0, 4)), np.zeros((0, 2), np.int64))):
        for op in (lambda J, B: bridges_to_rungs(J, B, _plate_web(5.0)), remove_kinks):
            J2, B2, m = op(J, B)
            assert np.array_equal(B2, B) and np.array_equal(J2, J) and len(m) == len(B)


def test_cycle_bones_are_the_bones_that_are_not_bridges():
    J, B = _two_loops_through_a_web()
    assert cycle_bones(len(J), B).all()
    tail = np.vstack([B, [(4, 11)]])
    got = cycle_bones(12, tail)
    assert got[:-1].all() and not got[-1]


def test_merge_short_bones_contracts_bones_under_a_tenth_of_their_radius():
    """A chain of radius-1 joints with a 0.05 bone in the middle: its ends become one joint (at
    their midpoint, both of degree 2); a 0.15 bone stays."""
    J = np.array([[0, 0, 0, 1.0], [1, 0, 0, 1], [1.05, 0, 0, 1], [2, 0, 0, 1], [2.15, 0, 0, 1]])
    B = np.array([[0, 1], [1, 2], [2, 3], [3, 4]])
    J2, B2, m = merge_short_bones(J, B, 0.1)
    assert len(J2) == 4 and len(B2) == 3
    assert np.isclose(J2[:, 0], 1.025).sum() == 1
    L = np.linalg.norm(J2[B2[:, 0], :3] - J2[B2[:, 1], :3], axis=1)
    assert L.min() >= 0.15 - 1e-12


def test_merge_short_bones_leaves_a_small_part_one_bone():
    """A part whose two bones are both shorter than a tenth of the radius keeps its longer bone
    (collapse_short_bones alone would leave a lone joint); another part is merged as usual."""
    J = np.array([[0, 0, 0, 1.0], [0.05, 0, 0, 1], [0.13, 0, 0, 1],
                  [5, 0, 0, 1], [6, 0, 0, 1], [6.02, 0, 0, 1], [7, 0, 0, 1]])
    B = np.array([[0, 1], [1, 2], [3, 4], [4, 5], [5, 6]])
    J2, B2, _ = merge_short_bones(J, B, 0.1)
    assert len(B2) == 3 and len(J2) == 5
    used = np.unique(B2)
    assert len(used) == len(J2)                       # no joint without a bone
    assert np.allclose(sorted(np.linalg.norm(J2[B2[:, 0], :3] - J2[B2[:, 1], :3], axis=1))[0], 0.08)
