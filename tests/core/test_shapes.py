"""Awkward shapes a new user brings (issue 30, "Done when": "make your own awkward shapes ... all
new tests"), and shapes whose answer the old method's stage tests asserted (a board's middle
line, a T's one junction, a flap's chain, a tab's bone): what the skeleton of each must be,
whatever stage or term gives it.

Meshes are built in ``tests/meshes.py``; each default skeleton is computed once per session.
"""

from __future__ import annotations

import numpy as np
import pytest

from curveskel_addon.core import skeletonize
from curveskel_addon.core.geometry.inside import InsideTest
from meshes import (BOARD, FLAP, KNOBBED, NUT, PLATE, TEE, board, board_with_tab,
                    capsule_with_flap, knob_centres, plate_with_holes, tube_along)
from skeletons import (bone_points, chain_straightness, inside_fraction, procedural_mesh,
                       procedural_skeleton, silhouette_distance, topology, turning_angles)


def _winding(P, c):
    """Winding number of the closed polygon P (k, 2) around the point c."""
    ang = np.arctan2(P[:, 1] - c[1], P[:, 0] - c[0])
    d = np.diff(np.r_[ang, ang[0]])
    d = (d + np.pi) % (2 * np.pi) - np.pi
    return d.sum() / (2 * np.pi)


def _cycle_joints(n, bones):
    """The joints of the one cycle of a graph with exactly one, in order around it (leaf
    branches peeled off first)."""
    bones = [tuple(b) for b in np.asarray(bones, np.int64).tolist()]
    alive = set(range(n))
    while True:
        deg = {j: 0 for j in alive}
        for a, b in bones:
            deg[a] += 1
            deg[b] += 1
        leaves = {j for j, d in deg.items() if d <= 1}
        if not leaves:
            break
        alive -= leaves
        bones = [(a, b) for a, b in bones if a in alive and b in alive]
    nbr = {j: [] for j in alive}
    for a, b in bones:
        nbr[a].append(b)
        nbr[b].append(a)
    start = min(alive)
    out, prev, cur = [start], None, start
    while True:
        nxt = nbr[cur][0] if nbr[cur][0] != prev else nbr[cur][1]
        if nxt == start:
            return out
        out.append(nxt)
        prev, cur = cur, nxt


# -- a flat hexagonal nut ------------------------------------------------------------------------
def test_a_hexagonal_nut_gives_one_clean_loop_inside_it():
    """Issue 30: "a flat hexagonal nut (a ring) gets spurs into its outline's corners, and its
    loop leaves the mesh (inside 0.86)". Its skeleton is one loop round the hole and nothing
    else: one cycle, no tip (no spur into a corner), every bone inside, the loop winding once
    round the hole between the hole's wall and the outline."""
    V, F = procedural_mesh("hex_nut")
    sk = procedural_skeleton("hex_nut")
    cycles, comps, deg = topology(sk.n_joints, sk.bones)
    assert (cycles, comps) == (1, 1)
    assert (deg == 1).sum() == 0, f"{(deg == 1).sum()} spurs: tips at {sk.joints[deg == 1, :3].round(3).tolist()}"
    assert inside_fraction(V, F, sk.joints, sk.bones) == 1.0
    loop = _cycle_joints(sk.n_joints, sk.bones)
    assert abs(round(_winding(sk.joints[loop, :2], (0.0, 0.0)))) == 1
    P = bone_points(sk.joints, sk.bones)
    rho = np.hypot(P[:, 0], P[:, 1])
    inradius = NUT["outer"] * np.cos(np.pi / 6)
    assert rho.min() > NUT["hole"] and rho.max() < NUT["outer"], (rho.min(), rho.max())
    # in the middle of the material: between the hole's wall and the hexagon's flats, within
    # a quarter of the wall's thickness there, and in the nut's mid-plane
    mid = (NUT["hole"] + inradius) / 2
    assert np.abs(rho - mid).max() < 0.25 * (NUT["outer"] - NUT["hole"]), np.abs(rho - mid).max()
    assert np.abs(P[:, 2]).max() < 0.1 * NUT["thickness"]


def test_a_hexagonal_nuts_loop_has_no_bone_of_no_length():
    """A clean loop: no two joints at one place (a bone of no length has no direction, and a
    rigger sees a joint he cannot grab)."""
    sk = procedural_skeleton("hex_nut")
    L = np.linalg.norm(sk.joints[sk.bones[:, 0], :3] - sk.joints[sk.bones[:, 1], :3], axis=1)
    assert L.min() > 0.1 * np.abs(sk.joints[:, 3]).min(), np.sort(L)[:4]


# -- a bone with two knobs at each end --------------------------------------------------------------
def test_a_bone_with_two_knobs_at_each_end_forks_at_each_end():
    """Issue 30: "a bone with two knobs at each end loses one knob's branch and zig-zags
    there". Its skeleton: a tree with four tips, one in each knob (within its radius of its
    centre), two at each end, no cycle, and no chain joint turning by more than 60 degrees."""
    V, F = procedural_mesh("knobbed_bone")
    sk = procedural_skeleton("knobbed_bone")
    cycles, comps, deg = topology(sk.n_joints, sk.bones)
    assert (cycles, comps) == (0, 1)
    tips = sk.joints[deg == 1, :3]
    assert len(tips) == 4, tips.round(3).tolist()
    assert (tips[:, 0] < 0).sum() == 2 and (tips[:, 0] > 0).sum() == 2
    gap = np.linalg.norm(knob_centres()[:, None] - tips[None], axis=2).min(axis=1)
    assert gap.max() < KNOBBED["knob"], gap
    _, ang = turning_angles(sk.joints, sk.bones)
    assert len(ang) == 0 or ang.max() < 60, ang.max()
    assert inside_fraction(V, F, sk.joints, sk.bones) == 1.0


# -- a board --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("size", [BOARD["size"], (4.0, 2.0, 0.3), (5.0, 3.0, 0.3)])
def test_a_board_gives_one_straight_middle_line(size):
    """Issue 30: "a board, which gives one straight middle line". (The first approximation's
    poles are two opposite corners: the old method's chain ran from corner to corner through
    the middle, a Z with joints up to 0.47 W off the middle line, until a corner rule.) One
    chain without branches, its joints within 0.05 W of the middle line y = 0 and a quarter of
    the thickness of the mid-plane, straight (no joint off the end-to-end line by more than 1 %
    of its length, no turn of 60 degrees), spanning the footprint's medial line."""
    V, F = board(size)
    sk = procedural_skeleton("board") if size == BOARD["size"] else skeletonize(V, F)
    L, W, t = size
    J = sk.joints
    cycles, comps, deg = topology(sk.n_joints, sk.bones)
    assert (cycles, comps) == (0, 1)
    assert deg.max() <= 2 and (deg == 1).sum() == 2, "a branch on a board"
    assert np.abs(J[:, 1]).max() <= 0.05 * W, J[:, :3].round(3).tolist()
    assert np.abs(J[:, 2]).max() <= 0.25 * t
    assert chain_straightness(J, sk.bones) <= 0.01
    _, ang = turning_angles(J, sk.bones)
    assert len(ang) == 0 or ang.max() < 60
    # it runs at least over the footprint's medial line (half a width short of each end)
    assert J[:, 0].min() <= -(L / 2 - W / 2) + 0.1 * W and J[:, 0].max() >= L / 2 - W / 2 - 0.1 * W


def test_a_square_tab_on_a_board_keeps_its_bone():
    """A tab as wide as it is long in the board's sheet is a part of its own: a tip in the tab
    (near its middle line x = 0.5), and the board's two ends on its middle line, none in a
    corner."""
    V, F = board_with_tab()
    sk = skeletonize(V, F)
    J = sk.joints
    deg = np.bincount(sk.bones.ravel(), minlength=len(J))
    tips = J[deg == 1, :3]
    inside_tab = (tips[:, 1] > 1.2) & (np.abs(tips[:, 0] - 0.5) < 0.25)
    assert inside_tab.any(), tips.round(2)
    ends = tips[tips[:, 1] < 1.0]
    assert len(ends) == 2 and np.abs(ends[:, 1]).max() < 0.1, tips.round(2)


# -- a plate with holes: loops and rungs ------------------------------------------------------------------
@pytest.mark.parametrize("holes", [(-2.0, 0.0, 2.0), (-1.2, 1.2)])
def test_a_plate_with_holes_gives_one_loop_per_hole(holes):
    """Issue 30: "a plate with holes, which gives loops and rungs": as many independent cycles
    as holes, every bone inside, and each hole wound round by the skeleton (its loops'
    projection on the plate's plane)."""
    if holes == PLATE["hole_x"]:
        V, F = procedural_mesh("plate_with_holes")
        sk = procedural_skeleton("plate_with_holes")
    else:
        V, F = plate_with_holes(hole_x=holes)
        sk = skeletonize(V, F)
    cycles, comps, _ = topology(sk.n_joints, sk.bones)
    assert (cycles, comps) == (len(holes), 1)
    assert inside_fraction(V, F, sk.joints, sk.bones) == 1.0
    P = bone_points(sk.joints, sk.bones, 20)
    to_hole = np.min([np.hypot(P[:, 0] - x, P[:, 1]) for x in holes], axis=0)
    assert to_hole.min() > PLATE["hole_radius"], "a bone across a hole"


# -- a T: one junction on the trunk ----------------------------------------------------------------------
def test_a_tee_has_one_junction_and_three_tips():
    """A trunk and a limb off its side: the skeleton is a T, one junction of three branches
    and three tips (the trunk's ends and the limb's), each near its capsule's end."""
    V, F = procedural_mesh("tee")
    sk = procedural_skeleton("tee")
    cycles, comps, deg = topology(sk.n_joints, sk.bones)
    assert (cycles, comps) == (0, 1)
    assert (deg >= 3).sum() == 1 and deg.max() == 3
    tips = sk.joints[deg == 1, :3]
    ends = np.array([[-TEE["trunk"], 0, 0], [TEE["trunk"], 0, 0], [0, TEE["limb"], 0]])
    gap = np.linalg.norm(ends[:, None] - tips[None], axis=2).min(axis=1)
    assert len(tips) == 3 and gap.max() < TEE["trunk_radius"], gap


def test_a_tees_junction_lies_on_the_trunks_axis():
    """A rigger's spine runs straight past a limb's root: the junction sits on the trunk's
    axis, within a tenth of the trunk's radius (the old method moved junctions onto their
    trunks' line; the limb's root pulls the trunk's cross-sections' centroids towards it)."""
    sk = procedural_skeleton("tee")
    deg = np.bincount(sk.bones.ravel(), minlength=sk.n_joints)
    j = sk.joints[deg >= 3, :3]
    off = np.hypot(j[:, 1], j[:, 2]) / TEE["trunk_radius"]
    assert off.max() <= 0.1, off


# -- a flap ---------------------------------------------------------------------------------------------------
def test_a_flaps_chain_ends_in_its_middle_on_a_straight_line():
    """A capsule with a flat round flap on its side (an ear): the flap's chain runs into the
    flap's middle (its tip within 0.3 of the flap's radius of its centre; the old method's ran to
    the far rim where the geodesic distance peaks, 0.93 R), straight (every joint of the chain
    within 0.02 R of the line through its ends), and every joint inside."""
    V, F = capsule_with_flap()
    sk = skeletonize(V, F)
    c, R = np.asarray(FLAP["centre"]), FLAP["radius"]
    deg = np.bincount(sk.bones.ravel(), minlength=sk.n_joints)
    tips = np.flatnonzero(deg == 1)
    ear = tips[sk.joints[tips, 0] > 1.2]               # the capsule's tips are on its axis
    assert len(ear) == 1, sk.joints[tips, :3].round(2).tolist()
    tip = sk.joints[ear[0], :3]
    assert np.linalg.norm(tip - c) <= 0.3 * R, tip
    chain, prev = [int(ear[0])], -1
    while deg[chain[-1]] <= 2 and len(chain) <= sk.n_joints:
        nb = [int(b) for a, b in np.r_[sk.bones, sk.bones[:, ::-1]] if a == chain[-1] and b != prev]
        prev = chain[-1]
        chain.append(nb[0])
    X = sk.joints[chain[:-1], :3]
    if len(X) >= 3:
        a, d = X[-1], (X[0] - X[-1]) / np.linalg.norm(X[0] - X[-1])
        off = np.linalg.norm((X - a) - ((X - a) @ d)[:, None] * d, axis=1)
        assert off.max() <= 0.02 * R, off
    assert InsideTest(V, F)(sk.joints[:, :3]).all()


# -- a cone: the radii of tangent balls ------------------------------------------------------------------
def test_a_cone_tubes_silhouette_is_the_cone():
    """A tube whose radius falls linearly from 1.0 to 0.4 over a length of 6 (a truncated cone,
    hemispherical caps). J's fit measures the distance to the silhouette (the union of the
    round cones), so the skeleton's silhouette reproduces the cone: one chain on the axis, the
    surface's vertices within 1 % of the thick end's radius of the silhouette on average, each
    body joint's radius that of the tube at its height (within 0.01: the tangent
    balls' radii rho(z) cos(phi) and rho(z) differ by 0.005 here). A fit across the axis at the
    vertices leaves the silhouette off the surface (the old method's nearest-bone radii)."""
    L, R0, R1 = 6.0, 1.0, 0.4
    path = np.column_stack([np.zeros(61), np.zeros(61), np.linspace(0, L, 61)])
    V, F = tube_along(path, np.linspace(R0, R1, 61), n_around=48)
    sk = skeletonize(V, F)
    cycles, comps, deg = topology(sk.n_joints, sk.bones)
    assert (cycles, comps) == (0, 1) and deg.max() <= 2
    assert np.hypot(sk.joints[:, 0], sk.joints[:, 1]).max() < 0.02
    d = np.abs(silhouette_distance(V, sk.joints, sk.bones))
    assert d.mean() <= 0.01 * R0, (d.mean(), d.max())
    J = sk.joints[deg == 2]
    rho = R0 + (R1 - R0) * np.clip(J[:, 2], 0, L) / L
    np.testing.assert_allclose(J[:, 3], rho, atol=0.01)
