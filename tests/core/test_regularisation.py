"""J's containment and smoothness terms at work in its minimisation: containment keeps a joint
that the fit alone would pull out of the mesh inside it, smoothness straightens a chain the fit
does not see, and with their weights at zero they change nothing."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from curveskel_addon.core.config import CONFIG
from curveskel_addon.core.geometry.samples import Samples, face_samples
from curveskel_addon.core.graph import SkeletonGraph
from curveskel_addon.core.mesh import Mesh
from curveskel_addon.core.objective.minimise import minimise
from curveskel_addon.core.objective.objective import Objective
from meshes import capsule
from skeletons import turning_angles


def _box(half=(2.0, 0.5, 0.5), n=16):
    """Closed, outward-oriented box mesh centred at the origin, each face an n x n grid."""
    h = np.asarray(half, float)
    V, F, o = [], [], 0
    g = np.linspace(-1.0, 1.0, n + 1)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    for ax in range(3):
        u, v = [k for k in range(3) if k != ax]
        for sgn in (1.0, -1.0):
            P = np.zeros((n + 1, n + 1, 3))
            P[..., ax] = sgn * h[ax]
            P[..., u] = g[:, None] * h[u]
            P[..., v] = g[None, :] * h[v]
            V.append(P.reshape(-1, 3))
            a, b, c, d = i, i + n + 1, i + n + 2, i + 1
            F.append(o + np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                                         np.stack([a, c, d], -1).reshape(-1, 3)]))
            o += (n + 1) ** 2
    V, inv = np.unique(np.round(np.concatenate(V), 9), axis=0, return_inverse=True)
    F = inv.ravel()[np.concatenate(F)]
    nrm = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    flip = np.einsum("ij,ij->i", nrm, V[F].mean(axis=1)) < 0      # convex: outward = away from 0
    F[flip] = F[flip][:, ::-1]
    return V, F


def _objective(V, F, keep, h=0.1, **weights):
    """J on (V, F) whose fit sees only the samples ``keep(points)`` (the others weigh 0: the
    containment still has the whole surface), each sample's thickness 0.5."""
    mesh = Mesh(V, F)
    s = face_samples(mesh.V, mesh.F, h)
    w = np.where(keep(s.points), s.weights, 0.0)
    s = Samples(s.points, w, s.face, s.bary, s.normal)
    return Objective(mesh, s, replace(CONFIG.weights, **weights), np.full(len(w), 0.5))


def _runaway(contain):
    """A bone fitted only to a small flat patch of a box's face: a ball through a plane patch
    fits it better the bigger it is, so without containment the joint leaves the box."""
    V, F = _box()
    patch = lambda P: (np.abs(P[:, 1] - 0.5) < 1e-9) & (np.abs(P[:, 0]) <= 0.5) & (np.abs(P[:, 2]) <= 0.3)  # noqa: E731
    obj = _objective(V, F, patch, contain=contain, centre=0.0, smooth=0.0)
    g = SkeletonGraph([[0.0, 0.2, 0.0, 0.3], [1.0, 0.0, 0.0, 0.3]], [[0, 1]], [[0, 0]], [0.5])
    return obj, minimise(obj, g, max_iterations=100, tolerance=1e-9)


def test_containment_keeps_a_runaway_joint_inside():
    _, (free, _, _) = _runaway(0.0)
    x = np.asarray(free.joints)
    # without containment the fit pulls the bone out through the patch (|y| <= 0.5 inside)
    assert np.abs(x[:, 1]).max() > 0.6, x
    obj, (held, ev, _) = _runaway(CONFIG.weights.contain)
    X = np.asarray(held.joints)
    assert (np.abs(X[:, :3]) <= [2.0, 0.5, 0.5]).all(), X     # both joints inside the box
    assert ev.terms["contain"] < 1e-3 * ev.terms["fit"] or ev.terms["contain"] < 1e-12
    assert obj.mesh.inside(np.linspace(X[0, :3], X[1, :3], 9)).all()


def _zigzag_graph():
    z = np.arange(7, dtype=float)
    joints = np.zeros((7, 4))
    joints[:, 2] = z
    joints[:, 0] = [0.0, 0.3, -0.3, 0.3, -0.3, 0.3, 0.0]
    joints[:, 3] = 1.0
    bones = np.array([[i, i + 1] for i in range(6)])
    return SkeletonGraph(joints, bones, np.c_[np.zeros(6, int), np.arange(6)], np.ones(6))


def _zigzag(graph):
    """The inner joints' largest distance from the tube's axis (the z axis)."""
    x = np.asarray(graph.joints)[1:-1, :3]
    return float(np.hypot(x[:, 0], x[:, 1]).max())


def _zigzag_objective(smooth):
    """A straight tube; its fit sees only the two ends (z < 0.5, z > 5.5), so the inner joints
    of a chain along it are free but for the smoothness (no centring)."""
    V, F = capsule(radius=1.0, length=6.0, n_around=24, n_body=24)
    ends = lambda P: (P[:, 2] < 0.5) | (P[:, 2] > 5.5)   # noqa: E731
    return _objective(V, F, ends, h=0.3, smooth=smooth, centre=0.0)


def test_smoothness_straightens_a_zigzag_chain():
    g0 = _zigzag_graph()
    start = _zigzag(g0)
    assert np.isclose(start, 0.3)
    free, _, _ = minimise(_zigzag_objective(0.0), g0, max_iterations=50, tolerance=1e-9)
    smooth, _, _ = minimise(_zigzag_objective(CONFIG.weights.smooth), g0, max_iterations=50,
                            tolerance=1e-9)
    assert _zigzag(free) > 0.25                 # unobserved inner joints keep their zig-zag
    assert turning_angles(free.joints, free.bones)[1].max() > 60
    # (J's smoothness prices turning, not spacing: the joints may slide along the axis)
    assert _zigzag(smooth) < 0.05 * start
    assert turning_angles(smooth.joints, smooth.bones)[1].max() < 1.0


def test_zero_weights_drop_their_terms():
    obj = _zigzag_objective(0.0)
    ev = obj.evaluate(_zigzag_graph())
    assert "smooth" not in ev.terms and "centre" not in ev.terms
    on = _zigzag_objective(1.0).evaluate(_zigzag_graph())
    assert on.terms["smooth"] > 0 and on.value > ev.value
    np.testing.assert_allclose(on.value - ev.value, on.terms["smooth"], rtol=1e-9)
