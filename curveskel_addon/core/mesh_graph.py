"""The mesh as a graph: unique edges, their lengths, connected components, adjacency."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

__all__ = ["unique_edges", "edge_lengths", "adjacency", "components"]


def unique_edges(F: np.ndarray) -> np.ndarray:
    """(e, 2) sorted unique undirected edges of triangles F (m, 3)."""
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    E.sort(axis=1)
    return np.unique(E, axis=0)


def edge_lengths(V: np.ndarray, E: np.ndarray) -> np.ndarray:
    """(e,) Euclidean length of each edge."""
    return np.linalg.norm(V[E[:, 1]] - V[E[:, 0]], axis=1)


def adjacency(n: int, E: np.ndarray, weights: np.ndarray | None = None) -> sp.csr_matrix:
    """Symmetric (n, n) CSR matrix with ``weights`` (default 1) on each edge."""
    w = np.ones(len(E)) if weights is None else weights
    A = sp.coo_matrix((np.concatenate([w, w]), (np.concatenate([E[:, 0], E[:, 1]]),
                                                np.concatenate([E[:, 1], E[:, 0]]))), shape=(n, n))
    return A.tocsr()


def components(n: int, F: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of the vertices through the faces: (count, label per vertex)."""
    E = unique_edges(F)
    return connected_components(adjacency(n, E), directed=False)
