"""Zero-length bones are contracted without changing topology or the mapping's points."""

import numpy as np

from curveskel_addon.core import skeletonize
from curveskel_addon.core.collapse import collapse_short_bones
from meshes import capsule


def test_coincident_chain_joints_are_merged_and_sigma_is_unchanged():
    J = np.array([[0, 0, 0, 1.0], [0, 0, 0, 1.0], [0, 0, 3, 1.0], [0, 0, 6, 1.0], [0, 0, 6, 1.0]])
    B = np.array([[0, 1], [2, 1], [2, 3], [3, 4]])       # bone 1 is stored reversed
    rng = np.random.default_rng(0)
    bone = rng.integers(0, 4, 200)
    t = rng.uniform(0, 1, 200)
    sig = lambda J, B, b, t: t[:, None] * J[B[b, 0], :3] + (1 - t[:, None]) * J[B[b, 1], :3]  # noqa: E731
    J2, B2, b2, t2 = collapse_short_bones(J, B, bone, t, 1e-9)
    assert len(J2) == 3 and len(B2) == 2
    np.testing.assert_allclose(sig(J2, B2, b2, t2), sig(J, B, bone, t), atol=1e-12)


def test_a_contraction_that_would_remove_a_cycle_is_refused():
    # a triangle whose three bones are all tiny: contracting would delete the cycle
    J = np.array([[0, 0, 0, 1.0], [1e-12, 0, 0, 1.0], [0, 1e-12, 0, 1.0]])
    B = np.array([[0, 1], [1, 2], [2, 0]])
    out = collapse_short_bones(J, B, np.array([0]), np.array([0.5]), 1e-9)
    assert out[0] is J and out[1] is B


def test_capsule_skeleton_has_no_zero_length_bone():
    V, F = capsule()
    sk = skeletonize(V, F)
    L = np.linalg.norm(sk.joints[sk.bones[:, 0], :3] - sk.joints[sk.bones[:, 1], :3], axis=1)
    D = np.linalg.norm(np.ptp(V, axis=0))
    assert L.min() > max(1e-4 * D, 0.02 * sk.joints[:, 3].min())
    assert sk.n_bones == sk.n_joints - 1
