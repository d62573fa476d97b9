"""Shape measures of issue 10 (measure.quality.curve_measures / curve_distances / shape_measures):
analytic answers, brute-force agreement, and agreement with ../shared/tools/shape_check.py."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from curveskel_addon.core import SkeletonParams
from curveskel_addon.core.skeleton import Skeleton
from curveskel_addon.measure.quality import (
    bbox_diagonal, close_bone_pairs, crossing_pairs, curve_arrays, curve_distances, curve_measures,
    curve_points, fold_pairs, mirror_asymmetry, quality, section_offsets, segment_points,
    segment_segment_distance, shape_measures, turn_angles)
from curveskel_addon.mesh_files import read_mesh
from tests.meshes import box_bar, capsule

SHARED = Path(__file__).resolve().parents[3] / "shared"


def chain(P):
    """Joints (n, 3) and bones of the polyline through P."""
    P = np.asarray(P, float)
    return P, np.stack([np.arange(len(P) - 1), np.arange(1, len(P))], 1)


def line(a, b, n):
    t = np.linspace(0, 1, n + 1)[:, None]
    return (1 - t) * np.asarray(a, float) + t * np.asarray(b, float)


# -- helpers ------------------------------------------------------------------------------------
def test_segment_points_spacing_and_ends():
    P, owner = segment_points(np.zeros((2, 3)), np.array([[1.0, 0, 0], [0, 0.3, 0]]), 0.25)
    assert owner.tolist() == [0] * 5 + [1] * 3
    assert np.allclose(P[:5, 0], [0, 0.25, 0.5, 0.75, 1.0])
    assert np.allclose(P[5:, 1], [0, 0.15, 0.3])
    # zero-length segment: its point twice
    P, owner = segment_points(np.ones((1, 3)), np.ones((1, 3)), 0.1)
    assert len(P) == 2 and np.allclose(P, 1)


def test_segment_segment_distance_against_dense_sampling():
    rng = np.random.default_rng(3)
    n = 120
    P = rng.normal(size=(4, n, 3))
    P[1, :20] = P[0, :20]                                  # first segment a point
    P[3, 20:40] = P[2, 20:40]                              # second segment a point
    P[1, 40:45] = P[0, 40:45]
    P[3, 40:45] = P[2, 40:45]                              # both points
    P[3, 45:70] = P[2, 45:70] + (P[1, 45:70] - P[0, 45:70]) * rng.uniform(-2, 2, (25, 1))  # parallel
    d = segment_segment_distance(*P)
    t = np.linspace(0, 1, 401)[:, None]
    for k in range(n):
        A = P[0, k] + t * (P[1, k] - P[0, k])
        B = P[2, k] + t * (P[3, k] - P[2, k])
        brute = np.linalg.norm(A[:, None] - B[None], axis=2).min()
        assert d[k] <= brute + 1e-12
        assert brute - d[k] < 2e-3 * (1 + np.ptp(P[:, k], axis=0).max())


def test_segment_segment_distance_crossing_and_touching():
    o = np.zeros((3, 3))
    x = np.tile([2.0, 0, 0], (3, 1))
    p2 = np.array([[1.0, -1, 0.5], [2.0, 0, 0], [3.0, 0, 0]])
    q2 = np.array([[1.0, 1, 0.5], [2.0, 5, 0], [4.0, 0, 0]])
    assert np.allclose(segment_segment_distance(o, x, p2, q2), [0.5, 0.0, 1.0])


def test_curve_arrays_accepts_every_form(tmp_path):
    X, B = chain(line([0, 0, 0], [1, 0, 0], 3))
    J = np.column_stack([X, np.full(len(X), 0.1)])
    path = tmp_path / "s.json"
    path.write_text(json.dumps({"joints": J.tolist(), "bones": B.tolist()}))
    sk = Skeleton(J, B, np.zeros(0, int), np.zeros(0))
    for form in (sk, (J, B), (X, B), {"joints": J, "bones": B}, str(path), path):
        X2, B2 = curve_arrays(form)
        assert np.array_equal(X2, X) and np.array_equal(B2, B)
    # self-loops dropped
    assert len(curve_arrays((X, np.array([[0, 0], [0, 1]])))[1]) == 1


# -- zig-zag ------------------------------------------------------------------------------------
def test_straight_chain_has_no_zigzag_or_fold():
    X, B = chain(line([0, 0, 0], [3, 1, 2], 40))
    m = curve_measures(X, B, D=5.0)
    assert m["zigzag"] == 0.0 and m["turn_p90"] < 1e-5
    assert m["folds"] == 0.0 and m["fold_pairs"] == 0
    assert m["degree2"] == 39 and m["leaves"] == 2
    assert m["length"] == pytest.approx(np.sqrt(14) / 5)


def test_turn_angles_of_a_polyline_with_known_turns():
    # turns of 30, 90, 120 and 170 degrees in the plane, then one out of it (90)
    headings = np.radians([0, 30, 120, 240, 410])
    P = [np.zeros(3)]
    for h in headings:
        P.append(P[-1] + [np.cos(h), np.sin(h), 0])
    P.append(P[-1] + [0, 0, 2.0])
    X, B = chain(P)
    order = np.random.default_rng(0).permutation(len(B))     # bone order does not matter
    B = B[order][:, ::-1]
    j, ang = turn_angles(X, B)
    ang = ang[np.argsort(j)]
    assert np.allclose(ang, [30, 90, 120, 170, 90])
    m = curve_measures(X, B, D=10.0)
    assert m["zigzag"] == pytest.approx(4 / 5)                 # all but the 30 degree turn
    assert m["fold_pairs"] == len(_brute_folds(X, B, 10.0))      # it crosses itself


def test_zigzag_ignores_leaves_branch_points_and_zero_bones():
    # a T: the junction has degree 3, not counted; a zero-length bone is skipped
    X = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0], [1, 2, 0], [1, 2, 0], [1, 3, 0]], float)
    B = np.array([[0, 1], [1, 2], [1, 3], [3, 4], [4, 5], [5, 6]])
    j, ang = turn_angles(X, B)
    assert sorted(j.tolist()) == [3]            # joints 4 and 5 touch the zero-length bone
    assert np.allclose(ang, 0)
    # a hairpin: 180 degrees
    X, B = chain([[0, 0, 0], [1, 0, 0], [0, 0.01, 0]])
    assert np.allclose(turn_angles(X, B)[1], [180 - np.degrees(np.arctan2(0.01, 1))])


# -- folds --------------------------------------------------------------------------------------
def _brute_folds(X, B, D, near=0.01, far=0.1):
    """O(B^2) pairs and all-pairs shortest paths: the definition, literally."""
    n = len(X)
    i, k = np.triu_indices(len(B), 1)
    d = segment_segment_distance(X[B[i, 0]], X[B[i, 1]], X[B[k, 0]], X[B[k, 1]])
    U = np.unique(np.sort(B, axis=1), axis=0)          # a duplicated bone is one edge
    w = np.linalg.norm(X[U[:, 1]] - X[U[:, 0]], axis=1) + 1e-12 * D
    G = csr_matrix((np.r_[w, w], (np.r_[U[:, 0], U[:, 1]], np.r_[U[:, 1], U[:, 0]])), shape=(n, n))
    Dm = dijkstra(G, directed=False)
    _, comp = connected_components(G, directed=False)
    g = np.min([Dm[B[i, a], B[k, b]] for a in (0, 1) for b in (0, 1)], axis=0)
    keep = (d < near * D) & (g > far * D) & (comp[B[i, 0]] == comp[B[k, 0]])
    return {(int(a), int(b)) for a, b in zip(i[keep], k[keep])}


def hairpin(gap=0.005, n=10):
    """Along x from 0 to 1 in n bones, up by ``gap``, and back: a chain doubling back."""
    out = line([0, 0, 0], [1, 0, 0], n)
    back = line([1, gap, 0], [0, gap, 0], n)
    return chain(np.concatenate([out, back]))


def test_chain_doubling_back_has_folds():
    X, B = hairpin()
    got = {tuple(p) for p in fold_pairs(X, B, 1.0).tolist()}
    assert got == _brute_folds(X, B, 1.0)
    # bone k of the way out lies beside bone 2n - k of the way back; the pairs near the bend are
    # closer than 0.1 along the chain (the path through the bend: 0.1 + gap) do not count
    assert (0, 20) in got and (0, 19) in got
    assert (9, 11) not in got and (8, 10) not in got and (8, 11) in got
    m = curve_measures(X, B, D=1.0)
    assert m["folds"] == pytest.approx(len(got) / len(B)) and m["folds"] > 0.5
    # the same chain opened wide (gap > 0.01 D): no fold
    X, B = hairpin(gap=0.02)
    assert curve_measures(X, B, D=1.0)["folds"] == 0


def test_separate_parts_overlapping_do_not_fold():
    a = line([0, 0, 0], [1, 0, 0], 10)
    b = line([0, 0.005, 0], [1, 0.005, 0], 10)
    X = np.concatenate([a, b])
    B = np.concatenate([chain(a)[1], chain(b)[1] + len(a)])
    assert curve_measures(X, B, D=1.0)["folds"] == 0
    # joined far away (a detour of 1 D through two more joints): now the same pairs are folds
    X2 = np.concatenate([X, [[1, 0, 0.5], [1, 0.005, 0.5]]])
    B2 = np.concatenate([B, [[len(a) - 1, len(X)], [len(X), len(X) + 1], [len(X) + 1, len(X) - 1]]])
    got = {tuple(p) for p in fold_pairs(X2, B2, 1.0).tolist()}
    assert got == _brute_folds(X2, B2, 1.0) and len(got) >= 10


def test_crossing_chains_fold_but_branches_sharing_a_joint_do_not():
    # an X of two chains joined only at far ends: the crossing bones fold
    a = line([-1, 0, 0], [1, 0, 0], 10)
    b = line([0, -1, 0.001], [0, 1, 0.001], 10)
    X = np.concatenate([a, b])
    B = np.concatenate([chain(a)[1], chain(b)[1] + len(a), [[len(a) - 1, len(a) + len(b) - 1]]])
    got = fold_pairs(X, B, 2.0)
    assert len(got) >= 1 and {tuple(p) for p in got.tolist()} == _brute_folds(X, B, 2.0)
    # a star: bones meet at the centre, all within 0.01 D of each other there, 0 apart
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]], float)
    B = np.array([[0, 1], [0, 2], [0, 3], [0, 4]])
    assert len(fold_pairs(X, B, 1.0)) == 0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fold_pairs_and_close_pairs_equal_brute_force_on_random_skeletons(seed):
    rng = np.random.default_rng(seed)
    # a random walk (folds, zig-zags) plus a few random extra bones (cycles) and a second part
    steps = rng.normal(size=(150, 3)) * 0.03
    X = np.cumsum(steps, axis=0)
    B = chain(X)[1]
    extra = rng.integers(0, 150, size=(10, 2))
    X = np.concatenate([X, X[:40] + rng.normal(size=(40, 3)) * 0.01])
    B = np.concatenate([B, extra[extra[:, 0] != extra[:, 1]], chain(X[150:])[1] + 150])
    D = bbox_diagonal(X)
    near = 0.03
    pairs, d = close_bone_pairs(X, B, near * D)
    i, k = np.triu_indices(len(B), 1)
    dd = segment_segment_distance(X[B[i, 0]], X[B[i, 1]], X[B[k, 0]], X[B[k, 1]])
    assert {tuple(p) for p in pairs.tolist()} == set(zip(i[dd < near * D].tolist(), k[dd < near * D].tolist()))
    got = {tuple(p) for p in fold_pairs(X, B, D, near=near).tolist()}
    want = _brute_folds(X, B, D, near=near)
    assert got == want and len(want) > 0


# -- distances to a reference -------------------------------------------------------------------
def test_to_ref_of_an_offset_curve_is_the_offset():
    ref = chain(line([0, 0, 0], [1, 0, 0], 7))
    ours = chain(line([0, 0.03, 0], [1, 0.03, 0], 3))
    m = curve_distances(ours, ref, D=1.0)
    # up to the fine sampling (nearest reference sample at most 1/4000 along x): 1e-6
    for k in ("to_ref_mean", "to_ref_p95", "to_ref_max", "from_ref_mean", "from_ref_max"):
        assert m[k] == pytest.approx(0.03, abs=2e-6)
    # a circle of radius 1 against one of radius 1.05 (offset 0.05), D = 2.1: both ways 0.05 / D
    u = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    ring = lambda R: (np.stack([R * np.cos(u), R * np.sin(u), 0 * u], 1),  # noqa: E731
                      np.stack([np.arange(200), (np.arange(200) + 1) % 200], 1))
    m = curve_distances(ring(1.05), ring(1.0), D=2.1)
    sag = 1.05 * (1 - np.cos(np.pi / 200))                  # chords cut inside the circles
    assert m["to_ref_mean"] == pytest.approx(0.05 / 2.1, abs=(sag + 2.1 / 4000) / 2.1)
    assert m["from_ref_mean"] == pytest.approx(0.05 / 2.1, abs=(sag + 2.1 / 4000) / 2.1)


def test_missing_branch_shows_in_from_ref_only():
    # reference: a T (stem 0..2 along x, branch 0..1 along y at x = 1); ours: the stem only
    ref = (np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0]], float),
           np.array([[0, 1], [1, 2], [1, 3]]))
    ours = chain(line([0, 0, 0], [2, 0, 0], 4))
    m = curve_distances(ours, ref, D=1.0)
    assert m["to_ref_mean"] == pytest.approx(0, abs=1e-12)
    # reference samples every 1/400, both ends of each bone: 2 x 401 on the stem at distance
    # 0, 401 on the branch at distance t
    t = np.arange(401) / 400
    want = t.sum() / (802 + 401)
    assert m["from_ref_mean"] == pytest.approx(want, rel=1e-9)
    assert m["from_ref_max"] == pytest.approx(1.0)


def test_shape_measures_on_a_capsule_and_length_ratio():
    V, F = capsule(radius=1.0, length=6.0, n_around=16, n_body=10, cap_rings=4)
    D = bbox_diagonal(V, F)
    ref = chain(line([0, 0, 0], [0, 0, 6], 12))
    sk = Skeleton(np.array([[0, 0, 0, 1], [0, 0, 3, 1], [0, 0, 6, 1]], float),
                  np.array([[0, 1], [1, 2]]), np.zeros(0, int), np.zeros(0))
    m = shape_measures(V, F, sk, ref)
    assert m["D"] == pytest.approx(D)
    # on the same line: only the distance to the nearest fine sample (<= D/4000) remains
    assert m["to_ref_max"] <= 1 / 4000 and m["from_ref_max"] <= 1 / 4000
    assert m["length_ratio"] == pytest.approx(1.0) and m["zigzag"] == 0 and m["folds"] == 0
    # half the reference's length: ratio 0.5; a zig-zag of the same extent: longer, zig-zags
    assert shape_measures(V, F, sk, chain(line([0, 0, 0], [0, 0, 12], 4)))["length_ratio"] == pytest.approx(0.5)
    zz = chain([[0, 0, 0], [0.5, 0, 1], [-0.5, 0, 2], [0.5, 0, 3], [-0.5, 0, 4], [0.5, 0, 5], [0, 0, 6]])
    mz = shape_measures(V, F, zz, ref)
    assert mz["zigzag"] == 1.0 and mz["length_ratio"] > 1.1
    # without a reference: only the reference-free measures
    assert "to_ref_mean" not in shape_measures(V, F, sk)


def test_curve_measures_default_D_is_the_skeletons_own():
    X, B = hairpin()
    assert curve_measures(X, B) == curve_measures(X, B, D=bbox_diagonal(X))
    assert curve_measures((X, B)) == curve_measures(X, B)


# -- agreement with the shared checker ----------------------------------------------------------
def _shape_check():
    path = SHARED / "tools" / "shape_check.py"
    if not path.is_file():
        pytest.skip("../shared/tools/shape_check.py not present")
    spec = importlib.util.spec_from_file_location("shape_check", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("name,mesh", [("horse", "horse.off"), ("3holes", "3holes.off")])
def test_agrees_with_shared_shape_check(name, mesh):
    """A jittered copy of the reference with random criss-cross bones (zig-zags, folds, extra
    length) against the reference: every measure equals shape_check.py's (same sampling)."""
    sc = _shape_check()
    ref_path = SHARED / "reference" / f"{name}.json"
    mesh_path = SHARED / "meshes" / mesh
    if not (ref_path.is_file() and mesh_path.is_file()):
        pytest.skip("shared mesh / reference not present")
    V, F = read_mesh(mesh_path)
    D = bbox_diagonal(V, F)
    assert D == pytest.approx(sc.mesh_diag(str(mesh_path)))
    ref = json.loads(ref_path.read_text())
    Xr, Br = curve_arrays(ref)
    rng = np.random.default_rng(7)
    X = Xr[::2] + rng.normal(size=Xr[::2].shape) * 0.015 * D
    old_to_new = np.arange(len(Xr)) // 2
    B = old_to_new[Br]
    B = B[B[:, 0] != B[:, 1]]
    # criss-cross: joints 0.02-0.2 D apart joined
    cand = cKDTree(X).query_pairs(0.2 * D, output_type="ndarray")
    cand = cand[np.linalg.norm(X[cand[:, 0]] - X[cand[:, 1]], axis=1) > 0.02 * D]
    B = np.concatenate([B, cand[rng.choice(len(cand), 15, replace=False)]])
    B = np.unique(np.sort(B, axis=1), axis=0)
    ours = {"joints": np.column_stack([X, np.ones(len(X))]).tolist(), "bones": B.tolist()}
    want = sc.curve_measures(D, sc.load_skeleton(ours), sc.load_skeleton(ref))
    got = shape_measures(V, F, ours, ref)
    for k_ours, k_sc in [("to_ref_mean", "to_ref_mean"), ("to_ref_p95", "to_ref_p95"),
                         ("from_ref_mean", "from_ref_mean"), ("from_ref_p95", "from_ref_p95"),
                         ("length_ratio", "length_ratio"), ("zigzag", "zigzag_frac"),
                         ("turn_p90", "turn_p90"), ("folds", "crossing_frac"),
                         ("leaves", "leaves"), ("ref_leaves", "ref_leaves"), ("bones", "bones")]:
        assert got[k_ours] == pytest.approx(want[k_sc], rel=1e-9, abs=1e-12), k_ours
    assert got["zigzag"] > 0.1 and got["folds"] > 0 and got["length_ratio"] > 1.0


def test_curve_points_without_bones_are_the_joints():
    X = np.array([[0, 0, 0], [1, 2, 3]], float)
    assert np.array_equal(curve_points(X, np.zeros((0, 2), int), 0.1), X)


# -- the developer table (scripts/shape_table.py) and the bench's target marks -------------------
def _script(name):
    path = Path(__file__).resolve().parents[2] / "scripts" / f"{name}.py"
    import sys
    sys.path.insert(0, str(path.parent))
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_shape_table_parses_overrides_and_marks_targets():
    st = _script("shape_table")
    fields = SkeletonParams().to_dict()
    sets = []
    for name, value in fields.items():       # one override of each type present
        if isinstance(value, bool):
            sets.append(f"{name}=0")
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            sets.append(f"{name}={value}")
    got = st.parse_sets(sets, paper=False)
    for k, v in got.items():
        assert type(v) is type(fields[k]) and (v == fields[k] or v is False)
    with pytest.raises(SystemExit):
        st.parse_sets(["no_such_parameter=1"], paper=False)
    row = {"mesh": "horse", "joints": 40, "topology_match": True, "inside": 0.99, "recon_mean": 0.005,
           "recon_ratio": 0.86, "zigzag": 0.2, "folds": 0.0, "length_ratio": 1.1, "to_ref_mean": 0.01,
           "from_ref_mean": 0.01, "seconds": 1.0, "components": 1, "cycles": 0}
    marks = st.shape_marks(row)
    assert [k for k, v in marks.items() if not v] == ["zigzag"]
    line = st.fmt_row(row)
    assert "0.20*" in line and line.count("*") == 1
    assert "zigzag 0" in st.summary([row]) and "all 0" in st.summary([row])
    good = row | {"mesh": "spot", "zigzag": 0.1, "to_ref_mean": 0.02, "recon_ratio": 1.0}
    sweep = st.sweep_row("smoothness 2", [row, good, {"mesh": "hand", "error": "boom"}])
    #           all, inside, recon, mean ratio, zig-zag, folds, length, to_ref, median, from_ref
    assert sweep == "| smoothness 2 | 1 | 2 | 2 | 0.93 | 1 | 2 | 2 | 2 | 0.0150 | 2 | (1 failed)"
    assert sweep.count("|") == st.SWEEP_HEADER.split("\n")[0].count("|")


def test_quality_reports_shape_measures():
    V, F = capsule(radius=1.0, length=6.0, n_around=16, n_body=10, cap_rings=4)
    sk = Skeleton(np.array([[0, 0, 0, 1], [0, 0, 3, 1], [0, 0, 6, 1]], float),
                  np.array([[0, 1], [1, 2]]), np.zeros(0, int), np.zeros(0))
    q = quality(V, F, sk, n_samples=500)
    assert q["zigzag"] == 0 and q["folds"] == 0 and "to_ref_mean" not in q
    q = quality(V, F, sk, n_samples=500, reference=chain(line([0, 0, 0], [0, 0, 6], 6)))
    assert q["length_ratio"] == pytest.approx(1.0) and q["to_ref_mean"] <= 1 / 4000


def test_crossings_count_bones_within_their_radius_far_along_the_skeleton():
    # a chain turns back over its first bone, 0.075 above it where they cross
    J = np.array([[0, 0, 0, 1], [4, 0, 0, 1], [4, 3, 0, 1], [2, 3, 0, 1], [2, -1, 0.1, 1.0]])
    B = np.array([[0, 1], [1, 2], [2, 3], [3, 4]])
    assert crossing_pairs(J, B, 10.0).tolist() == [[0, 3]]
    assert curve_measures(J, B, D=10.0)["crossings"] == 0.25
    # thinner bones: 0.075 is more than 0.3 of their radius 0.2
    assert len(crossing_pairs(J * [1, 1, 1, 0.2], B, 10.0)) == 0
    # near along the skeleton (a short loop): not a crossing
    assert len(crossing_pairs(J, B, 200.0)) == 0
    # no radii, no crossings measure
    assert curve_measures(J[:, :3], B, D=10.0)["crossings"] is None


def test_pinches_count_chain_joints_thinner_than_both_neighbours():
    """A waist of radius 0.3 between radii 1 and 0.9 is a pinch (< 0.4 of both); 0.5 is not; a
    tip is never one; a curve without radii has no pinch count."""
    X = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [4, 0, 0]])
    bones = np.array([[0, 1], [1, 2], [2, 3], [3, 4]])
    J = np.column_stack([X, [0.1, 1.0, 0.3, 0.9, 0.05]])
    assert curve_measures(J, bones, D=4.0)["pinches"] == 1
    J[2, 3] = 0.5
    assert curve_measures(J, bones, D=4.0)["pinches"] == 0
    assert curve_measures(X, bones, D=4.0)["pinches"] is None


def test_mirror_asymmetry_of_a_skeleton_and_its_reflection():
    """Points symmetric across x = 0 only; a bone on the plane is its own mirror image (0), a bone
    1 to its side lies 2 from its image everywhere (2 / D both ways); a box symmetric across three
    planes has no one mirror plane (None)."""
    V = np.array([[x, y, z] for x in (-2., 2) for y in (0., 1, 3) for z in (0., 1, 5)])
    bone = np.array([[0, 1]])
    assert mirror_asymmetry(V, (np.array([[0., 0, 0], [0, 3, 0]]), bone), 10.0) == pytest.approx(0, abs=1e-12)
    assert mirror_asymmetry(V, (np.array([[1., 0, 0], [1, 3, 0]]), bone), 10.0) == pytest.approx(0.2)
    box = np.array([[x, y, z] for x in (-1., 1) for y in (-2., 2) for z in (-3., 3)])
    assert mirror_asymmetry(box, (np.array([[1., 0, 0], [1, 3, 0]]), bone), 10.0) is None


def test_reference_centring_measures_how_far_a_curve_runs_from_its_sections_centres():
    """scripts/reference_centring.py on a capsule (radius 1, axis along z from 0 to 6): its own axis
    lies on its sections' centroids (offset ~0); the axis moved by 0.3 along x is 0.3 off
    them, and the curve through the centroids is 0.3 from it."""
    rc = _script("reference_centring")
    V, F = capsule(radius=1.0, length=6.0)
    D = float(np.linalg.norm(np.ptp(V, axis=0)))
    R = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 5.0]])
    RB = np.array([[0, 1]])
    found, off, to_ref = rc.reference_centring(V, F, R, RB)
    # (to_ref to the reference sampled every D/2000: within half a step of it)
    assert found == 1.0 and off.max() * D < 1e-3 and to_ref.max() <= 1 / 4000
    found, off, to_ref = rc.reference_centring(V, F, R + [0.3, 0.0, 0.0], RB)
    assert found == 1.0
    np.testing.assert_allclose(off * D, 0.3, atol=0.01)
    np.testing.assert_allclose(to_ref * D, 0.3, atol=0.01)


# -- section_offsets (how centred a curve is in the mesh's cross-sections) -------------------------
def test_section_offsets_of_a_bar_axis_and_of_a_line_beside_it():
    V, F = box_bar()                        # 8 x 1 x 1 along x
    D = bbox_diagonal(V, F)
    found, off = section_offsets(V, F, ([[-3.0, 0, 0], [3.0, 0, 0]], [[0, 1]]), D)
    assert found == 1.0 and np.allclose(off, 0.0, atol=1e-12)
    # moved 0.1 along y and 0.2 along z: every section's centroid is still the axis
    found, off = section_offsets(V, F, ([[-3.0, 0.1, 0.2], [3.0, 0.1, 0.2]], [[0, 1]]), D)
    assert found == 1.0 and np.allclose(off * D, np.hypot(0.1, 0.2))
    # points every D/400: 6 / (D/400) of them
    assert len(off) == int(np.ceil(6.0 / (D / 400)))


def test_section_offsets_outside_the_mesh_find_nothing():
    V, F = box_bar()
    found, off = section_offsets(V, F, ([[-3.0, 5, 0], [3.0, 5, 0]], [[0, 1]]))
    assert found == 0.0 and len(off) == 0
