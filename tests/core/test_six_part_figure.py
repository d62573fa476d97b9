"""tests/meshes.six_part_figure: six closed parts, each overlapping the torso (issue 31's figure)."""

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

import meshes


def test_six_closed_overlapping_parts():
    V, F, part = meshes.six_part_figure()
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    count, labels = connected_components(coo_matrix((np.ones(len(E)), E.T), shape=(len(V),) * 2),
                                         directed=False)
    assert count == 6
    names = list(meshes.SIX_PART)
    for k, name in enumerate(names):
        keep = part == k
        assert len(np.unique(labels[keep])) == 1                  # a part is one component
        faces = F[np.all(keep[F], axis=1)]
        assert len(faces) == np.count_nonzero(keep[F].any(axis=1))  # no face across parts
        edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
        _, count = np.unique(edges, axis=0, return_counts=True)
        assert np.all(count == 2)                                 # closed
        assert meshes._signed_volume(V, faces) > 0                # outwards
    # every other part reaches into the torso's capsule (the parts overlap, they do not just touch)
    a, b, r = (np.array(x, float) if i < 2 else x for i, x in enumerate(meshes.SIX_PART["torso"]))
    seg = b - a

    def inside_torso(P):
        t = np.clip((P - a) @ seg / (seg @ seg), 0, 1)
        return np.linalg.norm(P - (a + t[:, None] * seg), axis=1) < r
    for k, name in enumerate(names[1:], start=1):
        assert inside_torso(V[part == k]).any(), name
    # mirror-symmetric about x = 0: the mirrored vertex set is the vertex set
    d, _ = cKDTree(V).query(V * [-1, 1, 1])
    assert d.max() < 1e-9
