"""The method's configuration (core/config.py): its ``Numerics`` lay out the work and change no
skeleton. ``config.Numerics``' docstring: "none of these changes a skeleton, only speed and
memory"; they are therefore not counted among the method's constants
(tests/core/test_structure.py counts the others).

Each run below sets other values in every core module that holds the numerics (the modules
read ``CONFIG.numerics`` once, as ``_NUM``), checks that the new values are in use, and compares
the skeleton with the default run's: the same bones and mapping, and joints and the log of J
equal to rounding (the face tree's order is the order the cross-sections' areas are summed in,
and float addition is not associative; the minimisation's stopping point then moves by about
the rounding times the problem's conditioning, not to a different skeleton).
"""

from __future__ import annotations

import sys
from contextlib import contextmanager
from dataclasses import fields, replace

import numpy as np
import pytest

import curveskel_addon.core  # noqa: F401  (every core module imported)
from curveskel_addon.core import skeletonize
from curveskel_addon.core.config import CONFIG, Numerics
from curveskel_addon.core.geometry.face_tree import FaceTree
from skeletons import procedural_mesh, procedural_skeleton

#: other values for every field: smaller blocks, other tree and grid layouts, smaller batches
OTHER = {"block": 1 << 11, "tree_leaf": 7, "morton_bits": 6, "grid_cell_faces": 5.0,
         "grid_level": 2.0, "grid_side_median": 2.5, "meb_batch": 5, "meb_tolerance": 1e-13}


def test_every_numeric_has_another_value_here():
    assert set(OTHER) == {f.name for f in fields(Numerics)}
    assert all(OTHER[f.name] != getattr(CONFIG.numerics, f.name) for f in fields(Numerics))


@contextmanager
def numerics(**values):
    """Every core module's ``_NUM`` (and ``CONFIG.numerics``) replaced by ``values`` for the
    duration; yields the modules changed."""
    new = replace(CONFIG.numerics, **values)
    mods = [m for name, m in sorted(sys.modules.items())
            if name.startswith("curveskel_addon.core") and isinstance(getattr(m, "_NUM", None), Numerics)]
    old = CONFIG.numerics
    try:
        for m in mods:
            m._NUM = new
        object.__setattr__(CONFIG, "numerics", new)
        yield mods
    finally:
        for m in mods:
            m._NUM = old
        object.__setattr__(CONFIG, "numerics", old)


def _same(a, b):
    """The same skeleton up to rounding: the same graph and samples' bones, joints within 1e-6
    of the size (a hundredth of what a 1e-9 jitter of the input may move them, issue 30), J's
    log within 1e-8 of itself (the message gives every difference)."""
    diffs = {}
    if a.joints.shape != b.joints.shape or not np.array_equal(a.bones, b.bones):
        diffs["topology"] = (a.n_joints, a.n_bones, b.n_joints, b.n_bones)
    else:
        diffs["joints"] = float(np.abs(a.joints - b.joints).max())
    diffs["bone"] = int(np.count_nonzero(a.bone != b.bone))
    diffs["t"] = float(np.abs(a.t - b.t).max())
    ja, jb = [s["J"] for s in a.meta["stages"]], [s["J"] for s in b.meta["stages"]]
    diffs["J log"] = (len(ja), len(jb), float(np.max(np.abs(np.subtract(ja, jb)) / np.abs(ja)))
                      if len(ja) == len(jb) else None)
    size = float(np.linalg.norm(np.ptp(a.joints[:, :3], axis=0)))
    same = ("topology" not in diffs and diffs["joints"] <= 1e-6 * size and diffs["bone"] == 0
            and diffs["J log"][2] is not None and diffs["J log"][2] <= 1e-8)
    assert same, diffs


@pytest.mark.parametrize("name", ["plate_with_holes", "star"])
def test_other_numerics_give_the_identical_skeleton(name):
    """All numerics changed at once: the identical skeleton (the plate exercises the inside
    test, the cross-sections and the first approximation's handles; the star a junction)."""
    V, F = procedural_mesh(name)
    base = procedural_skeleton(name)
    with numerics(**OTHER) as mods:
        assert len(mods) >= 4                   # meb, face_tree, inside, segments
        V2, F2 = procedural_mesh("bent_tube")
        tree = FaceTree(V2, F2)                 # the new values are in use
        assert int((tree.leaf_stop - tree.leaf_start).max()) == OTHER["tree_leaf"]
        sk = skeletonize(V, F)
    _same(base, sk)


@pytest.mark.parametrize("field", sorted(OTHER))
def test_each_numeric_alone_gives_the_identical_skeleton(field):
    """One field at a time (which one, if the skeleton changes), on a small bent tube."""
    V, F = procedural_mesh("bent_tube")
    base = procedural_skeleton("bent_tube")
    with numerics(**{field: OTHER[field]}):
        sk = skeletonize(V, F)
    _same(base, sk)
