"""J's terms: each gradient against central finite differences, and the values of simple cases
worked out by hand (a straight tube, a right-angle turn, a bone leaving a box)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from curveskel_addon.core.geometry.samples import face_samples
from curveskel_addon.core.geometry.segments import closest_on_bones, nearest_on_silhouette
from curveskel_addon.core.mesh import Mesh
from curveskel_addon.core.objective import terms as T
from scipy.spatial import cKDTree


@pytest.fixture(scope="module")
def bumpy_capsule():
    """A capsule along z (radius 0.4, cylinder 2.0 long) with its vertices jittered: no term is
    zero and no symmetry hides a wrong sign."""
    m = trimesh.creation.capsule(height=2.0, radius=0.4, count=[16, 16])
    V = np.asarray(m.vertices) * (1 + 0.03 * np.random.default_rng(2).standard_normal((len(m.vertices), 3)))
    mesh = Mesh(V, m.faces)
    s = face_samples(mesh.V, mesh.F, 0.2)
    Z = np.array([[0, 0, -1.2, 0.3], [0.03, 0.02, -0.4, 0.4], [-0.02, 0.05, 0.3, 0.35],
                  [0.05, -0.03, 1.15, 0.3]])
    bones = np.array([[0, 1], [1, 2], [2, 3]])
    bone, t, _ = closest_on_bones(s.points, Z, bones)
    return mesh, s, Z, bones, bone, t


def _check_gradient(fn, Z, h=1e-7, rtol=1e-6):
    """2 J^T r of ``fn`` against central differences of sum r^2, every variable."""
    r, Jm = fn(Z, True)
    g = 2 * (Jm.T @ r)
    fd = np.zeros(Z.size)
    for q in range(Z.size):
        zp, zm = Z.ravel().copy(), Z.ravel().copy()
        zp[q] += h
        zm[q] -= h
        fd[q] = ((fn(zp.reshape(-1, 4), False)[0] ** 2).sum()
                 - (fn(zm.reshape(-1, 4), False)[0] ** 2).sum()) / (2 * h)
    assert np.abs(fd).max() > 0
    np.testing.assert_allclose(g, fd, rtol=0, atol=rtol * np.abs(fd).max())
    return (r ** 2).sum()


def test_fit_gradient(bumpy_capsule):
    mesh, s, Z, bones, bone, t = bumpy_capsule
    scale = 0.3 * (1 + 0.1 * np.sin(np.arange(len(t))))
    value = _check_gradient(lambda Z, jac: T.fit_term(Z, s, bones, bone, s.weights.sum(), scale,
                                                      jacobian=jac), Z)
    assert value > 0


def test_soft_fit_gradient_and_bound(bumpy_capsule):
    # three candidate cones per sample, softened over a tenth of the scale: the gradient
    # against central differences; the soft minimum lies between the least value less
    # tau log 3 and the least value
    mesh, s, Z, bones, *_ = bumpy_capsule
    bone, t, _ = nearest_on_silhouette(s.points, Z, bones, 3)
    scale = np.full(len(t), 0.3)
    fit = lambda Z, jac, soft=0.1: T.fit_term(Z, s, bones, bone, s.weights.sum(), scale,  # noqa: E731
                                              softness=soft, jacobian=jac)
    _check_gradient(fit, Z)
    hard = T.fit_term(Z, s, bones, bone[:, 0], s.weights.sum(), scale, jacobian=False)[0]
    assert np.all(fit(Z, False)[0] <= hard + 1e-12)
    # pseudo-Huber is 1-Lipschitz in z beyond its origin: the shift is at most tau log 3 / scale
    assert np.abs(fit(Z, False, 1e-6)[0] - hard).max() < 1e-5


def test_centre_gradient(bumpy_capsule):
    mesh, s, Z, bones, *_ = bumpy_capsule
    _check_gradient(lambda Z, jac: T.centre_term(Z, bones, mesh, mesh.D, np.full(3, 0.42),
                                                 jacobian=jac), Z)


def test_centre_gradient_where_discs_clip_the_section(bumpy_capsule):
    # discs of radius 2 * 0.18 inside a capsule of radius 0.4: the outline crosses them
    mesh, s, Z, bones, *_ = bumpy_capsule
    clipped = T.centre_term(Z, bones, mesh, mesh.D, np.full(3, 0.18), jacobian=False)[0]
    assert (clipped ** 2).sum() > 0
    _check_gradient(lambda Z, jac: T.centre_term(Z, bones, mesh, mesh.D, np.full(3, 0.18),
                                                 jacobian=jac), Z)


def test_smooth_gradient(bumpy_capsule):
    mesh, s, Z, bones, *_ = bumpy_capsule
    _check_gradient(lambda Z, jac: T.smooth_term(Z, bones, mesh.D, jacobian=jac), Z)


@pytest.mark.parametrize("shift", [0.25, 0.35, 0.6])
def test_contain_gradient(bumpy_capsule, shift):
    # pushed sideways: near the surface (0.25), partly out (0.35), out beyond the tangent
    # planes' reach (0.6, where the distance to the surface takes over)
    mesh, s, Z, bones, *_ = bumpy_capsule
    tree = cKDTree(s.points)
    out = Z + np.array([shift, 0, 0, 0])
    value = _check_gradient(lambda Z, jac: T.contain_term(Z, bones, mesh.inside, tree, s.points,
                                                          s.normal, mesh.D, np.full(3, 0.1),
                                                          jacobian=jac), out)
    assert value > 0


def test_contain_is_zero_deep_inside_and_grows_with_the_margin(bumpy_capsule):
    mesh, s, Z, bones, *_ = bumpy_capsule
    tree = cKDTree(s.points)
    axis = Z * np.array([0.1, 0.1, 0.5, 1])         # on the axis, 0.4 from the surface
    value = lambda margin: (T.contain_term(axis, bones, mesh.inside, tree, s.points, s.normal,  # noqa: E731
                                           mesh.D, np.full(3, margin), jacobian=False)[0] ** 2).sum()
    # the bones' points lie 0.35-0.42 under the jittered surface (the ends nearer the caps):
    # seven margins of 0.05 deep they cost next to nothing; under margins of 0.45 and 0.6 they
    # are short of the margin line and cost more with the larger margin
    assert value(0.05) < 1e-6 * value(0.45)
    assert 0 < value(0.45) < value(0.6)


def test_smooth_values_by_hand():
    # a right angle at joint 1, bones of length 1 and 3: 1 - cos 90 = 1; the radius 0.5 against
    # the mean of 0.2 and 0.4 (0.3): (0.2)^2 / (2 * D) with the mean length 2 and D = 10
    Z = np.array([[0, 0, 0, 0.2], [1, 0, 0, 0.5], [1, 3, 0, 0.4]], float)
    val = T.smooth_term(Z, np.array([[0, 1], [1, 2]]), 10.0, jacobian=None)
    np.testing.assert_allclose(val, [1.0 + 0.2 ** 2 / (2.0 * 10.0)])
    straight = T.smooth_term(np.array([[0, 0, 0, 1], [1, 0, 0, 1], [3, 0, 0, 1.0]]),
                             np.array([[0, 1], [1, 2]]), 10.0, jacobian=None)
    assert straight[0] == pytest.approx(0.0, abs=1e-15)


def test_centre_of_a_straight_tube_is_zero_on_its_axis():
    m = trimesh.creation.cylinder(radius=0.5, height=4.0, sections=64)
    mesh = Mesh(m.vertices, m.faces)
    on_axis = np.array([[0, 0, -1.0, 0.5], [0, 0, 1.0, 0.5]])
    off_axis = on_axis + np.array([0.1, 0, 0, 0])
    bones = np.array([[0, 1]])
    r_on = T.centre_term(on_axis, bones, mesh, mesh.D, np.array([0.5]), jacobian=False)[0]
    r_off = T.centre_term(off_axis, bones, mesh, mesh.D, np.array([0.5]), jacobian=False)[0]
    assert np.abs(r_on).max() < 1e-12
    # offset 0.1 in units of the thickness 0.5, weight sqrt(l / (2 D)) at each Gauss point
    expected = 2 * (2.0 / (2 * mesh.D)) * (0.1 / 0.5) ** 2
    assert (r_off ** 2).sum() == pytest.approx(expected, rel=1e-3)


def test_fit_is_zero_for_the_exact_silhouette():
    # a capsule's surface points at distance r from the axis segment: the silhouette fits
    m = trimesh.creation.capsule(height=2.0, radius=0.4, count=[32, 32])
    s = face_samples(np.asarray(m.vertices), np.asarray(m.faces), 0.05)
    P = s.points
    Z = np.array([[0, 0, -1.0, 0.4], [0, 0, 1.0, 0.4]])
    bone, t, d2 = closest_on_bones(P, Z, np.array([[0, 1]]))
    r, _ = T.fit_term(Z, s, np.array([[0, 1]]), bone, s.weights.sum(), 0.4, jacobian=False)
    # faces are flat chords of the round surface: within their sagitta (1 - cos(pi/32)) r
    assert np.abs(r).max() < 0.006
