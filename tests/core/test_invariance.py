"""Metamorphic tests (issue 12): the same surface, permuted, rotated, scaled, moved or with every
vertex moved by 1e-9 of its size, gives the same skeleton up to that transform.

"The same": as many joints and bones, and every point of either curve within 0.001 D of the
other (D = the bounding-box diagonal), after the transform is undone on the joints.

Each case failed before the fix it guards: the hand scaled by 1e-6 (a start radius of the
medial balls had an absolute 1e-9 in it: 0.0032 D), the horse moved by 1e6 of its size (squares
expanded far from the origin: 0.0059 D), spot jittered (mirror-image pole candidates tied and
the last bits chose: 35 joints instead of 30, 0.19 D), the octopus scaled or moved (a point on
a large face read as inside or outside by the last bits: 0.011 D). Shapes with more symmetry than one
mirror (the capsule and torus, bodies of revolution; the bent capsule, two mirror planes whose
composition turns one tip onto the other) have ties that no rule of the shape's own can break,
so they are not asserted; docs/benchmarks.md lists the measured figures.
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from curveskel_addon.core import skeletonize
from curveskel_addon.core.mesh_io import read_mesh

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))
from invariance_table import TOLERANCE, curve_gap, transformed  # noqa: E402

#: test names -> the table's transform codes
CASES = {"permuted": "perm", "rotated": "rot", "scaled 1e6": "s1e6", "scaled 1e-6": "s1e-6",
         "moved by 1e6 D": "t1e6", "jittered by 1e-9 D": "jit"}


@pytest.fixture(scope="module")
def hand(shared_meshes):
    V, F = read_mesh(shared_meshes / "hand.off")
    return V, F, skeletonize(V, F)


@pytest.fixture(scope="module")
def horse(shared_meshes):
    V, F = read_mesh(shared_meshes / "horse.off")
    return V, F, skeletonize(V, F)


def check_same(base, V, F, name):
    D = float(np.linalg.norm(np.ptp(V, axis=0)))
    V2, F2, undo = transformed(V, F, CASES[name], D)
    sk = skeletonize(V2, F2)
    assert (sk.n_joints, sk.n_bones) == (base.n_joints, base.n_bones), name
    d = curve_gap(base, (undo(sk.joints[:, :3]), sk.bones), D)
    assert d <= TOLERANCE, f"{name}: the curves differ by {d:.2e} D"
    return sk


@pytest.mark.parametrize("name", ["permuted", "rotated", "scaled 1e6", "scaled 1e-6",
                                  "moved by 1e6 D", "jittered by 1e-9 D"])
def test_the_hands_skeleton_does_not_depend_on_order_units_position_or_last_bits(hand, name):
    V, F, base = hand
    sk = check_same(base, V, F, name)
    if name == "permuted":          # sigma follows its vertex: the same skeleton point
        p = np.random.default_rng(1).permutation(len(V))
        D = float(np.linalg.norm(np.ptp(V, axis=0)))
        assert np.abs(sk.sigma() - base.sigma()[p]).max() <= 1e-9 * D
    if name.startswith("scaled"):   # radii scale with the shape
        # to a millionth of the size: the silhouette fit (iteratively reweighted, each sample
        # on its nearest cone) carries rounding further than the curve: after the polish's
        # own-section rule one hand radius moved 2.2e-7 D under x1e6, positions 1e-15 D;
        # without the silhouette fit the radii agree to 1e-11
        k = float(name.split()[1])
        r = sk.joints[:, 3] / k
        D = float(np.linalg.norm(np.ptp(V, axis=0)))
        np.testing.assert_allclose(np.sort(r), np.sort(base.joints[:, 3]), rtol=0, atol=1e-6 * D)


@pytest.mark.parametrize("name", ["scaled 1e-6", "moved by 1e6 D", "jittered by 1e-9 D"])
def test_the_horses_skeleton_does_not_depend_on_units_or_position(horse, name):
    V, F, base = horse
    check_same(base, V, F, name)


def test_the_armadillos_skeleton_does_not_hinge_on_last_bits(shared_meshes):
    """Every vertex moved by 1e-9 D (what another CPU's float kernels do): the geodesic key the
    medial samples are drawn from moves by ~1e-7 of its range, and near-tied keys change order.
    Uniforms drawn in key order swapped between them (6 of 3,000 samples changed, a joint moved
    2.2e-3 D); drawn as a continuous function of the key (state.canonical_subset) about one
    sample changes: measured 5.2e-4 D, the same 62 joints."""
    V, F = read_mesh(shared_meshes / "armadillo.obj")
    check_same(skeletonize(V, F), V, F, "jittered by 1e-9 D")


@pytest.fixture(scope="module")
def spot(shared_meshes):
    V, F = read_mesh(shared_meshes / "spot.obj")
    return V, F, skeletonize(V, F)


@pytest.mark.parametrize("name", ["jittered by 1e-9 D", "rotated", "moved by 1e6 D"])
def test_a_mirror_symmetric_cow_keeps_its_skeleton(spot, name):
    V, F, base = spot
    check_same(base, V, F, name)


@pytest.mark.parametrize("name", ["scaled 1e6", "scaled 1e-6", "moved by 1e6 D"])
def test_the_octopus_skeleton_does_not_depend_on_units_or_position(shared_meshes, name):
    """A medial centroid lying on one of the octopus's large faces was 'inside' or 'outside'
    depending on the last bits, and its depth (then the distance to the nearest vertex) decided
    whether a joint moved there: 0.011 D for every one of these transforms."""
    V, F = read_mesh(shared_meshes / "octopus.off")
    check_same(skeletonize(V, F), V, F, name)


@pytest.mark.parametrize("mesh", ["rocker-arm.obj", "fertility.off", "homer.obj", "3holes.off"])
def test_rotated_meshes_keep_their_skeleton(shared_meshes, mesh):
    """Rotation changes the vertex areas in their last bits. The centring's medial samples were
    drawn along a cumulative sum of the areas (rng.choice), so a last-bit change moved some of
    them: rocker-arm rotated had 30 joints instead of 34, fertility rotated differed by 0.035 D.
    Per-point scores (state.canonical_subset) pick them now. The fit's containment distance
    weighted its neighbours by their agreement with the nearest point's normal, which jumps when
    the nearest point changes under rounding (homer rotated: 1.8e-3 D once the neighbours faded
    out); a smooth reference normal replaces it. The fit's Levenberg-Marquardt damping was
    Marquardt's diag(J^T J), whose position entries change with the axes: 3holes rotated took
    another first step (1.6e-3 D); a joint's position entries now share their mean."""
    V, F = read_mesh(shared_meshes / mesh)
    check_same(skeletonize(V, F), V, F, "rotated")


@pytest.mark.parametrize("name", ["rotated", "scaled 1e-6", "jittered by 1e-9 D"])
def test_the_elephants_laid_ears_do_not_depend_on_orientation_units_or_last_bits(shared_meshes,
                                                                                 name):
    """The flap stage (flaps.py) judges a chain by planar sections, a median against a
    threshold, area-weighted quantiles and a nearest medial point: each could hinge on the
    axes, the units or the last bits. Measured when written: 1.3e-15, 4.0e-16, 6.8e-9 D."""
    V, F = read_mesh(shared_meshes / "elephant.obj")
    check_same(skeletonize(V, F), V, F, name)


@pytest.fixture(scope="module")
def small_star():
    from meshes import star
    V, F = star()
    return V, F, skeletonize(V, F)


@pytest.mark.parametrize("name", list(CASES))
def test_a_small_procedural_star_keeps_its_skeleton(small_star, name):
    """The metamorphic cases on a small generated mesh (four arms, 3,145 vertices) beside the
    shared ones. Its symmetry (a quarter turn maps it onto itself) leaves one skeleton, the four
    axes, so unlike a body of revolution it has one answer to compare with. Measured at fe5f615:
    at most 2.0e-5 D (jittered); 1.6e-4-5.0e-4 D before the continuous medial draw."""
    V, F, base = small_star
    check_same(base, V, F, name)


@pytest.mark.parametrize("scale, shift", [(1e9, 0.0), (1e-9, 0.0), (1.0, 1e9)])
def test_the_issues_capsule_scaled_by_1e9_or_moved_by_1e9_keeps_its_skeleton(scale, shift):
    """Issue 12's own row: a unit capsule x1e9, x1e-9 and moved by 1e9 units had 15 / 10 / 15 /
    7 / 29 joints against 11 at unit scale. The same joints now, the curve within 0.001 D
    (measured 6-8e-7 D)."""
    from meshes import capsule
    V, F = capsule()
    D = float(np.linalg.norm(np.ptp(V, axis=0)))
    base = skeletonize(V, F)
    sk = skeletonize(V * scale + shift, F)
    assert (sk.n_joints, sk.n_bones) == (base.n_joints, base.n_bones)
    assert curve_gap(base, ((sk.joints[:, :3] - shift) / scale, sk.bones), D) <= TOLERANCE
