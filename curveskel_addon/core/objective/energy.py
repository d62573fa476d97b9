"""The approximation error E (eq. 20), its exact gradient, and E along a line as a quartic.

Why a module of its own: every solver, the pruning/simplification passes and the quality
measures evaluate the same E, so its conventions live in one place:

* ``sigma_v = t_v x_i + (1 - t_v) x_j`` and ``rho_v = t_v r_i + (1 - t_v) r_j`` for the bone
  ``(i, j) = bones[bone[v]]`` (eqs. 16-19: ``t = 1`` at joint ``i``);
* ``e_v = |v - sigma_v|^2 - rho_v^2`` (the residual) and ``E = sum_v w_v e_v^2`` (eq. 20 with a
  weight per vertex; ``w = 1`` is the paper's vertex sum).

Everything is vectorised over the vertices; per-joint sums use ``np.bincount`` (``np.add.at`` is
an order of magnitude slower).

Line search coefficients
------------------------
Along a direction ``D`` (J, 4), ``sigma_v`` and ``rho_v`` are affine in ``lam``:
``v - sigma_v(joints - lam D) = d_v + lam p_v`` and ``rho_v(lam) = rho_v - lam q_v`` with
``p_v = t D_i[:3] + (1-t) D_j[:3]``, ``q_v = t D_i[3] + (1-t) D_j[3]``. Hence
``e_v(lam) = A + B lam + C lam^2`` with ``A = e_v``, ``B = 2 (d.p + rho q)``,
``C = |p|^2 - q^2``, and ``E(lam) = sum_k c_k lam^k`` with

    c4 = sum w C^2,  c3 = sum 2 w B C,  c2 = sum w (B^2 + 2 A C),  c1 = sum 2 w A B,  c0 = sum w A^2.

The paper's eq. 24 (the same expansion for one coordinate, ``((a z + b)^2 - c)^2``) has two
misprints: the ``z^3`` coefficient is ``4 a^3 b`` (printed ``4 a^3``) and the ``z^2`` coefficient
is ``6 a^2 b^2 - 2 a^2 c`` (printed ``6 a^2 b^2 - 2 b^2 c``). The derivation above does not use
eq. 24, so it is not affected.
"""

from __future__ import annotations

import numpy as np

from .problem import FitProblem

__all__ = ["residuals", "energy", "energy_and_gradient", "line_quartic", "sigma_terms", "bone_terms",
           "bone_to_joints", "interpolate", "line_residuals", "quartic_from_residuals"]


def interpolate(pr: FitProblem, values: np.ndarray) -> np.ndarray:
    """``t_v values_i + (1 - t_v) values_j`` per vertex, for per-joint 4-vectors ``values``.

    Computed per coordinate on contiguous 1-D arrays (``np.take`` from a per-bone table): several
    times faster than fancy-indexing (n, 4) rows.

    Parameters
    ----------
    pr : FitProblem
    values : (J, 4) float
        Joints (giving sigma and rho) or a direction (giving its effect on them).

    Returns
    -------
    (4, n) float
        Rows x, y, z, r.
    """
    base = values[pr.bones[:, 1]]                       # (B, 4): joint j, where t = 0
    slope = np.ascontiguousarray((values[pr.bones[:, 0]] - base).T)
    base = np.ascontiguousarray(base.T)
    out = np.empty((4, len(pr.bone)))
    for c in range(4):
        out[c] = np.take(base[c], pr.bone)
        out[c] += pr.t * np.take(slope[c], pr.bone)
    return out


def sigma_terms(pr: FitProblem, joints: np.ndarray | None = None):
    """``d = v - sigma_v``, ``rho_v`` and ``e_v`` (the hot path of every solver).

    Parameters
    ----------
    pr : FitProblem
    joints : (J, 4) float, optional
        Joints to evaluate at instead of ``pr.joints``.

    Returns
    -------
    d : (3, n) float
        ``v - sigma_v``, one row per coordinate (structure of arrays, for speed).
    rho : (n,) float
        Interpolated radius ``rho_v``.
    e : (n,) float
        Residual ``|d|^2 - rho^2``.
    """
    s = interpolate(pr, pr.joints if joints is None else joints)
    d = s[:3]
    np.subtract(pr.points.T, d, out=d)                 # in place: s[:3] becomes v - sigma
    rho = s[3]
    e = d[0] * d[0]
    e += d[1] * d[1]
    e += d[2] * d[2]
    e -= rho * rho
    return d, rho, e


def bone_terms(pr: FitProblem, joints: np.ndarray | None = None):
    """Per-vertex quantities shared by E, its gradient and the solvers.

    Parameters
    ----------
    pr : FitProblem
    joints : (J, 4) float, optional
        Joints to evaluate at instead of ``pr.joints``.

    Returns
    -------
    i, j : (n,) int
        The two joints of each vertex's bone (``t = 1`` at ``i``).
    d : (n, 3) float
        ``v - sigma_v``.
    rho : (n,) float
        Interpolated radius ``rho_v``.
    e : (n,) float
        Residual ``|d|^2 - rho^2``.
    """
    ij = pr.bones[pr.bone]
    d, rho, e = sigma_terms(pr, joints)
    return ij[:, 0], ij[:, 1], d.T, rho, e


def residuals(pr: FitProblem) -> np.ndarray:
    """Residuals ``e_v = |v - sigma_v|^2 - rho_v^2`` (unweighted).

    Parameters
    ----------
    pr : FitProblem

    Returns
    -------
    (n,) float

    Examples
    --------
    >>> import numpy as np
    >>> from curveskel_addon.core.objective.problem import FitProblem
    >>> pr = FitProblem(np.array([[1.0, 0, 0.5]]), np.ones(1), np.array([[0, 0, 0, 1.0], [0, 0, 1, 1.0]]),
    ...                 np.array([[0, 1]]), np.array([0]), np.array([0.5]))
    >>> residuals(pr)
    array([0.])
    """
    return sigma_terms(pr)[2]


def energy(pr: FitProblem, joints: np.ndarray | None = None) -> float:
    """E = sum_v w_v e_v^2 (eq. 20 with weights).

    Parameters
    ----------
    pr : FitProblem
    joints : (J, 4) float, optional
        Evaluate at these joints instead of ``pr.joints``.

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> from curveskel_addon.core.objective.problem import FitProblem
    >>> pr = FitProblem(np.array([[2.0, 0, 0.5]]), np.ones(1), np.array([[0, 0, 0, 1.0], [0, 0, 1, 1.0]]),
    ...                 np.array([[0, 1]]), np.array([0]), np.array([0.5]))
    >>> energy(pr)        # (2^2 - 1^2)^2
    9.0
    """
    e = sigma_terms(pr, joints)[2]
    return float(np.dot(pr.weights, e * e))


def bone_to_joints(bones: np.ndarray, Gi: np.ndarray, Gj: np.ndarray, n_joints: int) -> np.ndarray:
    """Add per-bone 4-vectors ``Gi`` into joint ``bones[:, 0]`` and ``Gj`` into ``bones[:, 1]``.

    Parameters
    ----------
    bones : (B, 2) int
    Gi, Gj : (B, 4) float
    n_joints : int

    Returns
    -------
    (n_joints, 4) float
    """
    idx = np.concatenate([bones[:, 0], bones[:, 1]])
    vals = np.concatenate([Gi, Gj])
    return np.stack([np.bincount(idx, weights=vals[:, c], minlength=n_joints) for c in range(4)], 1)


def energy_and_gradient(pr: FitProblem, joints: np.ndarray | None = None) -> tuple[float, np.ndarray]:
    """E and its exact gradient with respect to every joint's (x, y, z, r).

    With ``g_v = -4 w_v e_v (d_v, rho_v)`` (4-vector),
    ``dE/dJ_i = sum_v t_v g_v`` and ``dE/dJ_j = sum_v (1 - t_v) g_v``.

    Parameters
    ----------
    pr : FitProblem
    joints : (J, 4) float, optional
        Evaluate at these joints instead of ``pr.joints``.

    Returns
    -------
    E : float
    grad : (J, 4) float

    Examples
    --------
    >>> import numpy as np
    >>> from curveskel_addon.core.objective.problem import FitProblem
    >>> pr = FitProblem(np.array([[2.0, 0, 0.5]]), np.ones(1), np.array([[0, 0, 0, 1.0], [0, 0, 1, 1.0]]),
    ...                 np.array([[0, 1]]), np.array([0]), np.array([0.5]))
    >>> E, g = energy_and_gradient(pr)
    >>> g[:, 3]           # dE/dr: -4 * 3 * 1 * 0.5 on each joint
    array([-6., -6.])
    """
    J = pr.joints if joints is None else joints
    d, rho, e = sigma_terms(pr, J)
    we = pr.weights * e
    E = float(np.dot(we, e))
    # Sum per bone first (B bins, 8 bincounts over the vertices), then bones -> joints.
    B = len(pr.bones)
    c = -4.0 * we
    ct = c * pr.t
    Gi, Gall = np.empty((B, 4)), np.empty((B, 4))
    for k in range(4):
        col = d[k] if k < 3 else rho
        Gi[:, k] = np.bincount(pr.bone, weights=ct * col, minlength=B)
        Gall[:, k] = np.bincount(pr.bone, weights=c * col, minlength=B)
    return E, bone_to_joints(pr.bones, Gi, Gall - Gi, len(J))


def line_residuals(pr: FitProblem, D: np.ndarray, joints: np.ndarray | None = None,
                   terms: tuple | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-vertex ``e_v(joints - lam D) = A + B lam + C lam^2``.

    Parameters
    ----------
    pr : FitProblem
    D : (J, 4) float
        Direction.
    joints : (J, 4) float, optional
        Base point instead of ``pr.joints``.
    terms : (d, rho, e), optional
        :func:`sigma_terms` at ``joints`` if already computed (saves a pass over the vertices).

    Returns
    -------
    A, B, C : (n,) float
    """
    J = pr.joints if joints is None else joints
    d, rho, A = sigma_terms(pr, J) if terms is None else terms
    p = interpolate(pr, np.asarray(D, dtype=np.float64))    # t D_i + (1-t) D_j, rows x, y, z, r
    q = p[3]
    B = d[0] * p[0] + d[1] * p[1] + d[2] * p[2] + rho * q
    B *= 2.0
    C = p[0] * p[0] + p[1] * p[1] + p[2] * p[2] - q * q
    return A, B, C


def quartic_from_residuals(w: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray) -> np.ndarray:
    """c0..c4 of ``sum_v w_v (A_v + B_v lam + C_v lam^2)^2`` (see the module docstring)."""
    wA, wB, wC = w * A, w * B, w * C
    return np.array([
        np.dot(wA, A),
        2.0 * np.dot(wA, B),
        np.dot(wB, B) + 2.0 * np.dot(wA, C),
        2.0 * np.dot(wB, C),
        np.dot(wC, C),
    ])


def line_quartic(pr: FitProblem, D: np.ndarray, joints: np.ndarray | None = None) -> np.ndarray:
    """Coefficients c0..c4 with ``E(joints - lam D) = sum_k c_k lam^k`` exactly.

    See the module docstring for the derivation (and the misprints of the paper's eq. 24).

    Parameters
    ----------
    pr : FitProblem
    D : (J, 4) float
        Direction (for gradient descent, the gradient).
    joints : (J, 4) float, optional
        Base point instead of ``pr.joints``.

    Returns
    -------
    (5,) float
        ``c0, c1, c2, c3, c4``; ``c0 == E(joints)`` and ``c4 >= 0``.

    Examples
    --------
    >>> import numpy as np
    >>> from curveskel_addon.core.objective.problem import FitProblem
    >>> pr = FitProblem(np.array([[2.0, 0, 0.5]]), np.ones(1), np.array([[0, 0, 0, 1.0], [0, 0, 1, 1.0]]),
    ...                 np.array([[0, 1]]), np.array([0]), np.array([0.5]))
    >>> D = np.zeros((2, 4)); D[:, 3] = 1.0        # shrink both radii: e(lam) = 4 - (1 - lam)^2
    >>> line_quartic(pr, D)                        # (3 + 2 lam - lam^2)^2
    array([ 9., 12., -2., -4.,  1.])
    """
    return quartic_from_residuals(pr.weights, *line_residuals(pr, D, joints))
