"""The command line's --evaluate, --refine, --compare and --report (issue 33) on a small capsule:
the report printed and written, the refined skeleton written, the better of two named, one line
and exit 2 for a bad skeleton file."""

from __future__ import annotations

import json

import pytest

from cli_support import run_cli, write_capsule_obj
from meshes import capsule

@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli_eval")
    mesh = write_capsule_obj(d / "capsule.obj")
    V, _ = capsule(n_around=12, n_body=12)
    lo, hi = V.min(0), V.max(0)
    c = (lo + hi) / 2
    axis = int((hi - lo).argmax())
    ends = []
    for t in (0.15, 0.5, 0.85):
        p = c.copy()
        p[axis] = lo[axis] + t * (hi[axis] - lo[axis])
        ends.append(p.tolist())
    good = {"joints": ends, "bones": [[0, 1], [1, 2]]}
    off = [list(p) for p in ends]
    side = (axis + 1) % 3
    half = (hi[side] - lo[side]) / 2
    off[0][side] += 0.6 * half
    off[2][side] -= 0.6 * half
    bad = {"joints": off, "bones": [[0, 1], [1, 2]]}
    (d / "good.json").write_text(json.dumps(good))
    (d / "off.json").write_text(json.dumps(bad))
    (d / "broken.json").write_text(json.dumps({"joints": ends, "bones": [[0, 1], [1, 7]]}))
    return d, mesh


def test_evaluate_prints_and_writes_the_report(files):
    d, mesh = files
    out = d / "report.json"
    r = run_cli(mesh, "--evaluate", d / "good.json", "--report", out, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "J " in r.stdout and "inside" in r.stdout
    rep = json.loads(out.read_text())
    for key in ("J", "terms", "E", "inside_fraction", "recon_mean", "per_bone"):
        assert key in rep
    assert rep["inside_fraction"] == 1.0
    assert len(rep["vertex_residual"]) == len(capsule(n_around=12, n_body=12)[0])


def test_refine_writes_a_skeleton_with_lower_J(files):
    d, mesh = files
    out, rep = d / "refined.json", d / "refine_report.json"
    r = run_cli(mesh, "--refine", d / "off.json", "--json", out, "--report", rep, timeout=300)
    assert r.returncode == 0, r.stderr
    doc = json.loads(rep.read_text())
    assert doc["after"]["J"] < doc["before"]["J"]
    assert doc["after"]["inside_fraction"] >= doc["before"]["inside_fraction"]
    sk = json.loads(out.read_text())
    assert sk["format"] == "curveskel-skeleton/1"
    assert [list(b) for b in sk["bones"]] == [[0, 1], [1, 2]]


def test_compare_names_the_better_skeleton(files):
    d, mesh = files
    rep = d / "compare.json"
    r = run_cli(mesh, "--compare", d / "off.json", d / "good.json", "--report", rep, timeout=300)
    assert r.returncode == 0, r.stderr
    doc = json.loads(rep.read_text())
    assert doc["best"] == str(d / "good.json")
    assert doc["reports"][1]["J"] < doc["reports"][0]["J"]
    assert "good.json" in r.stdout


def test_a_bone_index_out_of_range_is_one_line(files):
    d, mesh = files
    r = run_cli(mesh, "--evaluate", d / "broken.json", timeout=300)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "7" in lines[0], r.stderr


def test_report_alone_is_refused(files):
    d, mesh = files
    r = run_cli(mesh, "--report", d / "x.json", timeout=300)
    assert r.returncode == 2 and "--report goes with" in r.stderr
    assert not (d / "x.json").exists()
