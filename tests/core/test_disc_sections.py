"""The cross-section inside a disc: its area and centroid against the circle-segment formulas,
its Jacobians against central differences, and its centroid continuous where a plane sweeps
over a saddle and two loops of the section join."""

from __future__ import annotations

import manifold3d as m3
import numpy as np
import pytest

from curveskel_addon.core.geometry.disc_sections import disc_sections
from curveskel_addon.core.geometry.face_tree import FaceTree
from curveskel_addon.core.geometry.inside import InsideTest
from tests.meshes import _to_arrays, torus

CUBE_V = np.array([[x, y, z] for x in (0.0, 1) for y in (0.0, 1) for z in (0.0, 1)])
CUBE_F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                   [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


@pytest.mark.parametrize("d", [0.05, 0.15, 0.25])
def test_disc_cut_by_a_face_is_the_circle_less_its_segment(d):
    # the plane x = 0.5 cuts the unit cube in the unit square; the disc of radius 0.3 round
    # (0.5, d, 0.5) loses the circular segment beyond y = 0, at distance d from its centre
    R = 0.3
    s = disc_sections(CUBE_V, CUBE_F, [[0.5, d, 0.5]], [[1.0, 0, 0]], [R])
    seg_area = R * R * np.arccos(d / R) - d * np.sqrt(R * R - d * d)
    seg_moment = 2.0 / 3.0 * (R * R - d * d) ** 1.5           # about the centre, towards -y
    area = np.pi * R * R - seg_area
    assert s.area[0] == pytest.approx(area, rel=1e-12)
    np.testing.assert_allclose(s.centroid[0], [0.5, d + seg_moment / area, 0.5], atol=1e-12)


def test_disc_all_inside_or_all_outside():
    s = disc_sections(CUBE_V, CUBE_F, [[0.5, 0.5, 0.5], [0.5, 0.5, 3.0]], [[0, 0, 1.0]] * 2, [0.2, 0.2])
    assert s.area.tolist() == pytest.approx([np.pi * 0.04, 0.0])
    np.testing.assert_allclose(s.centroid, [[0.5, 0.5, 0.5], [0.5, 0.5, 3.0]])


def test_disc_taking_the_whole_section_has_its_centroid():
    s = disc_sections(CUBE_V, CUBE_F, [[0.3, 0.2, 0.9]], [[0, 0, 1.0]], [5.0])
    assert s.area[0] == pytest.approx(1.0)
    np.testing.assert_allclose(s.centroid[0], [0.5, 0.5, 0.9], atol=1e-12)


def test_jacobians_against_central_differences():
    V, F = torus(3.0, 1.0, 48, 20)
    V = V * (1 + 0.02 * np.random.default_rng(1).standard_normal(V.shape))
    tree, inside = FaceTree(V, F), InsideTest(V, F)
    rng = np.random.default_rng(0)
    ang = rng.uniform(0, 2 * np.pi, 40)
    X = np.c_[3 * np.cos(ang), 3 * np.sin(ang), rng.uniform(-0.3, 0.3, 40)] + rng.normal(0, 0.2, (40, 3))
    N = np.c_[-np.sin(ang), np.cos(ang), np.zeros(40)] + rng.normal(0, 0.3, (40, 3))
    N /= np.linalg.norm(N, axis=1)[:, None]
    R = rng.uniform(0.5, 2.5, 40)
    s = disc_sections(V, F, X, N, R, tree=tree, inside=inside, jacobian=True)
    assert (s.area > 0).all() and (s.area < np.pi * R * R).any()      # the outlines are crossed
    h = 1e-6
    for J, which in ((s.dc_dx, 0), (s.dc_dn, 1)):
        for c in range(3):
            e = np.zeros((40, 3))
            e[:, c] = h
            args = lambda sign: (X + sign * e, N) if which == 0 else (X, N + sign * e)  # noqa: E731
            fd = (disc_sections(V, F, *args(1), R, tree=tree, inside=inside).centroid
                  - disc_sections(V, F, *args(-1), R, tree=tree, inside=inside).centroid) / (2 * h)
            np.testing.assert_allclose(J[:, :, c], fd, atol=1e-5)


def test_centroid_is_continuous_where_two_loops_join():
    # two upright bars of different widths joined by a round bridge along x (radius 0.3): a
    # plane z = const cuts two loops below and above the bridge and one across it. Sweeping the
    # plane over the saddles, the disc's centroid moves in steps of the sweep's order, never
    # jumps (a flat face in the plane would make the solid's own section jump).
    left = m3.Manifold.cube([0.6, 0.6, 3.0], True).translate([-1.0, 0, 0])
    right = m3.Manifold.cube([0.3, 0.3, 3.0], True).translate([1.0, 0, 0])
    bridge = m3.Manifold.cylinder(2.0, 0.3, 0.3, 48, True).rotate([0, 90, 0])
    V, F = _to_arrays(left + right + bridge)
    # (near z = 0.3 the section grows at about 40 per unit z: a step of 1e-5 moves the centroid
    # under 1e-3, where dropping or taking a loop would move it by 0.3)
    for lo, hi in ((-0.5, 0.5), (0.29, 0.31)):
        z = np.linspace(lo, hi, 2001)
        X = np.c_[np.full_like(z, 0.2), np.zeros_like(z), z]
        s = disc_sections(V, F, X, np.tile([0, 0, 1.0], (len(z), 1)), np.full(len(z), 2.0))
        step = np.linalg.norm(np.diff(s.centroid, axis=0), axis=1)
        assert step.max() < 100 * (z[1] - z[0])
    # the bridge pulls the centroid towards the middle across it
    s = disc_sections(V, F, [[0.2, 0, -0.5], [0.2, 0, 0]], [[0, 0, 1.0]] * 2, [2.0, 2.0])
    assert s.centroid[1, 0] > s.centroid[0, 0] + 0.05
