"""An armature's bones as a skeleton's segments (issue 33): connected bones share a joint,
disconnected children are joined to their parent's tail, coincident points are one joint."""

from __future__ import annotations

import numpy as np

from curveskel_addon.rig.armature_segments import armature_segments


def _pairs(s):
    return {tuple(sorted(p)) for p in s.segments.tolist()}


def test_connected_child_shares_the_parent_tail():
    heads = [[0, 0, 0], [0, 0, 1]]
    tails = [[0, 0, 1], [0, 0, 2]]
    s = armature_segments(heads, tails, [-1, 0], [False, True])
    assert len(s.joints) == 3 and len(s.segments) == 2
    assert s.tail[0] == s.head[1]
    np.testing.assert_array_equal(s.segment_of_bone, [0, 1])


def test_disconnected_child_is_joined_to_the_parent_tail():
    """A hand bone starting away from the forearm's tail (a gap): a link segment from the
    forearm's tail to its head keeps the skeleton one piece."""
    heads = [[0, 0, 0], [0.1, 0, 1.2]]
    tails = [[0, 0, 1], [0.1, 0, 2]]
    s = armature_segments(heads, tails, [-1, 0], [False, False])
    assert len(s.joints) == 4 and len(s.segments) == 3
    assert (min(s.tail[0], s.head[1]), max(s.tail[0], s.head[1])) in _pairs(s)
    np.testing.assert_array_equal(s.segment_of_bone, [0, 1])       # the link is the third


def test_coincident_points_are_one_joint():
    """Siblings that start at one point share it; a child placed on its parent's tail without
    'connected' gets no link of zero length; a link that runs back along the parent (a child
    starting at the parent's head) is not a second segment."""
    heads = [[0, 0, 0], [0, 0, 1], [0, 0, 1], [0, 0, 0]]
    tails = [[0, 0, 1], [1, 0, 1], [-1, 0, 1], [0, 1, 0]]
    s = armature_segments(heads, tails, [-1, 0, 0, 0], [False, False, False, False])
    assert len(s.joints) == 5
    assert s.head[1] == s.head[2] == s.tail[0]
    assert s.head[3] == s.head[0]
    # four bones' own segments; bone 3's link (parent tail -> its head) repeats bone 0
    assert len(s.segments) == 4
    np.testing.assert_array_equal(s.segment_of_bone, [0, 1, 2, 3])


def test_zero_length_bone_has_no_segment_and_positions_round_trip():
    heads = [[0, 0, 0], [0, 0, 1], [0, 0, 1]]
    tails = [[0, 0, 1], [0, 0, 1], [0, 0, 2]]
    s = armature_segments(heads, tails, [-1, 0, 1], [False, True, True])
    assert s.segment_of_bone[1] == -1
    H, T = s.bone_ends(s.joints)
    np.testing.assert_array_equal(H, heads)
    np.testing.assert_array_equal(T, tails)


def test_fixed_joints_of_bones():
    heads = [[0, 0, 0], [0, 0, 1], [0, 0, 2]]
    tails = [[0, 0, 1], [0, 0, 2], [0, 0, 3]]
    s = armature_segments(heads, tails, [-1, 0, 1], [False, True, True])
    np.testing.assert_array_equal(s.fixed_joints([False, True, False]), [False, True, True, False])


def test_roll_axes_are_perpendicular_and_follow_the_chain():
    """A chain up the z axis bending to +x: every roll axis is a unit vector perpendicular to
    its bone, and the order the bones are listed in does not change the axes."""
    from curveskel_addon.rig.armature_segments import bone_roll_axes

    heads = np.array([[0., 0, 0], [0, 0, 1], [0, 0, 2], [0.5, 0, 2.8]])
    tails = np.array([[0., 0, 1], [0, 0, 2], [0.5, 0, 2.8], [1.5, 0, 3.0]])
    parent = np.array([-1, 0, 1, 2])
    z = bone_roll_axes(heads, tails, parent, up=[0, 0, 1])
    d = (tails - heads) / np.linalg.norm(tails - heads, axis=1, keepdims=True)
    np.testing.assert_allclose(np.einsum("ij,ij->i", z, d), 0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(z, axis=1), 1, atol=1e-12)
    perm = np.array([3, 1, 0, 2])                      # children listed before parents
    inv = np.argsort(perm)
    parent_perm = np.where(parent[perm] >= 0, inv[np.maximum(parent[perm], 0)], -1)
    zp = bone_roll_axes(heads[perm], tails[perm], parent_perm, up=[0, 0, 1])
    np.testing.assert_allclose(zp, z[perm], atol=1e-12)
