"""Metamorphic tests (issue 12): the same surface, permuted, rotated, scaled or moved gives the
same skeleton up to that transform.

"The same": as many joints and bones, and every point of either curve within 0.001 D of the
other (D = the bounding-box diagonal; points every D/1000 along the bones), after the transform
is undone on the joints. (Every vertex moved by 1e-9 D, the last-bits case, is issue 30's
stricter jitter test: tests/core/test_objective_behaviour.py.)

Each case failed once before the fix it guards: the hand scaled by 1e-6 (an absolute 1e-9 in a
start radius: 0.0032 D), the horse moved by 1e6 of its size (squares expanded far from the
origin: 0.0059 D), spot's mirror-image pole candidates tied and the last bits chose (35 joints
instead of 30, 0.19 D), the octopus scaled or moved (a point on a large face read as inside or
outside by the last bits: 0.011 D), rotated meshes (a Levenberg-Marquardt damping that changes
with the axes: 3holes 1.6e-3 D). Shapes with more symmetry than one mirror (the capsule and
torus, bodies of revolution; the bent capsule) have ties no rule of the shape's own can break,
so only their scale and position are asserted.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from curveskel_addon.core import skeletonize
from skeletons import (bbox_D, curve_gap, procedural_mesh, procedural_skeleton, shared_mesh,
                       shared_skeleton)

#: issue 12's target: the curves within 0.001 D (bounding-box diagonal)
TOLERANCE = 1e-3

CASES = ["permuted", "rotated", "scaled 1e6", "scaled 1e-6", "moved by 1e6 D"]


def transformed(V, F, name, D):
    """(V', F', undo): permuted (vertices and faces renumbered), rotated (about the centroid),
    scaled by k, moved by k D."""
    rng = np.random.default_rng(1)
    c = V.mean(axis=0)
    if name == "permuted":
        p = rng.permutation(len(V))
        return V[p], np.argsort(p)[F][rng.permutation(len(F))], lambda X: X
    if name == "rotated":
        R = Rotation.random(random_state=3).as_matrix()
        return (V - c) @ R.T + c, F, lambda X: (X - c) @ R + c
    k = float(name.split()[-1] if name.startswith("scaled") else name.split()[2])
    if name.startswith("scaled"):
        return V * k, F, lambda X: X / k
    shift = np.array([1.0, -0.5, 0.25]) * k * D
    return V + shift, F, lambda X: X - shift


def check_same(base, V, F, name):
    D = bbox_D(V)
    V2, F2, undo = transformed(np.asarray(V), np.asarray(F), name, D)
    sk = skeletonize(V2, F2)
    assert (sk.n_joints, sk.n_bones) == (base.n_joints, base.n_bones), name
    d = curve_gap(base, (undo(sk.joints[:, :3]), sk.bones), D)
    assert d <= TOLERANCE, f"{name}: the curves differ by {d:.2e} D"
    return sk


@pytest.mark.slow
@pytest.mark.parametrize("name", CASES)
def test_the_hands_skeleton_does_not_depend_on_order_units_or_position(name):
    V, F = shared_mesh("hand.off")
    base = shared_skeleton("hand.off")
    sk = check_same(base, V, F, name)
    if name == "permuted":          # sigma follows its vertex: the same skeleton point
        p = np.random.default_rng(1).permutation(len(V))
        assert np.abs(sk.sigma() - base.sigma()[p]).max() <= 1e-9 * bbox_D(V)
    if name.startswith("scaled"):   # radii scale with the shape
        k = float(name.split()[1])
        np.testing.assert_allclose(np.sort(sk.joints[:, 3] / k), np.sort(base.joints[:, 3]),
                                   rtol=0, atol=1e-6 * bbox_D(V))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["scaled 1e-6", "moved by 1e6 D"])
def test_the_horses_skeleton_does_not_depend_on_units_or_position(name):
    check_same(shared_skeleton("horse.off"), *shared_mesh("horse.off"), name)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["rotated", "moved by 1e6 D"])
def test_a_mirror_symmetric_cow_keeps_its_skeleton(name):
    check_same(shared_skeleton("spot.obj"), *shared_mesh("spot.obj"), name)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["scaled 1e6", "scaled 1e-6", "moved by 1e6 D"])
def test_the_octopus_skeleton_does_not_depend_on_units_or_position(name):
    """A point on one of the octopus's large faces read as inside or outside by the last bits
    once moved a joint by 0.011 D under every one of these transforms."""
    check_same(shared_skeleton("octopus.off"), *shared_mesh("octopus.off"), name)


@pytest.mark.slow
@pytest.mark.parametrize("mesh", ["rocker-arm.obj", "fertility.off", "homer.obj", "3holes.off"])
def test_rotated_meshes_keep_their_skeleton(mesh):
    """Rotation changes the samples' and areas' last bits and the axes the solver steps along:
    a draw along a cumulative sum of areas, a containment weight that jumped with the nearest
    point, and a Levenberg-Marquardt damping by diag(J^T J) (not the same in any axes) each
    once changed a rotated skeleton (rocker-arm 30 joints instead of 34, fertility 0.035 D,
    homer 1.8e-3 D, 3holes 1.6e-3 D)."""
    check_same(shared_skeleton(mesh), *shared_mesh(mesh), "rotated")


@pytest.mark.slow
@pytest.mark.parametrize("name", ["rotated", "scaled 1e-6"])
def test_the_elephants_ears_do_not_depend_on_orientation_or_units(name):
    """The ears are flat flaps: their chains are decided by sections, which could hinge on the
    axes or the units."""
    check_same(shared_skeleton("elephant.obj"), *shared_mesh("elephant.obj"), name)


@pytest.mark.parametrize("name", CASES)
def test_a_small_procedural_star_keeps_its_skeleton(name):
    """The metamorphic cases on a small generated mesh (four arms, 3,145 vertices) beside the
    shared ones. Its symmetry (a quarter turn maps it onto itself) leaves one skeleton, the four
    axes, so unlike a body of revolution it has one answer to compare with."""
    check_same(procedural_skeleton("star"), *procedural_mesh("star"), name)


@pytest.mark.parametrize("scale, shift", [(1e9, 0.0), (1e-9, 0.0), (1.0, 1e9)])
def test_the_issues_capsule_scaled_by_1e9_or_moved_by_1e9_keeps_its_skeleton(scale, shift):
    """Issue 12's own row: a unit capsule x1e9, x1e-9 and moved by 1e9 units had 15 / 10 / 15 /
    7 / 29 joints against 11 at unit scale. The same joints now, the curve within 0.001 D."""
    V, F = procedural_mesh("capsule")
    base = procedural_skeleton("capsule")
    sk = skeletonize(V * scale + shift, F)
    assert (sk.n_joints, sk.n_bones) == (base.n_joints, base.n_bones)
    assert curve_gap(base, ((sk.joints[:, :3] - shift) / scale, sk.bones), bbox_D(V)) <= TOLERANCE
