"""Evaluate and refine a skeleton from outside curveskel (issue 33): the accepted forms, the
report's figures on shapes whose answer is known, refine's guarantees (J falls, fixed joints stay
to the last bit, the graph is kept) and one clear message for every bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

import meshes as M
from curveskel_addon.core import (CurveSkelError, OutsideSkeleton, Refinement, Skeleton,
                                  SkeletonParams, compare, evaluate, load_outside_skeleton,
                                  refine)
from curveskel_addon.core.evaluation import prepare, report_of

#: a skeleton on the capsule's axis (radius 1, from z = 0 to 6) and one off it
ON_AXIS = {"joints": [[0, 0, 0], [0, 0, 3], [0, 0, 6]], "bones": [[0, 1], [1, 2]]}
OFF_AXIS = {"joints": [[0.4, 0, 0.3], [-0.3, 0.2, 3], [0.3, 0, 5.5]], "bones": [[0, 1], [1, 2]]}


@pytest.fixture(scope="module")
def capsule():
    return M.capsule(radius=1.0, length=6.0)


@pytest.fixture(scope="module")
def star():
    return M.star(n_arms=4)


def _axis_distance(joints):
    return np.hypot(joints[:, 0], joints[:, 1])


# -- the report --------------------------------------------------------------------------------
def test_report_on_the_axis(capsule):
    V, F = capsule
    rep = evaluate(V, F, ON_AXIS)
    # no radii given: fitted, to the tube's radius
    assert rep.radii_fitted
    # (J's minimiser on the 32-sided tube: 0.998 at the ends, 0.987 in the middle)
    np.testing.assert_allclose(rep.joints[:, 3], 1.0, atol=0.015)
    np.testing.assert_array_equal(rep.joints[:, :3], ON_AXIS["joints"])
    # every vertex lies about one radius from the axis: residuals near zero
    assert rep.vertex_residual.shape == (len(V),)
    assert np.abs(rep.vertex_residual).max() < 0.015
    assert rep.inside_fraction == 1.0
    assert rep.topology == {"skeleton_components": 1, "skeleton_cycles": 0, "mesh_components": 1,
                            "mesh_genus": 0, "match": True}
    # J: the terms and their weights add up; the counts priced as the objective prices them
    assert rep.terms["joints"] == 3 and rep.terms["tips"] == 2
    assert rep.J == pytest.approx(sum(rep.weighted.values()), rel=1e-12)
    assert rep.terms["fit"] < 1e-4 and rep.terms["centre"] < 1e-12     # 3.9e-5: radius 0.987 mid-tube
    assert rep.E < 1e-6
    # per bone: the two bones share the surface, and the fit term
    np.testing.assert_allclose(rep.per_bone["area"].sum(), 1.0, rtol=1e-9)
    np.testing.assert_allclose(rep.per_bone["area"], 0.5, atol=0.01)
    np.testing.assert_allclose(rep.per_bone["fit"].sum(), rep.terms["fit"], rtol=1e-9)
    np.testing.assert_array_equal(rep.per_bone["inside"], 1.0)


def test_a_worse_skeleton_has_a_higher_j(capsule):
    V, F = capsule
    good, bad = evaluate(V, F, ON_AXIS), evaluate(V, F, OFF_AXIS)
    assert bad.J > 3 * good.J
    assert bad.terms["centre"] > 1e-3 > good.terms["centre"]
    assert np.abs(bad.vertex_residual).max() > 0.3


def test_missing_arm_is_where_the_residual_is(star):
    """A star of four arms with a skeleton of three: the fourth arm's surface is explained by
    no bone, its residual is its distance from the centre; the rest fits."""
    V, F = star
    three = {"joints": [[0, 0, 0], [4, 0, 0], [0, 4, 0], [-4, 0, 0]], "bones": [[0, 1], [0, 2], [0, 3]]}
    rep = evaluate(V, F, three)
    arm = V[:, 1] < -1.5                   # the fourth arm, along -y
    assert np.median(rep.vertex_residual[arm]) > 2.0
    assert np.median(np.abs(rep.vertex_residual[~arm])) < 0.1
    # the bones nearest the missing arm's surface fit worst: the two side arms, not the one
    # opposite it
    assert set(rep.worst_bones(2).tolist()) == {0, 2}
    four = dict(three, joints=three["joints"] + [[0, -4, 0]], bones=three["bones"] + [[0, 4]])
    assert evaluate(V, F, four).J < rep.J / 2


def test_topology_against_the_genus():
    V, F = M.torus()
    u = 2 * np.pi * np.arange(12) / 12
    ring = np.stack([3 * np.cos(u), 3 * np.sin(u), 0 * u], 1)
    closed = evaluate(V, F, (ring, [[k, (k + 1) % 12] for k in range(12)]))
    assert closed.topology["mesh_genus"] == 1 and closed.topology["skeleton_cycles"] == 1
    assert closed.topology["match"]
    cut = evaluate(V, F, (ring, [[k, k + 1] for k in range(11)]))
    assert cut.topology["skeleton_cycles"] == 0 and not cut.topology["match"]


def test_unused_vertex_and_joint(capsule):
    """Every input vertex gets a residual (one no face uses too); a joint of no bone is
    reported where it was and takes no part in J."""
    V, F = capsule
    V2 = np.vstack([V, [[0, 2.0, 3.0]]])           # 2 from the axis, no face
    sk = {"joints": ON_AXIS["joints"] + [[5, 5, 5]], "bones": ON_AXIS["bones"]}
    rep = evaluate(V2, F, sk)
    base = evaluate(V, F, ON_AXIS)
    assert rep.vertex_residual.shape == (len(V2),)
    assert rep.vertex_residual[-1] == pytest.approx(2.0 - rep.joints[1, 3], abs=1e-6)
    np.testing.assert_array_equal(rep.joints[3, :3], [5, 5, 5])
    assert rep.J == pytest.approx(base.J, rel=1e-12)


# -- the accepted forms --------------------------------------------------------------------------
def test_every_form_gives_the_same_report(capsule, tmp_path):
    V, F = capsule
    X = np.array(OFF_AXIS["joints"], float)
    radii = np.array([0.9, 1.1, 1.0])
    Z = np.column_stack([X, radii])
    sk = Skeleton(Z, OFF_AXIS["bones"], np.zeros(len(V)), np.zeros(len(V)))
    path = tmp_path / "sk.json"
    sk.save(path)
    plain = tmp_path / "plain.json"
    plain.write_text(json.dumps({"joints": Z.tolist(), "bones": OFF_AXIS["bones"]}))
    forms = [sk, sk.to_dict(), {"joints": Z.tolist(), "bones": OFF_AXIS["bones"]},
             (Z, OFF_AXIS["bones"]), OutsideSkeleton(X, OFF_AXIS["bones"], radii),
             load_outside_skeleton(path), load_outside_skeleton(plain)]
    Js = [evaluate(V, F, f).J for f in forms]
    assert not evaluate(V, F, forms[0]).radii_fitted     # radii given: used as they are
    np.testing.assert_allclose(Js, Js[0], rtol=1e-12)
    # without radii they are fitted: J can only be lower than with these guessed ones
    assert evaluate(V, F, OFF_AXIS).J < Js[0]


# -- refine --------------------------------------------------------------------------------------
def test_refine_lowers_j_and_keeps_the_graph(capsule):
    V, F = capsule
    res = refine(V, F, OFF_AXIS)
    assert res.after.J < 0.5 * res.before.J
    assert res.skeleton.meta["J"] == pytest.approx(res.after.J)
    assert res.skeleton.meta["J_before"] == pytest.approx(res.before.J)
    np.testing.assert_array_equal(res.skeleton.bones, OFF_AXIS["bones"])
    assert res.skeleton.n_joints == 3
    # the joints move onto the axis, the radii to the tube's
    assert _axis_distance(res.skeleton.joints).max() < 0.05 < _axis_distance(np.array(OFF_AXIS["joints"], float)).min()
    np.testing.assert_allclose(res.skeleton.joints[:, 3], 1.0, atol=0.05)
    # every input vertex mapped onto the kept bones
    assert len(res.skeleton.bone) == len(V) and set(np.unique(res.skeleton.bone)) <= {0, 1}
    # the report after is that of the refined skeleton on the given skeleton's J
    fit = prepare(V, F, OFF_AXIS)
    Z = res.skeleton.joints.copy()
    Z[:, :3] -= fit.origin
    assert report_of(fit, fit.graph.with_joints(Z)).J == pytest.approx(res.after.J, rel=1e-9)


def test_fixed_joints_stay_to_the_last_bit(capsule):
    V, F = capsule
    X = np.array(OFF_AXIS["joints"], float) + [1e-9 * np.pi, 0, 0]   # bits that a round trip loses
    res = refine(V, F, (X, OFF_AXIS["bones"]), fixed=[0, 2])
    np.testing.assert_array_equal(res.skeleton.joints[[0, 2], :3], X[[0, 2]])
    assert not np.array_equal(res.skeleton.joints[1, :3], X[1])
    assert res.after.J < res.before.J
    # a boolean mask says the same
    res2 = refine(V, F, (X, OFF_AXIS["bones"]), fixed=np.array([True, False, True]))
    np.testing.assert_array_equal(res2.skeleton.joints, res.skeleton.joints)


def test_refine_never_raises_j_from_its_minimum(capsule):
    V, F = capsule
    first = refine(V, F, OFF_AXIS)
    second = refine(V, F, first.skeleton)
    assert second.after.J <= second.before.J
    # (a chain joint of a straight tube may slide along it: J hardly sees where)
    assert _axis_distance(second.skeleton.joints).max() < 0.05


def test_refinement_steps_live(capsule):
    V, F = capsule
    run = Refinement(V, F, OFF_AXIS, step_iterations=1)
    values = [s.energy for s in run.steps()]
    assert len(values) >= 3 and values[-1] == values[-2]           # the last one is "done"
    assert all(b <= a for a, b in zip(values, values[1:]))
    assert run.current_skeleton().n_joints == 3
    assert run.result().after.J == pytest.approx(values[-1])


def test_refine_with_topology_edits(star):
    """A chain of many joints along every arm: with the topology moves the chain joints that
    explain no bend are merged away (J prices each joint) and J falls further than with the
    graph kept."""
    V, F = star
    t = np.linspace(0, 1, 6)[1:]
    X = [[0.0, 0, 0]]
    bones = []
    for k, (dx, dy) in enumerate([(4, 0), (0, 4), (-4, 0), (0, -4)]):
        base = len(X)
        X += [[s * dx, s * dy, 0.0] for s in t]
        bones += [[0, base]] + [[base + i, base + i + 1] for i in range(len(t) - 1)]
    kept = refine(V, F, (X, bones))
    edited = refine(V, F, (X, bones), edit_topology=True)
    assert edited.skeleton.n_joints < len(X)
    assert edited.after.J < kept.after.J < kept.before.J
    assert edited.after.topology["match"]
    assert [s["stage"] for s in edited.skeleton.meta["stages"]][0] == "initialise"


def test_compare_puts_both_on_one_ruler(star):
    V, F = star
    three = {"joints": [[0, 0, 0], [4, 0, 0], [0, 4, 0], [-4, 0, 0]], "bones": [[0, 1], [0, 2], [0, 3]]}
    four = {"joints": three["joints"] + [[0, -4, 0]], "bones": three["bones"] + [[0, 4]]}
    a, b = compare(V, F, [three, four])
    assert b.J < a.J
    # on one ruler the missing arm costs more than on the three-armed skeleton's own ruler
    # (there its surface is measured in units of its own large distance from the bones)
    assert a.J - b.J > evaluate(V, F, three).J - evaluate(V, F, four).J


# -- bad input -----------------------------------------------------------------------------------
@pytest.mark.parametrize("skeleton, message", [
    ({"joints": [[0, 0, 0], [0, 0, 1]], "bones": []}, "has no bones"),
    ({"joints": [[0, 0, 0], [0, 0, 1]], "bones": [[0, 2]]},
     "bone 0 joins joints 0 and 2, but the skeleton has 2 joints (indices 0 to 1)"),
    ({"joints": [[0, 0, 0], [0, 0, 1]], "bones": [[0, -1]]}, "bone 0 joins joints 0 and -1"),
    ({"joints": [[0, 0, 0], [0, 0, 1]], "bones": [[1, 1]]}, "bone 0 joins joint 1 to itself"),
    ({"joints": [[0, 0, 0], [0, 0, 1]], "bones": [[0, 1], [1, 0]]}, "more than one bone"),
    ({"joints": [[0, 0, float("nan")], [0, 0, 1]], "bones": [[0, 1]]}, "joint 0 has a coordinate"),
    ({"joints": [[0, 0], [0, 1]], "bones": [[0, 1]]}, "rows of [x, y, z]"),
    ({"joints": [[0, 0, 0], [0, 0, 1]], "bones": [[0.5, 1]]}, "integer joint indices"),
    ({"joints": [[0, 0, 0], [0, 0, 1]]}, "no 'bones'"),
    ({"format": "other/2", "joints": [], "bones": []}, "unknown skeleton format"),
    ("a string", "a skeleton must be"),
])
def test_bad_skeletons_get_one_message(capsule, skeleton, message):
    V, F = capsule
    with pytest.raises(CurveSkelError, match=None) as err:
        evaluate(V, F, skeleton)
    assert message in str(err.value)


def test_a_skeleton_outside_the_mesh_is_refused(capsule):
    V, F = capsule
    far = {"joints": [[10, 0, 0], [10, 0, 6]], "bones": [[0, 1]]}
    with pytest.raises(CurveSkelError, match="the skeleton lies outside the mesh"):
        evaluate(V, F, far)
    with pytest.raises(CurveSkelError, match="the skeleton lies outside the mesh"):
        refine(V, F, far)


def test_bad_refine_arguments(capsule):
    V, F = capsule
    with pytest.raises(CurveSkelError, match="fixed joint index is out of range"):
        refine(V, F, OFF_AXIS, fixed=[3])
    with pytest.raises(CurveSkelError, match="one entry per joint"):
        refine(V, F, OFF_AXIS, fixed=[True, False])
    with pytest.raises(CurveSkelError, match="only be kept with the skeleton's bones kept"):
        refine(V, F, OFF_AXIS, fixed=[0], edit_topology=True)
    with pytest.raises(CurveSkelError, match="params must be a SkeletonParams"):
        evaluate(V, F, OFF_AXIS, params={"spacing": 0.1})


def test_bad_files(tmp_path):
    with pytest.raises(CurveSkelError, match="cannot read skeleton .*nope.json"):
        load_outside_skeleton(tmp_path / "nope.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(CurveSkelError, match="bad.json is not valid JSON"):
        load_outside_skeleton(bad)
    oob = tmp_path / "oob.json"
    oob.write_text(json.dumps({"joints": [[0, 0, 0], [1, 0, 0]], "bones": [[0, 5]]}))
    with pytest.raises(CurveSkelError, match=r"skeleton .*oob.json: bone 0 joins joints 0 and 5"):
        load_outside_skeleton(oob)


def test_params_reach_j(capsule):
    """Smoothness scales J's smooth term's weight, as in a skeletonization (radii given: the
    fit of the radii would see the weight too)."""
    V, F = capsule
    sk = (np.column_stack([OFF_AXIS["joints"], [0.9, 1.0, 1.1]]), OFF_AXIS["bones"])
    a = evaluate(V, F, sk, SkeletonParams(smoothness=1.0))
    b = evaluate(V, F, sk, SkeletonParams(smoothness=3.0))
    assert b.weighted["smooth"] == pytest.approx(3 * a.weighted["smooth"], rel=1e-9)


def test_fixed_joints_set_before_the_first_step(capsule):
    V, F = capsule
    run = Refinement(V, F, OFF_AXIS)
    run.fix([1])
    res = run.result()
    np.testing.assert_array_equal(res.skeleton.joints[1, :3], OFF_AXIS["joints"][1])
    with pytest.raises(CurveSkelError, match="before the refinement starts"):
        run.fix([0])


def test_a_stopped_refinement_keeps_the_joints_reached(capsule):
    V, F = capsule
    run = Refinement(V, F, OFF_AXIS, step_iterations=1)
    steps = run.steps()
    first = next(steps)
    steps.close()
    run.stop()
    res = run.result()
    assert res.iterations == 1
    assert res.after.J == pytest.approx(first.energy) and res.after.J < res.before.J
    np.testing.assert_array_equal(res.skeleton.joints, run.current_skeleton().joints)
