"""Build the extension zip(s) (scipy wheels for Python 3.11 and 3.13), check that this Blender's
validator accepts every one, install this machine's platform zip with Blender's extension API into
a temporary user folder and run the operator from the installed copy (bl_ext.user_default.curveskel),
in a fresh process. Run by bpy 5.0.1 (.venv, Python 3.11) and bpy 5.2.3 (.venv313, Python 3.13)
through scripts/test.sh, and bpy 4.2 by run_blender_tests_42.sh.

Which zips: by default this machine's platform only (its two scipy wheels, about 75 MB, are
downloaded once into dist/wheel-cache/). All four platforms when CURVESKEL_ALL_PLATFORMS=1 is set
or when dist/wheel-cache/ already holds all eight wheels (the four-platform download is about
280 MB, too much for every fresh clone).
"""

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import textwrap
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest
from meshes import capsule
from curveskel_addon.core.params import SkeletonParams

ROOT = Path(__file__).resolve().parents[2]
PLATFORMS = {"windows-x64", "macos-x64", "macos-arm64", "linux-x64"}
PY_TAG = f"cp3{sys.version_info.minor}"          # cp311 or cp313: the wheels this Blender takes


def _pin(requirements: str, name: str) -> str:
    text = (ROOT / requirements).read_text()
    return re.search(rf"^{name}==(\S+)", text, re.M).group(1)


def _wheel_version(name: str) -> tuple[int, ...]:
    return tuple(int(x) for x in Path(name).name.split("-")[1].split("."))


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
    import scipy
    out["scipy"] = [scipy.__version__, scipy.__file__]
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


def _build_tools():
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import build_extension
    finally:
        sys.path.remove(str(ROOT / "scripts"))
    return build_extension


HERE = _build_tools().current_platform()


def platforms_to_build() -> list[str]:
    """This machine's platform, or all four when asked (CURVESKEL_ALL_PLATFORMS=1) or when their
    wheels are all in the cache already."""
    if os.environ.get("CURVESKEL_ALL_PLATFORMS") == "1" or _build_tools().cached_wheels():
        return sorted(PLATFORMS)
    assert HERE is not None, "this machine is none of Blender's four platforms"
    return [HERE]


def _zip_name(platform: str) -> str:
    from curveskel_addon import __version__

    return f"curveskel-{__version__}-{platform.replace('-', '_')}.zip"


@pytest.fixture(scope="module")
def built_zips():
    """The platform zips with wheels (:func:`platforms_to_build`), built (and validated) by
    this Blender's tool."""
    out = Path(tempfile.mkdtemp(prefix="curveskel-dist-"))
    platforms = platforms_to_build()
    try:
        proc = subprocess.run([sys.executable, str(ROOT / "scripts" / "build_extension.py"),
                               "--out-dir", str(out), "--build-dir", str(out / "stage"),
                               *(a for p in platforms for a in ("--platform", p))],
                              capture_output=True, text=True, cwd=ROOT)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        zips = {Path(line).name: Path(line) for line in proc.stdout.split()}
        assert sorted(zips) == sorted(_zip_name(p) for p in platforms)
        yield zips
    finally:
        shutil.rmtree(out, ignore_errors=True)


@pytest.fixture(scope="module")
def built_zip(built_zips):
    """This machine's zip (the one Blender installs here)."""
    return built_zips[_zip_name(HERE)]


def test_the_default_build_is_this_platforms_only(monkeypatch, tmp_path):
    """Without CURVESKEL_ALL_PLATFORMS and without the eight cached wheels, one platform is built
    (a fresh clone downloads two scipy wheels, not eight)."""
    tools = _build_tools()
    monkeypatch.delenv("CURVESKEL_ALL_PLATFORMS", raising=False)
    monkeypatch.setattr(tools, "ROOT", tmp_path)               # an empty wheel cache
    assert tools.cached_wheels() is False
    assert platforms_to_build() == [HERE]
    monkeypatch.setenv("CURVESKEL_ALL_PLATFORMS", "1")
    assert platforms_to_build() == sorted(PLATFORMS)


def _blender_ext() -> Path:
    import bpy

    return Path(bpy.utils.system_resource("SCRIPTS")) / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"


def test_manifest_fields():
    m = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    assert m["id"] == "curveskel" and m["type"] == "add-on"
    assert m["license"] == ["SPDX:GPL-3.0-or-later"]
    assert m["blender_version_min"] == "4.2.0"
    assert "blender_version_max" not in m        # none without a known incompatibility
    assert set(m["platforms"]) == PLATFORMS
    assert len(m["tagline"]) <= 64
    wheels = [Path(w).name for w in m["wheels"]]
    assert not any("numpy" in w or "trimesh" in w for w in wheels)
    cp311 = [w for w in wheels if "-cp311-cp311-" in w]
    cp313 = [w for w in wheels if "-cp313-cp313-" in w]
    assert len(cp311) == len(cp313) == 4 and len(wheels) == 8
    # the tests run on the scipy each Blender gets from the zip
    assert all(w.startswith(f"scipy-{_pin('requirements.txt', 'scipy')}-") for w in cp311)
    assert all(w.startswith(f"scipy-{_pin('requirements-313.txt', 'scipy')}-") for w in cp313)
    # Blender 4.2.0-4.2.12 ignore the Python tag and install the highest version: it must be cp311
    assert _wheel_version(cp311[0]) > _wheel_version(cp313[0])
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        from build_extension import wheel_platform
    finally:
        sys.path.remove(str(ROOT / "scripts"))
    assert {wheel_platform(w) for w in cp311} == {wheel_platform(w) for w in cp313} == PLATFORMS


def test_validator_accepts_every_zip_built(built_zips):
    tool = _blender_ext()
    assert tool.is_file(), tool
    for name, z in built_zips.items():
        proc = subprocess.run([sys.executable, str(tool), "validate", str(z)], capture_output=True, text=True)
        assert proc.returncode == 0 and "Success" in proc.stdout, (name, proc.stdout, proc.stderr)
        wheels = [n for n in zipfile.ZipFile(z).namelist() if n.endswith(".whl")]
        assert sorted(n.split("-")[2] for n in wheels) == ["cp311", "cp313"], (name, wheels)


def test_zip_layout(built_zip):
    names = zipfile.ZipFile(built_zip).namelist()
    assert "blender_manifest.toml" in names and "__init__.py" in names    # side by side at the top
    assert "core/pipeline.py" in names and "ops_generate.py" in names
    assert not any("__pycache__" in n or n.endswith(".pyc") for n in names)


def test_no_wheels_build_stages_a_manifest_without_wheels(tmp_path):
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        from build_extension import stage
    finally:
        sys.path.remove(str(ROOT / "scripts"))
    staged = stage(tmp_path / "stage", None, with_wheels=False)
    m = tomllib.loads((staged / "blender_manifest.toml").read_text())
    assert "wheels" not in m and (staged / "__init__.py").is_file()


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
    assert out["pref_spacing"] == pytest.approx(SkeletonParams().spacing)
    assert out["result"] == ["FINISHED"]
    assert out["objects"] == ["Capsule", "Capsule.silhouette", "Capsule.skeleton"]
    assert out["bones"] == out["edges"] and out["bones"] >= 1
    assert out["params"]["spacing"] == pytest.approx(0.08)      # the preference was the default
    assert out["scene_spacing"] == pytest.approx(0.08)
    assert out["disabled"]
    # installed under the temporary user folder, nowhere else
    assert list((tmp_path / "user").rglob("blender_manifest.toml"))
    # Blender took the scipy wheel for its own Python (one, of the version the manifest pins for it)
    infos = list((tmp_path / "user").rglob("scipy-*.dist-info"))
    m = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    wanted = [Path(w).name for w in m["wheels"]
              if f"-{PY_TAG}-" in w and _build_tools().wheel_platform(w) == HERE]
    assert len(infos) == 1 and len(wanted) == 1, (infos, wanted)
    assert infos[0].name == "-".join(wanted[0].split("-")[:2]) + ".dist-info"
    assert f"Tag: {PY_TAG}-{PY_TAG}-" in (infos[0] / "WHEEL").read_text()
    # ... and it loads in this Python with this Blender's numpy
    site = infos[0].parent
    probe = subprocess.run([sys.executable, "-c", "import sys; sys.path.insert(0, sys.argv[1]); "
                            "import numpy, scipy, scipy.sparse.csgraph, scipy.sparse.linalg, scipy.spatial; "
                            "print(scipy.__file__)",
                            str(site)], capture_output=True, text=True, env=env, timeout=120)
    assert probe.returncode == 0 and probe.stdout.startswith(str(site)), probe.stdout + probe.stderr
