"""The full report of an outside skeleton (issue 33), one layer above the core's evaluation.

:func:`curveskel_addon.core.evaluate` gives J, its terms, E, the inside fraction, the topology,
per bone and per vertex figures. The reconstruction distances need the silhouette's exact
distance field (:mod:`.quality`), which the core does not hold; :func:`full_report` adds them:

recon_mean, recon_p95
    Mesh -> silhouette: the surface samples' distance to the union of the round cones, / D.
recon_rev_mean, recon_rev_p95
    Silhouette -> mesh: samples of the silhouette's boundary to the surface, / D.

Here D is the diagonal of the mesh's bounding box, as everywhere in :mod:`.quality` (the
benchmark tables use it); J's own figures are in units of the core's D (the diameter of the
mesh's enclosing ball), which the report carries as ``D``.

Also here, for the command line and the Blender panel alike: the report as lines of text
(:func:`report_lines`, :func:`compare_lines`) and the per-vertex residual as heat-map colours
(:func:`heat_colours`).
"""

from __future__ import annotations

import time

import numpy as np

from .quality import (bbox_diagonal, mesh_distance, sample_silhouette_boundary, sample_surface,
                      silhouette_sdf)

__all__ = ["full_report", "recon_measures", "heat_colours", "report_lines", "compare_lines",
           "HEAT_RANGE", "RECON_SAMPLES"]

#: The residual, as a share of the mesh's size D, at which the heat map is full red: a part the
#: skeleton misses is off by its own length (a finger: a tenth of a hand), a fitted surface by
#: a fraction of its thickness (well under a hundredth).
HEAT_RANGE = 0.05
#: Samples of the surface and of the silhouette's boundary for the reconstruction distances.
RECON_SAMPLES = 10000
#: The heat map's colour stops (linear RGB): well explained, halfway, badly explained.
_STOPS = np.array([[0.15, 0.3, 0.85], [0.95, 0.85, 0.25], [0.85, 0.05, 0.03]])


def recon_measures(V, F, joints, bones, *, n_samples=RECON_SAMPLES, seed=0) -> dict:
    """Reconstruction distances both ways (module doc) of the skeleton (joints with radii).

    Parameters
    ----------
    V : (n, 3) float, F : (m, 3) int
    joints : (J, 4) float
    bones : (B, 2) int
    n_samples : int
    seed : int

    Returns
    -------
    dict
        ``recon_mean``, ``recon_p95``, ``recon_rev_mean``, ``recon_rev_p95``, ``recon_D``.
    """
    V = np.asarray(V, np.float64).reshape(-1, 3)
    F = np.asarray(F, np.int64).reshape(-1, 3)
    joints = np.asarray(joints, np.float64).reshape(-1, 4)
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    D = bbox_diagonal(V, F)
    rng = np.random.default_rng(seed)
    d = np.abs(silhouette_sdf(sample_surface(V, F, n_samples, rng), joints, bones)) / D
    B = sample_silhouette_boundary(joints, bones, n_samples, rng)
    dr = mesh_distance(B, V, F) / D if len(B) else np.zeros(1)
    return {"recon_mean": float(d.mean()), "recon_p95": float(np.quantile(d, 0.95)),
            "recon_rev_mean": float(dr.mean()), "recon_rev_p95": float(np.quantile(dr, 0.95)),
            "recon_D": D}


def full_report(V, F, report, *, n_samples=RECON_SAMPLES, vertices=False) -> dict:
    """The core's report (a :class:`~curveskel_addon.core.SkeletonReport`) as a JSON-ready
    dict with the reconstruction distances added (keys at least ``J``, ``terms``, ``E``,
    ``inside_fraction``, ``recon_mean``, ``per_bone``)."""
    t0 = time.perf_counter()
    out = report.to_dict(vertices=vertices)
    out.update(recon_measures(V, F, report.joints, report.bones, n_samples=n_samples))
    out["seconds"]["recon"] = time.perf_counter() - t0
    return out


def heat_colours(residual, D, heat_range=HEAT_RANGE) -> np.ndarray:
    """(n, 4) float32 RGBA per vertex: blue where ``|residual|`` is 0, through yellow to red at
    ``heat_range * D`` and beyond.

    Parameters
    ----------
    residual : (n,) float
        ``|v - sigma(v)| - r(sigma(v))`` per vertex, in the mesh's units.
    D : float
        The mesh's size, in the same units.
    heat_range : float
        Share of D at which the colour is full red.
    """
    u = np.clip(np.abs(np.asarray(residual, np.float64)) / max(heat_range * D, 1e-300), 0.0, 1.0)
    x = 2.0 * u
    lo = np.minimum(x.astype(np.int64), 1)          # 0: blue -> yellow, 1: yellow -> red
    f = (x - lo)[:, None]
    rgb = (1.0 - f) * _STOPS[lo] + f * _STOPS[lo + 1]
    return np.column_stack([rgb, np.ones(len(u))]).astype(np.float32)


def _g(x) -> str:
    return f"{x:.4g}" if isinstance(x, float) else str(x)


def report_lines(rep: dict, *, worst=3) -> list:
    """The report as lines of text: J and its weighted terms, E, inside fraction, the
    reconstruction distances (when measured), the topology, and the ``worst`` bones."""
    terms = rep.get("weighted", rep["terms"])
    lines = [f"J {rep['J']:.5g}   (" + ", ".join(f"{k} {v:.3g}" for k, v in terms.items()) + ")",
             f"E {rep['E']:.4g}   inside {rep['inside_fraction']:.3f}"]
    if "recon_mean" in rep:
        lines.append(f"recon mesh->silhouette {rep['recon_mean']:.4f} D, "
                     f"silhouette->mesh {rep['recon_rev_mean']:.4f} D")
    t = rep["topology"]
    lines.append(f"topology: {t['skeleton_components']} part(s), {t['skeleton_cycles']} cycle(s); "
                 f"mesh {t['mesh_components']} part(s), genus {t['mesh_genus']}"
                 + ("" if t["match"] else "  (does not match)"))
    bones = sorted(enumerate(rep["per_bone"]), key=lambda kv: -kv[1]["misfit"])[:worst]
    for b, pb in bones:
        lines.append(f"bone {b} {tuple(pb['bone'])}: {100 * pb['area']:.1f}% of the surface, "
                     f"misfit {pb['misfit']:.4f} D, inside {pb['inside']:.2f}")
    return lines


def compare_lines(names, reports) -> list:
    """Two or more reports side by side, and which skeleton fits better by J (the lowest)."""
    keys = [("J", "J"), ("E", "E"), ("inside", "inside_fraction"), ("recon", "recon_mean"),
            ("recon rev", "recon_rev_mean"), ("joints", None), ("bones", None),
            ("topology", None)]
    width = max(12, *(len(n) for n in names))
    out = [" " * 10 + "".join(f"{n:>{width + 2}}" for n in names)]
    for label, key in keys:
        cells = []
        for r in reports:
            if key is not None:
                v = r.get(key)
                cells.append("-" if v is None else _g(float(v)))
            elif label == "joints":
                cells.append(str(len(r["joints"])))
            elif label == "bones":
                cells.append(str(len(r["bones"])))
            else:
                t = r["topology"]
                cells.append(f"{t['skeleton_cycles']} cyc/{t['mesh_genus']} g"
                             + ("" if t["match"] else " !"))
        out.append(f"{label:<10}" + "".join(f"{c:>{width + 2}}" for c in cells))
    best = int(np.argmin([r["J"] for r in reports]))
    out.append(f"best by J: {names[best]}")
    return out
