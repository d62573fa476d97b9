"""Evaluate and refine real outside skeletons (issue 33): CGAL's curve skeletons of the shared
meshes, and the hand's with one finger taken away (the heat map's case)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from curveskel_addon.core import SkeletonParams, evaluate, load_outside_skeleton, refine
from curveskel_addon.measure.evaluation import HEAT_RANGE
from curveskel_addon.measure.quality import shape_measures
from curveskel_addon.mesh_files import read_mesh

from skeletons import SHARED as SHARED_MESHES
from outside_skeletons import hand_without_a_finger

REFERENCE = SHARED_MESHES.parent / "reference"
HUMAN = Path(__file__).resolve().parents[1] / "data" / "heldout" / "human.obj"
MESHES = ["armadillo.obj", "horse.off", "elephant.obj", "hand.off", "homer.obj", "spot.obj",
          "octopus.off", "rocker-arm.obj", "3holes.off", "fertility.off"]
#: Issue 10's shape targets against the reference (distances / D), as scripts/bench.py has them
TARGETS = {"zigzag": 0.15, "folds": 0.0, "length": (0.85, 1.25), "to_ref": 0.02, "from_ref": 0.025}
#: Minimisation steps of the refinements here (30 by default: the same figures, 5x the time;
#: scripts/evaluate_figures.py --cgal runs the default and docs/benchmarks.md has its table)
STEPS = 5


def _marks(m) -> dict:
    lo, hi = TARGETS["length"]
    return {"zigzag": m["zigzag"] <= TARGETS["zigzag"], "folds": m["folds"] <= TARGETS["folds"],
            "length": lo <= m["length_ratio"] <= hi, "to_ref": m["to_ref_mean"] <= TARGETS["to_ref"],
            "from_ref": m["from_ref_mean"] <= TARGETS["from_ref"]}


@pytest.mark.parametrize("name", MESHES)
def test_cgal_skeletons_refined_keep_their_shape(name):
    """CGAL's curve skeleton of every shared mesh: evaluated, refined with its graph kept; J
    falls, the topology still matches the genus, and each of issue 10's shape targets against
    that same reference that held before still holds."""
    V, F = read_mesh(SHARED_MESHES / name)
    ref = REFERENCE / (name.rsplit(".", 1)[0] + ".json")
    sk = load_outside_skeleton(ref)
    res = refine(V, F, sk, params=SkeletonParams(max_iterations=STEPS))
    print(f"\n{name}: J {res.before.J:.4g} -> {res.after.J:.4g}, inside "
          f"{res.before.inside_fraction:.3f} -> {res.after.inside_fraction:.3f}")
    assert res.after.J < res.before.J
    assert res.before.topology["match"] and res.after.topology["match"]
    np.testing.assert_array_equal(res.skeleton.bones, sk.bones)
    assert res.after.inside_fraction >= res.before.inside_fraction - 0.01
    before = _marks(shape_measures(V, F, (sk.joints, sk.bones), ref))
    after = _marks(shape_measures(V, F, (res.skeleton.joints, res.skeleton.bones), ref))
    assert [k for k in before if before[k] and not after[k]] == []


def test_the_missing_finger_is_where_the_skeleton_fits_badly():
    V, F, without, whole, finger = hand_without_a_finger()
    rep = evaluate(V, F, without)
    red = np.abs(rep.vertex_residual) / rep.D >= HEAT_RANGE      # full red on the heat map
    assert red[finger].mean() > 0.7
    # the whole skeleton explains the finger: no red there, and J is lower
    full = evaluate(V, F, whole)
    full_red = np.abs(full.vertex_residual) / full.D >= HEAT_RANGE
    assert full_red[finger].mean() == 0
    assert full.J < rep.J
    # outside the finger, taking it away adds no red: what is red there is red with the whole
    # skeleton too (round radii on the flat palm and the wrist's cut: 8 % of those vertices
    # with J's radii since the objective's merge), and the typical vertex is far from red
    assert red[~finger].mean() <= full_red[~finger].mean() + 0.01
    res = np.abs(rep.vertex_residual) / rep.D
    assert np.median(res[~finger]) < 0.2 * HEAT_RANGE < HEAT_RANGE < np.median(res[finger])


def test_metarig_on_the_human_moves_inside_and_keeps_every_bone():
    """Rigify's Basic Human metarig placed on the T-posed held-out human (tests/data; the Blender
    test makes it with Rigify itself): refined, its joints move inside the body and J falls; J
    alone would shrink bones to points (a turn costs nothing at a joint one of whose bones has
    no length), so the length guard holds some, and none ends shorter than it may."""
    from curveskel_addon.core import Refinement
    from curveskel_addon.rig.armature_segments import armature_segments
    from outside_skeletons import load_metarig, obj_to_blender, place_metarig

    V, F = read_mesh(HUMAN)
    Vw = obj_to_blender(V)
    names, parent, connected, H, T = load_metarig()
    scale, offset, H, T = place_metarig(names, parent, H, T, Vw)
    seg = armature_segments(scale * H + offset, scale * T + offset, parent, connected)
    run = Refinement(Vw, F, (seg.joints, seg.segments))
    res = run.result()
    print(f"\nmetarig on the human: J {res.before.J:.4g} -> {res.after.J:.4g}, inside "
          f"{res.before.inside_fraction:.3f} -> {res.after.inside_fraction:.3f}")
    assert res.before.inside_fraction < 0.9 and res.after.inside_fraction >= 0.98
    assert res.after.J < 0.3 * res.before.J
    assert run.held.any()
    X = res.skeleton.joints[:, :3]
    L = np.linalg.norm(X[seg.segments[:, 0]] - X[seg.segments[:, 1]], axis=1)
    assert (L >= run.min_length * (1 - 1e-9)).all()
    np.testing.assert_array_equal(res.skeleton.bones, seg.segments)
