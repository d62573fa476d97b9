"""The whole method end to end: topology, radii, mapping per input vertex, determinism, odd
input, the stage log, and the joint budget."""

import numpy as np
import pytest

from curveskel_addon.core import CurveSkelError, Skeleton, SkeletonParams, skeletonize
from meshes import capsule, star, two_capsules
from skeletons import procedural_skeleton, shared_skeleton, topology


def graph_figures(sk: Skeleton):
    """(components, independent cycles) of the skeleton graph."""
    cycles, comps, _ = topology(sk.n_joints, sk.bones)
    return comps, cycles


@pytest.fixture(scope="module")
def capsule_mesh():
    return capsule(radius=1.0, length=6.0)


@pytest.fixture(scope="module")
def capsule_runs(capsule_mesh):
    V, F = capsule_mesh
    return {"default": skeletonize(V, F), "paper": skeletonize(V, F, SkeletonParams.paper())}


@pytest.mark.parametrize("which", ["default", "paper"])
def test_capsule_is_one_chain_along_the_axis_with_the_true_radius(capsule_mesh, capsule_runs, which):
    V, F = capsule_mesh
    sk = capsule_runs[which]
    comps, cycles = graph_figures(sk)
    assert comps == 1 and cycles == 0
    deg = sk.degree()
    assert deg.max() <= 2 and (deg == 1).sum() == 2            # a single chain
    assert np.abs(sk.joints[:, :2]).max() < 0.1               # on the z axis
    # The radial function at the skeleton points of the middle of the body (eq. 17).
    middle = np.abs(V[:, 2] - 3.0) < 2.0
    np.testing.assert_allclose(sk.radius_at_mapping()[middle], 1.0, rtol=0.05)
    np.testing.assert_allclose(np.hypot(*sk.sigma()[middle, :2].T), 0.0, atol=0.05)


def test_the_paper_never_raises_e_and_j_never_rises_from_stage_to_stage(capsule_runs):
    """The paper's descent never raises E (its log: the first approximation's E, then the
    fit's); the search logs J after every kept stage and J never rises. Both logs start with
    the first approximation ("initialise"), and ``energy`` holds one E per logged stage."""
    for which, sk in capsule_runs.items():
        stages = sk.meta["stages"]
        assert stages[0]["stage"] == "initialise" and len(stages) >= 2
        J = np.array([s["J"] for s in stages])
        assert np.all(np.diff(J) <= 0) and J[-1] < J[0], (which, J)
        assert len(sk.energy) == len(stages)
        assert np.all(sk.joints[:, 3] >= 0)                   # negative radii flipped
    paper = capsule_runs["paper"]
    assert [s["stage"] for s in paper.meta["stages"]] == ["initialise", "fit"]
    assert paper.energy == [s["J"] for s in paper.meta["stages"]]   # the paper's J is its E


def test_torus_has_exactly_one_cycle():
    sk = procedural_skeleton("torus")
    assert graph_figures(sk) == (1, 1)


@pytest.mark.slow
@pytest.mark.parametrize("name, genus", [("3holes.off", 3), ("fertility.off", 4), ("rocker-arm.obj", 1)])
def test_shared_mesh_genus_equals_skeleton_cycles(name, genus):
    sk = shared_skeleton(name)
    assert graph_figures(sk) == (1, genus)


def test_two_components_give_two_trees():
    V, F = two_capsules()
    sk = procedural_skeleton("two_capsules")
    assert graph_figures(sk) == (2, 0)
    assert sk.meta["components"] == 2
    # each vertex is mapped to a bone of its own component's tree
    left = V[:, 0] < 2.5
    assert np.all(sk.sigma()[left, 0] < 2.5) and np.all(sk.sigma()[~left, 0] > 2.5)


def test_mapping_has_one_entry_per_input_vertex_in_input_order_even_with_repairs(capsule_mesh):
    V, F = capsule_mesh
    # add an isolated vertex near the middle, a duplicate of vertex 0 used by no face, a degenerate face
    V2 = np.vstack([V, [[0.0, 0.0, 3.0]], V[:1]])
    F2 = np.vstack([F, [[0, 0, 1]]])
    sk = skeletonize(V2, F2)
    assert len(sk.bone) == len(V2) == len(sk.t)
    assert sk.meta["input"]["isolated_vertices"] == 1
    assert np.all((sk.t >= 0) & (sk.t <= 1))
    # the isolated vertex takes the mapping of its nearest surface vertex
    np.testing.assert_allclose(sk.sigma()[-1], sk.sigma()[0])


def test_triangle_soup_gives_the_same_skeleton_as_the_indexed_mesh(capsule_mesh, capsule_runs):
    V, F = capsule_mesh
    a = capsule_runs["default"]
    soup_V = V[F.ravel()]
    b = skeletonize(soup_V, np.arange(len(soup_V)).reshape(-1, 3))
    assert graph_figures(b) == graph_figures(a) == (1, 0)
    assert (b.degree() == 1).sum() == (a.degree() == 1).sum() == 2
    assert len(b.bone) == len(soup_V)
    np.testing.assert_allclose(b.radius_at_mapping()[np.abs(soup_V[:, 2] - 3) < 2], 1.0, rtol=0.05)


def test_open_and_non_manifold_meshes_work(capsule_mesh):
    V, F = capsule_mesh
    open_F = F[F.max(axis=1) < len(V) - 2]                   # remove the end cap fans: two holes
    sk = skeletonize(V, open_F)
    assert sk.n_bones >= 1 and graph_figures(sk)[0] == 1
    fin = np.vstack([V, [[3.0, 3.0, 3.0]]])                  # a fin triangle on an existing edge
    e = F[0]
    nm_F = np.vstack([F, [[e[0], e[1], len(V)]]])
    sk2 = skeletonize(fin, nm_F)
    assert len(sk2.bone) == len(fin)


def test_same_seed_same_skeleton_and_json_round_trip(tmp_path):
    V, F = capsule(radius=1.0, length=6.0, n_around=16, n_body=16)
    a, b = skeletonize(V, F, seed=3), skeletonize(V, F, seed=3)
    np.testing.assert_array_equal(a.joints, b.joints)
    a.save(tmp_path / "a.json")
    c = Skeleton.load(tmp_path / "a.json")
    np.testing.assert_array_equal(c.joints, a.joints)
    np.testing.assert_array_equal(c.bone, a.bone)
    assert c.energy == a.energy
    assert c.meta["J"] == a.meta["J"] and c.meta["stages"] == a.meta["stages"]


def test_bad_parameters_are_reported_clearly(capsule_mesh):
    V, F = capsule_mesh
    with pytest.raises(CurveSkelError, match="unknown solver"):
        skeletonize(V, F, solver="newton")
    with pytest.raises(CurveSkelError, match="spacing"):
        skeletonize(V, F, spacing=0)


@pytest.fixture(scope="module")
def fine_star():
    V, F = star()
    return V, F, skeletonize(V, F, spacing=0.01, max_joints=0)


@pytest.mark.parametrize("budget", [12, 25])
def test_joint_budget_is_met_and_keeps_the_topology(fine_star, budget):
    """max_joints holds for the returned skeleton and for every stage the search logs (a live
    preview never shows more), while every arm of the star stays an arm."""
    V, F, free = fine_star
    assert free.meta["stages"][0]["joints"] > 25               # the budget has work to do
    sk = skeletonize(V, F, spacing=0.01, max_joints=budget)
    assert len(sk.joints) <= budget
    assert max(s["joints"] for s in sk.meta["stages"]) <= budget
    assert (sk.degree() == 1).sum() == 4 and graph_figures(sk) == (1, 0)
