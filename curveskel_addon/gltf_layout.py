"""glTF's node layout for skinned meshes, applied to a binary glTF (.glb) file. No bpy.

Blender's glTF exporter writes a skinned mesh where it sits in Blender: a mesh bound to an armature
is its child (the hierarchy riggers, Blender's exporter and FBX expect), so its node becomes a
child of the armature's node. glTF ignores the transform of a skinned mesh's node and of its
parents (only the joints place its vertices; glTF 2.0, "Skins"), and the Khronos glTF Validator
warns NODE_SKINNED_MESH_NON_ROOT for such a node (the exporter's open issue
KhronosGroup/glTF-Blender-IO#1626). :func:`skinned_meshes_to_root` moves every skinned mesh node to
the roots of the scenes that held it and drops the transforms glTF ignores there, which changes
nothing a conforming viewer shows.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

__all__ = ["read_glb", "write_glb", "skinned_meshes_to_root", "fix_glb_file"]

_MAGIC = b"glTF"
_JSON = 0x4E4F534A
_BIN = 0x004E4942
_TRANSFORMS = ("matrix", "translation", "rotation", "scale")


def read_glb(data: bytes) -> tuple[dict, list[tuple[int, bytes]]]:
    """(the JSON document, the other chunks as (type, bytes)) of a .glb file's bytes.
    Raises ValueError when ``data`` is not a version 2 .glb with a JSON chunk first."""
    if len(data) < 20 or data[:4] != _MAGIC:
        raise ValueError("not a binary glTF file (no 'glTF' header)")
    version, length = struct.unpack_from("<II", data, 4)
    if version != 2 or length != len(data):
        raise ValueError(f"binary glTF: version {version}, length {length} for {len(data)} bytes")
    chunks, at = [], 12
    while at < length:
        size, kind = struct.unpack_from("<II", data, at)
        chunks.append((kind, data[at + 8:at + 8 + size]))
        at += 8 + size
    if not chunks or chunks[0][0] != _JSON:
        raise ValueError("binary glTF: the first chunk is not JSON")
    return json.loads(chunks[0][1].decode("utf-8")), chunks[1:]


def write_glb(doc: dict, chunks: list[tuple[int, bytes]]) -> bytes:
    """The bytes of a .glb file holding ``doc`` and ``chunks`` (each padded to 4 bytes: the JSON
    with spaces, the others with zeros, as the format asks)."""
    text = json.dumps(doc, separators=(",", ":"), ensure_ascii=False).encode("utf-8")
    body = []
    for kind, payload in [(_JSON, text), *chunks]:
        pad = b" " if kind == _JSON else b"\0"
        payload = payload + pad * (-len(payload) % 4)
        body.append(struct.pack("<II", len(payload), kind) + payload)
    body = b"".join(body)
    return _MAGIC + struct.pack("<II", 2, 12 + len(body)) + body


def skinned_meshes_to_root(doc: dict) -> int:
    """Move each node with a skin out of its parent's children into the root nodes of every scene
    that holds its topmost ancestor; drop its transform (glTF ignores it). Returns how many
    nodes moved. Nodes without a skin, and skinned nodes already at a root, are left alone."""
    nodes = doc.get("nodes", [])
    parent = {c: i for i, n in enumerate(nodes) for c in n.get("children", [])}
    moved = 0
    for k, node in enumerate(nodes):
        if "skin" not in node or k not in parent:
            continue
        top = k
        while top in parent:
            top = parent[top]
        up = nodes[parent.pop(k)]
        up["children"].remove(k)
        if not up["children"]:
            del up["children"]
        for scene in doc.get("scenes", []):
            roots = scene.get("nodes", [])
            if top in roots and k not in roots:
                roots.append(k)
        for key in _TRANSFORMS:
            node.pop(key, None)
        moved += 1
    return moved


def fix_glb_file(path) -> int:
    """Apply :func:`skinned_meshes_to_root` to the .glb file at ``path`` in place (rewritten only
    when a node moved). Returns how many nodes moved."""
    path = Path(path)
    doc, chunks = read_glb(path.read_bytes())
    moved = skinned_meshes_to_root(doc)
    if moved:
        path.write_bytes(write_glb(doc, chunks))
    return moved
