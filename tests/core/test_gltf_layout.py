"""curveskel_addon.gltf_layout (no bpy): a skinned mesh node moved to the scene's roots, and the
.glb container read and written byte-exactly."""

import struct

import pytest

from curveskel_addon.gltf_layout import read_glb, skinned_meshes_to_root, write_glb


def rig_doc():
    """Blender's layout: the armature (0) holds a bone (1) and the skinned mesh (2), which has a
    translation glTF ignores; a plain node (3) sits under the bone."""
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}, {"nodes": [4]}],
        "nodes": [{"name": "armature", "children": [1, 2], "rotation": [0, 0, 0.6, 0.8]},
                  {"name": "bone", "children": [3]},
                  {"name": "mesh", "mesh": 0, "skin": 0, "translation": [1.0, 2.0, 3.0]},
                  {"name": "prop", "mesh": 1},
                  {"name": "other scene"}],
        "skins": [{"joints": [1]}],
    }


def test_skinned_mesh_moves_to_its_scenes_roots():
    doc = rig_doc()
    assert skinned_meshes_to_root(doc) == 1
    nodes = doc["nodes"]
    assert nodes[0]["children"] == [1] and nodes[1]["children"] == [3]      # the rest as it was
    assert doc["scenes"] == [{"nodes": [0, 2]}, {"nodes": [4]}]             # only the scene it was in
    assert nodes[2] == {"name": "mesh", "mesh": 0, "skin": 0}               # its ignored transform gone
    assert nodes[0]["rotation"] == [0, 0, 0.6, 0.8]                         # the armature's kept
    assert skinned_meshes_to_root(doc) == 0                                 # once is enough


def test_deeper_skinned_mesh_and_emptied_children():
    doc = rig_doc()
    doc["nodes"][0]["children"] = [1]
    doc["nodes"][1]["children"] = [2]                 # under the bone: its topmost ancestor is 0
    assert skinned_meshes_to_root(doc) == 1
    assert "children" not in doc["nodes"][1] and doc["scenes"][0]["nodes"] == [0, 2]


def test_nothing_to_move():
    doc = rig_doc()
    doc["nodes"][0]["children"] = [1]
    doc["scenes"][0]["nodes"] = [0, 2]
    before = repr(doc)
    assert skinned_meshes_to_root(doc) == 0 and repr(doc) == before


def test_glb_round_trip_pads_and_counts():
    doc = rig_doc()
    binary = bytes(range(16))
    data = write_glb(doc, [(0x004E4942, binary)])
    magic, version, length = struct.unpack_from("<4sII", data)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_len, kind = struct.unpack_from("<I4s", data, 12)
    assert kind == b"JSON" and json_len % 4 == 0
    assert data[20 + json_len - 1:20 + json_len] in (b"}", b" ")           # padded with spaces
    got, chunks = read_glb(data)
    assert got == doc and chunks == [(0x004E4942, binary)]
    # odd lengths are padded with zeros, the header follows
    data = write_glb({"a": "é"}, [(0x004E4942, b"xyz")])
    assert len(data) % 4 == 0 and read_glb(data)[1] == [(0x004E4942, b"xyz\0")]
    assert read_glb(data)[0] == {"a": "é"}


@pytest.mark.parametrize("data", [b"", b"not a glb file at all",
                                  b"glTF" + struct.pack("<II", 2, 999) + b"\0" * 12,      # truncated
                                  b"glTF" + struct.pack("<II", 1, 20) + b"\0" * 8])       # version 1
def test_read_glb_refuses_what_is_not_a_whole_glb(data):
    with pytest.raises(ValueError):
        read_glb(data)
