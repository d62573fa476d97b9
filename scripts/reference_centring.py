"""Developer table for issue 10: how far each reference curve lies from the centres of its own
cross-sections.

    .venv/bin/python scripts/reference_centring.py [MESH ...] [--heldout [DIR]]

J's centring term pulls chain joints to the centres of the mesh's cross-sections
(``core/geometry/sections.py``, ``core/objective/terms.py``). Where the reference curve (``../shared/reference``: CGAL's mean-curvature skeletons) does not run through
those centres, ``to_ref`` measures a centred curve against an off-centre one. For each reference
bone, points every D/400 along it are cut by the plane across the bone (normal along it); the
section loop round each point (within D/4) gives the area centroid. Columns:

- ``found``: share of the points with a closed section loop round them;
- ``|c - ref|``: mean and median distance from a point to its section's centroid (÷ D);
- ``> 0.02``: share of the points whose centroid lies more than 0.02 D away (issue 10's to_ref
  target per mesh);
- ``centroid to_ref``: the centroids' ``to_ref`` (mean distance to the nearest point of the
  reference, points every D/2000 along it, as ``measure.quality``): what a curve through the section
  centres would score, mean and median.

Not asserted anywhere: it explains a measure, it does not grade the method.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "scripts")]

from bench import REFERENCE, load_mesh  # noqa: E402
from curveskel_addon.measure.quality import (SHAPE_FINE_STEP, curve_arrays,  # noqa: E402
                                             curve_points, section_offsets)

SHARED_ORDER = ["3holes.off", "rocker-arm.obj", "spot.obj", "elephant.obj", "homer.obj",
                "fertility.off", "hand.off", "armadillo.obj", "octopus.off", "horse.off"]


def reference_centring(V, F, R, RB):
    """(found, offset, centroid_to_ref) of the reference curve (R, RB) in the mesh (V, F):
    the share of its sample points with a section loop, each found point's distance to its
    section's centroid (:func:`measure.quality.section_offsets`) and each centroid's distance to
    the reference, both ÷ D."""
    D = float(np.linalg.norm(np.ptp(V, axis=0)))
    found, off, C = section_offsets(V, F, (R, RB), D, centroids=True)
    dense = curve_points(R, RB, SHAPE_FINE_STEP * D)
    return found, off, cKDTree(dense).query(C)[0] / D


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("meshes", nargs="*", help="mesh file names (default: the ten shared meshes)")
    ap.add_argument("--heldout", nargs="?", const=str(ROOT / "tests" / "data" / "heldout"),
                    help="a folder of held-out meshes with a reference/ beside them")
    args = ap.parse_args(argv)
    folder = Path(args.heldout) if args.heldout else None
    ref_dir = folder / "reference" if folder else REFERENCE
    names = args.meshes or (sorted(p.name for p in folder.iterdir()
                                   if p.suffix in (".off", ".obj", ".ply", ".stl"))
                            if folder else SHARED_ORDER)
    print(f"{'mesh':12s} {'found':>5s} {'|c - ref| mean':>14s} {'median':>7s} {'> 0.02':>6s}"
          f" {'centroid to_ref':>15s} {'median':>7s}")
    for name in names:
        stem = Path(name).stem
        V, F = load_mesh(name, folder)[:2]
        R, RB = curve_arrays(str(ref_dir / f"{stem}.json"))
        found, off, to_ref = reference_centring(V, F, R, np.asarray(RB))
        print(f"{stem:12s} {found:5.2f} {off.mean():14.4f} {np.median(off):7.4f}"
              f" {np.mean(off > 0.02):6.2f} {to_ref.mean():15.4f} {np.median(to_ref):7.4f}")


if __name__ == "__main__":
    main()
