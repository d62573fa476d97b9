"""The state one skeletonization passes through its stages (initialise, centre, edit, fit).

Every stage reads a :class:`PipelineState` and leaves a new graph in it; :meth:`PipelineState.record`
logs the stage with the E of the skeleton it left (E of eq. 20 with the state's weights and its
own mapping), so the E reported for a run is always the E of the skeleton returned.

The mapping sigma never leaves the Reeb structure: ``pairs`` lists (region, bone) -- the bones
that explain each Reeb region of the first approximation. Edits rewrite the bone side through
their ``bone_map``; :meth:`PipelineState.remap` then puts every vertex on the closest point of
the bones of its own region.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .energy import energy
from .mapping import closest_on_bones
from .problem import FitProblem

__all__ = ["PipelineState", "candidates_from_pairs", "canonical_subset"]


#: Cycles of the draw's uniform over the key's range (see :func:`canonical_subset`). A 1e-9 D
#: move of every vertex changes the geodesic key by ~1e-7 of its range (rounding summed along
#: the paths), so u moves by ~1e-3 and a pick flips only within that of the k-th score: about
#: one of 3,000 medial samples (armadillo, horse), where ranks flipped 4-6 near-tied pairs.
#: Adjacent vertices differ by ~1e-3 of the range even on a 1M-vertex mesh: ~10 cycles apart,
#: so the draw still looks independent from one vertex to the next.
DRAW_CYCLES = 9973.0


def canonical_subset(key, k, seed=0, p=None):
    """``k`` indices drawn without replacement (probabilities ``p``, uniform if None) from a
    quantity of the shape, ``key`` (e.g. the geodesic distance from the pole), so a permuted,
    moved, rotated or scaled copy of the mesh gets the same points, and a copy whose vertices
    moved by their last bits gets nearly all of them (issue 12). Sorted indices.

    Efraimidis & Spirakis's weighted sampling without replacement: the ``k`` points with the
    largest ``u ** (1 / p)``. Each point's ``u`` is a continuous function of its own key,
    ``frac(c z + phase)`` with ``z`` the key scaled to [0, 1] and ``c`` ~ :data:`DRAW_CYCLES`
    (``seed`` changes ``c`` and the phase), so a point's pick depends on its own key and weight
    only and changes only where its score is within rounding of the k-th. Uniforms drawn from
    a generator in key order (the previous sampler) handed two near-tied keys each other's
    draws when their order flipped: 6 of the armadillo's 3,000 medial samples changed under a
    1e-9 D jitter and a joint moved 2.2e-3 D. The randomness is the key's fine structure:
    points whose keys differ by a multiple of ``1 / c`` of the range share ``u`` (a regular
    grid of keys is drawn in a regular pattern; a mesh's geodesic distances are not a grid).
    ``rng.choice`` with probabilities walks a cumulative sum instead: one last-bit change of
    the weights moved 26 of 3,000 samples that way (and it is O(n k)).

    Examples
    --------
    >>> key = np.random.default_rng(0).random(1000)
    >>> pick = canonical_subset(key, 10)
    >>> perm = np.random.default_rng(1).permutation(1000)     # numbered otherwise
    >>> np.array_equal(np.sort(perm[canonical_subset(key[perm], 10)]), pick)
    True
    """
    key = np.asarray(key, np.float64)
    n = len(key)
    if k >= n:
        return np.arange(n)
    lo, hi = float(key.min()), float(key.max())
    z = (key - lo) / (hi - lo) if hi > lo else np.zeros(n)
    golden = 0.6180339887498949
    c = DRAW_CYCLES * (1.0 + (seed * golden) % 1.0)
    u = np.modf(z * c + (seed * np.sqrt(2.0)) % 1.0)[0]
    score = np.log(np.maximum(u, 1e-300))     # log u / p: the same order as u ** (1 / p)
    if p is not None:
        w = np.asarray(p, np.float64)
        score = np.where(w > 0, score / np.where(w > 0, w, 1.0), -np.inf)
    pick = np.argpartition(-score, k - 1)[:k]
    return np.sort(pick)


def candidates_from_pairs(pairs, region, n_regions):
    """CSR (indptr, bone ids) of each point's candidate bones: the bones of its region.

    Parameters
    ----------
    pairs : (P, 2) int
        (region, bone) rows, unique.
    region : (n,) int
        Region of each point.
    n_regions : int

    Returns
    -------
    (indptr (n + 1,), ids (p,)) as :func:`.mapping.closest_on_bones` takes them.
    """
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    o = np.argsort(pairs[:, 0], kind="stable")
    st = np.concatenate([[0], np.cumsum(np.bincount(pairs[:, 0], minlength=n_regions))])
    cnt = np.diff(st)[region]
    indptr = np.concatenate([[0], np.cumsum(cnt)])
    local = np.arange(indptr[-1]) - np.repeat(indptr[:-1], cnt)
    return indptr, pairs[o, 1][np.repeat(st[region], cnt) + local]


@dataclass
class PipelineState:
    """Working mesh, weights, the skeleton so far and its mapping.

    Attributes
    ----------
    V : (n, 3) float, F : (m, 3) int
        The cleaned working mesh.
    weights : (n,) float
        Weight of each vertex in E (area, mean 1; or 1 for the paper's vertex sum).
    joints : (J, 4) float, bones : (B, 2) int
    bone : (n,) int, t : (n,) float
        sigma of every vertex.
    region : (n,) int
        Reeb region of every vertex (unique over components).
    pairs : (P, 2) int
        (region, bone): the bones each region's vertices may map to.
    log : list of dict
        One entry per stage: name, E, joints, bones, seconds.
    """

    V: np.ndarray
    F: np.ndarray
    weights: np.ndarray
    joints: np.ndarray
    bones: np.ndarray
    bone: np.ndarray
    t: np.ndarray
    region: np.ndarray
    pairs: np.ndarray
    log: list = field(default_factory=list)
    medial: tuple | None = None     # (M (k, 3), rho (k,)): medial points of surface samples
    medial_points: int = 0          # surface points the medial balls shrank against
    key: np.ndarray | None = None   # (n,) a quantity of the shape per vertex the draws read (geodesic f)
    areas: np.ndarray | None = None  # (n,) vertex areas, if the weights step computed them
    face_cross: np.ndarray | None = None  # (m, 3) vertex_area.face_cross, until the centring
    _inside: object = None
    _size: float | None = None
    _faces_around: tuple | None = None
    _vertex_edges: np.ndarray | None = None
    _diag: float | None = None
    _bbox: tuple | None = None

    @property
    def size(self) -> float:
        """Diameter of the working mesh's minimum enclosing ball (:func:`.meb.size_of`), once."""
        if self._size is None:
            from .meb import size_of
            self._size = size_of(self.V) if len(self.V) else 1.0
        return self._size

    @property
    def inside(self):
        """Exact inside test of the working mesh (:class:`.quality.InsideTest`), built once."""
        if self._inside is None:
            from .quality import InsideTest
            self._inside = InsideTest(self.V, self.F)
        return self._inside

    @property
    def bbox(self) -> tuple:
        """(lo (3,), hi (3,)): the working vertices' bounding box, once."""
        if self._bbox is None:
            from .rows import col_max, col_min
            self._bbox = (col_min(self.V), col_max(self.V))
        return self._bbox

    @property
    def diag(self) -> float:
        """The working vertices' bounding-box diagonal (the unit of the fold measure), once
        (:func:`.quality.bbox_diagonal`, from :attr:`bbox`)."""
        if self._diag is None:
            if len(self.V) == 0:
                return 0.0
            lo, hi = self.bbox
            self._diag = float(np.linalg.norm(hi - lo))
        return self._diag

    @property
    def faces_around(self):
        """(indptr, faces): the faces around each vertex (:func:`.mesh_graph.faces_around`),
        built once."""
        if self._faces_around is None:
            from .mesh_graph import faces_around
            self._faces_around = faces_around(self.F, len(self.V))
        return self._faces_around

    @property
    def vertex_edges(self) -> np.ndarray:
        """(n,) the longest side of the faces around each vertex
        (:func:`.cross_section.vertex_edges`: the slab of a cross-section), built once."""
        if self._vertex_edges is None:
            from .cross_section import vertex_edges
            self._vertex_edges = vertex_edges(self.V, self.F, self.faces_around)
        return self._vertex_edges

    @property
    def n_regions(self) -> int:
        return int(max(self.region.max(initial=-1), self.pairs[:, 0].max(initial=-1)) + 1)

    def problem(self) -> FitProblem:
        """The fitting problem of the current skeleton (all vertices)."""
        return FitProblem(self.V, self.weights, self.joints, self.bones, self.bone, self.t)

    def energy(self) -> float:
        """E of the current skeleton with its own mapping."""
        return float(energy(self.problem()))

    def candidates(self, idx=None):
        """Candidate bones (CSR) of all vertices, or of the vertices ``idx``."""
        reg = self.region if idx is None else self.region[idx]
        return candidates_from_pairs(self.pairs, reg, self.n_regions)

    def apply_bone_map(self, bone_map) -> None:
        """After an edit: rewrite the bone side of ``pairs`` (old bone -> new bone)."""
        bone_map = np.asarray(bone_map, np.int64)
        p = self.pairs.copy()
        p[:, 1] = bone_map[p[:, 1]]
        p = p[p[:, 1] >= 0]
        self.pairs = np.unique(p, axis=0)
        # a region whose bones all vanished maps to any bone the edit kept at its place:
        # closest_on_bones falls back to every bone for a point without candidates

    def remap(self) -> None:
        """sigma of every vertex: closest point on the bones of its own region."""
        self.bone, self.t, _ = closest_on_bones(self.V, self.joints, self.bones, self.candidates())

    def record(self, stage: str, seconds: float, **extra) -> None:
        self.log.append({"stage": stage, "energy": self.energy(), "joints": int(len(self.joints)),
                         "bones": int(len(self.bones)), "seconds": float(seconds), **extra})
