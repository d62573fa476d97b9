"""Where separate parts touch: the contacts and the figures they make, read off the parts'
closed surfaces before any curve is built (:mod:`.parts` joins the curves there).

Two parts touch where their volumes overlap, or where their surfaces come within
``CONFIG.initial.contact_gap`` of the thinner part's radius (``2 volume / area``: a tube's
radius, :func:`part_radii`). Where they touch, the samples of each part near the other's surface
form a seam (the ring where an arm enters a torso) or face each other across the gap; each
connected seam is one contact, at its centre (:func:`find_contacts`). Every overlap joins its
two parts; a gap joins only parts not joined yet (nearest first): the joined parts make a
figure (:func:`find_figures`). A surface sample inside another part is not on the figure's
surface (the union's): it is *hidden*. All parts share the mesh's resolution
(:func:`part_spacing`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..config import CONFIG
from ..geometry.inside import InsideTest
from ..geometry.meb import size_of
from ..geometry.rows import col_max, col_min, row_norm

__all__ = ["Contact", "Figures", "PartInside", "PartGroups", "find_contacts", "find_figures",
           "part_radii", "part_spacing"]

_CFG = CONFIG.initial


@dataclass(frozen=True)
class Contact:
    """Where two parts touch.

    Attributes
    ----------
    parts : (int, int)
        The two parts, lower index first.
    centre : (3,) float
        The centre of the seam (area-weighted mean of its samples on both parts).
    area : float
        The seam's sample area (both parts).
    overlap : bool
        The volumes overlap (else the surfaces face each other across a small gap).
    gap : float
        The smallest distance between the two surfaces' samples outside each other (0 for an
        overlap).
    """

    parts: tuple
    centre: np.ndarray
    area: float
    overlap: bool
    gap: float


class PartInside:
    """The inside test of each part alone, built on first use; ``others(P, own)`` tells whether
    each point lies inside any part but its own (the bounding boxes pick the tests to run).

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    face_part : (m,) int
        The part of every face.
    n_parts : int
    """

    def __init__(self, V, F, face_part, n_parts):
        self.V, self.F = V, F
        order = np.argsort(face_part, kind="stable")
        self._faces = np.split(order, np.cumsum(np.bincount(face_part, minlength=n_parts))[:-1])
        lo = np.full((n_parts, 3), np.inf)
        hi = np.full((n_parts, 3), -np.inf)
        corner = V[F].reshape(-1, 3)
        fp = np.repeat(face_part, 3)
        for j in range(3):
            np.minimum.at(lo[:, j], fp, corner[:, j])
            np.maximum.at(hi[:, j], fp, corner[:, j])
        self.lo, self.hi = lo, hi
        self._tests = {}

    def test(self, q) -> InsideTest:
        """The inside test of part ``q`` alone (a closed part: parity)."""
        if q not in self._tests:
            Fq = self.F[self._faces[q]]
            used, local = np.unique(Fq, return_inverse=True)
            self._tests[q] = InsideTest(self.V[used], local.reshape(-1, 3))
        return self._tests[q]

    def in_box(self, P, q):
        """(n,) bool: inside part ``q``'s bounding box."""
        return np.all((P >= self.lo[q]) & (P <= self.hi[q]), axis=1)

    def of(self, P, q) -> np.ndarray:
        """(n,) bool: inside part ``q``."""
        out = np.zeros(len(P), bool)
        box = np.flatnonzero(self.in_box(P, q))
        if len(box):
            out[box] = self.test(q)(P[box])
        return out

    def others(self, P, own) -> np.ndarray:
        """(n,) bool: inside any part other than ``own`` (n,)."""
        P = np.asarray(P, np.float64).reshape(-1, 3)
        own = np.broadcast_to(np.asarray(own, np.int64), (len(P),))
        out = np.zeros(len(P), bool)
        if not len(P):
            return out
        near = np.flatnonzero(np.all((self.hi >= col_min(P)) & (self.lo <= col_max(P)), axis=1))
        for q in near:
            sel = np.flatnonzero(~out & (own != q) & self.in_box(P, q))
            if len(sel):
                out[sel] = self.test(q)(P[sel])
        return out


class PartGroups:
    """Union-find over the parts: ``join(a, b)`` (False if already joined), ``find(a)`` (a
    part's representative), ``labels()`` (every part's group, numbered from 0)."""

    def __init__(self, n):
        self.up = np.arange(n)

    def find(self, a):
        while self.up[a] != a:
            self.up[a] = self.up[self.up[a]]
            a = self.up[a]
        return int(a)

    def join(self, a, b):
        ra, rb = self.find(a), self.find(b)
        if ra == rb:
            return False
        self.up[max(ra, rb)] = min(ra, rb)
        return True

    def labels(self):
        roots = np.array([self.find(a) for a in range(len(self.up))])
        return np.unique(roots, return_inverse=True)[1]


def _clusters(P, link):
    """Labels of the groups of points chained by steps of at most ``link``."""
    if len(P) < 2:
        return np.zeros(len(P), np.int64)
    pairs = cKDTree(P).query_pairs(link, output_type="ndarray")
    G = coo_matrix((np.ones(len(pairs), np.int8), (pairs[:, 0], pairs[:, 1])), shape=(len(P),) * 2)
    return connected_components(G, directed=False)[1]


def part_radii(mesh, labels, n_parts):
    """Every part's radius, ``2 volume / area``: a long tube's radius, two thirds of a ball's
    (the mean distance of its surface from a diameter is about 0.8 of it); a property of the
    part's closed surface alone, known before any curve.

    Parameters
    ----------
    mesh : Mesh
    labels : (n,) int
        The part of every working vertex.
    n_parts : int

    Returns
    -------
    (k,) float
    """
    V, F = mesh.V, mesh.F
    fp = labels[F[:, 0]]
    cnt = np.maximum(np.bincount(labels, minlength=n_parts), 1).astype(np.float64)
    centre = np.stack([np.bincount(labels, V[:, j], n_parts) for j in range(3)], 1) / cnt[:, None]
    # about each part's centre: no digits lost far from the origin
    vol = np.bincount(fp, np.einsum("ij,ij->i", V[F[:, 0]] - centre[fp], mesh.face_cross) / 6.0,
                      n_parts)
    area = np.bincount(fp, row_norm(mesh.face_cross) / 2.0, n_parts)
    return 2.0 * np.abs(vol) / np.maximum(area, 1e-300)


def find_contacts(samples, spart, radius, inside: PartInside, band):
    """Where the parts touch, and which samples lie inside another part.

    Parameters
    ----------
    samples : Samples
    spart : (s,) int
        The part of every sample.
    radius : (k,) float
        Every part's radius (:func:`part_radii`).
    inside : PartInside
    band : float
        The seam's half-width: the samples' own spacing (the distance from a point to the
        nearest sample of a surface is its distance to the surface within that).

    Returns
    -------
    contacts : list of Contact
        Every connected seam of every touching pair: overlaps first, then largest first.
    hidden : (s,) bool
        The samples inside another part.
    """
    P, w = samples.points, samples.weights
    n_parts = len(radius)
    hidden = np.zeros(len(P), bool)
    by_pair: dict = {}
    order = np.argsort(spart, kind="stable")
    members = np.split(order, np.cumsum(np.bincount(spart, minlength=n_parts))[:-1])
    for a in range(n_parts):
        ia = members[a]
        if not len(ia):
            continue
        grow = _CFG.contact_gap * radius[a]
        lo, hi = col_min(P[ia]) - grow, col_max(P[ia]) + grow
        cand = np.flatnonzero((spart != a) & np.all((P >= lo) & (P <= hi), axis=1))
        if not len(cand):
            continue
        d, _ = cKDTree(P[ia]).query(P[cand])
        ins = inside.of(P[cand], a)
        hidden[cand[ins]] = True
        tol = _CFG.contact_gap * np.minimum(radius[spart[cand]], radius[a])
        touch = ins | (d <= tol)
        for b in np.unique(spart[cand[touch]]):
            on_b = spart[cand] == b
            overlap = bool(ins[on_b].any())
            out_d = d[on_b & ~ins]
            gap = 0.0 if overlap or not len(out_d) else float(out_d.min())
            seam = on_b & (d <= gap + band)
            if not seam.any():                 # deep inside: the part's samples in the other
                seam = on_b & touch
            key = (min(a, b), max(a, b))
            entry = by_pair.setdefault(key, {"idx": [], "overlap": False, "gap": np.inf})
            entry["idx"].append(cand[seam])
            entry["overlap"] |= overlap
            entry["gap"] = min(entry["gap"], gap)
    contacts = []
    for (a, b), entry in sorted(by_pair.items()):
        idx = np.unique(np.concatenate(entry["idx"]))
        lab = _clusters(P[idx], min(radius[a], radius[b]))
        for c in range(int(lab.max()) + 1):
            sel = idx[lab == c]
            area = float(w[sel].sum())
            contacts.append(Contact((a, b), (w[sel] @ P[sel]) / max(area, 1e-300), area,
                                    entry["overlap"], 0.0 if entry["overlap"] else entry["gap"]))
    contacts.sort(key=lambda c: (not c.overlap, -c.area, c.parts))
    return contacts, hidden


@dataclass
class Figures:
    """What the parts' surfaces say before any curve is built: where they touch, which
    samples the union hides, and the figures the contacts make.

    Attributes
    ----------
    n_parts : int
    spart : (s,) int
        The part of every sample.
    radius : (k,) float
        Every part's radius (:func:`part_radii`).
    contacts : list of Contact
    joins : list of Contact
        The contacts that are joined: every overlap, and the gaps (nearest first) between parts
        not joined yet.
    hidden : (s,) bool
        The samples inside another part.
    group : (k,) int
        The figure of every part (before free parts are hung).
    part_area, part_centre : (k,) float, (k, 3) float
        Every part's visible area and its centroid.
    inside : PartInside
    """

    n_parts: int
    spart: np.ndarray
    radius: np.ndarray
    contacts: list
    joins: list
    hidden: np.ndarray
    group: np.ndarray
    part_area: np.ndarray
    part_centre: np.ndarray
    inside: object = field(repr=False, default=None)


def find_figures(mesh, labels, n_parts, samples, *, band) -> Figures:
    """The contacts of the parts and the figures they make (see the module's doc).

    Parameters
    ----------
    mesh : Mesh
        The working mesh (all parts).
    labels : (n,) int
        The part of every working vertex.
    n_parts : int
    samples : Samples
        Surface samples of the whole mesh.
    band : float
        The samples' spacing (the seam's half-width).

    Returns
    -------
    Figures
    """
    V, F = mesh.V, mesh.F
    face_part = labels[F[:, 0]]
    spart = face_part[samples.face]
    inside = PartInside(V, F, face_part, n_parts)
    radius = np.maximum(part_radii(mesh, labels, n_parts), band)
    contacts, hidden = find_contacts(samples, spart, radius, inside, band)
    groups = PartGroups(n_parts)
    joins = [c for c in contacts if c.overlap]
    for c in joins:
        groups.join(*c.parts)
    gaps = sorted((c for c in contacts if not c.overlap), key=lambda c: (c.gap, -c.area, c.parts))
    for c in gaps:
        if groups.join(*c.parts):                   # gaps: only parts not joined yet
            joins.append(c)
    group = groups.labels()
    w = samples.weights * ~hidden
    part_area = np.bincount(spart, w, n_parts)
    part_centre = np.stack([np.bincount(spart, w * samples.points[:, j], n_parts)
                            for j in range(3)], 1) / np.maximum(part_area, 1e-300)[:, None]
    return Figures(n_parts, spart, radius, contacts, joins, hidden, group, part_area,
                   part_centre, inside)


def part_spacing(mesh, labels, n_parts, spacing):
    """The spacing of every part's first approximation when the parts make one shape: the
    *Detail Size* a share of the whole mesh's size, as for one mesh (a leg of a quarter of the
    figure's size gets a quarter of the contours of the figure's height, not as many as the
    body; 200 small spheres get a few contours each).

    Parameters
    ----------
    mesh : Mesh
    labels : (n,) int
        The part of every working vertex.
    n_parts : int
    spacing : float
        The *Detail Size*: a share of the mesh's size.

    Returns
    -------
    (k,) float
        The spacing as a share of each part's own size (:func:`.first.initial_graph`).
    """
    order = np.argsort(labels, kind="stable")
    pieces = np.split(order, np.cumsum(np.bincount(labels, minlength=n_parts))[:-1])
    size = np.array([size_of(mesh.V[ids]) if len(ids) else 0.0 for ids in pieces])
    return spacing * mesh.D / np.maximum(size, 1e-300 * mesh.D)
