"""Issue 32: curveskel as a Python package. The wheel is built from a copy of the package's
files (nothing written into the work tree) without network access (--no-build-isolation: the
pinned setuptools of requirements-dev.txt / -313.txt), installed with --no-deps into a fresh venv
that sees this environment's numpy, SciPy and trimesh through a .pth file, and its ``curveskel``
command is run on a small mesh against scripts/skeletonize.py."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
import zipfile
from pathlib import Path

import pytest

from cli_support import run_cli, write_capsule_obj

ROOT = Path(__file__).resolve().parents[2]


def _env():
    """This environment without PYTHONPATH (nothing of the source tree leaks in)."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy2(ROOT / name, src / name)
    shutil.copytree(ROOT / "curveskel_addon", src / "curveskel_addon",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                        "--disable-pip-version-check", "-w", str(tmp / "dist"), str(src)],
                       capture_output=True, text=True, env=_env(), timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    (whl,) = (tmp / "dist").glob("curveskel-*.whl")
    return whl


@pytest.fixture(scope="module")
def venv(wheel, tmp_path_factory):
    """A fresh venv with the wheel installed (no dependencies fetched: numpy, SciPy and trimesh
    come from this environment's site-packages, added after the venv's own by a .pth file)."""
    v = tmp_path_factory.mktemp("venv") / "v"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(v)], check=True, timeout=120)
    py = v / "bin" / "python"
    site = Path(subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    (site / "zz_shared_site.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    r = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps",
                        "--no-index", "--disable-pip-version-check", str(wheel)],
                       capture_output=True, text=True, env=_env(), timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return v


def test_the_wheel_holds_the_package_and_its_command_only(wheel):
    from curveskel_addon import __version__

    names = zipfile.ZipFile(wheel).namelist()
    assert wheel.name == f"curveskel-{__version__}-py3-none-any.whl"
    top = {n.split("/")[0] for n in names}
    assert top == {"curveskel_addon", f"curveskel-{__version__}.dist-info"}, top
    assert not any(n.startswith(("tests/", "scripts/")) or "__pycache__" in n for n in names)
    for module in ("core/pipeline.py", "core/geometry/inside.py", "core/objective/terms.py",
                   "mesh_files.py", "run_summary.py", "measure/__init__.py", "measure/quality.py",
                   "rig/__init__.py", "rig/rig_layout.py", "cli/__init__.py", "cli/skeletonize.py",
                   "cli/outputs.py", "ops_generate.py"):
        assert f"curveskel_addon/{module}" in names
    z = zipfile.ZipFile(wheel)
    entry = z.read(f"curveskel-{__version__}.dist-info/entry_points.txt").decode()
    assert "curveskel = curveskel_addon.cli:run" in entry
    meta = z.read(f"curveskel-{__version__}.dist-info/METADATA").decode()
    assert "License-Expression: GPL-3.0-or-later" in meta
    assert "Provides-Extra: blender" in meta and "Provides-Extra: batch" in meta
    for req in ("numpy>=1.26.4", "scipy>=1.15.2", "trimesh>=4.5.3", 'bpy==5.0.1; python_version == "3.11" and extra == "blender"',
                'dask==2025.9.1; extra == "batch"', 'distributed==2025.9.1; extra == "batch"',
                'tqdm==4.67.1; extra == "batch"'):
        assert f"Requires-Dist: {req}" in meta, req


def test_the_installed_command_gives_the_scripts_skeleton(venv, tmp_path):
    from curveskel_addon import __version__

    exe = venv / "bin" / "curveskel"
    r = subprocess.run([str(exe), "--version"], capture_output=True, text=True, cwd=tmp_path,
                       env=_env(), timeout=120)
    assert r.returncode == 0 and r.stdout == f"curveskel {__version__}\n", r.stderr
    mesh = write_capsule_obj(tmp_path / "capsule.obj")
    a, b = tmp_path / "installed.json", tmp_path / "script.json"
    r = subprocess.run([str(exe), "skeletonize", str(mesh), "--json", str(a)], capture_output=True,
                       text=True, cwd=tmp_path, env=_env(), timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"mesh        {mesh}: ") and f"wrote       {a}" in r.stdout
    s = run_cli(mesh, "--json", b)
    assert s.returncode == 0, s.stderr
    da, db = json.loads(a.read_text()), json.loads(b.read_text())
    for key in ("format", "joints", "bones", "mapping"):
        assert da[key] == db[key], key
    assert da["meta"]["params"] == db["meta"]["params"]


def test_the_installed_package_is_the_venvs_and_imports_no_blender(venv, tmp_path):
    code = ("import sys, curveskel_addon, curveskel_addon.core, curveskel_addon.cli.skeletonize, "
            "curveskel_addon.measure.quality, curveskel_addon.rig.skin_weights; "
            "print(curveskel_addon.__file__); print('bpy' in sys.modules)")
    r = subprocess.run([str(venv / "bin" / "python"), "-c", code], capture_output=True, text=True,
                       cwd=tmp_path, env=_env(), timeout=120)
    assert r.returncode == 0, r.stderr
    where, bpy_loaded = r.stdout.split()
    assert Path(where).is_relative_to(venv) and bpy_loaded == "False"


def test_pyproject_extras_are_pinned_for_both_pythons():
    p = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert p["scripts"] == {"curveskel": "curveskel_addon.cli:run"}
    blender = p["optional-dependencies"]["blender"]
    dev = (ROOT / "requirements-dev.txt").read_text()
    py313 = (ROOT / "requirements-313.txt").read_text()
    assert "bpy==5.0.1; python_version == '3.11'" in blender and "bpy==5.0.1" in dev
    assert "bpy==5.2.3; python_version == '3.13'" in blender and "bpy==5.2.3" in py313
    assert all("==" in req for req in p["optional-dependencies"]["batch"])
