"""core.graph_root: the most central joint of each part of a skeleton graph."""

import numpy as np

from curveskel_addon.rig.graph_root import central_joints


def _line(n):
    return np.stack([np.arange(n), np.zeros(n), np.zeros(n)], 1).astype(float)


def test_chain_centre_and_single_joint_parts():
    P = np.concatenate([_line(5), [[10.0, 0, 0]]])
    assert central_joints(P, [[0, 1], [1, 2], [2, 3], [3, 4]]).tolist() == [2, 5]


def test_centre_uses_bone_lengths_not_hops():
    # joints at x = 0, 1, 2, 10: the middle by length is joint 2 (distance 8 to joint 3)
    P = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [10, 0, 0]], float)
    assert central_joints(P, [[0, 1], [1, 2], [2, 3]]).tolist() == [2]


def test_star_loop_and_two_parts_in_joint_order():
    star = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0]], float)
    ang = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    loop = np.stack([np.cos(ang), np.sin(ang), np.zeros(6)], 1) + [5, 0, 0]
    P = np.concatenate([loop, star])
    E = [[i, (i + 1) % 6] for i in range(6)] + [[6, 7], [6, 8], [6, 9]]
    roots = central_joints(np.c_[P, np.ones(len(P))], E)     # a radius column is ignored
    assert roots.tolist() == [0, 6]                            # loop: tie -> lowest index


def test_zero_length_bone_still_connects():
    P = np.array([[0, 0, 0], [0, 0, 0], [1, 0, 0]], float)
    assert len(central_joints(P, [[0, 1], [1, 2]])) == 1


def test_empty():
    assert central_joints(np.zeros((0, 4)), np.zeros((0, 2), int)).tolist() == []
