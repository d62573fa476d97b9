"""Properties shared by the operator, the sidebar panel (scene settings) and the preferences.

``GenerateSettings`` is a mixin of property annotations: the operator, the scene's
``CurveSkelSceneSettings`` and the add-on preferences all inherit it, so every parameter is
declared once, with its default taken from :class:`core.SkeletonParams`.
"""

from __future__ import annotations

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty

from .core.params import SOLVERS, SkeletonParams

__all__ = ["GenerateSettings", "CurveSkelSceneSettings", "PARAM_NAMES", "ADVANCED_NAMES",
           "OPTION_NAMES",
           "settings_dict", "skeleton_params", "CLASSES"]

_D = SkeletonParams()

_SOLVER_ITEMS = {
    "lm": ("lm", "Objective Search", "Search for the minimum of the objective J: joints and "
           "radii fitted (Levenberg-Marquardt), joints merged, branches pruned, each change kept "
           "only when J falls"),
    "paper": ("paper", "Paper's Method", "The paper's method as published: its first "
              "approximation, then gradient descent on E with the exact line search"),
}


def _solver_items():
    return [_SOLVER_ITEMS.get(s, (s, s, s)) for s in SOLVERS]


class GenerateSettings:
    """Parameters of one CurveSkel run (annotations only; inherited, never registered alone)."""

    # -- the artist's settings (SkeletonParams.ARTIST) ---------------------------------------
    spacing: FloatProperty(
        name="Detail Size", description="Smallest parts found, as a fraction of each part's "
        "size (the spacing of the first approximation's contours): smaller finds fingers and "
        "ears", default=_D.spacing, min=0.001, max=0.5, soft_min=0.005, soft_max=0.1, step=0.1,
        precision=3)
    smoothness: FloatProperty(
        name="Smoothness", description="How straight the bones run between branchings (the "
        "weight of the objective's smoothness term): 0 follows the middle of the shape "
        "exactly, 10 is nearly straight", default=_D.smoothness, min=0.0, max=1000.0,
        soft_max=10.0, precision=2, step=10)
    prune: FloatProperty(
        name="Branch Pruning", description="The price of a branch: a branch stays only where it "
        "explains more of the shape than it costs; higher removes more small branches (0 keeps "
        "every branch found)", default=_D.prune, min=0.0, max=1000.0, soft_max=10.0,
        precision=2, step=10)
    max_joints: IntProperty(
        name="Max Joints", description="The skeleton never has more joints than this (0: no "
        "limit)", default=_D.max_joints, min=0, max=100_000, soft_max=1000)
    # -- advanced (SkeletonParams' other fields: the command line's advanced group) ----------
    solver: EnumProperty(name="Solver", description="How the skeleton is found",
                         items=_solver_items(), default=_D.solver)
    max_iterations: IntProperty(name="Iterations", description="At most this many steps per "
                                "minimisation between the search's moves (Objective Search; the "
                                "last one, to convergence, up to 100 at least) or gradient-descent "
                                "iterations (Paper's Method)", default=_D.max_iterations, min=0,
                                max=100_000, soft_max=1000)
    tolerance: FloatProperty(name="Tolerance", description="Paper's Method: stop when an "
                             "iteration lowers the energy by less than this fraction of the "
                             "initial energy", default=_D.tolerance, min=1e-9, max=1.0,
                             precision=6, step=0.01)
    seed: IntProperty(name="Seed", description="Where the pole search starts: 0 at the vertex "
                      "farthest from the centre (the same skeleton in any pose or numbering), "
                      "another value at a random vertex (results are reproducible)",
                      default=_D.seed, min=0)
    min_component_area: FloatProperty(name="Min Part Area", description="Leave out loose parts "
                                      "with less than this share of the total area (scan debris; "
                                      "0 keeps all)", default=_D.min_component_area, min=0.0,
                                      max=0.99, precision=4, step=0.1)
    separate_parts: BoolProperty(name="Separate Parts", description="One skeleton per loose "
                                 "part, as modelled (by default parts that overlap or nearly "
                                 "touch are joined where they meet and small free parts hang "
                                 "from the nearest larger one: one armature)",
                                 default=_D.separate_parts)
    make_armature: BoolProperty(name="Armature", description="Create an armature from the skeleton",
                                default=True)
    make_silhouette: BoolProperty(name="Silhouette", description="Create an edge mesh with a Skin "
                                  "modifier showing the joints' radii", default=True)
    silhouette_in_render: BoolProperty(name="Render Silhouette",
                                       description="Show the silhouette in renders", default=False)
    bind: BoolProperty(name="Bind Mesh", description="Bind the mesh to the armature: an Armature "
                       "modifier, one vertex group per deforming bone, and the armature as the mesh's "
                       "parent (its world transform kept)",
                       default=False)
    interactive: BoolProperty(name="Interactive", description="Watch the search: the "
                              "silhouette updates while it runs, Esc stops it and keeps the "
                              "skeleton so far (ignored in background mode)", default=False)
    update_every: IntProperty(name="Update Every", description="Search stages between "
                              "silhouette updates in interactive mode", default=1, min=1,
                              soft_max=50)


#: Properties that are parameters of the core: every SkeletonParams field, the artist's first.
PARAM_NAMES = SkeletonParams.ARTIST
ADVANCED_NAMES = ("solver", "max_iterations", "tolerance", "seed", "min_component_area",
                  "separate_parts")
#: Properties of the Blender side of a run.
OPTION_NAMES = ("make_armature", "make_silhouette", "silhouette_in_render", "bind", "interactive",
                "update_every")


def _decimal(value):
    """A float property's value as the decimal the user typed: Blender stores floats in single
    precision (0.04 reads back as 0.03999999910593033), the core and the command line use 0.04."""
    if isinstance(value, float):
        return float(str(np.float32(value)))
    return value


def settings_dict(src) -> dict:
    """Every GenerateSettings value of an operator, scene settings or preferences, by name."""
    return {name: _decimal(getattr(src, name)) for name in PARAM_NAMES + ADVANCED_NAMES + OPTION_NAMES}


def skeleton_params(src) -> SkeletonParams:
    """The core parameters named by GenerateSettings properties; other fields keep their defaults."""
    return SkeletonParams.from_dict({name: _decimal(getattr(src, name))
                                     for name in PARAM_NAMES + ADVANCED_NAMES})


class CurveSkelSceneSettings(GenerateSettings, bpy.types.PropertyGroup):
    """The sidebar panel's parameters, stored per scene (``scene.curveskel``)."""


CLASSES = (CurveSkelSceneSettings,)


def draw_settings(layout, data, *, advanced: bool) -> None:
    """The parameters and options of a run, drawn for ``data`` (the operator in Adjust Last
    Operation, or the scene's settings in the sidebar); ``advanced`` adds the other parameters
    (the sidebar shows them in a sub-panel instead)."""
    col = layout.column()
    for name in PARAM_NAMES:
        col.prop(data, name)
    if advanced:
        # collapsed by default: solver internals are not an artist's first concern
        header, body = layout.panel("CURVESKEL_adjust_advanced", default_closed=True)
        header.label(text="Advanced")
        if body is not None:
            col = body.column()
            for name in ADVANCED_NAMES:
                col.prop(data, name)
    col = layout.column(heading="Create")
    for name in ("make_armature", "make_silhouette", "silhouette_in_render", "bind"):
        col.prop(data, name)
    col = layout.column(heading="Watch")
    col.prop(data, "interactive")
    sub = col.column()
    sub.active = data.interactive
    sub.prop(data, "update_every")
