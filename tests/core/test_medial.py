"""Medial balls by shrinking (core/medial.py): the joints the local refinement places where a
bone leaves a thin part (issue 5)."""

from __future__ import annotations

import numpy as np

from curveskel_addon.core.medial import MedialBalls, surface_points
from curveskel_addon.core.quality import InsideTest
from tests.meshes import bent_capsule, capsule, torus


def test_surface_normals_point_outwards():
    V, F = capsule(radius=1.0, length=6.0)
    P, N = surface_points(V, F)
    assert len(P) == len(V) + len(F)
    axis = np.stack([0 * P[:, 2], 0 * P[:, 2], np.clip(P[:, 2], 0.0, 6.0)], axis=1)
    assert np.all(np.einsum("ij,ij->i", P - axis, N) > 0.9 * np.linalg.norm(P - axis, axis=1))
    np.testing.assert_allclose(np.linalg.norm(N, axis=1), 1.0)


def test_capsule_balls_have_its_radius_and_sit_on_its_axis():
    # Every medial ball of a capsule has its radius, centred on the segment between the caps.
    V, F = capsule(radius=1.0, length=6.0)
    balls = MedialBalls(V, F)
    c, r = balls.at(np.arange(len(balls.pts)))
    assert len(r) == len(V)                                 # vertices only
    body = (balls.pts[:, 2] > 0.5) & (balls.pts[:, 2] < 5.5)
    np.testing.assert_allclose(r[body], 1.0, atol=1e-9)
    np.testing.assert_allclose(c[body, :2], 0.0, atol=1e-9)
    assert np.quantile(r, 0.05) > 0.88 and r.max() <= 1.0 + 1e-9
    assert InsideTest(V, F)(c).all()


def test_denoising_keeps_balls_from_shrinking_to_neighbours():
    # At the seam of cap and body the vertex normals tilt: without the separation-angle test
    # the ball shrinks towards a neighbour of the touching point.
    V, F = capsule(radius=1.0, length=6.0)
    r_plain = MedialBalls(V, F, min_angle=0.0).at(np.arange(len(V)))[1]
    r_denoised = MedialBalls(V, F).at(np.arange(len(V)))[1]
    assert np.all(r_denoised >= r_plain - 1e-12)
    assert np.quantile(r_plain, 0.05) < 0.8 < 0.88 < np.quantile(r_denoised, 0.05)


def test_ball_at_nearest_surface_of_an_outside_point_is_the_tube_cross_section():
    # A point outside the L's corner (the middle of the chord that cuts it): the ball touching
    # the surface nearest to it is the tube's own cross-section there.
    V, F = bent_capsule(radius=0.5)
    c, r = MedialBalls(V, F).at_nearest(np.array([[-2.0, 0.0, 2.0]]))
    assert abs(r[0] - 0.5) < 0.05
    assert InsideTest(V, F)(c).all()


def test_balls_on_a_subset_of_the_surface_stay_on_the_axis():
    # The centring's medial balls on a huge mesh shrink against a subsample of its vertices:
    # a capsule's balls through every 4th vertex still have its radius and sit on its axis
    # (within the subsample's sagitta, gap^2 / radius).
    V, F = capsule(radius=1.0, length=6.0, n_around=64, n_body=60)
    every = MedialBalls(V, F)
    sub = np.arange(0, len(V), 4)
    balls = MedialBalls(V, F, points=sub)
    np.testing.assert_array_equal(balls.ids, sub)
    np.testing.assert_array_equal(balls.pts, every.pts[sub])
    c, r = balls.at(np.arange(len(sub)))
    body = (balls.pts[:, 2] > 0.5) & (balls.pts[:, 2] < 5.5)
    assert body.sum() > 100
    np.testing.assert_allclose(r[body], 1.0, atol=1e-6)
    np.testing.assert_allclose(c[body, :2], 0.0, atol=1e-6)
    assert InsideTest(V, F)(c).all()


def test_settled_balls_are_within_a_few_settle_fractions_of_the_converged_ones(monkeypatch):
    # A ball stops once a shrink changes its radius by less than SETTLE (the last, costly
    # queries from a centre equidistant from a band of the surface are skipped). On a finely
    # tessellated torus, where about one ball in ten would shrink further by tiny steps, the
    # radii stay within a few SETTLE of the fully converged ones and never below them.
    import curveskel_addon.core.medial as medial
    settle = medial.SETTLE
    V, F = torus(n_major=256, n_minor=64)
    q = np.arange(0, len(V), 5)
    r_settled = MedialBalls(V, F).at(q)[1]
    monkeypatch.setattr(medial, "SETTLE", 0.0)
    r_full = MedialBalls(V, F).at(q)[1]
    assert np.mean(r_settled != r_full) > 0.02               # the rule did stop some balls
    assert np.all(r_settled >= r_full)                       # shrinking only: never past it
    assert np.max(r_settled / r_full - 1.0) < 5 * settle
