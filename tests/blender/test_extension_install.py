"""Build the extension zip, install it with Blender's extension API into a temporary user folder
and run the operator from the installed copy (bl_ext.user_default.curveskel), in a fresh process."""

import json
import os
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import numpy as np
import pytest
from meshes import capsule

ROOT = Path(__file__).resolve().parents[2]

INSTALL_AND_RUN = textwrap.dedent('''
    import json, sys
    import bpy, numpy as np
    zip_path, npz = sys.argv[1], sys.argv[2]
    bpy.ops.wm.read_homefile(use_empty=True)
    out = {"install": list(bpy.ops.extensions.package_install_files(
        filepath=zip_path, repo="user_default", enable_on_install=True))}
    mod = "bl_ext.user_default.curveskel"
    out["enabled"] = mod in bpy.context.preferences.addons
    op = getattr(bpy.types, "CURVESKEL_OT_generate", None)
    out["operator_module"] = op.__module__ if op is not None else None
    out["source_tree_imported"] = "curveskel_addon" in sys.modules
    prefs = bpy.context.preferences.addons[mod].preferences
    out["pref_spacing"] = round(prefs.spacing, 6)
    prefs.spacing = 0.08                      # a preference default the operator must pick up

    data = np.load(npz)
    V, F = data["V"].astype(np.float32), data["F"].astype(np.int32)
    me = bpy.data.meshes.new("Capsule")
    me.vertices.add(len(V)); me.vertices.foreach_set("co", V.ravel())
    me.loops.add(F.size); me.loops.foreach_set("vertex_index", F.ravel())
    me.polygons.add(len(F)); me.polygons.foreach_set("loop_start", np.arange(0, F.size, 3, dtype=np.int32))
    me.update(calc_edges=True)
    ob = bpy.data.objects.new("Capsule", me)
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob
    out["result"] = list(bpy.ops.curveskel.generate())
    bpy.ops.curveskel.reset_settings()          # the sidebar's "Reset to Defaults"
    out["scene_spacing"] = round(bpy.context.scene.curveskel.spacing, 6)
    arm = bpy.data.objects.get("Capsule.skeleton")
    sil = bpy.data.objects.get("Capsule.silhouette")
    out["objects"] = sorted(o.name for o in bpy.data.objects)
    out["bones"] = arm.get("curveskel_n_bones") if arm else None
    out["edges"] = len(sil.data.edges) if sil else None
    out["params"] = json.loads(arm["curveskel_params"]) if arm else None
    import addon_utils
    addon_utils.disable(mod)
    out["disabled"] = not hasattr(bpy.types, "CURVESKEL_OT_generate")
    print("RESULT " + json.dumps(out))
''')


@pytest.fixture(scope="module")
def built_zip(tmp_path_factory):
    out = tmp_path_factory.mktemp("dist")
    proc = subprocess.run([sys.executable, str(ROOT / "scripts" / "build_extension.py"), "--no-wheels",
                           "--out-dir", str(out), "--build-dir", str(out / "stage")],
                          capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    zips = [Path(line) for line in proc.stdout.split()]
    assert len(zips) == 1 and zips[0].is_file()
    return zips[0]


def test_manifest_fields():
    m = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    assert m["id"] == "curveskel" and m["type"] == "add-on"
    assert m["license"] == ["SPDX:GPL-3.0-or-later"]
    assert m["blender_version_min"] == "4.2.0"
    assert set(m["platforms"]) == {"windows-x64", "macos-x64", "macos-arm64", "linux-x64"}
    assert len(m["tagline"]) <= 64
    wheels = [Path(w).name for w in m["wheels"]]
    assert len(wheels) == 4 and all(w.startswith("scipy-1.15.3-cp311-cp311-") for w in wheels)
    assert not any("numpy" in w or "trimesh" in w for w in m["wheels"])


def test_zip_layout(built_zip):
    import zipfile

    names = zipfile.ZipFile(built_zip).namelist()
    assert "blender_manifest.toml" in names and "__init__.py" in names    # side by side at the top
    assert "core/pipeline.py" in names and "ops_generate.py" in names
    assert not any("__pycache__" in n or n.endswith(".pyc") for n in names)


def test_install_and_run_from_installed_copy(built_zip, tmp_path):
    V, F = capsule()
    np.savez(tmp_path / "mesh.npz", V=V, F=F)
    script = tmp_path / "install_and_run.py"
    script.write_text(INSTALL_AND_RUN)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["BLENDER_USER_RESOURCES"] = str(tmp_path / "user")
    proc = subprocess.run([sys.executable, str(script), str(built_zip), str(tmp_path / "mesh.npz")],
                          capture_output=True, text=True, cwd=tmp_path, env=env, timeout=300)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stdout[-3000:] + proc.stderr[-3000:]
    out = json.loads(lines[-1][len("RESULT "):])
    assert out["install"] == ["FINISHED"] and out["enabled"]
    assert out["operator_module"].startswith("bl_ext.user_default.curveskel")
    assert not out["source_tree_imported"]
    assert out["pref_spacing"] == pytest.approx(0.04)
    assert out["result"] == ["FINISHED"]
    assert out["objects"] == ["Capsule", "Capsule.silhouette", "Capsule.skeleton"]
    assert out["bones"] == out["edges"] and out["bones"] >= 1
    assert out["params"]["spacing"] == pytest.approx(0.08)      # the preference was the default
    assert out["scene_spacing"] == pytest.approx(0.08)
    assert out["disabled"]
    # installed under the temporary user folder, nowhere else
    assert list((tmp_path / "user").rglob("blender_manifest.toml"))
