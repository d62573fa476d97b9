"""Issue 31: the preview render frames a mesh of any size (1,500 units across, 0.001 across), and
a blank render is an error that writes nothing. Renders are tiny (96 x 72, 2 samples, Cycles on
the CPU); the command-line tests render at its own size. conftest.py registers the add-on and
empties the scene before every test."""

import re

import bpy
import numpy as np
import pytest

import meshes
from cli_support import run_cli
from curveskel_addon import headless
from curveskel_addon.core import CurveSkelError

TINY = {"resolution": (96, 72), "samples": 2}


def png_pixels(path):
    """(h, w, 4) float pixels of a PNG, read with Blender's image loader."""
    img = bpy.data.images.load(str(path), check_existing=False)
    try:
        w, h = img.size
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(img)
    return px.reshape(h, w, 4)


def assert_framed(path):
    """Not blank: a good share of the pixels differ from the background (the corner's colour),
    those pixels are centred, fill most of the height or width and keep off the border."""
    px = png_pixels(path)[..., :3]
    h, w = px.shape[:2]
    fg = np.abs(px - px[0, 0]).max(axis=2) > 0.05
    ys, xs = np.nonzero(fg)
    fraction = fg.mean()
    centre = (xs.mean() / w, ys.mean() / h) if fg.any() else (None, None)
    assert fraction > 0.05, f"{path.name}: {fraction:.1%} of the pixels differ from the background"
    assert abs(centre[0] - 0.5) < 0.1 and abs(centre[1] - 0.5) < 0.1, centre
    span = max((ys.max() - ys.min() + 1) / h, (xs.max() - xs.min() + 1) / w)
    assert span > 0.7, span                                     # framed, not a speck
    assert xs.min() > 0 and ys.min() > 0 and xs.max() < w - 1 and ys.max() < h - 1   # not cut off
    return fraction


def figure(across):
    """The six-part figure scaled to ``across`` units wide, generated (armature + silhouette)."""
    V, F, _ = meshes.six_part_figure()
    V = V * (across / np.ptp(V[:, 0]))
    ob = headless.mesh_object_from_arrays("figure", V, F)
    headless.generate(ob, spacing=0.08)          # the framing, not the skeleton's detail
    return ob


@pytest.mark.parametrize("across", [1500.0, 0.001])
def test_preview_frames_any_size(across, tmp_path):
    ob = figure(across)
    path = headless.render_preview(tmp_path / "figure.png", ob, **TINY)
    assert path == tmp_path / "figure.png"
    print(across, f"{assert_framed(path):.1%} of the pixels differ from the background")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figure.png"]     # no temporary left
    cam = [o for o in bpy.data.objects if o.type == 'CAMERA']
    assert cam == []                                                          # the preview's camera removed


def test_blank_render_is_an_error_and_writes_nothing(tmp_path):
    """Nothing to see (the mesh hidden from renders, no silhouette): one clear error, the old
    picture kept, no temporary file, the scene's helpers removed."""
    V, F = meshes.capsule(length=3.0, n_around=16, n_body=12)
    ob = headless.mesh_object_from_arrays("cap", V, F)
    headless.generate(ob, make_silhouette=False, spacing=0.08)
    ob.hide_render = True
    path = tmp_path / "cap.png"
    path.write_bytes(b"old")
    with pytest.raises(CurveSkelError, match=r"preview render of 'cap' is blank .* no picture was written"):
        headless.render_preview(path, ob, **TINY)
    assert path.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cap.png"]
    assert not [o.name for o in bpy.data.objects if o.name.startswith("CurveSkel Preview")]
    assert not [m.name for m in bpy.data.materials if m.name.startswith("CurveSkel Preview")]
    assert ob.hide_render and not ob.data.materials


def write_obj(path, V, F):
    with open(path, "w") as fh:
        fh.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V)
        fh.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F)
    return path


def test_cli_render_of_a_mesh_1500_units_across(tmp_path):
    V, F = meshes.capsule(length=3.0, n_around=16, n_body=12)
    mesh = write_obj(tmp_path / "big.obj", V * (1500.0 / np.ptp(V, axis=0).max()), F)
    r = run_cli(mesh, "--render", tmp_path / "big.png", "--spacing", "0.08")
    assert r.returncode == 0, r.stderr[-2000:]
    assert f"wrote       {tmp_path / 'big.png'}" in r.stdout
    assert_framed(tmp_path / "big.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.obj", "big.png"]


def test_cli_blank_render_is_an_error(tmp_path):
    """A mesh 1e-7 across: Blender's camera clips no nearer than 1e-6, the picture is blank: exit
    2 with one line that says so, no PNG, no temporary file."""
    V, F = meshes.capsule(length=3.0, n_around=16, n_body=12)
    mesh = write_obj(tmp_path / "speck.obj", V * (1e-7 / np.ptp(V, axis=0).max()), F)
    r = run_cli(mesh, "--render", tmp_path / "speck.png", "--spacing", "0.08")
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("error:")]
    assert len(errors) == 1 and re.search(r"preview render of 'speck' is blank", errors[0]), r.stderr
    assert "Traceback" not in r.stderr and "wrote       " not in r.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["speck.obj"]
