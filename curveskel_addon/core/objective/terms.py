"""The terms of the objective J, each a sum of squared residuals with an exact Jacobian.

Every term is scale-free: lengths are measured in units of D (the diameter of the mesh's
minimum enclosing ball) and integrals are normalised, so a scaled, moved or rotated mesh has
the same J. With ``z`` the joints' (x, y, z, r) stacked (4 per joint), each term gives its
residuals ``rho(z)`` and their Jacobian ``d rho / d z`` (a sparse ``(m, 4J)`` matrix); its
value is ``sum rho^2`` and its gradient ``2 (d rho/dz)^T rho``. The mapping sigma (each
sample's bone and parameter ``t``) is held fixed here: :mod:`.objective` chooses it.

fit
    The paper's E (eq. 8) over the surface: ``(1/A) sum_s w_s e_s^2 / L_s^4`` with
    ``e_s = |p_s - sigma_s|^2 - r(sigma_s)^2``; ``w_s`` the area of quadrature point ``p_s``
    (:mod:`..geometry.samples`), A the surface area, ``L_s`` a length: D gives the paper's E in
    units of D (reported), the thickness of the sample's part gives each part the same weight
    for the same relative error (J's fit term: in units of D a finger's errors count 10^4
    times less than a torso's ten times thicker).
centre
    How far the middle of each bone lies from the area centroid of the mesh's cross-section
    through it, across the bone (:mod:`..geometry.sections`), relative to its part's
    thickness: ``sum_b (l_b / D) f_b^2 |q_b - c_b|^2 / t_b^2``, ``l_b`` the bone's length,
    ``t_b`` the thickness of the Reeb regions it explains, ``f_b`` fading out a section that is
    not the part's own (far wider than ``t_b``). The integral along the curve of its squared
    distance from the sections' centres, each in units of its part's thickness. ``t_b`` is the
    mesh's, not the skeleton's: a bone cannot lower the term by changing its radius.
smooth
    How much the chains turn, and their radii bend: ``sum_k (h_k / D) (1 - cos theta_k) +
    (r_k - (r_a + r_b) / 2)^2 / (m_k D)`` over chain joints, ``theta_k`` the angle between a
    joint's two bones (0 on a straight chain, 1 per joint of a right-angled zig-zag, whatever
    the size), ``h_k`` and ``m_k`` the harmonic and arithmetic means of its bone lengths.
contain
    How far the bones leave the mesh: at points along every bone that lie outside (the exact
    inside test), their height above the tangent plane of the nearest surface sample:
    ``sum_q (l_q / D) max(0, h_q)^2 / D^2``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..geometry.rows import row_norm
from ..geometry.sections import cross_sections

__all__ = ["fit_term", "centre_term", "bone_centres", "smooth_term", "smooth_triplets",
           "contain_term", "chain_neighbours", "BONE_POINTS"]

#: Points per bone (ends included) where containment is measured.
BONE_POINTS = np.linspace(0.0, 1.0, 9)


def _jac(rows, cols, vals, m, J):
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(m, 4 * J))


def chain_neighbours(bones, n_joints):
    """(k, a, b): the chain joints (two bones each) and their two neighbours."""
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    deg = np.bincount(bones.ravel(), minlength=n_joints)
    ends = np.concatenate([bones[:, 0], bones[:, 1]])
    other = np.concatenate([bones[:, 1], bones[:, 0]])
    order = np.argsort(ends, kind="stable")
    start = np.concatenate([[0], np.cumsum(deg)])
    k = np.flatnonzero(deg == 2)
    return k, other[order][start[k]], other[order][start[k] + 1]


def fit_term(Z, samples, bones, bone, t, area, scale, *, jacobian=True):
    """Residuals ``sqrt(w_s / A) e_s / scale_s^2`` (and Jacobian) of the fit E.

    Parameters
    ----------
    Z : (J, 4) float
        Joints (x, y, z, r).
    samples : Samples
    bones : (B, 2) int
    bone, t : (s,) int, (s,) float
        sigma of every sample: ``t`` at ``bones[bone, 0]``, ``1 - t`` at the other end.
    area : float
    scale : float or (s,) float
        The length each sample's residual is measured in (D: the paper's E in units of D;
        the part's own thickness: a relative fit, see the module docstring).
    """
    ij = bones[bone]
    i, j = ij[:, 0], ij[:, 1]
    S = t[:, None] * Z[i] + (1.0 - t)[:, None] * Z[j]
    d = samples.points - S[:, :3]
    rho = S[:, 3]
    e = np.einsum("ij,ij->i", d, d) - rho * rho
    c = np.sqrt(samples.weights / area) / np.asarray(scale, np.float64) ** 2
    res = c * e
    if not jacobian:
        return res, None
    n, J = len(t), len(Z)
    G = np.column_stack([d, rho]) * (-2.0 * c)[:, None]
    rows = np.repeat(np.arange(n), 4)
    col4 = np.arange(4)
    return res, _jac([rows, rows], [(4 * i[:, None] + col4).ravel(), (4 * j[:, None] + col4).ravel()],
                     [(G * t[:, None]).ravel(), (G * (1.0 - t)[:, None]).ravel()], n, J)


def _fade(x, lo, hi):
    """sqrt of a smoothstep falling from 1 at ``x <= lo`` to 0 at ``x >= hi``, and its
    derivative in ``x``."""
    t = np.clip((hi - x) / (hi - lo), 0.0, 1.0)
    q = np.sqrt(3.0 - 2.0 * t)
    inner = (t > 0) & (t < 1)
    d = np.where(inner, (q - t / q) * (-1.0 / (hi - lo)), 0.0)
    return t * q, d


#: A section whose rms spread exceeds OWN[0] times the part's thickness is fading out (not the
#: part's own: at a limb's root the plane cuts the body too), gone at OWN[1]; loops are looked
#: for within REACH times the thickness (a disc's spread is 0.71 of its radius).
OWN = (1.5, 3.0)
REACH = 6.0


def centre_term(Z, bones, mesh, D, thick, *, jacobian=True):
    """Residuals ``sqrt(l_b / D) f_b (q_b - c_b) / t_b`` (3 per bone whose section was found)
    and their Jacobian: ``q_b`` the bone's middle, ``c_b`` the centroid of the cross-section
    through it across the bone, ``l_b`` the bone's length, ``t_b = thick[b]`` the thickness of
    its part (from its Reeb regions; fixed during a minimisation), ``f_b`` fading the section
    out where it is not the part's own: its rms spread from ``OWN[0]`` to ``OWN[1]`` times
    ``t_b``. ``mesh`` provides ``V``, ``F`` and ``face_tree``.

    The middle of every bone, not the joints: a long bone cutting across a part is off its
    sections' centres there however well its two ends are placed.

    ``jacobian=None`` returns the value per bone instead (for the moves' estimates)."""
    return bone_centres(Z[:, :3][bones[:, 0]], Z[:, :3][bones[:, 1]], bones, mesh, D, thick,
                        len(Z), jacobian=jacobian)


def bone_centres(A, B, bones, mesh, D, thick, n_joints, *, jacobian=True):
    """The centre residuals of segments ``A[i] -> B[i]`` (rows of ``bones`` give their joints,
    for the Jacobian); see :func:`centre_term`."""
    nb = len(A)
    rows_of = np.arange(nb)
    T = B - A
    L = row_norm(T)
    ok = L > 0
    A, B, T, L, rows_of = A[ok], B[ok], T[ok], L[ok], rows_of[ok]
    tb = np.asarray(thick, np.float64)[rows_of]
    n = T / L[:, None]
    Q = 0.5 * (A + B)
    sec = cross_sections(mesh.V, mesh.F, Q, n, REACH * tb, tree=mesh.face_tree,
                         jacobian=bool(jacobian))
    fq, dfq = _fade(sec.spread / tb, *OWN)
    f = np.flatnonzero(sec.found & (fq > 0))
    n, L, tb, fq, dfq, Q, rows_of = n[f], L[f], tb[f], fq[f], dfq[f], Q[f], rows_of[f]
    off = Q - sec.centroid[f]
    sw = np.sqrt(L / D)
    amp = sw * fq
    res = (amp[:, None] * off / tb[:, None]).ravel()
    if jacobian is None:
        return np.bincount(rows_of, (res.reshape(-1, 3) ** 2).sum(1), nb)
    if not jacobian:
        return res, None
    m = len(f)
    eye = np.eye(3)
    P = (eye - n[:, :, None] * n[:, None, :]) / L[:, None, None]    # dn/dx_j = -dn/dx_i = P
    dcx = sec.dc_dx[f]
    dcn = np.einsum("kij,kjl->kil", sec.dc_dn[f], P)
    dsx = sec.ds_dx[f]
    dsn = np.einsum("kj,kjl->kl", sec.ds_dn[f], P)
    # q = (x_i + x_j)/2; residual = amp (q - c) / t, amp = sqrt(L/D) f(spread / t)
    # d/dx_i: (q - c) part: I/2 - dcx/2 + dcn;   d/dx_j: I/2 - dcx/2 - dcn
    # amp: dL/dx_i = -n, dL/dx_j = n; d spread = dsx/2 -+ dsn
    gl = fq / (2.0 * np.sqrt(L * D))
    gs = sw * dfq / tb
    od = off / tb[:, None]
    Ti = amp[:, None, None] / tb[:, None, None]
    half = 0.5 * (eye - dcx)
    blocks = {0: Ti * (half + dcn) + od[:, :, None] * (-gl[:, None] * n + gs[:, None] * (0.5 * dsx - dsn))[:, None, :],
              1: Ti * (half - dcn) + od[:, :, None] * (gl[:, None] * n + gs[:, None] * (0.5 * dsx + dsn))[:, None, :]}
    rows, cols, vals = [], [], []
    r3 = np.repeat(3 * np.arange(m)[:, None] + np.arange(3), 3, axis=1)          # (m, 9)
    for end in (0, 1):
        idx = bones[rows_of, end]
        rows.append(r3.ravel())
        cols.append(np.tile(4 * idx[:, None] + np.arange(3), (1, 3)).ravel())
        vals.append(blocks[end].reshape(m, 9).ravel())
    return res, _jac(rows, cols, vals, 3 * m, n_joints)


def smooth_term(Z, bones, D, *, jacobian=True):
    """:func:`smooth_triplets` of every chain joint of the graph."""
    k, a, b = chain_neighbours(bones, len(Z))
    return smooth_triplets(Z, k, a, b, D, jacobian=jacobian)


def smooth_triplets(Z, k, a, b, D, *, jacobian=True):
    """Residuals of the chains' smoothness, 4 per chain joint ``k`` with neighbours ``a``,
    ``b``, and their Jacobian:

    * ``sqrt(h_k / (2D)) (u_out - u_in)``: their squares sum to ``(h_k / D)(1 - cos theta_k)``
      (``h_k`` the harmonic mean of the joint's two bone lengths: a bend's weight vanishes with
      its shorter bone, so a bone shrinking to nothing cannot make the turn's direction, and J,
      jump);
    * ``(r_k - (r_a + r_b) / 2) / sqrt(m_k D)`` (``m_k`` their mean): the radius's second
      difference along the chain, per length (a linear taper costs nothing). It also fixes the
      radius of a joint the surface hardly maps near (the fit alone leaves it free).
    """
    J, n_in = len(Z), len(k)
    X = Z[:, :3]
    rows_of = np.arange(n_in)
    vin, vout = X[k] - X[a], X[b] - X[k]
    lin, lout = row_norm(vin), row_norm(vout)
    ok = (lin > 0) & (lout > 0)
    k, a, b, vin, vout, lin, lout = k[ok], a[ok], b[ok], vin[ok], vout[ok], lin[ok], lout[ok]
    rows_of = rows_of[ok]
    uin, uout = vin / lin[:, None], vout / lout[:, None]
    ell = 2.0 * lin * lout / (lin + lout)
    mean = 0.5 * (lin + lout)
    sw = np.sqrt(ell / (2.0 * D))
    du = uout - uin
    dr = Z[k, 3] - 0.5 * (Z[a, 3] + Z[b, 3])
    sr = 1.0 / np.sqrt(mean * D)
    m = len(k)
    res = np.concatenate([(sw[:, None] * du).ravel(), sr * dr])
    if jacobian is None:                     # per triplet: the value of each given row
        val = (sw[:, None] * du) ** 2
        return np.bincount(rows_of, val.sum(1) + (sr * dr) ** 2, n_in)
    if not jacobian:
        return res, None
    eye = np.eye(3)
    Pin = (eye - uin[:, :, None] * uin[:, None, :]) / lin[:, None, None]     # du_in/dx_k
    Pout = (eye - uout[:, :, None] * uout[:, None, :]) / lout[:, None, None]  # du_out/dx_b
    g = 1.0 / (2.0 * np.sqrt(2.0 * ell * D))                  # d sqrt(l / (2D)) / dl
    # dh/dlin = 2 lout^2 / (lin + lout)^2 (and likewise); dlin/dx_k = uin, dlin/dx_a = -uin,
    # dlout/dx_b = uout, dlout/dx_k = -uout
    gi = g * 2.0 * lout ** 2 / (lin + lout) ** 2
    go = g * 2.0 * lin ** 2 / (lin + lout) ** 2
    dsw = {"k": gi[:, None] * uin - go[:, None] * uout, "a": -gi[:, None] * uin,
           "b": go[:, None] * uout}
    dres = {"k": -Pout - Pin, "a": Pin, "b": Pout}
    # d sr / d mean = -sr / (2 mean); dmean = (dlin + dlout) / 2
    gm = -0.5 * sr / mean * dr * 0.5
    dmean = {"k": gm[:, None] * (uin - uout), "a": -gm[:, None] * uin, "b": gm[:, None] * uout}
    rows, cols, vals = [], [], []
    r3 = np.repeat(3 * np.arange(m)[:, None] + np.arange(3), 3, axis=1)          # (m, 9)
    rr = 3 * m + np.arange(m)
    for who, idx in (("k", k), ("a", a), ("b", b)):
        blk = sw[:, None, None] * dres[who] + du[:, :, None] * dsw[who][:, None, :]
        c3 = 4 * idx[:, None] + np.arange(3)
        rows += [r3.ravel(), np.repeat(rr, 3), rr]
        cols += [np.tile(c3, (1, 3)).ravel(), c3.ravel(), 4 * idx + 3]
        vals += [blk.reshape(m, 9).ravel(), dmean[who].ravel(),
                 sr * (1.0 if who == "k" else -0.5)]
    return res, _jac(rows, cols, vals, 4 * m, J)


def contain_term(Z, bones, inside, tree, points, normals, D, *, jacobian=True):
    """Residuals ``sqrt(l_b / (m D)) max(0, h_q) / D`` at the ``m`` points ``BONE_POINTS``
    of every bone ``b`` (length ``l_b``) that lie outside the mesh (``inside``: its exact
    inside test), ``h_q`` the height of point ``q`` above the tangent plane of its nearest
    surface sample (``tree``: a KD-tree of ``points``, with their ``normals``); and their
    Jacobian (the nearest sample held). Zero for a point inside; at the surface, where it
    leaves, ``h`` is zero too."""
    J, B = len(Z), len(bones)
    u = BONE_POINTS
    m = len(u)
    X = Z[:, :3]
    i, j = bones[:, 0], bones[:, 1]
    vb = X[i] - X[j]
    lb = row_norm(vb)
    Q = (u[None, :, None] * X[i][:, None, :] + (1 - u)[None, :, None] * X[j][:, None, :]).reshape(-1, 3)
    res = np.zeros(len(Q))
    out = np.flatnonzero(~inside(Q))
    if len(out):
        _, nn = tree.query(Q[out])
        nq = normals[nn]
        h = np.maximum(np.einsum("ij,ij->i", Q[out] - points[nn], nq), 0.0)
        res[out] = np.sqrt(lb[out // m] / (m * D)) * h / D
    if not jacobian:
        return res, None
    act = out[res[out] > 0]
    hp = res[act] / np.sqrt(lb[act // m] / (m * D)) * D if len(act) else np.zeros(0)
    nqa = nq[res[out] > 0] if len(out) else np.zeros((0, 3))
    uq = u[act % m]
    bq = act // m
    lq = lb[bq]
    sw = np.sqrt(lq / (m * D))
    # d sqrt(l/(mD)) / dx_i = (1 / (2 sqrt(l m D))) (x_i - x_j)/l
    ub = vb[bq] / np.maximum(lq, 1e-300)[:, None]
    g = 1.0 / (2.0 * np.sqrt(lq * m * D))
    hd = hp / D
    di = sw[:, None] * uq[:, None] * nqa / D + (hd * g)[:, None] * ub
    dj = sw[:, None] * (1 - uq)[:, None] * nqa / D - (hd * g)[:, None] * ub
    rows = np.repeat(act, 3)
    c3 = np.arange(3)
    return res, _jac([rows, rows], [(4 * i[bq][:, None] + c3).ravel(), (4 * j[bq][:, None] + c3).ravel()],
                     [di.ravel(), dj.ravel()], len(res), J)
