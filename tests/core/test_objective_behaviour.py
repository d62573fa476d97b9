"""The method as one objective (issue 30): what its "Done when" asks of J, its log and the
user's settings, measured on the skeletons.

* J per stage: every entry of ``meta["stages"]`` has ``J`` and ``terms``, J never rises from
  one logged stage to the next, ``meta["J"]`` is the lowest in the log and is the J of the
  returned skeleton, and J is the stated weighted sum of its terms.
* Continuous in its input: a 1e-9 D jitter of every vertex moves the skeleton by less than
  1e-4 D with the same joint count.
* *Max Joints* (10, 20, 40) is never exceeded.
* *Smoothness* and *Branch Pruning* change the skeleton monotonically in their direction
  (the chains' bending; the number of tips).

D is the method's unit (the diameter of the vertices' minimum enclosing ball). Shared-mesh
cases are marked ``slow`` (seconds to a minute a run); each default run is shared with the other
test files through ``tests/skeletons.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from curveskel_addon.core import SkeletonParams, SkeletonRun, skeletonize
from curveskel_addon.core.objective.objective import weights_for
from skeletons import (bending, curve_gap, procedural_mesh, procedural_skeleton, shared_mesh,
                       shared_skeleton, topology, total_turning, unit_D)

SHARED_TEN = ["horse.off", "armadillo.obj", "elephant.obj", "hand.off", "octopus.off", "spot.obj",
              "homer.obj", "rocker-arm.obj", "3holes.off", "fertility.off"]
TERMS = ("fit", "centre", "smooth", "contain", "joints", "tips")


def _skeleton(name):
    return shared_skeleton(name) if "." in name else procedural_skeleton(name)


def _mesh(name):
    return shared_mesh(name) if "." in name else procedural_mesh(name)


# -- J per stage -------------------------------------------------------------------------------------
def _check_log(sk):
    stages = sk.meta["stages"]
    assert stages[0]["stage"] == "initialise" and len(stages) >= 2
    for st in stages:
        assert np.isfinite(st["J"]) and st["J"] > 0
        assert set(TERMS) <= set(st["terms"]), st["terms"]
    J = np.array([st["J"] for st in stages])
    rises = np.flatnonzero(np.diff(J) > 0)
    assert not len(rises), f"J rose at {[stages[i + 1]['stage'] for i in rises]}: {J[rises]} -> {J[rises + 1]}"
    assert sk.meta["J"] == J.min() == J[-1]
    assert sk.meta["terms"] == stages[-1]["terms"]
    assert (stages[-1]["joints"], stages[-1]["bones"]) == (sk.n_joints, sk.n_bones)


@pytest.mark.parametrize("name", ["capsule", "torus", "star", "plate_with_holes", "bent_tube"])
def test_j_never_rises_from_stage_to_stage_and_the_result_is_the_lowest(name):
    _check_log(_skeleton(name))


@pytest.mark.slow
@pytest.mark.parametrize("name", SHARED_TEN)
def test_every_shared_meshs_log_has_j_non_increasing_and_the_lowest_last(name):
    """Issue 30: "Every shared mesh's run logs J per stage, non-increasing, and the returned
    skeleton's J is the lowest in its log"."""
    _check_log(_skeleton(name))


@pytest.mark.parametrize("name", ["star", "plate_with_holes"])
def test_j_is_the_weighted_sum_of_its_terms(name):
    """J = fit + w_centre centre + w_smooth smooth + w_contain contain + w_joint joints +
    w_branch tips, with the weights of the run's own settings (Smoothness and Branch Pruning
    scale theirs): the logged J is the objective the README states, stage by stage."""
    sk = _skeleton(name)
    w = weights_for(SkeletonParams.from_dict(sk.meta["params"]))
    for st in sk.meta["stages"]:
        t = st["terms"]
        want = (t["fit"] + w.centre * t.get("centre", 0.0) + w.smooth * t.get("smooth", 0.0)
                + w.contain * t.get("contain", 0.0) + w.joint * t["joints"] + w.branch * t["tips"])
        assert st["J"] == pytest.approx(want, rel=1e-12), st["stage"]
        assert t["joints"] == st["joints"]


def test_meta_j_is_the_j_of_the_returned_skeleton():
    """The returned skeleton evaluated afresh by the run's own objective gives ``meta["J"]``:
    the log's last J is the result's, not a stage's before a last change."""
    V, F = procedural_mesh("bent_capsule")
    run = SkeletonRun(V, F)
    sk = run.result()
    np.testing.assert_array_equal(sk.joints[:, :3], np.asarray(run.graph.joints)[:, :3] + run.origin)
    assert run.objective.evaluate(run.graph).value == pytest.approx(sk.meta["J"], rel=1e-12)


# -- continuous in its input: a 1e-9 D jitter ------------------------------------------------------------
def _jittered(V, D, seed=1):
    rng = np.random.default_rng(seed)
    return V + rng.uniform(-1.0, 1.0, V.shape) * 1e-9 * D


def _check_jitter(name):
    V, F = _mesh(name)
    base = _skeleton(name)
    D = unit_D(V)
    sk = skeletonize(_jittered(V, D), F)
    gap = curve_gap(base, sk, D)
    assert sk.n_joints == base.n_joints and gap < 1e-4, \
        f"a 1e-9 D jitter: {base.n_joints} -> {sk.n_joints} joints, the curve moved by {gap:.2e} D"


@pytest.mark.parametrize("name", ["star", "bent_tube", "plate_with_holes", "knobbed_bone"])
def test_a_jitter_of_1e_9_D_moves_a_small_shape_by_less_than_1e_4_D(name):
    """Issue 30, item 5: "a 1e-9 D jitter of every vertex moves the skeleton less than 1e-4 D,
    with the same joint count" (every vertex moved by up to 1e-9 D along each axis; the curves
    compared both ways, points every D/1000, the largest distance)."""
    _check_jitter(name)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["hand.off", "spot.obj", "armadillo.obj", "elephant.obj", "horse.off"])
def test_a_jitter_of_1e_9_D_moves_a_shared_mesh_by_less_than_1e_4_D(name):
    """As above, on shared meshes: the old method's armadillo moved 2.2e-3 D (a step decision
    turned one swapped sample into a jump), spot's mirror-image pole candidates tied and the
    last bits chose (0.19 D)."""
    _check_jitter(name)


# -- Max Joints ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("budget", [10, 20, 40])
@pytest.mark.parametrize("name", ["torus", "plate_with_holes"])
def test_max_joints_is_never_exceeded(name, budget):
    """*Max Joints* is a hard upper bound: neither the result nor any logged stage (a live
    preview) has more joints (the old method gave 16 joints for max_joints=10 on 3holes)."""
    V, F = procedural_mesh(name)
    sk = skeletonize(V, F, max_joints=budget)
    assert sk.n_joints <= budget
    assert max(st["joints"] for st in sk.meta["stages"]) <= budget


@pytest.mark.slow
@pytest.mark.parametrize("budget", [10, 20, 40])
@pytest.mark.parametrize("name", ["octopus.off", "3holes.off"])
def test_max_joints_is_never_exceeded_on_shared_meshes(name, budget):
    """As above on the shared meshes with the most joints (octopus 93 by default, 3holes 47)."""
    V, F = shared_mesh(name)
    sk = skeletonize(V, F, max_joints=budget)
    assert sk.n_joints <= budget
    assert max(st["joints"] for st in sk.meta["stages"]) <= budget


def test_max_joints_bounds_the_papers_solver_too():
    """The setting's contract (``SkeletonParams.max_joints``: "a hard upper bound on the joints
    of the result") names no solver: ``solver="paper"`` with a budget keeps to it as well."""
    V, F = procedural_mesh("star")
    sk = skeletonize(V, F, SkeletonParams.paper(max_joints=20))
    assert sk.n_joints <= 20, sk.n_joints


# -- the settings move the skeleton in their direction -----------------------------------------------------
SMOOTHNESS = (0.0, 1.0, 10.0)


@pytest.mark.parametrize("name", ["bent_tube", "bent_capsule"])
def test_smoothness_straightens_the_chains_monotonically(name):
    """*Smoothness* is the weight of J's smoothness term: as it rises from 0 to 1 to 10 the
    chains' bending (the sum of 1 - cos(theta) over the chain joints, the angular part of that
    term: the lower the weight, the more a minimiser of J may spend on it) never grows, and 10
    bends measurably less than 0 (the setting does something). Both tubes bend by a right
    angle; the total turning angle is given in the message beside the bending."""
    V, F = procedural_mesh(name)
    runs = [skeletonize(V, F, smoothness=s) for s in SMOOTHNESS]
    bend = [bending(sk.joints, sk.bones) for sk in runs]
    figures = {s: (round(b, 4), round(total_turning(sk.joints, sk.bones), 1), sk.n_joints)
               for s, b, sk in zip(SMOOTHNESS, bend, runs)}
    assert all(b <= a + 1e-12 for a, b in zip(bend, bend[1:])), f"(bending, turning, joints): {figures}"
    assert bend[-1] < 0.9 * bend[0], f"(bending, turning, joints): {figures}"


PRUNING = (0.0, 1.0, 10.0, 100.0)


@pytest.mark.parametrize("name", ["star", "knobbed_bone"])
def test_branch_pruning_removes_tips_monotonically(name):
    """*Branch Pruning* is the price of a branch: the number of tips never grows as it rises
    (0, 1, 10, 100), and the highest removes at least one tip the lowest keeps."""
    V, F = procedural_mesh(name)
    tips = []
    for p in PRUNING:
        sk = skeletonize(V, F, prune=p)
        tips.append(int((topology(sk.n_joints, sk.bones)[2] == 1).sum()))
    assert all(b <= a for a, b in zip(tips, tips[1:])), dict(zip(PRUNING, tips))
    assert tips[-1] < tips[0], dict(zip(PRUNING, tips))
