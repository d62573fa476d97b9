#!/usr/bin/env python3
"""Build the CurveSkel Blender extension zip(s) into dist/.

    python scripts/build_extension.py                  # scipy wheels for 4 platforms, one zip each
    python scripts/build_extension.py --no-wheels      # one zip without wheels (tests, CI)
    python scripts/build_extension.py --platform linux-x64

Steps: stage curveskel_addon/ with blender_manifest.toml beside its __init__.py (build/extension/),
download the scipy wheels the manifest lists (pip download, cached in dist/wheel-cache/) into
the staged ./wheels, then validate and build with Blender's own extension tool (blender_ext.py,
shipped in the bpy wheel). Exit status 0 on success; the zips are printed one per line.

The manifest lists wheels for Python 3.11 (Blender 4.2 - 5.0) and 3.13 (Blender 5.1+); each zip
holds both for its platform and Blender installs the ones matching its Python. The platform and
Python of a wheel are read from its file name, so any Python the bpy in use runs on can build.
"""

from __future__ import annotations

import argparse
import importlib.util
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "curveskel_addon"
MANIFEST = ROOT / "blender_manifest.toml"
PLATFORMS = ("windows-x64", "macos-x64", "macos-arm64", "linux-x64")


def wheel_tags(name: str) -> tuple[str, str, list[str]]:
    """(python tag, abi tag, platform tags) of a wheel file name, e.g. ('cp313', 'cp313',
    ['manylinux_2_17_x86_64', 'manylinux2014_x86_64'])."""
    parts = Path(name).name.removesuffix(".whl").split("-")
    if len(parts) not in (5, 6):
        sys.exit(f"error: not a wheel file name: {name}")
    return parts[-3], parts[-2], parts[-1].split(".")


def wheel_platform(name: str) -> str:
    """The Blender platform a wheel is for (the way Blender matches them: OS and architecture)."""
    plat = wheel_tags(name)[2][0]
    if plat == "win_amd64":
        return "windows-x64"
    if plat.startswith("macosx_") and plat.endswith("_x86_64"):
        return "macos-x64"
    if plat.startswith("macosx_") and plat.endswith("_arm64"):
        return "macos-arm64"
    if plat.startswith("manylinux") and plat.endswith("_x86_64"):
        return "linux-x64"
    sys.exit(f"error: wheel {name} is for none of the platforms {PLATFORMS}")


def current_platform() -> str | None:
    """The Blender platform of this machine ("linux-x64", ...), None for one Blender has no
    build for."""
    import platform

    machine = platform.machine().lower()
    if sys.platform.startswith("linux") and machine in ("x86_64", "amd64"):
        return "linux-x64"
    if sys.platform == "darwin":
        return {"x86_64": "macos-x64", "arm64": "macos-arm64"}.get(machine)
    if sys.platform == "win32" and machine in ("amd64", "x86_64"):
        return "windows-x64"
    return None


def cached_wheels(platforms=PLATFORMS) -> bool:
    """Whether every wheel the manifest lists for ``platforms`` is in dist/wheel-cache/ (then
    a build for them downloads nothing)."""
    manifest = tomllib.loads(MANIFEST.read_text())
    names = [Path(w).name for w in manifest.get("wheels", [])]
    return all((ROOT / "dist" / "wheel-cache" / wheel_platform(n) / n).is_file()
               for n in names if wheel_platform(n) in platforms)


def wheel_python(name: str) -> str:
    """'3.13' for a cp313 wheel."""
    tag = wheel_tags(name)[0]
    if not re.fullmatch(r"cp3\d+", tag):
        sys.exit(f"error: wheel {name}: expected a CPython tag like cp311, found {tag}")
    return f"3.{tag[3:]}"


def blender_ext() -> Path:
    """Path of blender_ext.py inside the installed bpy wheel (without importing bpy)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        sys.exit("error: bpy is not installed in this Python (pip install bpy==5.0.1)")
    base = Path(list(spec.submodule_search_locations)[0])
    found = sorted(base.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not found:
        sys.exit(f"error: blender_ext.py not found under {base}")
    return found[-1]


def stage(build_dir: Path, platforms: list[str] | None, with_wheels: bool) -> Path:
    """Copy the add-on and the manifest (edited for the chosen platforms/wheels) to build_dir."""
    if build_dir.exists():
        shutil.rmtree(build_dir)
    shutil.copytree(PACKAGE, build_dir, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    text = MANIFEST.read_text()
    manifest = tomllib.loads(text)
    if platforms:
        unknown = sorted(set(platforms) - set(manifest["platforms"]))
        if unknown:
            sys.exit(f"error: unknown platform(s) {unknown}; the manifest has {manifest['platforms']}")
        text = re.sub(r"^platforms = \[.*?\]", "platforms = [" + ", ".join(f'"{p}"' for p in platforms) + "]",
                      text, count=1, flags=re.M | re.S)
    chosen = platforms or manifest["platforms"]
    wheels = [w for w in manifest.get("wheels", []) if wheel_platform(w) in chosen] if with_wheels else []
    block = "wheels = [\n" + "".join(f'  "{w}",\n' for w in wheels) + "]" if wheels else ""
    text = re.sub(r"^wheels = \[.*?\]\n?", block + ("\n" if block else ""), text, count=1, flags=re.M | re.S)
    (build_dir / "blender_manifest.toml").write_text(text)
    tomllib.loads(text)  # still valid TOML
    if wheels:
        fetch_wheels(wheels, chosen, build_dir / "wheels")
    return build_dir


def fetch_wheels(wheels: list[str], platforms: list[str], dest: Path) -> None:
    """pip download each listed wheel once (cache: dist/wheel-cache/<platform>/), for the Python
    and platform its file name names, and copy it to ``dest``."""
    dest.mkdir(parents=True, exist_ok=True)
    for name in (Path(w).name for w in wheels):
        p = wheel_platform(name)
        if p not in platforms:
            continue
        cache = ROOT / "dist" / "wheel-cache" / p
        if not (cache / name).is_file():
            dist, version = name.split("-")[:2]
            _py_tag, abi_tag, plat_tags = wheel_tags(name)
            cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--disable-pip-version-check",
                   "--only-binary=:all:", "--no-deps", "--implementation", "cp",
                   "--python-version", wheel_python(name), "--abi", abi_tag,
                   *(a for t in plat_tags for a in ("--platform", t)),
                   f"{dist}=={version}", "-d", str(cache)]
            print("downloading", name, file=sys.stderr)
            subprocess.run(cmd, check=True)
        if not (cache / name).is_file():
            found = sorted(x.name for x in cache.glob("*.whl"))
            sys.exit(f"error: pip did not fetch {name} (found: {found})")
        shutil.copy2(cache / name, dest / name)


def run_tool(*args: str) -> str:
    out = subprocess.run([sys.executable, str(blender_ext()), *args], capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"error: blender_ext.py {args[0]} failed:\n{out.stdout}{out.stderr}")
    return out.stdout


def build(out_dir: Path, *, with_wheels: bool = True, platforms: list[str] | None = None,
          split: bool | None = None, build_dir: Path | None = None) -> list[Path]:
    """Stage, validate and build; returns the zip files written to ``out_dir``."""
    build_dir = build_dir or ROOT / "build" / "extension"
    staged = stage(build_dir, platforms, with_wheels)
    run_tool("validate", str(staged))
    out_dir.mkdir(parents=True, exist_ok=True)
    split = with_wheels if split is None else split
    before = {p: p.stat().st_mtime for p in out_dir.glob("curveskel-*.zip")}
    args = ["build", "--source-dir", str(staged), "--output-dir", str(out_dir)]
    if split:
        args.append("--split-platforms")
    run_tool(*args)
    zips = sorted(p for p in out_dir.glob("curveskel-*.zip") if before.get(p) != p.stat().st_mtime)
    for z in zips:
        run_tool("validate", str(z))
    return zips


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--no-wheels", action="store_true",
                    help="bundle no wheels (the installed add-on uses the scipy of Blender's Python)")
    ap.add_argument("--platform", action="append", choices=PLATFORMS,
                    help="build for this platform only (repeatable; default: all in the manifest)")
    ap.add_argument("--no-split", action="store_true", help="one zip for all platforms")
    ap.add_argument("--out-dir", type=Path, default=ROOT / "dist")
    ap.add_argument("--build-dir", type=Path, default=None, help="staging folder (default build/extension)")
    a = ap.parse_args(argv)
    zips = build(a.out_dir.resolve(), with_wheels=not a.no_wheels, platforms=a.platform,
                 split=False if a.no_split else None, build_dir=a.build_dir)
    for z in zips:
        print(z)
    return 0


if __name__ == "__main__":
    sys.exit(main())
