"""Unit tests of core/silhouette_radii.py (issue 10: radii fitted to the union of round cones):
analytic answers on a capsule and a cone-shaped tube, against the nearest-bone fit."""

from __future__ import annotations

import numpy as np

from curveskel_addon.core.centreline import fit_radii_surface
from curveskel_addon.core.quality import silhouette_sdf
from curveskel_addon.core.silhouette_radii import BAND, fit_radii_silhouette
from curveskel_addon.core.vertex_area import vertex_areas
from tests.meshes import capsule, tube_along


def _axis(z0, z1, k):
    z = np.linspace(z0, z1, k)
    return np.column_stack([np.zeros(k), np.zeros(k), z]), np.stack([np.arange(k - 1),
                                                                     np.arange(1, k)], 1)


def _mean_abs_sdf(V, w, X, bones, r):
    return float(np.sum(w * np.abs(silhouette_sdf(V, np.column_stack([X, r]), bones))) / w.sum())


def test_capsule_radii_stay_its_radius():
    """A capsule of radius 1 along z from 0 to 6: a chain on its axis explains it exactly with
    radius 1 everywhere; the fit, started 20 % off, returns there."""
    V, F = capsule(radius=1.0, length=6.0, n_around=32, n_body=40)
    w = vertex_areas(V, F)
    X, bones = _axis(0.0, 6.0, 7)
    r, hist = fit_radii_silhouette(V, w, np.column_stack([X, np.full(7, 1.2)]), bones)
    np.testing.assert_allclose(r, 1.0, atol=0.01)
    assert hist[-1] < 0.01 * hist[0]


def test_cone_tube_radii_are_the_tangent_balls_and_beat_the_nearest_bone_fit():
    """A tube whose radius falls linearly from 1.0 to 0.4 over a length of 6 (a truncated cone,
    hemispherical caps). The round cones that reproduce its side have radii rho(z) cos(phi)
    (balls tangent to a side tilted by phi); the nearest-bone fit, which measures distances
    across the axis, gives about rho(z) instead and leaves the silhouette off the surface."""
    L, R0, R1 = 6.0, 1.0, 0.4
    k = 7
    path = np.column_stack([np.zeros(61), np.zeros(61), np.linspace(0, L, 61)])
    V, F = tube_along(path, np.linspace(R0, R1, 61), n_around=48)
    w = vertex_areas(V, F)
    X, bones = _axis(0.0, L, k)
    r_near, _, _ = fit_radii_surface(V, w, np.column_stack([X, np.full(k, 0.7)]), bones)
    r, hist = fit_radii_silhouette(V, w, np.column_stack([X, r_near]), bones)
    phi = np.arctan((R0 - R1) / L)
    want = np.linspace(R0, R1, k) * np.cos(phi)
    # interior joints (the end joints also hold the caps)
    np.testing.assert_allclose(r[1:-1], want[1:-1], atol=0.01)
    assert _mean_abs_sdf(V, w, X, bones, r) < 0.5 * _mean_abs_sdf(V, w, X, bones, r_near)
    assert all(b <= a for a, b in zip(hist, hist[1:]))          # never worse (backtracking)


def test_no_samples_leave_the_radii():
    J = np.array([[0.0, 0, 0, 0.5], [0, 0, 1, 0.7]])
    r, hist = fit_radii_silhouette(np.zeros((0, 3)), np.zeros(0), J, np.array([[0, 1]]))
    np.testing.assert_array_equal(r, [0.5, 0.7])
    assert hist == []


def test_radii_stay_within_the_band_of_their_start():
    """Started at 3x the capsule's radius the fit cannot go below BAND[0] x 3: the band keeps a
    joint the neighbours' balls cover from collapsing into a pinch of the skin."""
    V, F = capsule(radius=1.0, length=6.0, n_around=32, n_body=40)
    X, bones = _axis(0.0, 6.0, 7)
    r, _ = fit_radii_silhouette(V, vertex_areas(V, F), np.column_stack([X, np.full(7, 3.0)]),
                                bones)
    np.testing.assert_allclose(r, BAND[0] * 3.0, rtol=1e-12)
