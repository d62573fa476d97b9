"""The terms of the objective J, each a sum of squared residuals with an exact Jacobian.

Every term is scale-free: lengths are measured in units of D (the diameter of the mesh's
minimum enclosing ball) and integrals are normalised, so a scaled, moved or rotated mesh has
the same J. With ``z`` the joints' (x, y, z, r) stacked (4 per joint), each term gives its
residuals ``rho(z)`` and their Jacobian ``d rho / d z`` (a sparse ``(m, 4J)`` matrix); its
value is ``sum rho^2`` and its gradient ``2 (d rho/dz)^T rho``. The mapping sigma (each
sample's bone and parameter ``t``) is held fixed here: :mod:`.objective` chooses it.

fit
    How far each surface point lies from the silhouette of its skeleton point, the paper's
    own residual: ``(1/A) sum_s w_s h(d_s / L_s)``, ``d_s`` the soft minimum (softness a
    share of ``L_s``) over the sample's few nearest cones of ``|p_s - sigma| - r(sigma)``, so
    the distance to the silhouette changes smoothly when another cone becomes the nearest;
    ``h`` the pseudo-Huber loss (``z^2`` within a thickness, ``2|z|`` beyond), ``w_s`` the
    area of quadrature point ``p_s`` (:mod:`..geometry.samples`), A the surface area, ``L_s``
    the thickness of the sample's part (each part the same weight for the same relative
    error). The paper's E (eq. 8) squares the squared distances, ``(|p - sigma|^2 - r^2)^2``:
    it is computed and reported (:func:`paper_energy`), but as J's fit it weighs a flat
    section's far side so much that the balls bulge out of its near sides (a flat-sided
    torso: the silhouette 0.02 D out), and in units of D a finger's errors count 10^4
    times less than a torso's ten times thicker.
centre
    How far the points along each bone lie from the area centroids of the mesh's cross-sections
    through them, across the bone (:mod:`..geometry.sections`), relative to the part's
    thickness: ``sum_b (l_b / D) mean_q |q - c_q|^2 / t_b^2`` over the bone's two Gauss
    points ``q``, ``l_b`` the bone's length, ``t_b`` the thickness of the Reeb regions it
    explains, each section taken within a disc of a few ``t_b`` (the part's own). The integral along the curve of its squared
    distance from the sections' centres, each in units of its part's thickness. ``t_b`` is the
    mesh's, not the skeleton's: a bone cannot lower the term by changing its radius.
smooth
    How much the chains turn, and their radii bend: ``sum_k (1 - cos theta_k) +
    (r_k - (r_a + r_b) / 2)^2 / (m_k D)`` over chain joints, ``theta_k`` the angle between a
    joint's two bones (0 straight on, 1 at a right angle, whatever the size), ``m_k`` the mean
    of its two bone lengths (the radius's second difference per length).
contain
    How far the bones come closer to the surface than a margin, or leave the mesh: at points
    along every bone, their signed height ``s_q`` over the surface (:func:`surface_heights`),
    ``sum_q (l_q / D) (margin / D)^2 softplus((s_q + margin) / margin)^2``, ``margin`` a
    share of the first approximation's spacing (``CONFIG.objective.contain_margin``): about
    the squared height beyond the surface, next to nothing a few margins inside, and smooth
    between (a hinge at the margin would be invisible to a step until it crosses).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..config import CONFIG
from ..geometry.rows import row_norm

__all__ = ["fit_term", "fit_values", "fit_residuals", "paper_energy", "centre_term", "bone_centres", "smooth_term", "smooth_triplets",
           "contain_term", "bone_contain", "surface_heights", "chain_neighbours", "BONE_POINTS"]

#: Where along every bone (ends included) containment is measured.
BONE_POINTS = np.linspace(0.0, 1.0, CONFIG.objective.bone_points)


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


def _pseudo_huber(z):
    """``psi(z)`` with ``psi^2 = 2 (sqrt(1 + z^2) - 1)``, sign of z (about z^2 for small z,
    2|z| for large), and ``dpsi/dz``: a least-squares residual whose square is the
    pseudo-Huber loss."""
    q = np.sqrt(1.0 + z * z)
    psi = np.sign(z) * np.sqrt(2.0 * (q - 1.0))
    small = np.abs(z) < 1e-4
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(small, 1.0 - 0.375 * z * z, np.abs(z) / (q * np.where(small, 1.0, np.abs(psi))))
    return np.where(small, z * (1.0 - 0.125 * z * z), psi), d


def fit_residuals(Z, samples, bones, bone, t):
    """Per sample: ``d = p - sigma``, ``rho = r(sigma)`` and the paper's ``e = |d|^2 - rho^2``."""
    ij = bones[bone]
    S = t[:, None] * Z[ij[:, 0]] + (1.0 - t)[:, None] * Z[ij[:, 1]]
    d = samples.points - S[:, :3]
    rho = S[:, 3]
    return d, rho, np.einsum("ij,ij->i", d, d) - rho * rho


def paper_energy(Z, samples, bones, bone, t, area, D) -> float:
    """The paper's E (eq. 8) over the samples, in units of D: ``(1/A) sum w e^2 / D^4``."""
    e = fit_residuals(Z, samples, bones, bone, t)[2]
    return float(np.dot(samples.weights, e * e)) / (area * D ** 4)


def fit_values(P, w, S, area, scale):
    """Each sample's share of the fit: ``w/A h((|p - s| - r(s)) / scale)`` for skeleton
    points ``S`` (rows x, y, z, r); ``h`` the pseudo-Huber loss (see :func:`fit_term`)."""
    z = (row_norm(P - S[:, :3]) - S[:, 3]) / scale
    return w / area * 2.0 * (np.sqrt(1.0 + z * z) - 1.0)


def fit_term(Z, samples, bones, bone, area, scale, *, softness=0.0, jacobian=True):
    """Residuals ``sqrt(w_s / A) psi(v_s / scale_s)`` (and Jacobian), ``psi^2`` the
    pseudo-Huber loss (squares for errors within the part's thickness, linear beyond: a point
    mapped far from its bone, at a junction, must not inflate the ball), ``v_s`` the sample's
    distance to the silhouette: with one bone per sample ``|p_s - sigma_s| - r(sigma_s)``,
    ``sigma_s`` the closest point of the bone's axis; with ``k`` candidate bones per sample
    (``bone`` of shape (s, k)), the soft minimum ``-tau log sum_k exp(-v_sk / tau)``,
    ``tau = softness * scale_s``, of their values.

    The bones are held, the points on them are not: sigma is the closest point of the bone
    for the joints as they are, and the Jacobian follows it (along a tapered bone the radius
    at sigma changes as sigma slides; holding sigma's parameter instead makes a Gauss-Newton
    step mispredict the fit). The soft minimum makes the fit smooth where the nearest cone
    changes (the least of two smooth functions has a kink there, which a step holding the
    choice cannot see), and a sample inside two cones at a junction asks both to shrink.

    Parameters
    ----------
    Z : (J, 4) float
        Joints (x, y, z, r).
    samples : Samples
    bones : (B, 2) int
    bone : (s,) or (s, k) int
        Each sample's bone (its candidates).
    area : float
    scale : float or (s,) float
        The thickness of each sample's part: the unit its distance is measured in.
    softness : float
        tau in units of ``scale`` (for ``k > 1``).
    """
    bone = np.asarray(bone).reshape(len(samples.points), -1)
    n, k = bone.shape
    sc = np.broadcast_to(np.asarray(scale, np.float64), (n,))
    ij = bones[bone]                                            # (n, k, 2)
    Zi, Zj = Z[ij[:, :, 0]], Z[ij[:, :, 1]]
    dv = Zi[:, :, :3] - Zj[:, :, :3]                            # d = x_i - x_j
    dd = np.einsum("nkc,nkc->nk", dv, dv)
    w = samples.points[:, None, :] - Zj[:, :, :3]
    t_free = np.einsum("nkc,nkc->nk", w, dv) / np.where(dd > 0, dd, 1.0)
    t = np.clip(np.where(dd > 0, t_free, 0.0), 0.0, 1.0)
    S = t[:, :, None] * Zi + (1.0 - t)[:, :, None] * Zj
    d = samples.points[:, None, :] - S[:, :, :3]
    dist = np.sqrt(np.einsum("nkc,nkc->nk", d, d))
    v = dist - S[:, :, 3]
    if k > 1:
        tau = (softness * sc)[:, None]
        m = v.min(axis=1, keepdims=True)
        with np.errstate(under="ignore"):          # a far cone's weight is 0
            e = np.exp(-(v - m) / tau)
        e[e < 1e-200] = 0.0                         # (and no subnormal products below)
        W = e.sum(axis=1, keepdims=True)
        soft = (m - tau * np.log(W))[:, 0]
        share = e / W                                           # d soft / d v_k
    else:
        soft, share = v[:, 0], np.ones((n, 1))
    z = soft / sc
    psi, dpsi = _pseudo_huber(z)
    c = np.sqrt(samples.weights / area)
    res = c * psi
    if not jacobian:
        return res, None
    # v = |p - s| - r(s), s = t x_i + (1 - t) x_j, t the closest point's parameter:
    # dv/dx_i = -t u - (r_i - r_j) dt/dx_i, dv/dr_i = -t (and with 1 - t for j), u the unit
    # vector from s to p; d|p - s|/dt = 0 at an inner closest point, dt = 0 where t is clipped;
    # dt/dx_i = ((p - x_j) - 2 t d) / d.d, dt/dx_j = (2 t d - d - (p - x_j)) / d.d
    u = d / np.maximum(dist, 1e-300)[:, :, None]
    inner = ((t_free > 0) & (t_free < 1) & (dd > 0))[:, :, None]
    inv = (1.0 / np.where(dd > 0, dd, 1.0))[:, :, None]
    dt_i = np.where(inner, (w - 2.0 * t[:, :, None] * dv) * inv, 0.0)
    dt_j = np.where(inner, (2.0 * t[:, :, None] * dv - dv - w) * inv, 0.0)
    taper = (Zi[:, :, 3] - Zj[:, :, 3])[:, :, None]
    f = (c * dpsi / sc)[:, None, None] * share[:, :, None]
    Gi = np.concatenate([-t[:, :, None] * u - taper * dt_i, -t[:, :, None]], axis=2) * f
    Gj = np.concatenate([-(1.0 - t)[:, :, None] * u - taper * dt_j, -(1.0 - t)[:, :, None]],
                        axis=2) * f
    rows = np.repeat(np.arange(n), 4 * k)
    col4 = np.arange(4)
    ci = (4 * ij[:, :, 0, None] + col4).reshape(n, -1).ravel()
    cj = (4 * ij[:, :, 1, None] + col4).reshape(n, -1).ravel()
    return res, _jac([rows, rows], [ci, cj], [Gi.ravel(), Gj.ravel()], n, len(Z))


#: Where along a bone the centring is measured, and how much each point weighs: the two-point
#: Gauss rule, exact for the integral of a squared offset that varies linearly along the bone
#: (a zig-zag whose bones' middles sit on the centres is off them here).
GAUSS_U = np.array([0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0)])


def centre_term(Z, bones, mesh, D, thick, *, jacobian=True):
    """Residuals ``sqrt(l_b / (2D)) (q - c) / t_b`` at the two Gauss points ``q`` of every
    bone (3 each) and their Jacobian: ``c`` the area centroid of the solid's cross-section
    through ``q`` across the bone within ``reach`` thicknesses of ``q``
    (:class:`..config.ObjectiveConfig`, :mod:`..geometry.disc_sections`), ``l_b`` the bone's
    length, ``t_b = thick[b]`` the thickness of its part. The disc keeps the section the
    part's own (at a limb's root the plane cuts the body too, mostly beyond it) and its centroid
    continuous: where two loops of a section join at a saddle the region grows by the area
    joining them, where choosing one loop would jump. ``mesh`` is a :class:`..mesh.Mesh`.

    Points along the bones, not the joints: a long bone cutting across a part is off its
    sections' centres however well its two ends are placed.

    ``jacobian=None`` returns the value per bone instead (for the moves' estimates)."""
    return bone_centres(Z[:, :3][bones[:, 0]], Z[:, :3][bones[:, 1]], bones, mesh, D, thick,
                        len(Z), jacobian=jacobian)


def bone_centres(A, B, bones, mesh, D, thick, n_joints, *, jacobian=True):
    """The centre residuals of segments ``A[i] -> B[i]`` (rows of ``bones`` give their joints,
    for the Jacobian); see :func:`centre_term`."""
    nb = len(A)
    T = B - A
    L = row_norm(T)
    ok = np.flatnonzero(L > 0)
    nq = len(GAUSS_U)
    rows_of = np.repeat(ok, nq)                       # the bone of each point
    u = np.tile(GAUSS_U, len(ok))                     # q = u A + (1 - u) B
    A, B, L = A[rows_of], B[rows_of], L[rows_of]
    n = (B - A) / L[:, None]
    tb = np.asarray(thick, np.float64)[rows_of]
    Q = u[:, None] * A + (1.0 - u)[:, None] * B
    sec = mesh.discs(Q, n, CONFIG.objective.reach * tb, jacobian=bool(jacobian))
    off = Q - sec.centroid
    sw = np.sqrt(L / (nq * D))
    res = (sw[:, None] * off / tb[:, None]).ravel()
    if jacobian is None:
        return np.bincount(rows_of, (res.reshape(-1, 3) ** 2).sum(1), nb)
    if not jacobian:
        return res, None
    m = len(Q)
    eye = np.eye(3)
    P = (eye - n[:, :, None] * n[:, None, :]) / L[:, None, None]    # dn/dx_j = -dn/dx_i = P
    dcn = np.einsum("kij,kjl->kil", sec.dc_dn, P)
    # residual = sw (q - c) / t, sw = sqrt(L / (nq D)):
    # d(q - c)/dx_i = u (I - dc/dx) + dcn,  d(q - c)/dx_j = (1 - u)(I - dc/dx) - dcn;
    # dL/dx_i = -n, dL/dx_j = n
    gl = 1.0 / (2.0 * np.sqrt(L * nq * D))
    od = off / tb[:, None]
    Ti = sw[:, None, None] / tb[:, None, None]
    I_c = eye - sec.dc_dx
    uu = u[:, None, None]
    blocks = {0: Ti * (uu * I_c + dcn) - od[:, :, None] * (gl[:, None] * n)[:, None, :],
              1: Ti * ((1.0 - uu) * I_c - dcn) + od[:, :, None] * (gl[:, None] * n)[:, None, :]}
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

    * ``(u_out - u_in) / sqrt(2)``: their squares sum to ``1 - cos theta_k``, the turn at the
      joint: 0 straight on, 1 at a right angle, 2 for a hairpin, whatever the bones' lengths
      (weighting a turn by a length would let a knot of short bones, or a bone stretched to no
      end, lower it).
    * ``(r_k - (r_a + r_b) / 2) / sqrt(m_k D)``: the radius's second difference along the
      chain, per length (a linear taper costs nothing). It also fixes the radius of a joint
      the surface hardly maps near (the fit alone leaves it free).

    ``jacobian=None`` returns the value per given joint instead (for the moves' estimates).
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
    mean = 0.5 * (lin + lout)
    sw = np.full(len(k), np.sqrt(0.5))
    du = uout - uin
    dr = Z[k, 3] - 0.5 * (Z[a, 3] + Z[b, 3])
    sr = 1.0 / np.sqrt(mean * D)
    m = len(k)
    res = np.concatenate([(sw[:, None] * du).ravel(), sr * dr])
    if jacobian is None:
        return np.bincount(rows_of, ((sw[:, None] * du) ** 2).sum(1) + (sr * dr) ** 2, n_in)
    if not jacobian:
        return res, None
    eye = np.eye(3)
    Pin = (eye - uin[:, :, None] * uin[:, None, :]) / lin[:, None, None]     # du_in/dx_k
    Pout = (eye - uout[:, :, None] * uout[:, None, :]) / lout[:, None, None]  # du_out/dx_b
    # d sqrt(D / m) / dm = -sw / (2 m);  d sr / dm = -sr / (2 m);  dm = (dlin + dlout) / 2,
    # dlin/dx_k = uin, dlin/dx_a = -uin, dlout/dx_b = uout, dlout/dx_k = -uout
    dmk, dma, dmb = 0.5 * (uin - uout), -0.5 * uin, 0.5 * uout
    gw = np.zeros(len(k))
    gr = -sr / (2.0 * mean) * dr
    dres = {"k": -Pout - Pin, "a": Pin, "b": Pout}
    dm = {"k": dmk, "a": dma, "b": dmb}
    rows, cols, vals = [], [], []
    r3 = np.repeat(3 * np.arange(m)[:, None] + np.arange(3), 3, axis=1)          # (m, 9)
    rr = 3 * m + np.arange(m)
    for who, idx in (("k", k), ("a", a), ("b", b)):
        blk = sw[:, None, None] * dres[who] + du[:, :, None] * (gw[:, None] * dm[who])[:, None, :]
        c3 = 4 * idx[:, None] + np.arange(3)
        rows += [r3.ravel(), np.repeat(rr, 3), rr]
        cols += [np.tile(c3, (1, 3)).ravel(), c3.ravel(), 4 * idx + 3]
        vals += [blk.reshape(m, 9).ravel(), (gr[:, None] * dm[who]).ravel(),
                 sr * (1.0 if who == "k" else -0.5)]
    return res, _jac(rows, cols, vals, 4 * m, J)


def surface_heights(Q, inside, tree, points, normals):
    """Signed height of points ``Q`` over the surface, and its gradient: inside the mesh (its
    exact test ``inside``) the height above the tangent plane of the nearest surface sample
    (negative), outside the larger of that and the distance to the sample (a point outside a
    concave part can lie below a tangent plane). Continuous where a point crosses the surface:
    both are zero there."""
    _, nn = tree.query(Q)
    p, n = points[nn], normals[nn]
    w = Q - p
    h = np.einsum("ij,ij->i", w, n)
    dist = row_norm(w)
    out = ~inside(Q)
    far = out & (dist > h)
    s = np.where(far, dist, h)
    g = np.where(far[:, None], w / np.maximum(dist, 1e-300)[:, None], n)
    return s, g


def contain_term(Z, bones, inside, tree, points, normals, D, margin, *, jacobian=True):
    """:func:`bone_contain` of every bone of the graph (``margin[b]`` per bone)."""
    X = Z[:, :3]
    return bone_contain(X[bones[:, 0]], X[bones[:, 1]], bones, inside, tree, points, normals, D,
                        margin, len(Z), jacobian=jacobian)


def bone_contain(A, B, bones, inside, tree, points, normals, D, margin, n_joints, *,
                 jacobian=True):
    """Residuals ``sqrt(l_b / (m D)) (margin_b / D) softplus((s_q + margin_b) / margin_b)`` at
    the ``m`` points ``BONE_POINTS`` of every segment ``A[b] -> B[b]`` (length ``l_b``; rows of
    ``bones`` give its joints, for the Jacobian), ``s_q`` the point's signed height over the
    surface (:func:`surface_heights`), ``margin_b`` how deep inside a bone keeps (a curve
    grazing the surface from inside is outside a step later); and their Jacobian (the nearest
    sample held). ``jacobian=None`` returns the value per segment (for the moves' estimates)."""
    u = BONE_POINTS
    m = len(u)
    nb = len(A)
    vb = A - B
    lb = row_norm(vb)
    Q = (u[None, :, None] * A[:, None, :] + (1 - u)[None, :, None] * B[:, None, :]).reshape(-1, 3)
    s, g = surface_heights(Q, inside, tree, points, normals)
    bq_all = np.repeat(np.arange(nb), m)
    mq = np.repeat(np.broadcast_to(np.asarray(margin, np.float64), (nb,)), m)
    # softplus of the height over the margin line, in margins: ~0 deep inside, 1.3 margins on
    # the surface, the height itself beyond; smooth, so a step towards the surface sees it
    x = (s + mq) / mq
    sp = np.logaddexp(0.0, x)
    sw_all = np.sqrt(lb[bq_all] / (m * D))
    res = sw_all * mq * sp / D
    if jacobian is None:
        return np.bincount(bq_all, res * res, nb)
    if not jacobian:
        return res, None
    act = np.flatnonzero(res > 1e-12 * np.maximum(mq, 1e-300) / D)
    bq, uq = bq_all[act], u[act % m]
    lq = lb[bq]
    sw = sw_all[act]
    # d sqrt(l/(mD)) / dx_i = (1 / (2 sqrt(l m D))) (x_i - x_j)/l;  d sp / ds = sigmoid(x) / margin
    ub = vb[bq] / np.maximum(lq, 1e-300)[:, None]
    gl = 1.0 / (2.0 * np.sqrt(np.maximum(lq, 1e-300) * m * D))
    hd = mq[act] * sp[act] / D
    slope = (sw / D) * (0.5 * (1.0 + np.tanh(0.5 * x[act])))      # sw margin/D dsp/ds
    di = (slope * uq)[:, None] * g[act] + (hd * gl)[:, None] * ub
    dj = (slope * (1 - uq))[:, None] * g[act] - (hd * gl)[:, None] * ub
    rows = np.repeat(act, 3)
    c3 = np.arange(3)
    i, j = bones[bq, 0], bones[bq, 1]
    return res, _jac([rows, rows], [(4 * i[:, None] + c3).ravel(), (4 * j[:, None] + c3).ravel()],
                     [di.ravel(), dj.ravel()], len(res), n_joints)
