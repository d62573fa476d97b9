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
    for word in ("vertices", "component", "joints", "bones", "J ", "stages", "E ", "time"):
        assert word in r.stdout
    d = json.loads(out.read_text())
    assert d["format"] == "curveskel-skeleton/1"
    n_in = len(V) if suffix != ".stl" else 3 * len(F)          # STL stores a vertex per corner
    assert len(d["mapping"]["bone"]) == n_in
    # the paper's E after every logged stage of the search (J is what falls, not E); the final
    # one is the returned skeleton's
    assert d["energy"]["final"] == d["energy"]["history"][-1]
    assert len(d["energy"]["history"]) == len(d["meta"]["stages"])


def _terms(line):
    """{name: (weight, value)} of the summary's ``terms`` line."""
    out = {}
    for part in line.split(" = ", 1)[1].split(" + "):
        name, rest = part.split(" ", 1)
        weight, value = rest.split(" x ") if " x " in rest else ("1", rest)
        out[name] = (float(weight), float(value))
    return out


def test_the_summary_prints_J_and_its_terms(tmp_path):
    """Issue 30: the CLI prints J and its terms. J of the first stage -> the returned skeleton's
    (the lowest logged), every term of J with its weight, and they add up to J."""
    V, F = capsule(n_around=16, n_body=20)
    path = tmp_path / "c.obj"
    write_obj(path, V, F)
    out = tmp_path / "o.json"
    r = run(path, "--json", out)
    assert r.returncode == 0, r.stderr
    meta = json.loads(out.read_text())["meta"]
    stages = meta["stages"]
    assert meta["J"] == min(st["J"] for st in stages) == stages[-1]["J"]
    lines = {ln.split(None, 1)[0]: ln.split(None, 1)[1] for ln in r.stdout.splitlines() if ln.strip()}
    assert lines["objective"].startswith(f"J {stages[0]['J']:.6g} -> {meta['J']:.6g} in "
                                         f"{len(stages)} stages")
    terms = _terms(lines["terms"])
    assert lines["terms"].startswith(f"J {meta['J']:.6g} = ")
    assert set(terms) == set(meta["terms"]) - {"E"}
    for name, (_, value) in terms.items():
        assert value == pytest.approx(meta["terms"][name], rel=1e-3, abs=1e-300)
    assert terms["joints"][1] == len(json.loads(out.read_text())["joints"])
    assert sum(w * v for w, v in terms.values()) == pytest.approx(meta["J"], rel=1e-3)
    # the paper's E of the first and the last stage
    assert lines["energy"].startswith(f"E {stages[0]['terms']['E']:.6g} -> "
                                      f"{stages[-1]['terms']['E']:.6g} ")


def test_the_paper_solver_prints_E_and_its_iterations(tmp_path):
    V, F = capsule(n_around=16, n_body=20)
    path = tmp_path / "c.obj"
    write_obj(path, V, F)
    out = tmp_path / "o.json"
    r = run(path, "--json", out, "--paper")
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    line = next(ln for ln in r.stdout.splitlines() if ln.startswith("objective"))
    fit = [st for st in d["meta"]["stages"] if st["stage"] == "fit"]
    assert f"E {d['energy']['initial']:.6g} -> {d['energy']['final']:.6g} in " \
           f"{fit[-1]['iterations']} iterations" in line and "solver paper" in line
    assert not any(ln.startswith("terms") for ln in r.stdout.splitlines())     # J is E there


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


def test_the_summary_says_how_many_surface_samples_J_is_measured_on(tmp_path):
    # J integrates over surface samples, not the vertices (issue 11: nothing approximated
    # silently): the summary says how many, as meta does
    V, F = capsule(n_around=16, n_body=20)
    path = tmp_path / "capsule.obj"
    write_obj(path, V, F)
    out = tmp_path / "o.json"
    r = run(path, "--json", out)
    assert r.returncode == 0, r.stderr
    n = json.loads(out.read_text())["meta"]["samples"]
    line = next(ln for ln in r.stdout.splitlines() if ln.startswith("objective"))
    assert n > 0 and f"over {n:,} surface samples" in line
