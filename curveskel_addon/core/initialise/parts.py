"""Parts become one figure: separate closed parts that overlap or nearly touch are joined where
they meet, and small free parts hang from the nearest larger part.

Many assets are modelled in pieces (a torso, a head and four limbs pushed into it; an insect's
segments and legs; eyes and buttons set on a surface). The solid they show is the union of the
parts, so the first approximations of the parts (one Reeb graph each, :mod:`.first`) are joined
as the union asks:

contacts
    Where two parts overlap or nearly touch, and the figures they make, are read off the
    parts' closed surfaces before any curve is built (:mod:`.contacts`); all parts share the
    mesh's resolution (:func:`.contacts.part_spacing`).
the union's surface
    A surface sample of one part inside another is not on the figure's surface: it leaves J's
    fit (:attr:`Joined.visible`), and J's inside test is the union's (the pipeline's
    :class:`..mesh.Mesh` with ``union``).
joined curves
    At each contact both parts' curves get a joint at their point nearest the seam's centre (a
    bone split there). The two joints are one when each lies within the other's ball (a head on
    a neck: both curves pass through the seam), otherwise a bone links them (a limb hangs from
    the body's curve by a bone to the limb's curve where it enters the body: the shoulder, not
    the middle of the limb). Bones of a part's curve lying inside another part are dropped: the
    union's curve there is the other part's (the arm's stub inside the torso); their surface
    maps onto the bones where they were cut. Every overlap is joined (each is a place the solid
    is continuous: a handle pushed into a mug at both ends makes the loop the solid has); a
    contact across a gap joins only parts not joined yet (a gap makes no loop).
rigid children
    A group of joined parts touching no other (a free part) hangs from a larger part when all
    of it lies within ``CONFIG.objective.reach`` radii of that part's curve (the radius of
    the curve where it comes nearest): an eye on a head, a button on a coat. A *rigid link*
    joins the larger part's curve, where it comes nearest, to the small part's curve, where it
    comes nearest that point. It carries no surface: the small part's vertices stay on its own
    bones, which hang from the link as one rigid child. Parts that float free and are not small
    against their neighbour (200 equal spheres, two figures side by side) stay separate trees.

So a figure is one tree, rooted in its largest part (:func:`parts_meta`), with each limb hanging
from the body at the contact. The search then minimises J over it like over any graph: it may
merge a limb's joint at the seam (a straight limb needs none: it then hangs from the body's
curve by one bone) or prune a small part's branch (too small to pay for it: its vertices then
ride on the bone it hung from, rigid with it).

Every link bone explains a *link region*: a region id above the Reeb regions that no surface
lies in. The moves carry it like any region (:func:`..graph.rewrite_pairs`), so the result still
names its links (:func:`parts_meta`: the bones carrying each link's region; a rigid link is
intact while one bone carries its region and no surface region).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..config import CONFIG
from ..geometry.rows import col_max, col_min, row_norm
from ..geometry.segments import closest_on_bones
from ..graph import SkeletonGraph
from .contacts import Figures, PartGroups, PartInside
from .first import Initial

__all__ = ["Joined", "join_parts", "parts_meta"]

_CFG = CONFIG.initial


@dataclass
class Joined:
    """The parts' first approximations joined into figures.

    Attributes
    ----------
    init : Initial
        The joined first approximation (its graph holds the contact joints and link bones;
        ``bone_part`` is -1 for a link bone).
    visible : (s,) bool
        The samples on the union's surface (a sample inside another part is not).
    region_part : (R,) int
        The part of every region, -1 for a link region.
    links : list of dict
        One per link bone: ``region`` (its link region), ``kind`` ("contact": an overlap;
        "gap": across a small gap; "rigid": a free part hung from a larger one), ``parts``.
    group : (k,) int
        The figure (tree) every part belongs to.
    contacts : list of Contact
    part_area : (k,) float
        The visible surface area of every part.
    part_centre : (k, 3) float
        The area centroid of every part's visible surface.
    loops : int
        The loops the joins close (seams beyond the ones that join the parts: a handle pushed
        into a mug at both ends): cycles of the union that no part has alone.
    """

    init: Initial
    visible: np.ndarray
    region_part: np.ndarray
    links: list = field(default_factory=list)
    group: np.ndarray | None = None
    contacts: list = field(default_factory=list)
    part_area: np.ndarray | None = None
    part_centre: np.ndarray | None = None
    loops: int = 0


class _Curves:
    """The joined graph under construction: joints, bones, (region, bone) pairs, each bone's
    part (``part``: -1 for a link; ``owner``: a link's first part), and the link regions."""

    def __init__(self, init: Initial, n_regions, spacing_length):
        g = init.graph
        self.Z = np.array(g.joints, np.float64)
        self.bones = np.array(g.bones, np.int64)
        self.pairs = np.array(g.pairs, np.int64)
        self.part = np.array(init.bone_part, np.int64)
        self.owner = self.part.copy()
        self.h = spacing_length
        self.next_region = n_regions
        self.links: list = []
        self.protected: set = set()

    # -- edits ---------------------------------------------------------------------------------
    def split(self, b, t) -> int:
        """A joint on bone ``b`` at ``t`` (sigma's convention: t at its first joint); an end
        within the part's contraction length is used instead (two places that close are one)."""
        i, j = self.bones[b]
        z = t * self.Z[i] + (1.0 - t) * self.Z[j]
        tol = _CFG.contract * self.h[self.part[b]] if self.part[b] >= 0 else 0.0
        for end in (i, j):
            if row_norm(self.Z[end:end + 1, :3] - z[None, :3])[0] <= tol:
                return int(end)
        n = len(self.Z)
        self.Z = np.vstack([self.Z, z])
        nb = len(self.bones)
        self.bones[b] = (i, n)
        self.bones = np.vstack([self.bones, [n, j]])
        self.part = np.append(self.part, self.part[b])
        self.owner = np.append(self.owner, self.owner[b])
        on_b = self.pairs[self.pairs[:, 1] == b]
        self.pairs = np.vstack([self.pairs, np.stack([on_b[:, 0], np.full(len(on_b), nb)], 1)])
        return n

    def nearest(self, point, parts):
        """(bone, t, squared distance) of the point of the curves of ``parts`` nearest
        ``point``, or None if they have no bone."""
        cand = np.flatnonzero(np.isin(self.part, list(parts)))
        if not len(cand):
            return None
        b, t, d2 = closest_on_bones(np.asarray(point, np.float64)[None], self.Z, self.bones[cand])
        return int(cand[b[0]]), float(t[0]), float(d2[0])

    def attach(self, point, parts):
        """A joint on the curves of ``parts`` where they come nearest ``point`` (or None)."""
        hit = self.nearest(point, parts)
        return None if hit is None else self.split(hit[0], hit[1])

    def link(self, ja, jb, kind, parts):
        """Join joints ``ja`` and ``jb``: one joint when each lies within the other's ball (not
        for a rigid link), else a link bone carrying a new link region."""
        if ja == jb:
            return
        za, zb = self.Z[ja], self.Z[jb]
        dist = float(row_norm((za - zb)[None, :3])[0])
        if kind != "rigid" and dist < min(za[3], zb[3]):
            self.Z[ja] = 0.5 * (za + zb)
            self.bones[self.bones == jb] = ja
            self.protected.add(int(ja))
            self.protected.discard(int(jb))
            return
        nb = len(self.bones)
        self.bones = np.vstack([self.bones, [ja, jb]])
        self.part = np.append(self.part, -1)
        self.owner = np.append(self.owner, parts[0])
        self.pairs = np.vstack([self.pairs, [[self.next_region, nb]]])
        self.links.append({"region": self.next_region, "kind": kind,
                           "parts": [int(p) for p in parts]})
        self.next_region += 1
        self.protected.update((int(ja), int(jb)))

    def drop_covered(self, inside: PartInside):
        """Drop the bones of a part lying inside another part (both ends and the middle; a
        protected joint, on a seam, counts as inside). Their regions map onto the kept bones
        where the dropped pieces were cut off (else onto the nearest kept bone)."""
        own = self.part >= 0
        if not own.any():
            return
        ids = np.flatnonzero(own)
        i, j = self.bones[ids, 0], self.bones[ids, 1]
        Z = self.Z[:, :3]
        prot = np.zeros(len(self.Z), bool)
        prot[list(self.protected)] = True
        covered = np.ones(len(ids), bool)
        middle = (0.5 * (Z[i] + Z[j]), np.zeros(len(ids), bool))
        for pts, guard in ((Z[i], prot[i]), (Z[j], prot[j]), middle):
            covered &= guard | inside.others(pts, self.part[ids])
        gone = ids[covered]
        if not len(gone):
            return
        keep = np.ones(len(self.bones), bool)
        keep[gone] = False
        kept = np.flatnonzero(keep)
        J = len(self.Z)
        kept_deg = np.bincount(self.bones[kept].ravel(), minlength=J)
        G = coo_matrix((np.ones(len(gone)), (self.bones[gone, 0], self.bones[gone, 1])),
                       shape=(J, J))
        _, lab = connected_components(G, directed=False)
        new_pairs = [self.pairs[keep[self.pairs[:, 1]]]]
        for comp in np.unique(lab[self.bones[gone, 0]]):
            piece = gone[lab[self.bones[gone, 0]] == comp]
            joints = np.unique(self.bones[piece].ravel())
            cut = joints[kept_deg[joints] > 0]
            target = kept[np.isin(self.bones[kept], cut).any(axis=1)]
            if not len(target) and len(kept):
                mid = self.Z[self.bones[piece]].mean(axis=(0, 1))[None, :3]
                target = kept[closest_on_bones(mid, self.Z, self.bones[kept])[0]]
            regions = np.unique(self.pairs[np.isin(self.pairs[:, 1], piece), 0])
            if len(target) and len(regions):
                new_pairs.append(np.stack([np.repeat(regions, len(target)),
                                           np.tile(target, len(regions))], 1))
        remap = np.cumsum(keep) - 1
        pairs = np.concatenate(new_pairs)
        self.pairs = np.unique(np.stack([pairs[:, 0], remap[pairs[:, 1]]], 1), axis=0)
        self.bones, self.part, self.owner = self.bones[kept], self.part[kept], self.owner[kept]

    def connect(self, members):
        """Link every piece of the curves of the parts ``members`` (and their links) that the
        drops cut off to the largest piece, at the piece's joint nearest it (a seam the
        contacts did not see), until they are one."""
        J = len(self.Z)
        while True:
            mine = np.flatnonzero(np.isin(self.owner, members))
            G = coo_matrix((np.ones(len(mine)), (self.bones[mine, 0], self.bones[mine, 1])),
                           shape=(J, J))
            lab = connected_components(G, directed=False)[1][self.bones[mine, 0]]
            comps, count = np.unique(lab, return_counts=True)
            if len(comps) < 2:
                return
            main = lab == comps[int(np.argmax(count))]
            rest, other = mine[main], mine[~main]
            pj = np.unique(self.bones[other].ravel())
            b, t, d2 = closest_on_bones(self.Z[pj, :3], self.Z, self.bones[rest])
            k = int(np.argmin(d2))
            host = int(self.owner[rest[b[k]]])
            child = int(self.owner[other[np.isin(self.bones[other], pj[k]).any(axis=1)][0]])
            self.link(self.split(int(rest[b[k]]), float(t[k])), int(pj[k]), "contact",
                      [host, child])
            J = len(self.Z)

    def graph(self):
        """The graph without unused joints, and each bone's part."""
        used = np.zeros(len(self.Z), bool)
        used[self.bones.ravel()] = True
        new_id = np.cumsum(used) - 1
        return SkeletonGraph(self.Z[used], new_id[self.bones], self.pairs), self.part.copy()


def _hang_free_parts(curves: _Curves, groups: PartGroups, samples, spart, visible, part_area):
    """Hang every free group from a larger one when it lies within ``CONFIG.objective.reach`` radii of
    that group's curve (:func:`join_parts`, rigid children). Smaller groups first; a group hangs
    only from a larger one, so no loop forms."""
    lab = groups.labels()
    n_groups = int(lab.max()) + 1
    g_area = np.bincount(lab, part_area, n_groups)
    order = np.lexsort((np.arange(n_groups), g_area))        # smallest first, ties by index
    rank = np.empty(n_groups, np.int64)
    rank[order] = np.arange(n_groups)
    P = samples.points
    for g in order[:-1]:
        parts_g = np.flatnonzero(lab == g)
        pts = P[np.isin(spart, parts_g) & visible]
        if not len(pts):
            pts = P[np.isin(spart, parts_g)]
        larger = np.flatnonzero(rank[lab] > rank[g])
        cand = np.flatnonzero(np.isin(curves.part, larger))
        if not len(cand) or not len(pts):
            continue
        Z = curves.Z
        za, zb = Z[curves.bones[cand, 0]], Z[curves.bones[cand, 1]]     # the bones' ends
        reach = CONFIG.objective.reach * np.maximum(za[:, 3], zb[:, 3])
        blo = np.minimum(za[:, :3], zb[:, :3]) - reach[:, None]
        bhi = np.maximum(za[:, :3], zb[:, :3]) + reach[:, None]
        cand = cand[np.all((bhi >= col_min(pts)) & (blo <= col_max(pts)), axis=1)]
        if not len(cand):
            continue
        b, t, d2 = closest_on_bones(pts, Z, curves.bones[cand])
        k = int(np.argmin(d2))
        bone, tk = int(cand[b[k]]), float(t[k])
        i, j = curves.bones[bone]
        x = tk * Z[i] + (1.0 - tk) * Z[j]
        if row_norm(pts - x[None, :3]).max() > CONFIG.objective.reach * x[3]:
            continue
        host = int(curves.part[bone])
        ja = curves.split(bone, tk)
        jb = curves.attach(curves.Z[ja, :3], parts_g)
        if jb is None:
            continue
        child = int(curves.part[np.isin(curves.bones, jb).any(axis=1) & (curves.part >= 0)][0])
        curves.link(ja, jb, "rigid", [host, child])
        groups.join(int(parts_g[0]), host)


def join_parts(figures: Figures, samples, init: Initial) -> Joined:
    """Join the parts' first approximations into figures (see the module's doc).

    Parameters
    ----------
    figures : Figures
        The parts' contacts (:func:`find_figures`).
    samples : Samples
        Surface samples of the whole mesh (the ones ``init`` was built with).
    init : Initial
        The parts' first approximations, side by side (:func:`.first.initial_graph`).

    Returns
    -------
    Joined
    """
    g = init.graph
    n_parts = figures.n_parts
    n_vertices = len(init.vertex_region)
    n_reg = int(max(init.vertex_region.max(initial=-1), init.sample_region.max(initial=-1),
                    g.pairs[:, 0].max(initial=-1))) + 1
    region_part = np.full(n_reg, -1, np.int64)
    region_part[init.sample_region] = figures.spart
    region_part[g.pairs[:, 0]] = init.bone_part[g.pairs[:, 1]]
    h = np.array([m.get("spacing_used", 1.0) * m["size"] for m in init.meta], np.float64)
    curves = _Curves(init, n_reg, h)
    for c in figures.joins:
        if c.overlap:                               # overlaps: every seam is joined
            a, b = c.parts
            ja, jb = curves.attach(c.centre, [a]), curves.attach(c.centre, [b])
            if ja is not None and jb is not None:
                curves.link(ja, jb, "contact", [a, b])
    if any(c.overlap for c in figures.joins):
        curves.drop_covered(figures.inside)
    groups = PartGroups(n_parts)
    loops = 0
    for c in figures.joins:
        if c.overlap:       # a seam between parts joined already closes a loop of the solid
            loops += not groups.join(*c.parts)
    lab = groups.labels()
    for grp in range(int(lab.max()) + 1):
        members = np.flatnonzero(lab == grp)
        if len(members) > 1:
            curves.connect(members)
    for c in figures.joins:                         # gaps, as the figures were found
        if not c.overlap:
            a, b = c.parts
            ja, jb = curves.attach(c.centre, [a]), curves.attach(c.centre, [b])
            if ja is not None and jb is not None:
                curves.link(ja, jb, "gap", [a, b])
            groups.join(a, b)
    visible = ~figures.hidden
    _hang_free_parts(curves, groups, samples, figures.spart, visible, figures.part_area)
    graph, bone_part = curves.graph()
    region_part = np.concatenate([region_part, np.full(curves.next_region - n_reg, -1, np.int64)])
    joined_init = replace(init, graph=graph, bone_part=bone_part,
                          vertex_bone=np.zeros(n_vertices, np.int64), vertex_t=np.zeros(n_vertices))
    return Joined(joined_init, visible, region_part, curves.links, groups.labels(),
                  figures.contacts, figures.part_area, figures.part_centre, loops)


def parts_meta(joined: Joined, graph) -> dict:
    """What the result says about its parts (``Skeleton.meta["parts"]``).

    Parameters
    ----------
    joined : Joined
    graph : SkeletonGraph
        The search's result.

    Returns
    -------
    dict
        ``count`` (parts), ``trees`` (connected pieces of the skeleton: one per figure),
        ``figures`` (the figure of every part: parts joined by contacts or rigid links share
        one), ``loops`` (cycles the joins close: :attr:`Joined.loops`), ``contacts`` (overlaps and gaps found), ``hidden_samples`` (samples inside another
        part, left out of the fit), ``largest_part``, ``root`` (the joint of the largest part
        nearest the centroid of its visible surface: where a rig roots the figure),
        ``part_bones`` (per part, the bones explaining its surface alone: 0 for a small part
        whose branch the search pruned, its vertices then riding on the bone it hung from),
        ``links`` (per link: ``kind`` "contact", "gap" or "rigid", ``parts`` (host, child),
        ``bones`` carrying its link region, ``intact``: one bone carries it and no surface, so
        that bone is the link itself: a rigid child's connecting bone, which deforms nothing).
    """
    J = graph.n_joints
    G = coo_matrix((np.ones(len(graph.bones)), (graph.bones[:, 0], graph.bones[:, 1])),
                   shape=(J, J))
    trees = connected_components(G, directed=False)[0] if J else 0
    pairs = graph.pairs
    rp = joined.region_part[pairs[:, 0]]
    surface = rp >= 0
    links = []
    for link in joined.links:
        bones = np.unique(pairs[pairs[:, 0] == link["region"], 1])
        on_surface = np.isin(pairs[:, 1], bones) & surface
        links.append({"kind": link["kind"], "parts": list(link["parts"]),
                      "bones": [int(b) for b in bones],
                      "intact": bool(len(bones) == 1 and not on_surface.any())})
    n_parts = len(joined.part_area)
    B = len(graph.bones)
    lo = np.full(B, n_parts, np.int64)
    hi = np.full(B, -1, np.int64)
    np.minimum.at(lo, pairs[surface, 1], rp[surface])
    np.maximum.at(hi, pairs[surface, 1], rp[surface])
    alone = (lo == hi) & (hi >= 0)
    part_bones = np.bincount(hi[alone], minlength=n_parts)
    largest = int(np.argmax(joined.part_area))
    mine = np.unique(pairs[rp == largest, 1])
    js = np.unique(graph.bones[mine].ravel()) if len(mine) else np.arange(J)
    centre = joined.part_centre[largest]
    root = int(js[np.argmin(row_norm(graph.joints[js, :3] - centre))]) if J else -1
    return {"count": int(n_parts), "trees": int(trees),
            "figures": [int(x) for x in joined.group], "loops": int(joined.loops),
            "contacts": {"overlap": int(sum(c.overlap for c in joined.contacts)),
                         "gap": int(sum(not c.overlap for c in joined.contacts))},
            "hidden_samples": int(np.count_nonzero(~joined.visible)),
            "largest_part": largest, "root": root,
            "part_bones": [int(x) for x in part_bones], "links": links}
