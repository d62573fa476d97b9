"""Issue 31: every vertex of a mesh file has its mapping entry, in file order, in every format;
every unreadable file is one line naming the file (and the line, for OBJ and OFF)."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from cli_support import run_cli
from meshes import capsule

from curveskel_addon.core import CurveSkelError, skeletonize
from curveskel_addon.mesh_files import read_mesh

CAPSULE = capsule(n_around=24, n_body=26)          # 962 vertices
UNUSED = np.array([0.3, -0.2, 2.5])                # inside the capsule, used by no face
AT = 417                                           # its place among the file's vertices


def _with_unused_vertex():
    """The capsule with one unused vertex inserted at AT: 963 file vertices."""
    V, F = CAPSULE
    V2 = np.insert(V, AT, UNUSED, axis=0)
    F2 = np.where(F >= AT, F + 1, F)
    return V2, F2


def _write(path, V, F):
    suffix = path.suffix
    if suffix == ".obj":
        with open(path, "w") as fh:
            fh.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V)
            fh.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F)
    elif suffix == ".off":
        with open(path, "w") as fh:
            fh.write(f"OFF\n{len(V)} {len(F)} 0\n")
            fh.writelines(f"{x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V)
            fh.writelines(f"3 {a} {b} {c}\n" for a, b, c in F)
    else:
        import trimesh

        trimesh.Trimesh(V, F, process=False).export(path)
    return path


def test_the_capsule_has_962_vertices_and_the_file_963():
    assert len(CAPSULE[0]) == 962 and len(_with_unused_vertex()[0]) == 963


@pytest.mark.parametrize("suffix", [".obj", ".off", ".ply"])
def test_an_unused_vertex_is_read_in_its_place(tmp_path, suffix):
    V2, F2 = _with_unused_vertex()
    V, F = read_mesh(_write(tmp_path / f"m{suffix}", V2, F2))
    assert V.shape == (963, 3)
    np.testing.assert_allclose(V, V2, atol=1e-6)
    np.testing.assert_array_equal(F, F2)


@pytest.mark.parametrize("suffix", [".obj", ".off", ".ply"])
def test_the_mapping_covers_every_file_vertex_in_file_order(tmp_path, suffix):
    """963 file vertices -> 963 entries; the used ones map as the mesh without the unused
    vertex does (not shifted by one), the unused one as its nearest vertex (the nearest bone)."""
    V2, F2 = _with_unused_vertex()
    path = _write(tmp_path / f"m{suffix}", V2, F2)
    out = tmp_path / "o.json"
    r = run_cli(path, "--json", out)
    assert r.returncode == 0, r.stderr
    assert "isolated vertices: 1" in r.stdout
    d = json.loads(out.read_text())
    bone, t = np.array(d["mapping"]["bone"]), np.array(d["mapping"]["t"])
    assert len(bone) == len(t) == 963
    ref = skeletonize(*_read_back(path, drop=AT))
    used = np.r_[0:AT, AT + 1:963]
    np.testing.assert_array_equal(bone[used], ref.bone)
    np.testing.assert_allclose(t[used], ref.t, atol=1e-12)
    nearest = int(np.argmin(np.linalg.norm(V2[used] - UNUSED, axis=1)))
    assert bone[AT] == ref.bone[nearest] and t[AT] == pytest.approx(ref.t[nearest])


def _read_back(path, drop):
    V, F = read_mesh(path)
    return np.delete(V, drop, axis=0), np.where(F > drop, F - 1, F)


def test_an_stl_maps_every_triangle_corner(tmp_path):
    V, F = CAPSULE
    path = _write(tmp_path / "m.stl", V, F)
    out = tmp_path / "o.json"
    r = run_cli(path, "--json", out)
    assert r.returncode == 0, r.stderr
    assert len(json.loads(out.read_text())["mapping"]["bone"]) == 3 * len(F)


# -- OBJ face corners --------------------------------------------------------------------------------
TET = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvn 0 0 1\n"
TET_F = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]


@pytest.mark.parametrize("faces", [
    "f 1/1/1 3//1 2/1\nf 1/1/1 2//1 4/1\nf 1/1/1 4//1 3/1\nf 2/1/1 3//1 4/1\n",   # mixed corners
    "f 1//1 3//1 2//1\nf 1//1 2//1 4//1\nf 1//1 4//1 3//1\nf 2//1 3//1 4//1\n",
    "f -4 -2 -3\nf -4 -3 -1\nf -4 -1 -2\nf -3 -2 -1\n",                           # relative
    "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2/1 3/1 4/1\n",
])
def test_obj_face_corners_with_texture_and_normal_indices(tmp_path, faces):
    p = tmp_path / "t.obj"
    p.write_text(TET + faces)
    V, F = read_mesh(p)
    assert len(V) == 4 and F.tolist() == TET_F


def test_the_issues_mixed_corner_face_is_a_face(tmp_path):
    """'f 1/1/1 2//1 3/1' was read as a degenerate face ('every face is degenerate')."""
    p = tmp_path / "one.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2//1 3/1\n")
    V, F = read_mesh(p)
    assert F.tolist() == [[0, 1, 2]]


def test_polygons_are_split_into_triangles(tmp_path):
    p = tmp_path / "q.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nf 1 2 3 4\nf 1 2 5\n")
    assert read_mesh(p)[1].tolist() == [[0, 1, 2], [0, 2, 3], [0, 1, 4]]


# -- one line naming the file and the line -----------------------------------------------------------
BAD = {
    "binary garbage .obj": ("g.obj", bytes(range(256)) * 8, "g.obj line 1: binary data"),
    "garbage after text": ("g2.obj", b"v 0 0 0\nv 1 0 0\n\x00\x01\x02", "g2.obj line 3: binary data"),
    "a word for a coordinate": ("w.obj", b"v 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n",
                                "w.obj line 2: 'x' is not a number"),
    "two coordinates": ("c.obj", b"v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n",
                        "c.obj line 2: expected 3 coordinates, found 2"),
    "index past the end": ("i.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n",
                           "i.obj line 5: face uses vertex 7, but the file has 3 vertices"),
    "a word for an index": ("a.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 two 3\n",
                            "a.obj line 4: 'two' is not a vertex index"),
    "a two-corner face": ("e.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2\n",
                          "e.obj line 5: a face needs at least 3 vertices, found 2"),
    "0-based OBJ": ("z.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "z.obj line 4: face uses vertex index 0"),
    "OFF: bad counts": ("c.off", b"OFF\n3 x 0\n", "c.off line 2: expected the counts"),
    "OFF: truncated": ("t.off", b"OFF\n4 1 0\n0 0 0\n1 0 0\n", "t.off: the header announces 4 vertices"),
    "OFF: index out of range": ("r.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
                                "r.off line 6: face uses vertex 3, but the file has 3 vertices"),
    "OFF: short face": ("s.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n",
                        "s.off line 6: the face announces 3 vertices but lists 2"),
    "OFF: a word": ("n.off", b"OFF\n3 1 0\n0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n",
                    "n.off line 4: 'zero' is not a number"),
    "binary OFF": ("b.off", b"OFF BINARY\n", "b.off line 1: binary OFF is not supported"),
    "PLY garbage": ("p.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n", "cannot read p.ply:"),
    "STL garbage": ("s.stl", b"\0" * 80 + struct.pack("<I", 1000) + b"\1" * 100, "s.stl is not a valid STL file"),
}


@pytest.mark.parametrize("name", list(BAD))
def test_a_bad_file_is_one_line_naming_the_file_and_line(tmp_path, name):
    fname, data, message = BAD[name]
    path = tmp_path / fname
    path.write_bytes(data)
    with pytest.raises(CurveSkelError) as e:
        read_mesh(path)
    assert message in str(e.value) and "\n" not in str(e.value)


def test_the_command_line_says_it_in_one_line(tmp_path):
    path = tmp_path / "g.obj"
    path.write_bytes(bytes(range(256)) * 8)                 # today: "No module named 'chardet'"
    r = run_cli(path)
    assert r.returncode == 2
    assert r.stderr == "error: g.obj line 1: binary data (byte 0x00), not a text OBJ file\n"


# -- arrays through the Python API --------------------------------------------------------------------
@pytest.mark.parametrize("F, message", [
    (np.array([0, 1, 2]), r"faces must have shape \(m, 3\).*got an array of shape \(3,\)"),
    ([0, 1, 2], "faces must be index lists.*got a face 0"),
    (np.zeros((2, 3, 3), int), r"got an array of shape \(2, 3, 3\)"),
    (5, "faces must be an \\(m, 3\\) array or a list of index lists, got int 5"),
])
def test_faces_of_the_wrong_shape_are_a_curveskel_error(F, message):
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    with pytest.raises(CurveSkelError, match=message):
        skeletonize(V, F)
