"""Unit tests of core/cross_section.py (issue 10: the polish stage): section centroids against
the analytic centre of a box, a tube and a plate's strip; the loops it refuses; the polish of a
displaced chain."""

from __future__ import annotations

import numpy as np
import pytest

from curveskel_addon.core import cross_section
from curveskel_addon.core.cross_section import (FADE, REACH, STEP, polish_chains, shared_sections,
                                                section_centroids, vertex_edges)
from curveskel_addon.core.quality import InsideTest
from tests.meshes import (BAR, PLATE, box_bar, capsule, plate_with_holes, t_beam,
                          t_beam_centroid_y)


@pytest.fixture(scope="module")
def bar():
    return box_bar()


@pytest.fixture(scope="module")
def plate():
    return plate_with_holes()


def test_box_section_centroid_is_the_axis(bar):
    """The section of the 8 x 1 x 1 bar across x is the unit square about the axis, wherever
    the point lies in it."""
    V, F = bar
    X = np.array([[-2.0, 0.3, -0.2], [0.0, -0.45, 0.45], [1.5, 0.0, 0.1]])
    C, extent = section_centroids(V, F, X, np.tile([1.0, 0, 0], (3, 1)), [2.0, 2.0, 2.0])
    assert np.isfinite(extent).all()
    np.testing.assert_allclose(C, X * [1, 0, 0], atol=1e-9)


def test_tube_section_centroid_is_on_the_axis_also_for_a_slanted_plane():
    """A capsule (radius 1, axis z): a plane across the axis cuts a regular polygon, a plane
    slanted by 25 degrees an ellipse-like polygon; both centred on the axis."""
    V, F = capsule(radius=1.0, length=6.0, n_around=32, n_body=40)
    X = np.array([[0.4, 0.2, 2.0], [-0.3, 0.5, 3.3], [0.1, -0.6, 4.0]])
    a = np.radians(25)
    T = np.array([[0, 0, 1.0], [np.sin(a), 0, np.cos(a)], [0, np.sin(a), np.cos(a)]])
    C, extent = section_centroids(V, F, X, T, 3.0)
    assert np.isfinite(extent).all()
    # on the axis: x = y = 0 (within the faceting of a 32-gon, ~1e-3 of the radius), and in
    # the point's plane
    assert np.abs(C[:, :2]).max() < 2e-3, C
    np.testing.assert_allclose(np.einsum("ij,ij->i", C - X, T), 0, atol=1e-12)


def test_plate_strip_section_centroid_is_the_middle_of_the_strip(plate):
    """Above the middle hole of the plate (holes of radius 0.5 at x = -2, 0, 2 in a 6 x 2 x 0.4
    box) the section across x is the strip y in [0.5, 1], z in [-0.2, 0.2]: centroid y = 0.75,
    z = 0, wherever the point lies in the strip (on a plate the medial points do not say)."""
    V, F = plate
    hole, half_w = PLATE["hole_radius"], PLATE["size"][1] / 2
    X = np.array([[0.0, 0.55, 0.15], [0.0, 0.95, -0.1]])
    C, extent = section_centroids(V, F, X, np.tile([1.0, 0, 0], (2, 1)), 1.0)
    assert np.isfinite(extent).all()
    np.testing.assert_allclose(C, [[0, (hole + half_w) / 2, 0]] * 2, atol=2e-3)


def test_no_centroid_where_the_loop_is_not_the_points_own(plate, bar):
    V, F = plate
    # in the middle hole: the plane cuts the strips above and below it, neither round the point
    C, extent = section_centroids(V, F, [[0.0, 0.0, 0.0]], [[1.0, 0, 0]], 5.0)
    assert extent[0] == np.inf and np.array_equal(C, [[0.0, 0.0, 0.0]])
    # a loop reaching farther than `reach`: the bar's section has its corners 0.71 away
    Vb, Fb = bar
    C, extent = section_centroids(Vb, Fb, [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
                                  [[1.0, 0, 0], [1.0, 0, 0]], [0.7, 0.72])
    assert extent[0] == np.inf and extent[1] == pytest.approx(np.sqrt(0.5))


def test_vertex_edges_is_the_longest_side_of_the_faces_around_each_vertex(bar):
    """Against a loop over the faces."""
    V, F = bar
    want = np.zeros(len(V))
    for f in F:
        side = max(np.linalg.norm(V[f[a]] - V[f[b]]) for a, b in ((0, 1), (1, 2), (2, 0)))
        want[f] = np.maximum(want[f], side)
    np.testing.assert_allclose(vertex_edges(V, F), want, rtol=1e-12)


def test_polish_brings_a_displaced_chain_back_to_the_axis(bar):
    """A chain along the bar with its joints pushed off the axis by 0.1-0.25 (alternately up
    and down: a zig-zag) and its tips 0.3 off: two rounds take every joint, tips included,
    to within 0.05 of the axis (radius 0.75: every section within REACH radii)."""
    V, F = bar
    L = BAR["size"][0]
    x = np.linspace(-L / 2 + 0.3, L / 2 - 0.3, 9)
    off = np.array([0.3, 0.15, -0.2, 0.25, -0.1, 0.2, -0.25, 0.1, 0.3])
    J = np.column_stack([x, off, 0.5 * off, np.full(9, 0.75)])
    bones = np.stack([np.arange(8), np.arange(1, 9)], 1)
    X, moved = polish_chains(V, F, J, bones, InsideTest(V, F))
    assert moved == 9
    assert np.hypot(X[:, 1], X[:, 2]).max() < 0.05, np.hypot(X[:, 1], X[:, 2])
    # along the axis a little (a tip moves in its plane, which the zig-zag tilts)
    np.testing.assert_allclose(X[:, 0], x, atol=0.15)


def test_polish_keeps_a_joint_whose_new_place_is_outside(bar):
    V, F = bar
    J = np.array([[-3.0, 0.2, 0, 0.5], [0.0, 0.3, 0, 0.5], [3.0, 0.2, 0, 0.5]])
    bones = np.array([[0, 1], [1, 2]])
    X, _ = polish_chains(V, F, J, bones, lambda P: np.zeros(len(P), bool))
    np.testing.assert_array_equal(X, J[:, :3])


def test_junctions_do_not_move(bar):
    """A star of three chains meeting off the axis: the junction stays where it is."""
    V, F = bar
    J = np.array([[0.0, 0.3, 0.0, 0.5], [-2.0, 0.2, 0, 0.5], [-3.5, 0, 0, 0.5],
                  [2.0, 0.2, 0, 0.5], [3.5, 0, 0, 0.5], [0.2, 0.4, 0.1, 0.3]])
    bones = np.array([[0, 1], [1, 2], [0, 3], [3, 4], [0, 5]])
    X, _ = polish_chains(V, F, J, bones, InsideTest(V, F))
    np.testing.assert_array_equal(X[0], J[0, :3])


def test_a_section_beyond_reach_and_fade_moves_nothing_and_the_step_fades_between(bar):
    """The bar's section reaches 0.71 from its axis: radius 0.71 / (REACH + FADE) and smaller
    leave a joint on the axis' side where it is, radius 0.71 / REACH moves it a full step."""
    V, F = bar
    inside = InsideTest(V, F)
    bones = np.array([[0, 1], [1, 2]])

    def moved(r):
        J = np.array([[-2.0, 0, 0, r], [0.0, 0.1, 0, r], [2.0, 0, 0, r]])
        X, _ = polish_chains(V, F, J, bones, inside, rounds=1, smooth=0.0)
        return 0.1 - X[1, 1]

    # the point is 0.1 off the axis: its loop reaches ~0.78 from it
    ext = np.hypot(0.5, 0.6)
    assert moved(0.99 * ext / (REACH + FADE)) == 0.0
    assert moved(1.01 * ext / REACH) == pytest.approx(STEP * 0.1, abs=1e-9)
    mid = moved(ext / (REACH + FADE / 2))
    assert 0.2 * STEP * 0.1 < mid < 0.8 * STEP * 0.1


@pytest.fixture(scope="module")
def beam():
    return t_beam()


def _web_chain(n=13, y=-0.9, r=0.2):
    """A straight chain along the T-beam's web, off its section's centroid, radius ``r``: the
    section reaches 1.25 from a joint, 6.3 radii, beyond REACH + FADE."""
    x = np.linspace(-3.6, 3.6, n)
    J = np.column_stack([x, np.full(n, y), np.zeros(n), np.full(n, r)])
    return J, np.stack([np.arange(n - 1), np.arange(1, n)], 1)


def test_a_chain_along_a_t_beam_moves_to_its_sections_centroid(beam):
    """rocker-arm's lever made plain: a T-section beam whose section reaches 6.3 radii from
    the chain. Every chain joint between two chain joints moves to the T's area centroid
    (analytic y = -0.372), not only those whose section lies within REACH radii; the joints
    next to the tips, whose run of sections cannot be compared on both sides, stay nearer
    where they were. Fails with the rule off (nothing moves)."""
    V, F = beam
    J, bones = _web_chain()
    c = t_beam_centroid_y()
    X, moved = polish_chains(V, F, J, bones, InsideTest(V, F), rounds=8)
    assert moved == 9                        # the 11 chain joints but the two next to the tips
    np.testing.assert_allclose(X[4:9, 1], c, atol=0.01)
    np.testing.assert_allclose(X[:, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(X[:, 0], J[:, 0], atol=0.1)    # slid along by the smoothing
    # the default two rounds go three quarters of the way in the middle
    X, _ = polish_chains(V, F, J, bones, InsideTest(V, F))
    np.testing.assert_allclose(X[4:9, 1], -0.9 + 0.75 * (c + 0.9), atol=0.01)


def test_a_section_holding_another_part_of_the_skeleton_moves_nothing(beam):
    """The same chain beside a second one along the flange: every plane of the first cuts the
    second inside the same loop (the section is not the first chain's own), so beyond REACH
    nothing moves; nor does the second (its sections reach 9 of its radii)."""
    V, F = beam
    J, bones = _web_chain()
    J2, _ = _web_chain(y=0.1, r=0.15)
    X, moved = polish_chains(V, F, np.vstack([J, J2]), np.vstack([bones, bones + len(J)]),
                             InsideTest(V, F))
    assert moved == 0
    np.testing.assert_allclose(X, np.vstack([J, J2])[:, :3], atol=1e-12)


def test_the_own_rule_fades_out_where_a_section_outgrows_its_neighbours(beam):
    """A limb's root: its plane takes in the body and its section reaches well beyond its
    neighbours' (spot's hind leg, 1.6x). The rule's weight is full up to OWN_RATIO times the
    larger neighbour's extent and fades to none over FADE beyond (a continuous decision),
    with everything else equal (sections given, a chain of five on the beam)."""
    V, F = beam
    J, bones = _web_chain(n=5)
    X = J[:, :3]
    moving = np.array([1, 2, 3, 0, 4])
    tip = np.array([False, False, False, True, True])
    T = np.tile([1.0, 0.0, 0.0], (5, 1))
    C = X[moving] + [0.0, 0.5, 0.0]
    area = np.full(5, 0.54)
    w = np.zeros(5)

    def weight(ratio):
        extent = np.array([1.0, ratio, 1.0, 1.0, 1.0])
        er = extent / 0.5
        return cross_section._own_weight(V, F, X, T, moving, tip, C, extent, area, er, w,
                                         bones, None, None)[1]

    r0 = cross_section.OWN_RATIO
    assert weight(1.0) == 1.0
    assert weight(r0) == 1.0
    assert 0.0 < weight(r0 + FADE / 2) < 1.0
    assert weight(r0 + FADE) == 0.0


def test_two_curves_in_one_part_share_their_sections_and_two_parts_do_not(bar, plate):
    """Two lines along the bar, 0.7 apart across its 1 x 1 section, cut by the same section
    loop at every joint: shared. On the plate (holes at x = -2, 0, 2 of radius 0.5 through a
    6 x 2 x 0.4 plate) the lines along y through the two webs at x = -1 and x = 1 are cut in
    two loops (the hole between them): not shared; two lines in the one web at x = -1, 0.3
    apart across the web's 1.0 width: shared."""
    V, F = bar
    P = np.column_stack([np.linspace(-3, 3, 7), np.full(7, -0.35), np.zeros(7)])
    Q = P + [0.0, 0.7, 0.2]
    assert shared_sections(V, F, P, Q, 2.0).all()
    V, F = plate
    y = np.linspace(-0.8, 0.8, 5)
    web_a = np.column_stack([np.full(5, -1.0), y, np.zeros(5)])
    web_b = web_a + [2.0, 0.0, 0.0]
    assert not shared_sections(V, F, web_a, web_b, 4.0).any()
    assert shared_sections(V, F, web_a, web_a + [0.3, 0.0, 0.1], 4.0)[1:-1].all()


def test_a_loop_within_reach_of_the_point_is_found_from_the_crossing_too(plate):
    """The plate's web between its left and middle holes is 1.0 wide (x = -1.5 to -0.5) and 0.4
    deep. A line up its middle (x = -1.0) and one near its right side (x = -0.55): the loop round
    the first reaches 0.54 from it, 0.97 from the second's crossing. Within a reach of 0.6 the
    first shares its sections with the second (the crossing is looked for within the reach
    plus its distance; with the reach alone it was not found and nothing was shared); the
    second, whose own loop is beyond 0.6, does not."""
    V, F = plate
    y = np.linspace(-0.2, 0.2, 5)
    mid = np.column_stack([np.full(5, -1.0), y, np.zeros(5)])
    side = np.column_stack([np.full(5, -0.55), y, np.zeros(5)])
    assert shared_sections(V, F, mid, side, 0.6).all()
    assert not shared_sections(V, F, side, mid, 0.6).any()
