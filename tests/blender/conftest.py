"""Headless Blender (bpy as a module) for tests/blender.

BLENDER_USER_RESOURCES points at a temporary folder before bpy is imported, so nothing is
written to the user's Blender configuration. The add-on is registered once for the session
(from the source tree) and the scene is emptied before every test.
"""

import os
import tempfile

_USER = tempfile.mkdtemp(prefix="curveskel-blender-user-")
os.environ["BLENDER_USER_RESOURCES"] = _USER

import bpy  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import curveskel_addon  # noqa: E402
from curveskel_addon.headless import mesh_object_from_arrays  # noqa: E402


@pytest.fixture(scope="session", autouse=True)
def addon():
    curveskel_addon.register()
    yield
    curveskel_addon.unregister()


@pytest.fixture(autouse=True)
def empty_scene():
    bpy.ops.wm.read_homefile(use_empty=True)
    yield


@pytest.fixture
def user_resources():
    return _USER


@pytest.fixture
def make_mesh():
    """make_mesh(name, V, F) -> active, selected mesh object built with foreach_set."""
    def make(name, V, F):
        return mesh_object_from_arrays(name, V, F)
    return make


def _mesh_arrays(ob):
    """(V float64, F int64) exactly as the operator reads them (float32 positions, triangles)."""
    from curveskel_addon.mesh_read import evaluated_triangles

    return evaluated_triangles(ob, bpy.context.evaluated_depsgraph_get())


def _scene_snapshot() -> dict:
    """Everything the operator could create or change, for 'nothing changed' assertions."""
    return {
        "objects": sorted(o.name for o in bpy.data.objects),
        "meshes": sorted(m.name for m in bpy.data.meshes),
        "armatures": sorted(a.name for a in bpy.data.armatures),
        "collections": sorted(c.name for c in bpy.data.collections),
        "active": getattr(bpy.context.view_layer.objects.active, "name", None),
        "modifiers": {o.name: [m.name for m in o.modifiers] for o in bpy.data.objects},
    }


def _mesh_digest(ob) -> dict:
    """Arrays and a hash of a mesh object's data (vertices, edges, loops, polygons, transform)."""
    import hashlib

    me = ob.data
    out = {}
    for coll, attr, dtype, width in ((me.vertices, "co", np.float32, 3), (me.edges, "vertices", np.int32, 2),
                                     (me.loops, "vertex_index", np.int32, 1),
                                     (me.polygons, "loop_start", np.int32, 1),
                                     (me.polygons, "loop_total", np.int32, 1)):
        a = np.empty(len(coll) * width, dtype)
        coll.foreach_get(attr, a)
        out[f"{attr}"] = a
    h = hashlib.sha256()
    for k in sorted(out):
        h.update(k.encode())
        h.update(out[k].tobytes())
    out["sha256"] = h.hexdigest()
    out["matrix_world"] = np.array(ob.matrix_world)
    out["name"] = (ob.name, me.name, me.users)
    out["modifiers"] = [m.name for m in ob.modifiers]
    out["vertex_groups"] = [g.name for g in ob.vertex_groups]
    # custom properties only: Blender 4.2 also lists the storage of registered (bpy.props)
    # properties such as the result pointers in keys(), 5.0+ does not
    out["keys"] = sorted(k for k in ob.keys() if k not in ob.bl_rna.properties)
    return out


@pytest.fixture
def mesh_arrays():
    return _mesh_arrays


@pytest.fixture
def scene_snapshot():
    return _scene_snapshot


@pytest.fixture
def mesh_digest():
    return _mesh_digest
