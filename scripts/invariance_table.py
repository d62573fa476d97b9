"""Developer table of issue 12's metamorphic invariance: per mesh and transform, whether the
skeleton of the transformed surface is the same skeleton, transformed.

    .venv/bin/python scripts/invariance_table.py [MESH ...]

MESH: a shared mesh's stem (hand, spot, ...) or a procedural shape of tests/meshes.py (capsule,
bent_capsule, torus, star); default: four of each. Each cell: the joint count (``!`` when it
differs from the untransformed run) and the largest distance between the two curves (both ways,
points every D/1000 along the bones) over the bounding-box diagonal D (``*`` above 0.001 D,
the issue's target). Not asserted here: tests/core/test_invariance.py asserts the cases that
hold, with this script's transforms and measure.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from curveskel_addon.core import skeletonize  # noqa: E402
from curveskel_addon.measure.quality import curve_distances  # noqa: E402
from curveskel_addon.mesh_files import read_mesh  # noqa: E402

SHARED = ROOT.parent / "shared" / "meshes"
DEFAULT = ["capsule", "bent_capsule", "torus", "star", "hand", "spot", "horse", "3holes"]
TRANSFORMS = ["perm", "rot", "s1e6", "s1e-6", "t1e6", "jit"]
TOLERANCE = 1e-3


def load(name):
    import meshes

    if hasattr(meshes, name):
        V, F = getattr(meshes, name)()
        return np.asarray(V, float), np.asarray(F)
    path = next(p for p in sorted(SHARED.iterdir()) if p.stem == name)
    return read_mesh(path)


def transformed(V, F, name, D):
    """(V', F', undo): perm(ute), rot(ate), s<k> (scale), t<k> (move by k D), jit(ter 1e-9 D)."""
    rng = np.random.default_rng(1)
    c = V.mean(axis=0)
    if name == "perm":
        p = rng.permutation(len(V))
        return V[p], np.argsort(p)[F][rng.permutation(len(F))], lambda X: X
    if name == "rot":
        R = Rotation.random(random_state=3).as_matrix()
        return (V - c) @ R.T + c, F, lambda X: (X - c) @ R + c
    if name.startswith("s"):
        k = float(name[1:])
        return V * k, F, lambda X: X / k
    if name.startswith("t"):
        shift = np.array([1.0, -0.5, 0.25]) * float(name[1:]) * D
        return V + shift, F, lambda X: X - shift
    if name == "jit":
        return V + rng.uniform(-1.0, 1.0, V.shape) * 1e-9 * D, F, lambda X: X
    raise ValueError(name)


def curve_gap(a, b, D) -> float:
    """Largest distance from a point of either curve to the other, / D: both sampled every
    D/1000 (the same step both ways, so the same curve gives 0 to rounding)."""
    g = curve_distances(a, b, D, coarse=1e-3, fine=1e-3)
    return max(g["to_ref_max"], g["from_ref_max"])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("meshes", nargs="*", default=DEFAULT)
    args = ap.parse_args(argv)
    print("mesh           J  " + "  ".join(f"{t:>12s}" for t in TRANSFORMS))
    for name in args.meshes:
        V, F = load(name)
        D = float(np.linalg.norm(np.ptp(V, axis=0)))
        base = skeletonize(V, F)
        cells = []
        for t in TRANSFORMS:
            V2, F2, undo = transformed(V, F, t, D)
            sk = skeletonize(V2, F2)
            d = curve_gap(base, (undo(sk.joints[:, :3]), sk.bones), D)
            mark = ("" if sk.n_joints == base.n_joints else "!") + ("" if d <= TOLERANCE else "*")
            cells.append(f"{sk.n_joints:>3d} {d:7.1e}{mark:2s}")
        print(f"{name:12s} {base.n_joints:3d}  " + "  ".join(cells), flush=True)


if __name__ == "__main__":
    main()
