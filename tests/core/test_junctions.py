"""Junctions moved onto their trunks (core/junctions.py, part of the polish stage; issue 10)."""

import numpy as np

from curveskel_addon.core.junctions import TRUNK_POWER, onto_trunks


def _t(junction_y=0.3, limb_r=0.3):
    """A trunk along x (radius 1) with its junction lifted towards a limb along +y."""
    X = np.array([[-1.0, 0, 0], [0, junction_y, 0], [1, 0, 0], [0, 2, 0]])
    r = np.array([1.0, 1.0, 1.0, limb_r])
    return X, r, np.array([[0, 1], [1, 2], [1, 3]])


def test_a_junction_lifted_towards_its_limb_goes_back_onto_the_trunk():
    X, r, bones = _t()
    Y = onto_trunks(X, r, bones)
    # the limb's pairs weigh 0.3 ** 8 against the trunk's 1: the trunk line, to 1e-4
    assert np.abs(Y[1] - [0, 0, 0]).max() < 1e-4
    np.testing.assert_array_equal(Y[[0, 2, 3]], X[[0, 2, 3]])     # only junctions move


def test_the_move_is_the_weighted_mean_of_the_pairs_closest_points():
    X, r, bones = _t(junction_y=0.5, limb_r=0.5)
    Y = onto_trunks(X, r, bones)
    # pairs (0, 2): (0, 0, 0); (0, 3) and (2, 3): the closest points of the junction on the
    # segments from (-1, 0) and (1, 0) to (0, 2), weighted 1 : 0.5 ** 8 : 0.5 ** 8
    def closest(a, b, p):
        d = b - a
        return a + np.clip((p - a) @ d / (d @ d), 0, 1) * d
    w = np.array([1.0, 0.5 ** TRUNK_POWER, 0.5 ** TRUNK_POWER])
    P = np.array([closest(X[0], X[2], X[1]), closest(X[0], X[3], X[1]), closest(X[2], X[3], X[1])])
    np.testing.assert_allclose(Y[1], w @ P / w.sum(), atol=1e-12)


def test_a_symmetric_pelvis_stays_on_its_mirror_plane_and_rounding_cannot_flip_it():
    # a spine (radius 1) and two legs (radius 0.6) mirrored in x = 0; the junction off to +x
    X = np.array([[0.3, 0.0, 0], [0, 2, 0], [-1, -2, 0], [1, -2, 0]])
    bones = np.array([[0, 1], [0, 2], [0, 3]])
    r = np.array([1.0, 1.0, 0.6, 0.6])
    Y = onto_trunks(X, r, bones)
    # the two spine-leg pairs weigh alike: their proposals mirror each other but for the
    # junction's own offset; the leg-leg pair proposes (0.3, -2)
    r2 = r.copy()
    r2[2] *= 1 + 1e-9                                      # a last-bit difference between the legs
    Z = onto_trunks(X, r2, bones)
    assert np.abs(Y - Z).max() < 1e-7                      # continuous: no choice flips
    Xs = X.copy()
    Xs[0, 0] = 0.0                                         # the junction on the mirror plane
    assert abs(onto_trunks(Xs, r, bones)[0, 0]) < 1e-15   # stays on it


def test_units_and_degenerate_input():
    X, r, bones = _t()
    Y = onto_trunks(X * 1e-9, r * 1e-9, bones)             # no underflow of r ** 8
    assert np.abs(Y[1] / 1e-9 - onto_trunks(X, r, bones)[1]).max() < 1e-9
    np.testing.assert_array_equal(onto_trunks(X, r, np.zeros((0, 2), int)), X)
    # a chain only (no junction): unchanged
    np.testing.assert_array_equal(onto_trunks(X, r, np.array([[0, 1], [1, 2]])), X)
    # two neighbours at one place: a zero-length pair proposes that place, no NaN
    X2 = X.copy()
    X2[2] = X2[0]
    assert np.isfinite(onto_trunks(X2, r, bones)).all()
