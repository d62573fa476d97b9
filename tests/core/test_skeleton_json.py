"""The curveskel-skeleton/1 JSON: written as the issue specifies, read back identically."""

import json

import numpy as np
import pytest

from curveskel_addon.core.errors import CurveSkelError
from curveskel_addon.core.skeleton import FORMAT, Skeleton


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
