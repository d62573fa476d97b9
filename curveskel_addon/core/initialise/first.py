"""The search's starting point: the paper's first approximation at the spacing's resolution.

Per connected component, the Reeb graph of the geodesic distance from a pole, its contours'
enclosing balls as joints (:mod:`.reeb`). Then its bones are brought to the resolution the
*Detail Size* asks for, one spacing ``s``: bones shorter than ``s / 2`` are contracted (two
contours that close are one place, and a bone of almost no length has no direction), bones
longer than ``s`` are split into equal pieces (a junction region's bone from the middle of a
body to a limb's far end can then bend into the limb). The surface of each Reeb region maps
only onto the bones made from that region's bones.

Returned with it: the Reeb region of every surface sample and of every working vertex, which
tie sigma to the regions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import CONFIG
from ..graph import SkeletonGraph
from ..moves.topology import contract_short, split_long
from .reeb import first_approximation

__all__ = ["Initial", "initial_graph"]


@dataclass
class Initial:
    """The first approximation of every component, as one graph.

    Attributes
    ----------
    graph : SkeletonGraph
    sample_region : (s,) int
        Reeb region of every surface sample.
    vertex_region : (n,) int
        Reeb region of every working vertex.
    key : (n,) float
        The geodesic distance from each component's pole at every working vertex: an order of
        the vertices no renumbering changes.
    meta : list of dict
        Per component: pole, spacing, levels, cycles...
    vertex_bone, vertex_t : (n,) int, (n,) float
        The first approximation's own mapping of every working vertex (the paper's sigma; with
        ``resolve``, onto the resolved graph's bones).
    bone_part : (B,) int
        The component each bone was found in.
    """

    graph: SkeletonGraph
    sample_region: np.ndarray
    vertex_region: np.ndarray
    key: np.ndarray
    meta: list
    vertex_bone: np.ndarray
    vertex_t: np.ndarray
    bone_part: np.ndarray | None = None


def initial_graph(mesh, labels, n_components, samples, *, spacing, seed, inside=None,
                  edges=None, resolve=True) -> Initial:
    """The first approximation of every component of ``mesh`` at the spacing's resolution.

    Parameters
    ----------
    mesh : Mesh
    labels : (n,) int
        Component of every working vertex.
    n_components : int
    samples : Samples
        Surface samples (their faces and barycentric coordinates locate their regions).
    spacing : float or (n_components,) float
        Contour spacing, a fraction of each component's size (one per component: the parts
        of a figure at the figure's resolution, :mod:`.parts`).
    seed : int
    inside : callable, optional
        Returns the mesh's inside test (one component only: see :func:`.reeb.first_approximation`).
    edges : tuple, optional
        The mesh's edge table (one component only).
    resolve : bool
        Bring the bones to the spacing's resolution (contract the short, split the long);
        False: the paper's first approximation as it is.
    """
    V, F = mesh.V, mesh.F
    face_label = labels[F[:, 0]]
    joints, bones, pairs, meta, bone_part = [], [], [], [], []
    vertex_region = np.zeros(len(V), np.int64)
    vertex_bone = np.zeros(len(V), np.int64)
    vertex_t = np.zeros(len(V))
    sample_region = np.zeros(len(samples.face), np.int64)
    key = np.zeros(len(V))
    nj = nr = 0
    one = n_components == 1
    s_face_label = face_label[samples.face]
    for c in range(n_components):
        vids = np.flatnonzero(labels == c) if not one else np.arange(len(V))
        fids = np.flatnonzero(face_label == c) if not one else np.arange(len(F))
        local = np.full(len(V), -1, np.int64)
        local[vids] = np.arange(len(vids))
        Vc, Fc = V[vids], local[F[fids]]
        sp = float(spacing[c]) if np.ndim(spacing) else spacing
        fa = first_approximation(Vc, Fc, spacing=sp, seed=seed,
                                 inside=inside if one else None, edges=edges if one else None)
        h = fa.meta.get("spacing_used", sp) * fa.meta["size"]
        if fa.region is None:                       # one bone for the whole component
            reg_v = np.zeros(len(vids), np.int64)
            breg = np.zeros(len(fa.bones), np.int64)
        else:
            reg_v, breg = fa.region, fa.bone_region
        g = SkeletonGraph(fa.joints, fa.bones, np.stack([breg, np.arange(len(fa.bones))], 1))
        vb, vt = fa.bone, fa.t
        if resolve:
            g, _ = contract_short(g, CONFIG.initial.contract * h)
            g, _ = split_long(g, h)
            vb, vt = np.zeros(len(vids), np.int64), np.zeros(len(vids))   # (not the paper's)
        ss = np.flatnonzero(s_face_label == c)
        local_face = np.full(len(F), -1, np.int64)
        local_face[fids] = np.arange(len(fids))
        if fa.region is None:
            s_reg = np.zeros(len(ss), np.int64)
        else:
            s_reg = fa.region_of(Fc, local_face[samples.face[ss]], samples.bary[ss])
        joints.append(np.asarray(g.joints))
        bones.append(g.bones + nj)
        bone_part.append(np.full(len(g.bones), c, np.int64))
        pairs.append(g.pairs + np.array([nr, 0]))
        vertex_region[vids] = reg_v + nr
        vertex_bone[vids] = vb + sum(len(b) for b in bones[:-1])
        vertex_t[vids] = vt
        sample_region[ss] = s_reg + nr
        key[vids] = fa.f if fa.f is not None else 0.0
        n_reg = int(max(reg_v.max(initial=-1), breg.max(initial=-1))) + 1
        meta.append({k: v for k, v in fa.meta.items() if k != "timings"}
                    | {"vertices": int(len(vids)), "timings": fa.meta.get("timings", {})})
        nj += g.n_joints
        nr += n_reg
    # bone ids of each component's pairs are local: shift them
    nb = 0
    shifted = []
    for p, b in zip(pairs, bones):
        shifted.append(p + np.array([0, nb]))
        nb += len(b)
    graph = SkeletonGraph(np.concatenate(joints), np.concatenate(bones),
                          np.concatenate(shifted))
    return Initial(graph, sample_region, vertex_region, np.where(np.isfinite(key), key, 0.0),
                   meta, vertex_bone, vertex_t, np.concatenate(bone_part))
