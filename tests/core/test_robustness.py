"""Issue 12, input side: the right skeleton or a clear refusal on every awkward input, and no
file ever lost. One table per kind of input, each row asserting the wanted outcome; the meshes
are made here. (The Blender operator and the Blender outputs of the command line:
tests/blender/test_robustness_blender.py; the method's own invariances are tested elsewhere.)
"""

from __future__ import annotations

import json
import os
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest

from cli_support import run_cli as _run_cli, write_capsule_obj
from meshes import capsule

from curveskel_addon.core import CurveSkelError, SkeletonParams, skeletonize
from curveskel_addon.core.config import CONFIG
from curveskel_addon.core.mesh_input import clean_mesh
from curveskel_addon.core.params import RULES
from curveskel_addon.mesh_files import _OBJ_ZERO_INDEX, read_mesh

MERGE_TOLERANCE = CONFIG.input.merge_tolerance

ROOT = Path(__file__).resolve().parents[2]
CLI = ROOT / "scripts" / "skeletonize.py"

CAPSULE = capsule(n_around=16, n_body=20)          # z from -1 to 7, radius 1, outward
TET_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


@pytest.fixture(scope="module")
def reference():
    """The capsule's skeleton, the answer the repairable rows must give."""
    V, F = CAPSULE
    return skeletonize(V, F)


def _strict(V, F, **kw):
    """skeletonize with every warning an error (no RuntimeWarning, no NaN on the way)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with np.errstate(all="raise"):
            return skeletonize(V, F, **kw)


def _in_box(sk, V, slack=1e-9):
    lo, hi = V.min(axis=0), V.max(axis=0)
    d = np.linalg.norm(hi - lo) * slack
    J = sk.joints[:, :3]
    return bool(np.all((J >= lo - d) & (J <= hi + d)))


# -- repairable meshes give the skeleton of the clean mesh -----------------------------------------
def _inverted():
    V, F = CAPSULE
    return V, F[:, ::-1].copy()


def _partly_inverted():
    V, F = CAPSULE
    F = F.copy()
    F[::3] = F[::3, ::-1]
    return V, F


def _sliver_new_vertex():
    """A zero-area face on an edge's midpoint (a T-junction sliver)."""
    V, F = CAPSULE
    a, b = F[0, 0], F[0, 1]
    return np.vstack([V, (V[a] + V[b]) / 2]), np.vstack([F, [[a, b, len(V)]]])


def _sliver_near_duplicate():
    """A needle face to a copy of a vertex moved by 1e-9 of the size."""
    V, F = CAPSULE
    a, b = F[5, 0], F[5, 1]
    return np.vstack([V, V[a] + 1e-9]), np.vstack([F, [[a, b, len(V)]]])


def _repeated_faces():
    V, F = CAPSULE
    return V, np.vstack([F, F[:40], F[40:60, ::-1]])


def _debris(k, seed=0):
    """The capsule and k specks (tetrahedra 1 % of its radius) scattered around it."""
    V, F = CAPSULE
    rng = np.random.default_rng(seed)
    centres = rng.uniform([-3, -3, -2], [3, 3, 8], (k, 3))
    sV = (TET_V[None] * 0.01 + centres[:, None]).reshape(-1, 3)
    sF = (TET_F[None] + len(V) + 4 * np.arange(k)[:, None, None]).reshape(-1, 3)
    return np.vstack([V, sV]), np.vstack([F, sF])


SAME_AS_CLEAN = {
    "inverted normals": (_inverted, {"flipped_faces": len(CAPSULE[1]), "reoriented_components": 1}),
    "every third face inverted": (_partly_inverted, {"flipped_faces": len(CAPSULE[1][::3])}),
    "zero-area sliver on an edge": (_sliver_new_vertex, {"degenerate_faces_dropped": 1,
                                                         "isolated_vertices": 1}),
    "needle to a near-duplicate vertex": (_sliver_near_duplicate, {"merged_duplicates": 1,
                                                                   "degenerate_faces_dropped": 1}),
    "repeated faces, both windings": (_repeated_faces, {"degenerate_faces_dropped": 60}),
    "scan debris: 1000 specks": (lambda: _debris(1000), {"small_components_dropped": 1000,
                                                         "small_components_vertices": 4000}),
}


@pytest.mark.parametrize("name", list(SAME_AS_CLEAN))
def test_repairable_mesh_gives_the_clean_meshes_skeleton(name, reference):
    make, expected_info = SAME_AS_CLEAN[name]
    V, F = make()
    V0, F0 = V.copy(), F.copy()
    sk = _strict(V, F)
    np.testing.assert_array_equal(V, V0)                   # the caller's arrays are not touched
    np.testing.assert_array_equal(F, F0)
    info = sk.meta["input"]
    for key, value in expected_info.items():
        assert info[key] == value, (key, info)
    np.testing.assert_allclose(sk.joints, reference.joints, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(sk.bones, reference.bones)
    assert len(sk.bone) == len(V) and np.all(np.isfinite(sk.t))
    # vertices left out (isolated, debris) follow the nearest kept vertex: on a bone, finite
    n = len(CAPSULE[0])
    np.testing.assert_array_equal(sk.bone[:n], reference.bone)
    assert np.all((sk.bone >= 0) & (sk.bone < sk.n_bones))


def test_scan_debris_is_kept_when_asked_and_the_share_is_reported():
    V, F = _debris(20)
    kept = clean_mesh(V, F)                                # clean_mesh alone keeps every part
    assert kept.components[0] == 21 and "small_components_dropped" not in kept.info
    dropped = clean_mesh(V, F, min_component_area=0.01)
    assert dropped.components[0] == 1
    assert 0 < dropped.info["small_components_area_share"] < 0.001
    assert (dropped.work_index[len(CAPSULE[0]):] == -1).all()
    # the option through the API: 0 keeps every part (each speck gets its own little tree)
    sk = skeletonize(V, F, min_component_area=0)
    assert sk.meta["components"] == 21 and "small_components_dropped" not in sk.meta["input"]


def test_the_largest_part_is_kept_whatever_the_share():
    V, F = _debris(3)
    m = clean_mesh(V, F, min_component_area=0.99)
    assert m.components[0] == 1 and len(m.V) == len(CAPSULE[0])


def test_triangle_soup_with_jitter_is_welded_and_the_merge_reported(reference):
    V, F = CAPSULE
    rng = np.random.default_rng(1)
    soup = V[F.ravel()] + rng.uniform(-1e-7, 1e-7, (3 * len(F), 3))
    sF = np.arange(len(soup)).reshape(-1, 3)
    sk = _strict(soup, sF)
    info = sk.meta["input"]
    assert info["merged_duplicates"] == info["merged_within_tolerance"] == len(soup) - len(V)
    assert info["merge_tolerance"] == pytest.approx(MERGE_TOLERANCE * np.linalg.norm(np.ptp(soup, 0)))
    assert sk.meta["components"] == 1
    assert abs(sk.n_joints - reference.n_joints) <= 2
    assert np.abs(sk.joints[:, :2]).max() < 0.05            # on the axis
    assert _in_box(sk, soup)


@pytest.mark.parametrize("scale, shift", [(1.0, 0.0), (1e-9, 0.0), (1e9, 0.0), (1.0, 1e6), (1e-3, -5e3)])
def test_the_input_stage_is_the_same_at_every_scale_and_position(scale, shift):
    """Tolerances are relative to the size: the same repairs whatever the units and position."""
    V, F = CAPSULE
    rng = np.random.default_rng(2)
    soup = V[F.ravel()] + rng.uniform(-1e-7, 1e-7, (3 * len(F), 3))
    soup = np.vstack([soup, (V[F[0, 0]] + V[F[0, 1]]) / 2])
    sF = np.vstack([np.arange(3 * len(F)).reshape(-1, 3)[:, ::-1],          # inverted, too
                    [[3 * 0, 3 * 0 + 1, len(soup) - 1]]])                     # and a sliver
    m = clean_mesh(soup * scale + shift, sF, min_component_area=0.01)
    assert len(m.V) == len(V) and len(m.F) == len(F)
    assert m.info["merged_duplicates"] == 3 * len(F) - len(V)
    assert m.info["isolated_vertices"] == 1                 # the sliver's own vertex
    assert m.info["flipped_faces"] == len(F) and m.info["degenerate_faces_dropped"] == 1


# -- inputs with no volume: a skeleton inside the box, or a clear refusal --------------------------
def _hemisphere():
    V, F = CAPSULE
    return V, F[V[F][:, :, 2].max(axis=1) <= 1e-9]         # the bottom cap alone: an open bowl


NO_VOLUME = {
    "flat square": (np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]), [[0, 1, 2], [0, 2, 3]],
                    "flat"),
    "two separate triangles": (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5], [6, 5, 5], [5, 6, 6]]),
                               [[0, 1, 2], [3, 4, 5]], "flat"),
    "two triangles folded (a tent)": (np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 1], [0, 1, 0]]),
                                      [[0, 1, 2], [0, 2, 3]], "encloses a volume"),
    "a tilted flat disc": (None, None, "flat"),
    "an unwelded soup (corners not shared)": (np.arange(36.0).reshape(12, 3) ** 1.5 % 7,
                                              np.arange(12).reshape(4, 3), "flat .*triangle soup"),
}


@pytest.mark.parametrize("name", list(NO_VOLUME))
def test_a_surface_with_no_volume_is_refused_with_the_reason(name):
    V, F, message = NO_VOLUME[name]
    if V is None:                                          # a disc in a tilted plane, far away
        ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        P = np.c_[np.cos(ang), np.sin(ang), np.zeros(24)]
        R = np.linalg.qr(np.random.default_rng(3).normal(size=(3, 3)))[0]
        V = np.vstack([[0, 0, 0], P]) @ R.T + 1e4
        F = np.c_[np.zeros(24, int), 1 + np.arange(24), 1 + (np.arange(24) + 1) % 24]
    with pytest.raises(CurveSkelError, match=message):
        skeletonize(V, F)


OPEN = {
    "an open hemisphere (a bowl)": (_hemisphere, 1),
    "a capsule open at both ends (a tube)": (lambda: (CAPSULE[0], CAPSULE[1][CAPSULE[1].max(axis=1)
                                                                              < len(CAPSULE[0]) - 2]), 2),
    "half a capsule": (lambda: (CAPSULE[0], CAPSULE[1][CAPSULE[0][CAPSULE[1]][:, :, 2].max(axis=1) <= 3]), 1),
}


@pytest.mark.parametrize("name", list(OPEN))
def test_an_open_surface_is_capped_and_gets_a_skeleton_inside_its_box(name):
    make, holes = OPEN[name]
    V, F = make()
    sk = _strict(V, F)
    used = V[np.unique(F)]
    assert sk.meta["input"]["holes_capped"] == holes
    assert sk.n_joints >= 1 and np.all(np.isfinite(sk.joints)) and np.all(np.isfinite(sk.t))
    assert _in_box(sk, used)
    assert len(sk.bone) == len(V)


def test_flat_parts_beside_a_solid_are_left_out_and_reported(reference):
    V, F = CAPSULE
    sq = np.array([[3.0, 3, 0], [4, 3, 0], [4, 4, 0], [3, 4, 0]])
    V2 = np.vstack([V, sq])
    F2 = np.vstack([F, len(V) + np.array([[0, 1, 2], [0, 2, 3]])])
    sk = _strict(V2, F2)
    assert sk.meta["input"]["flat_components_dropped"] == 1
    np.testing.assert_allclose(sk.joints, reference.joints, atol=1e-9)


# -- parameters: one place, one rule per field, the parameter named --------------------------------
def _field_names():
    from dataclasses import fields

    return [f.name for f in fields(SkeletonParams)]


def _bad_values(name):
    """Values the rule of ``name`` must refuse, made from the rule table itself (so a field
    added later is covered as soon as it has a rule)."""
    kind, low, high = RULES[name]
    if kind == "choice":
        return ["no-such-" + name, 3]
    if kind == "bool":
        return ["yes", 2]
    out = [float("nan"), float("inf"), "0.1", None, True]
    if kind == "int":
        out.append(2.5)
    for bound, below in ((low, True), (high, False)):
        if bound is not None:
            b = bound[0] if isinstance(bound, tuple) else bound
            step = 0 if isinstance(bound, tuple) else (1 if kind == "int" else 1e-3)
            out.append(b - step if below else b + step)
    return out


GENERATED = [(name, v) for name in RULES for v in _bad_values(name) if name in _field_names()]


@pytest.mark.parametrize("name, value", GENERATED, ids=[f"{n}={v!r}" for n, v in GENERATED])
def test_every_rule_refuses_its_bad_values_naming_the_parameter(name, value):
    with pytest.raises(CurveSkelError, match=name):
        SkeletonParams(**{name: value})
    with pytest.raises(CurveSkelError, match=name):
        SkeletonParams.from_dict({name: value})
    with pytest.raises(CurveSkelError, match=name):
        skeletonize(TET_V, TET_F, **{name: value})          # refused before any work


#: The issue's own examples (the rows whose field exists).
ISSUE_PARAMS = [
    ({"containment": float("nan")}, "containment"),
    ({"containment": float("inf")}, "containment"),
    ({"smoothness": -1}, "smoothness"),
    ({"refine": -1}, "refine"),
    ({"seed": -1}, "seed"),
    ({"max_fit_points": -5}, "max_fit_points"),
    ({"max_iterations": 2.5}, "max_iterations"),
    ({"refine": 2.5}, "refine"),
    ({"spacing": "0.1"}, "spacing"),
]


@pytest.mark.parametrize("kw, name", ISSUE_PARAMS, ids=[str(k) for k, _ in ISSUE_PARAMS])
def test_the_issues_bad_parameters_are_refused_naming_them(kw, name):
    # a parameter the method no longer has (refine) is refused as unknown, still by its name
    with pytest.raises(CurveSkelError, match=name):
        skeletonize(TET_V, TET_F, **kw)


def test_an_unknown_parameter_is_named_with_a_suggestion():
    with pytest.raises(CurveSkelError, match="unknown parameter 'smothness' .*did you mean 'smoothness'"):
        skeletonize(TET_V, TET_F, smothness=5)
    with pytest.raises(CurveSkelError, match="'colour'"):
        SkeletonParams.from_dict({"colour": 1})


def test_good_values_are_normalised_to_plain_python():
    p = SkeletonParams(max_iterations=np.int64(7), spacing=np.float32(0.25), seed=3.0)
    assert type(p.max_iterations) is int and type(p.spacing) is float and p.seed == 3
    json.dumps(p.to_dict())
    assert SkeletonParams.from_dict(SkeletonParams.paper().to_dict()) == SkeletonParams.paper()


def test_a_field_assigned_after_construction_is_checked_when_run():
    p = SkeletonParams()
    p.min_component_area = -1.0
    with pytest.raises(CurveSkelError, match="min_component_area"):
        skeletonize(TET_V, TET_F, p)


def test_every_field_has_a_rule():
    missing = set(_field_names()) - set(RULES)
    assert not missing, f"add a line to params.RULES for {sorted(missing)}"


# -- mesh files -------------------------------------------------------------------------------------
def _bad_stl(p):
    p.write_bytes(b"\0" * 80 + struct.pack("<I", 1000) + bytes(range(200, 256)) * 9)


def _zero_based_obj(p):
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 0 2 1\nf 0 1 3\nf 0 3 2\nf 1 2 3\n")


def _short_stl(p):
    p.write_bytes(b"\x89\x01\x02")


FILES = {
    "bad binary STL": ("x.stl", _bad_stl, "not a valid STL file: as binary STL its header announces 1000"),
    "3-byte STL": ("x.stl", _short_stl, "not an STL file"),
    "a directory": ("d.obj", lambda p: p.mkdir(), "is a directory"),
    "0-based OBJ": ("z.obj", _zero_based_obj, "looks 0-based"),
}


@pytest.mark.parametrize("name", list(FILES))
def test_a_bad_mesh_file_says_what_is_wrong(tmp_path, name):
    fname, make, message = FILES[name]
    path = tmp_path / fname
    make(path)
    with pytest.raises(CurveSkelError, match=message):
        read_mesh(path)


@pytest.mark.parametrize("text, zero_based", [
    (b"f 1 2 3\nf 10 20 30\n", False),
    (b"f 1/0/2 10/1 20\n", False),            # a 0 texture index is not a vertex index
    (b"# f 0 1 2\nvt 0 0\nf 1 2 3\n", False),
    (b"f 1 2 3\nf 0 1 2\n", True),
    (b"  f 3 0/1 2\r\n", True),
    (b"f 4 5 0", True),
])
def test_zero_based_obj_detection(text, zero_based):
    assert (_OBJ_ZERO_INDEX.search(text) is not None) == zero_based


def test_a_one_based_obj_is_read_as_before(tmp_path):
    p = tmp_path / "ok.obj"
    p.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in TET_V)
                 + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in TET_F))
    V2, F2 = read_mesh(p)
    np.testing.assert_array_equal(V2, TET_V)
    np.testing.assert_array_equal(F2, TET_F)


# -- the command line: outputs checked first, written whole, never over the input -------------------
def run_cli(*args, limit=None):
    return _run_cli(*args, limit=limit, timeout=300)


@pytest.fixture(scope="module")
def mesh_file(tmp_path_factory):
    return write_capsule_obj(tmp_path_factory.mktemp("cli") / "capsule.obj")


def _refused_before_running(r, message):
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith("error:") and message in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    assert "skeleton" not in r.stdout                  # checked before the computation


CLI_REFUSALS = {
    "--json is the input": (lambda m, d: ["--json", m], "is the input mesh"),
    "--json is the input by another name": (lambda m, d: ["--json", m.parent / "." / m.name],
                                            "is the input mesh"),
    "--blend's parent is a file": (lambda m, d: ["--blend", m / "out.blend"], "is a file, not a folder"),
    "--json's grandparent is a file": (lambda m, d: ["--json", m / "a" / "b.json"], "is a file, not a folder"),
    "--json is a directory": (lambda m, d: ["--json", d], "is a directory"),
    "two outputs, one file": (lambda m, d: ["--json", d / "x.json", "--render", d / "x.json"],
                              "name the same file"),
    "--glb without .glb": (lambda m, d: ["--glb", d / "x.gltf"], "must end in .glb"),
    "--prune nan": (lambda m, d: ["--prune", "nan"], "prune must be a finite number"),
    "--containment nan (no longer a parameter)": (lambda m, d: ["--containment", "nan"],
                                                  "unrecognized arguments: --containment"),
    "--smoothness -1": (lambda m, d: ["--smoothness", "-1"], "smoothness must be >= 0"),
    # --refine is no longer a method parameter but issue 33's SKEL.json: a file not there
    "--refine -1 (a skeleton file that is not there)": (lambda m, d: ["--refine", "-1"],
                                                        "cannot read skeleton -1"),
    "--seed -1": (lambda m, d: ["--seed", "-1"], "seed must be >= 0"),
    "--max-joints -5": (lambda m, d: ["--max-joints", "-5"], "max_joints must be >= 0"),
    "--tolerance inf": (lambda m, d: ["--tolerance", "inf"], "tolerance must be a finite number"),
    "--min-component-area 1": (lambda m, d: ["--min-component-area", "1"], "min_component_area must be"),
}


@pytest.mark.parametrize("name", list(CLI_REFUSALS))
def test_cli_refuses_before_running(mesh_file, tmp_path, name):
    make, message = CLI_REFUSALS[name]
    before = mesh_file.read_bytes()
    r = run_cli(mesh_file, *make(mesh_file, tmp_path))
    _refused_before_running(r, message)
    assert mesh_file.read_bytes() == before


def test_cli_mesh_path_errors(tmp_path):
    r = run_cli(tmp_path)
    assert r.returncode == 2 and "is a directory" in r.stderr
    _bad_stl(tmp_path / "bad.stl")
    r = run_cli(tmp_path / "bad.stl")
    assert r.returncode == 2 and "not a valid STL file" in r.stderr and "chardet" not in r.stderr
    _zero_based_obj(tmp_path / "z.obj")
    r = run_cli(tmp_path / "z.obj")
    assert r.returncode == 2 and "0-based" in r.stderr


def _load_cli():
    from curveskel_addon.cli import outputs

    return outputs


def test_a_read_only_folder_is_refused_before_running(tmp_path, monkeypatch, mesh_file):
    from curveskel_addon.cli.skeletonize import build_parser

    cli = _load_cli()
    args = build_parser().parse_args([str(mesh_file), "--json", str(tmp_path / "ro" / "x.json")])
    real = os.access
    monkeypatch.setattr(cli.os, "access", lambda p, mode: False if Path(p) == tmp_path else real(p, mode))
    with pytest.raises(CurveSkelError, match="not writable"):
        cli.check_outputs(args)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_folder_is_refused_before_running_for_real(tmp_path, mesh_file):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        _refused_before_running(run_cli(mesh_file, "--json", ro / "x.json"), "not writable")
    finally:
        ro.chmod(0o700)


def test_a_full_disk_keeps_the_old_json_and_exits_non_zero(mesh_file, tmp_path):
    out = tmp_path / "out.json"
    out.write_text('{"old": true}')
    r = run_cli(mesh_file, "--json", out, limit=4000)      # the new JSON is larger than that
    assert r.returncode == 2, r.stderr
    assert "could not write --json" in r.stderr and "previous file is kept" in r.stderr
    assert json.loads(out.read_text()) == {"old": True}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]     # no temporary left


def test_json_is_written_whole_through_a_temporary_file(mesh_file, tmp_path):
    out = tmp_path / "new" / "out.json"
    r = run_cli(mesh_file, "--json", out)
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    assert d["format"] == "curveskel-skeleton/1" and "min_component_area" in d["meta"]["input"]
    assert [p.name for p in out.parent.iterdir()] == ["out.json"]


def test_cli_reports_repairs_and_dropped_debris(tmp_path):
    V, F = _debris(30)
    F = F.copy()
    F[: len(CAPSULE[1])] = F[: len(CAPSULE[1]), ::-1]
    path = tmp_path / "debris.obj"
    with open(path, "w") as fh:
        fh.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V)
        fh.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F)
    r = run_cli(path)
    assert r.returncode == 0, r.stderr
    assert "faces turned outwards: 1088" in r.stdout
    # by default debris is judged per part against its nearest neighbour (issue 31)
    assert "dropped     30 small part(s) smaller than the Detail Size" in r.stdout
