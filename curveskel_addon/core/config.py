"""Every constant of the method, in one place, grouped by stage, each with its reason.

J's weights (:class:`Weights`) say how the objective's terms trade against each other; the
user's settings scale two of them (*Smoothness*, *Branch Pruning*). Everything else here is a
resolution, a tolerance or a budget: none names a mesh, and none decides a shape on its own
(every move is kept or refused by J). ``tests/core/test_config.py`` counts them: at most 30
outside the weights, and no other named number in the core.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

__all__ = ["CONFIG", "Config", "Weights", "Numerics", "count_constants"]


@dataclass(frozen=True)
class Weights:
    """J's weights; every term is already scale-free (:mod:`.objective.terms`)."""

    #: the centring term against the fit (both relative to the part's thickness: an offset of
    #: a tenth of the thickness along the whole curve costs what a tenth of a thickness of
    #: misfit over the whole surface costs)
    centre: float = 1.0
    #: one unit of *Smoothness*: a right-angle turn costs what a 1 % misfit of the whole
    #: surface does
    smooth: float = 0.01
    #: containment: a barrier, orders above the other terms (a bone leaving the mesh by a
    #: hundredth of D along its whole length outweighs any fit it buys)
    contain: float = 10_000.0
    #: the price of a joint: a chain joint stays only where it explains a bend
    joint: float = 1e-3
    #: one unit of *Branch Pruning*: the price of a branch (a tip)
    branch: float = 0.01


@dataclass(frozen=True)
class InputConfig:
    """Cleaning the mesh (:mod:`.mesh_input`); tolerances are shares of the mesh's size."""

    #: a length below this share of the size is zero: vertices on open edges closer are one
    #: vertex, faces thinner have no area, a mesh within it of one plane has no volume
    merge_tolerance: float = 1e-5
    #: a part is turned over only when its signed volume is clearly negative: below minus this
    #: share of the sum of the absolute per-face volumes
    orient_margin: float = 1e-3
    #: rays that vote whether a point is inside (odd: a ray grazing an edge spoils one count,
    #: the majority holds)
    inside_rays: int = 3


@dataclass(frozen=True)
class InitialConfig:
    """The first approximation (:mod:`.initialise`)."""

    #: levels of f at least (a small part still gets a chain)
    min_levels: int = 6
    #: levels of f at most (cost), four times as many when refined to find a lost handle
    max_levels: int = 400
    #: halvings of the spacing to find a handle the Reeb graph lost
    max_refinements: int = 3
    #: a cap region lower than this share of a spacing is below the level set's resolution:
    #: merged into the region under it
    cap_fraction: float = 0.5
    #: cubes along the longest extent of the grid whose inside paths let f go round a hole
    interior_resolution: int = 64
    #: pole candidates: graph distance within this share of the maximum (a tip, not a side)
    pole_slack: float = 0.1
    #: a shape is its own mirror image when its reflected points lie within this of it (in
    #: rms radii): then f grows from the pole and its twin, so paired limbs branch alike
    mirror_tolerance: float = 0.038
    #: points the mirror test uses at most
    mirror_points: int = 4000
    #: bones shorter than this share of a spacing are contracted: two contours that close
    #: are one place, and a bone of almost no length has no direction
    contract: float = 0.5
    #: far below any geometric scale: values within this share of the largest are tied (a
    #: mirror image's distance), told apart by the side of a plane of the shape, not by the
    #: coordinates' last bits; a bone the first approximation leaves with no length gets this
    #: share of the size (every bone has a direction)
    tie: float = 1e-6
    #: separate parts whose surfaces come within this share of the thinner one's radius are
    #: joined where they meet (:mod:`.initialise.parts`): a gap small against their radii is a
    #: part modelled just short of its body, not a second figure
    contact_gap: float = 0.5


@dataclass(frozen=True)
class ObjectiveConfig:
    """J's sampling and its terms' extents (:mod:`.objective`)."""

    #: the surface quadrature's sub-triangles are at most this share of a spacing across
    sample_length: float = 0.5
    #: surface samples at most (a uniform subset above: the same integral, less work)
    max_samples: int = 10_000
    #: a part's thickness is at least this share of a spacing (the fit's unit there)
    thickness_floor: float = 0.25
    #: a part's neighbourhood, in its thicknesses: the cross-section a bone is centred in is
    #: the solid's within this of its point (all of a round part's, whose outline is about one
    #: thickness away; little of the body a limb's root cuts across), and a free part within
    #: this many radii of a larger part's curve hangs from it (an eye on a head, a button)
    reach: float = 2.0
    #: the fit's distance to the silhouette is a soft minimum over each sample's nearest cones,
    #: this many
    soft_bones: int = 3
    #: ... softened over this share of the part's thickness (smooth where the nearest cone
    #: changes; at most this times log(soft_bones) below the true least distance)
    fit_softness: float = 0.05
    #: a bone keeps this share of a spacing inside the surface (containment): grazing the
    #: surface from inside, a curve is outside one step of the search later
    contain_margin: float = 0.1
    #: points along every bone (ends included) where containment is measured
    bone_points: int = 9
    #: the uniform subset of samples hashes each sample's geodesic distance this many times
    #: round [0, 1): a sample's pick depends on its own distance only, so a tiny move of the
    #: vertices swaps a pick only where it is within rounding of the cut
    draw_cycles: float = 9973.0


@dataclass(frozen=True)
class SearchConfig:
    """The search (:mod:`.search`, :mod:`.objective.minimise`)."""

    #: rounds of moves at most
    rounds: int = 30
    #: minimisation steps after a move before J decides on it
    refit_steps: int = 3
    #: when a batch of moves fails, this many are tried alone
    singles: int = 8
    #: a minimisation between rounds stops when a step lowers J by less than this share
    round_tolerance: float = 1e-3
    #: the last minimisation stops when a step lowers J by less than this share: converged,
    #: so a tiny change of the input moves the result as little
    final_tolerance: float = 1e-6
    #: a junction split in two: the new joint starts this share of the way towards its bones'
    #: far ends (then J's minimisation places it)
    split_fraction: float = 0.25


@dataclass(frozen=True)
class Numerics:
    """How the work is laid out, not what it computes: none of these changes a skeleton
    (``tests/core/test_config.py`` runs the pipeline with other values and compares), only
    speed and memory. Not counted among the method's constants."""

    #: elements of an array op at most (point-bone pairs, ray-triangle pairs): bounds memory
    block: int = 1 << 18
    #: faces per leaf of the face tree (cross-sections' search)
    tree_leaf: int = 4
    #: bits per axis of the Morton order the face tree sorts its faces by
    morton_bits: int = 10
    #: the inside test's ray grid: about this many faces per cell, cells this much coarser
    #: from one level to the next, and at least this many median triangles wide
    grid_cell_faces: float = 2.0
    grid_level: float = 1.5
    grid_side_median: float = 1.0
    #: the exact minimum enclosing ball's working set: its size at first and the violators
    #: added per round; its containment tolerance (squared distances, relative)
    meb_batch: int = 32
    meb_tolerance: float = 1e-12


@dataclass(frozen=True)
class Config:
    weights: Weights = field(default_factory=Weights)
    input: InputConfig = field(default_factory=InputConfig)
    initial: InitialConfig = field(default_factory=InitialConfig)
    objective: ObjectiveConfig = field(default_factory=ObjectiveConfig)
    search: SearchConfig = field(default_factory=SearchConfig)
    numerics: Numerics = field(default_factory=Numerics)


CONFIG = Config()


def count_constants(config: Config = CONFIG) -> int:
    """The constants outside J's weights (a tuple counts each of its numbers)."""
    n = 0
    for group in fields(config):
        if group.name in ("weights", "numerics"):
            continue
        for f in fields(getattr(config, group.name)):
            v = getattr(getattr(config, group.name), f.name)
            n += len(v) if isinstance(v, tuple) else 1
    return n
