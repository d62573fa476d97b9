"""The command line: a summary and JSON for a good file, one line and exit 2 for a bad one."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from meshes import capsule

ROOT = Path(__file__).resolve().parents[2]
CLI = ROOT / "scripts" / "skeletonize.py"


def run(*args):
    return subprocess.run([sys.executable, str(CLI), *map(str, args)], capture_output=True, text=True, timeout=300)


def write_obj(path, V, F):
    with open(path, "w") as fh:
        fh.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V)
        fh.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F)


@pytest.mark.parametrize("suffix", [".obj", ".off", ".ply", ".stl"])
def test_skeletonizes_every_supported_format_and_writes_json(tmp_path, suffix):
    import trimesh

    V, F = capsule(n_around=16, n_body=20)
    path = tmp_path / f"capsule{suffix}"
    trimesh.Trimesh(V, F, process=False).export(path)
    out = tmp_path / "o.json"
    r = run(path, "--json", out)
    assert r.returncode == 0, r.stderr
    for word in ("vertices", "component", "joints", "bones", "E0", "iterations", "time"):
        assert word in r.stdout
    d = json.loads(out.read_text())
    assert d["format"] == "curveskel-skeleton/1"
    n_in = len(V) if suffix != ".stl" else 3 * len(F)          # STL stores a vertex per corner
    assert len(d["mapping"]["bone"]) == n_in
    # E after every stage (the stages optimise different things: it need not fall each time);
    # the final one is the returned skeleton's
    assert d["energy"]["final"] == d["energy"]["history"][-1]
    assert len(d["energy"]["history"]) == len(d["meta"]["stages"])


def test_energy_line_says_what_the_fit_reached_and_what_the_skeleton_has(tmp_path):
    """The fit of E lowers E; the stages after it fit the radii to the silhouette, which E does
    not measure (a capsule: 0.046 after the fit, 62.8 returned). The summary line must not read
    as if the optimisation made E worse: E after the fit first, the returned skeleton's after."""
    from curveskel_addon.core import Skeleton

    V, F = capsule(n_around=16, n_body=20)
    path = tmp_path / "c.obj"
    write_obj(path, V, F)
    out = tmp_path / "o.json"
    r = run(path, "--json", out)
    assert r.returncode == 0, r.stderr
    s = Skeleton.load(str(out)).summary()
    stages = {st["stage"]: st["energy"] for st in json.loads(out.read_text())["meta"]["stages"]}
    assert s["E_fit"] == stages["fit"] and s["E"] == stages["polish"]
    line = next(ln for ln in r.stdout.splitlines() if ln.startswith("energy"))
    assert f"E {s['E_fit']:.6g} in" in line
    assert (f"E {s['E']:.6g} for the returned skeleton" in line) == (s["E"] != s["E_fit"])


def test_obj_vertex_order_is_kept(tmp_path):
    V, F = capsule(n_around=16, n_body=20)
    path = tmp_path / "c.obj"
    write_obj(path, V, F)
    out = tmp_path / "o.json"
    assert run(path, "--json", out, "--paper").returncode == 0
    d = json.loads(out.read_text())
    J, B = np.array(d["joints"]), np.array(d["bones"])
    b, t = np.array(d["mapping"]["bone"]), np.array(d["mapping"]["t"])
    sigma = t[:, None] * J[B[b, 0], :3] + (1 - t[:, None]) * J[B[b, 1], :3]
    # the skeleton point of input vertex k lies on the axis at about the height of vertex k
    assert np.abs(sigma[:, 2] - np.clip(V[:, 2], 0, 6)).max() < 1.2


@pytest.mark.parametrize("content, message", [
    (None, "no such mesh file"),
    ("", "no vertices"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no faces"),
    ("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", "NaN"),
])
def test_bad_files_give_one_line_and_exit_2(tmp_path, content, message):
    path = tmp_path / "bad.obj"
    if content is not None:
        path.write_text(content)
    r = run(path)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert r.stderr.startswith("error:") and message in r.stderr


def test_unsupported_suffix_and_help(tmp_path):
    p = tmp_path / "x.fbx"
    p.write_text("nothing")
    r = run(p)
    assert r.returncode == 2 and "unsupported mesh format" in r.stderr
    h = run("--help")
    assert h.returncode == 0
    for opt in ("--spacing", "--solver", "--max-iterations", "--tolerance", "--seed", "--paper", "--json"):
        assert opt in h.stdout


def test_help_explains_every_method_parameter():
    from dataclasses import fields

    from curveskel_addon.core import SkeletonParams

    from curveskel_addon.cli import skeletonize as cli
    names = {f.name for f in fields(SkeletonParams)}
    assert names <= set(cli._HELP), sorted(names - set(cli._HELP))
    h = run("--help").stdout
    assert "--smoothness SMOOTHNESS" in h and "smoothness of the curve" in h
    # the artist's four settings come first, in their own group; the rest under "advanced"
    art = h.index("skeleton settings")
    adv = h.index("advanced method parameters")
    assert art < adv
    for name in SkeletonParams.ARTIST:
        assert art < h.index("\n  --" + name.replace("_", "-"), art) < adv
    for name in names - set(SkeletonParams.ARTIST):
        assert h.index("\n  --" + name.replace("_", "-")) > adv


def test_subsampled_stages_are_said_on_the_console_and_in_meta(tmp_path):
    # above --max-fit-points the fit uses an area-weighted subset: the summary says so (issue 11:
    # nothing approximated silently); a run on all points prints no such line
    V, F = capsule(n_around=16, n_body=20)
    path = tmp_path / "capsule.obj"
    write_obj(path, V, F)
    out = tmp_path / "o.json"
    r = run(path, "--json", out, "--max-fit-points", 200)
    assert r.returncode == 0, r.stderr
    line = [x for x in r.stdout.splitlines() if x.startswith("sampled")]
    assert len(line) == 1 and "fit on 200 " in line[0] and f"of {len(V):,}" in line[0]
    meta = json.loads(out.read_text())["meta"]
    assert meta["fit_points_subset"] is True and meta["fit_points"] == 200
    assert meta["medial_points_subset"] is False and meta["medial_points"] == len(V)
    r = run(path, "--json", out)
    assert r.returncode == 0 and not any(x.startswith("sampled") for x in r.stdout.splitlines())
