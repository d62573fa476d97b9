"""Surface samples (core/geometry/samples.py): the quadrature points J integrates over, and the
numbering-free subset drawn from them."""

from __future__ import annotations

import numpy as np
import pytest

from curveskel_addon.core.geometry.samples import canonical_subset, face_samples


def test_canonical_subset_does_not_depend_on_numbering():
    rng = np.random.default_rng(3)
    key = rng.random(5000)
    p = rng.random(5000)
    pick = canonical_subset(key, 1200, seed=7, p=p)
    assert len(pick) == 1200 == len(np.unique(pick)) and np.all(np.diff(pick) > 0)
    perm = rng.permutation(5000)                       # the same points, numbered otherwise
    pick_perm = canonical_subset(key[perm], 1200, seed=7, p=p[perm])
    np.testing.assert_array_equal(np.sort(perm[pick_perm]), pick)
    # moved, scaled: the key is scaled to its range first
    np.testing.assert_array_equal(canonical_subset(3.0 * key + 5.0, 1200, seed=7, p=p), pick)


def test_canonical_subset_follows_the_weights():
    # (the draw's randomness is the key's fine structure: a mesh's geodesic distances, not a
    # regular grid of keys, which is drawn in a regular pattern)
    key = np.random.default_rng(11).random(10)
    p = np.ones(10)
    p[0], p[9] = 6.0, 0.0                              # a heavy point and one never drawn
    hits = np.zeros(10)
    for seed in range(3000):
        hits[canonical_subset(key, 3, seed, p)] += 1
    freq = hits / 3000
    assert freq[9] == 0.0
    assert freq[0] > 0.75 and np.all(np.abs(freq[1:9] - freq[1:9].mean()) < 0.05)
    np.testing.assert_array_equal(canonical_subset(key, 10, 0, p), np.arange(10))


def test_canonical_subset_ignores_last_bit_changes_of_the_weights():
    # a rotated or jittered mesh's vertex areas differ in their last bits: the draw must not
    # (a cumulative-sum draw, rng.choice(p=...), moved 26 of 3,000 medial samples that way)
    rng = np.random.default_rng(5)
    key = rng.random(40_000)
    p = rng.random(40_000)
    nudged = p * (1.0 + rng.uniform(-1e-9, 1e-9, p.shape))
    pick = canonical_subset(key, 3000, 0, p)
    np.testing.assert_array_equal(canonical_subset(key, 3000, 0, nudged), pick)


def test_canonical_subset_keeps_its_picks_when_near_tied_keys_swap():
    # issue 12: a mesh whose vertices moved by 1e-9 of its size has geodesic keys ~1e-7 of
    # their range apart from the original's, and many near-tied keys change order. Uniforms
    # drawn in key order swapped between such keys (6 of the armadillo's 3,000 medial
    # samples changed, a joint moved 2.2e-3 D); u as a function of the key keeps the picks.
    rng = np.random.default_rng(2)
    key = rng.integers(0, 2000, 40_000) / 2000.0 + rng.uniform(0.0, 1e-9, 40_000)
    p = rng.random(40_000)
    moved = key + rng.uniform(-1e-9, 1e-9, key.shape)
    flipped = np.argsort(key, kind="stable") != np.argsort(moved, kind="stable")
    assert flipped.sum() > 10_000                      # the order changed a lot
    pick = canonical_subset(key, 3000, 0, p)
    assert len(np.setdiff1d(pick, canonical_subset(moved, 3000, 0, p))) <= 1


def test_face_samples_integrate_the_area_and_the_centroid_exactly():
    """The midpoint rule on congruent sub-triangles: the weights sum to each face's area, and
    the weighted mean of the points is each face's centroid (a linear function is integrated
    exactly)."""
    rng = np.random.default_rng(0)
    V = rng.normal(size=(30, 3))
    F = np.array([[i, (i + 1) % 30, (i + 7) % 30] for i in range(30)])
    s = face_samples(V, F, 0.3)
    area = np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1) / 2
    np.testing.assert_allclose(np.bincount(s.face, s.weights, len(F)), area, rtol=1e-12)
    moment = np.stack([np.bincount(s.face, s.weights * s.points[:, c], len(F)) for c in range(3)], 1)
    np.testing.assert_allclose(moment / area[:, None], V[F].mean(axis=1), atol=1e-12)
    # each face split into k^2 sub-triangles, k its longest side over h rounded up
    longest = np.max([np.linalg.norm(V[F[:, a]] - V[F[:, b]], axis=1) for a, b in ((0, 1), (1, 2), (2, 0))], axis=0)
    np.testing.assert_array_equal(np.bincount(s.face, minlength=len(F)), np.ceil(longest / 0.3) ** 2)


def test_face_samples_do_not_depend_on_how_a_face_is_split():
    """One flat square as 2 triangles or as 8: the samples' integral of a quadratic over it
    agrees to the midpoint rule's error (h^2), whatever the triangulation."""
    V2 = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    F2 = np.array([[0, 1, 2], [0, 2, 3]])
    g = np.linspace(0, 1, 3)
    V8 = np.array([[x, y, 0.0] for y in g for x in g])
    F8 = np.array([[a, a + 1, a + 4] for a in (0, 1, 3, 4)] + [[a, a + 4, a + 3] for a in (0, 1, 3, 4)])
    exact = 2.0 / 3.0                                  # integral of x^2 + y^2 over the square
    for V, F in ((V2, F2), (V8, F8)):
        s = face_samples(V, F, 0.02)
        assert s.weights.sum() == pytest.approx(1.0, rel=1e-12)
        assert (s.weights * (s.points[:, 0] ** 2 + s.points[:, 1] ** 2)).sum() == pytest.approx(exact, abs=1e-3)
