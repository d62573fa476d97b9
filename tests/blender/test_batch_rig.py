"""Issue 32: rig outputs in a batch. Workers that loaded Blender are restarted every K assets;
the .glb is the single-file command's, byte for byte; the .blend is complete."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

from curveskel_addon.cli.outputs import incomplete

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared" / "meshes"
ONE_THREAD = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
#: a coarse Detail Size: the rig outputs and the workers' restarts are under test, not the detail
METHOD = {"spacing": 0.15}


def test_batch_rig_outputs_restart_blender_workers_every_k_assets(tmp_path):
    from curveskel_addon.batch import run

    src = tmp_path / "in"
    (src / "sub").mkdir(parents=True)
    shutil.copy2(SHARED / "octopus.off", src / "octopus.off")
    shutil.copy2(SHARED / "spot.obj", src / "sub" / "spot.obj")
    shutil.copy2(ROOT / "tests" / "data" / "heldout" / "quadknot.obj", src / "quadknot.obj")
    out = tmp_path / "out"
    res = run(src, out, workers=1, glb=True, blend=True, bind=True, restart_every=2, params=METHOD)
    assert [r["status"] for r in res] == ["ok"] * 3, res
    for r in res:
        assert r["outputs"] == [r["path"] + s for s in (".json", ".glb", ".blend")]
        for o in r["outputs"]:
            assert incomplete(out / o) is None, o
    # one worker, restarted after two Blender assets: the third ran in a new process
    order = sorted(res, key=lambda r: -(src / r["path"]).stat().st_size)
    pids = [r["worker"] for r in order]
    assert pids[0] == pids[1] != pids[2]
    assert res.workers_started == 2
    # the .glb is what `curveskel skeletonize MESH --glb` writes (one BLAS thread, as the workers)
    one = tmp_path / "one.glb"
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "skeletonize.py"),
                        str(src / "sub" / "spot.obj"), "--glb", str(one), "--quiet", "--spacing", "0.15"],
                       capture_output=True, text=True, timeout=600, env={**os.environ, **ONE_THREAD})
    assert r.returncode == 0, r.stderr
    assert one.read_bytes() == (out / "sub" / "spot.obj.glb").read_bytes()
    # a rerun reuses the three assets (their .glb and .blend unchanged)
    again = run(src, out, workers=1, glb=True, blend=True, bind=True, params=METHOD)
    assert [r["reused"] for r in again] == [True] * 3
    rec = json.loads((out / ".curveskel-batch" / "records" / "sub" / "spot.obj.json").read_text())
    assert sorted(rec["outputs"]) == ["blend", "glb", "json"]
