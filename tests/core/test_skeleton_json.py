"""The curveskel-skeleton/1 JSON: written as the issue specifies, read back identically."""

import json

import numpy as np
import pytest

from curveskel_addon.core import skeletonize
from curveskel_addon.core.errors import CurveSkelError
from curveskel_addon.core.skeleton import FORMAT, Skeleton
from meshes import capsule


def _skeleton():
    rng = np.random.default_rng(1)
    joints = np.c_[rng.normal(size=(5, 3)), rng.uniform(0.1, 1, 5)]
    bones = np.array([[0, 1], [1, 2], [1, 3], [3, 4]])
    bone = rng.integers(0, 4, 50)
    t = rng.uniform(0, 1, 50)
    return Skeleton(joints, bones, bone, t, energy=[3.0, 1.5, 1.25], timings={"reeb": 0.1},
                    meta={"components": 1, "vertices": np.int64(50), "arr": np.arange(3)})


def test_round_trip_is_exact(tmp_path):
    sk = _skeleton()
    p = tmp_path / "s.json"
    sk.save(p)
    back = Skeleton.load(p)
    np.testing.assert_array_equal(back.joints, sk.joints)
    np.testing.assert_array_equal(back.bones, sk.bones)
    np.testing.assert_array_equal(back.bone, sk.bone)
    np.testing.assert_array_equal(back.t, sk.t)
    assert back.energy == sk.energy
    assert back.timings == sk.timings
    assert back.meta["vertices"] == 50 and back.meta["arr"] == [0, 1, 2]


def test_document_has_the_specified_fields(tmp_path):
    d = json.loads(json.dumps(_skeleton().to_dict()))
    assert d["format"] == FORMAT == "curveskel-skeleton/1"
    assert len(d["joints"][0]) == 4
    assert d["bones"][2] == [1, 3]
    assert set(d["mapping"]) >= {"bone", "t"} and len(d["mapping"]["bone"]) == 50
    assert d["energy"]["initial"] == 3.0 and d["energy"]["final"] == 1.25
    assert d["energy"]["iterations"] == 2
    assert isinstance(d["meta"], dict)


def test_sigma_follows_eq_19():
    sk = _skeleton()
    i, j = sk.bones[sk.bone].T
    expected = sk.t[:, None] * sk.joints[i, :3] + (1 - sk.t[:, None]) * sk.joints[j, :3]
    np.testing.assert_allclose(sk.sigma(), expected)
    np.testing.assert_allclose(sk.radius_at_mapping(), sk.t * sk.joints[i, 3] + (1 - sk.t) * sk.joints[j, 3])


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d.update(format="other/1"), "not a curveskel-skeleton/1"),
    (lambda d: d["bones"].append([0, 99]), "out of range"),
    (lambda d: d["mapping"]["t"].pop(), "differ in length"),
])
def test_bad_documents_are_rejected(tmp_path, mutate, message):
    d = _skeleton().to_dict()
    mutate(d)
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(d))
    with pytest.raises(CurveSkelError, match=message):
        Skeleton.load(p)


def test_unreadable_file_is_our_error(tmp_path):
    p = tmp_path / "x.json"
    p.write_text("{not json")
    with pytest.raises(CurveSkelError, match="cannot read"):
        Skeleton.load(p)


@pytest.fixture(scope="module")
def run():
    V, F = capsule(radius=1.0, length=6.0, n_around=12, n_body=12)
    return skeletonize(V, F)


def test_a_runs_document_carries_j_per_stage_and_reads_back(run, tmp_path):
    """Issue 30: every entry of ``meta["stages"]`` carries ``J`` and ``terms`` (a dict of the
    terms' values), ``meta["J"]`` is the returned skeleton's J, and the JSON keeps them."""
    d = json.loads(json.dumps(run.to_dict()))
    stages = d["meta"]["stages"]
    assert len(stages) >= 2
    for st in stages:
        assert isinstance(st["J"], float) and np.isfinite(st["J"])
        assert {"fit", "centre", "smooth", "contain", "joints", "tips", "E"} <= set(st["terms"])
    assert d["meta"]["J"] == stages[-1]["J"] == run.meta["J"]
    assert d["energy"]["history"] == [st["terms"]["E"] for st in stages]
    p = tmp_path / "run.json"
    run.save(p)
    back = Skeleton.load(p)
    assert back.meta["stages"] == run.meta["stages"] and back.meta["J"] == run.meta["J"]


def test_a_runs_summary_has_its_figures(run):
    """What the Blender panel and the command line print after a run (``Skeleton.summary``):
    joints, bones, components, E0 (the first approximation's E), E (the returned skeleton's),
    iterations, seconds."""
    s = run.summary()
    assert (s["joints"], s["bones"], s["components"]) == (run.n_joints, run.n_bones, 1)
    assert s["E0"] == run.energy[0] and s["E"] == run.energy[-1]
    assert s["iterations"] >= 1 and s["seconds"] > 0
