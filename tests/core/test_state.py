"""Pipeline state helpers (core/state.py): numbering-free samples."""

from __future__ import annotations

import numpy as np

from curveskel_addon.core.state import canonical_sample, canonical_subset


def test_canonical_subset_does_not_depend_on_numbering():
    rng = np.random.default_rng(3)
    key = rng.random(5000)
    p = rng.random(5000)
    pick = canonical_subset(key, 1200, seed=7, p=p)
    assert len(pick) == 1200 == len(np.unique(pick)) and np.all(np.diff(pick) > 0)
    perm = rng.permutation(5000)                       # the same points, numbered otherwise
    pick_perm = canonical_subset(key[perm], 1200, seed=7, p=p[perm])
    np.testing.assert_array_equal(np.sort(perm[pick_perm]), pick)
    order = np.argsort(key, kind="stable")             # a precomputed order changes nothing
    np.testing.assert_array_equal(canonical_subset(key, 1200, 7, p, order=order), pick)
    np.testing.assert_array_equal(canonical_sample(key, 300, 7, p, order=order),
                                  canonical_sample(key, 300, 7, p))


def test_canonical_subset_follows_the_weights():
    key = np.arange(10.0)
    p = np.ones(10)
    p[0], p[9] = 6.0, 0.0                              # a heavy point and one never drawn
    hits = np.zeros(10)
    for seed in range(3000):
        hits[canonical_subset(key, 3, seed, p)] += 1
    freq = hits / 3000
    assert freq[9] == 0.0
    assert freq[0] > 0.75 and np.all(np.abs(freq[1:9] - freq[1:9].mean()) < 0.05)
    np.testing.assert_array_equal(canonical_subset(key, 10, 0, p), np.arange(10))
