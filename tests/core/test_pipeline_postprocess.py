"""The issue-5 switches reach the pipeline: prune/simplify/candidates through skeletonize."""
import numpy as np
import pytest

from curveskel_addon.core import CurveSkelError, Skeleton, skeletonize
from meshes import capsule, star


def _joints_added_after_postprocess(meta) -> int:
    """Joints the stages after post-processing add: refinement splits (kept rounds), less the
    folds merged away before it, the short reversals merged after it and the zero-length bones
    contracted at the end."""
    r = meta.get("refine", {})
    split = sum(n for n, kept in zip(r.get("split", []), r.get("kept", [])) if kept)
    return (split - r.get("unfolded", 0) - r.get("reversals", 0)
            - meta.get("collapsed_joints", 0))


def test_switches_reach_the_pipeline():
    V, F = star(4, arm=4.0, radius=0.5)
    off = skeletonize(V, F, prune=0.0, simplify=0.0, candidates=1)
    on = skeletonize(V, F, prune=0.02, simplify=0.01, candidates=3)
    assert "postprocess" not in off.meta and "postprocess" in on.meta
    assert on.n_joints < off.n_joints
    assert on.meta["postprocess"]["joints_out"] + _joints_added_after_postprocess(on.meta) == on.n_joints
    assert len(on.bone) == len(V) and on.bone.max() < on.n_bones
    cands = on.meta["component_info"][0]["candidates"]
    assert len(cands) == 3 and sum(c["chosen"] for c in cands) == 1
    assert "candidates" in on.timings and "postprocess" in on.timings
    assert np.array_equal(skeletonize(V, F, prune=0.02, simplify=0.01, candidates=3).joints, on.joints)


@pytest.mark.parametrize("bad", [dict(prune=-0.1), dict(prune=1.5), dict(simplify=-1), dict(candidates=0)])
def test_bad_switch_values_raise(bad):
    V, F = capsule()
    with pytest.raises(CurveSkelError):
        skeletonize(V, F, **bad)


def test_postprocessed_skeleton_round_trips_through_json(tmp_path):
    V, F = star(3, arm=4.0, radius=0.6)
    sk = skeletonize(V, F, prune=0.02, simplify=0.01, candidates=3)
    sk.validate()
    sk.save(tmp_path / "s.json")
    back = Skeleton.load(tmp_path / "s.json")
    assert np.array_equal(back.bones, sk.bones)
    assert back.meta["postprocess"]["joints_out"] + _joints_added_after_postprocess(back.meta) == sk.n_joints
