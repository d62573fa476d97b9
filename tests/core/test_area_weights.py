"""Area weights make the skeleton independent of how densely the surface is sampled (issue 5,
improvement 3; the paper's future work 2: "skeletons of the detailed meshes are more accurate").

The test shape must be one the fat curve cannot fit exactly, otherwise every weighting has the
same optimum (a cylinder is fitted exactly whatever its sampling). So: a capsule whose radius
ripples, ``r(z) = 1 + A cos(2 pi z / P)``, with a period P several times shorter than the joint
spacing; the skeleton cannot follow the ripple and has to average it. The area-weighted optimum
is the surface average (``R^2 ~ mean r^2``); the vertex sum averages over *vertices*. The
non-uniform mesh puts 5x more rings on the outer half of every ripple (the crests) than on the
inner half, so without area weights the fitted radius is pulled towards the crests.

Measured (spacing 0.08, P = 0.1, A = 0.12, seeds 0-2): mean body radius of the dense mesh vs the
uniform one 0.3-0.7 % off with area weights, 4.0-4.3 % without.

The skeleton comparison uses the fixed mapping of the paper (``refit_mapping=False``). With the
re-fit, a vertex keeps a new closest point only when it lowers its own term, so vertices slide
along the axis until their distance matches the radius; on this shape the radius profile then
varies by about 8 % along the body whatever the sampling or weighting, which hides the effect of
the weights (measured; reported to the re-fit's owner).
"""

import numpy as np
import pytest

from curveskel_addon.core import skeletonize
from meshes import tube_along

BODY = (0.5, 5.5)          # compare away from the caps (the ends of a skeleton are free to vary)
ZQ = np.linspace(*BODY, 51)
SPACING = 0.08             # about 50 joints: every bone spans several ripple periods
# Isolate the weighting: the other improvements (pruning, merging, the joint budget) change the
# joint layout being compared and are tested on their own.
ISOLATE = dict(centre=False, prune=0.0, simplify=0.0, max_joints=0, max_iterations=100)


def ripple_capsule(density_ratio=1.0, P=0.1, A=0.12, L=6.0, per_period=8, n_around=24):
    """Rippled capsule along z in [0, L]; rings ``density_ratio`` times denser on the crests.

    The ring heights are ``z = s - beta P/(2 pi) sin(2 pi s / P)`` for uniform s, whose
    derivative ``1 - beta cos`` gives the density ratio ``(1 + beta) / (1 - beta)`` between
    troughs and crests.
    """
    beta = (density_ratio - 1) / (density_ratio + 1)
    s = np.linspace(0, L, int(round(L / P)) * per_period + 1)
    z = s - beta * P / (2 * np.pi) * np.sin(2 * np.pi * s / P)
    r = 1 + A * np.cos(2 * np.pi * z / P)
    return tube_along(np.c_[0 * z, 0 * z, z], r, n_around, 8)


def profile(sk):
    """(51, 4) joints' x, y, z, r interpolated along z over the body (the skeleton is a chain
    along z)."""
    J = sk.joints[np.argsort(sk.joints[:, 2])]
    return np.stack([np.interp(ZQ, J[:, 2], J[:, k]) for k in range(4)], 1)


def body_axis_offset(sk):
    J = sk.joints
    J = J[(J[:, 2] > BODY[0]) & (J[:, 2] < BODY[1])]
    return np.hypot(J[:, 0], J[:, 1])


@pytest.fixture(scope="module")
def meshes():
    uniform, dense = ripple_capsule(1.0), ripple_capsule(5.0)
    assert len(uniform[0]) == len(dense[0])              # same vertex count, other distribution
    return uniform, dense


@pytest.mark.parametrize("seed", [0, 1])
def test_area_weights_make_the_radius_independent_of_the_sampling(meshes, seed):
    (Vu, Fu), (Vd, Fd) = meshes
    kw = dict(spacing=SPACING, refit_mapping=False, seed=seed, **ISOLATE)
    ref = profile(skeletonize(Vu, Fu, area_weighted=True, **kw))
    err = {}
    for aw in (True, False):
        p = profile(skeletonize(Vd, Fd, area_weighted=aw, **kw))
        err[aw] = (abs(p[:, 3].mean() / ref[:, 3].mean() - 1),          # mean radius, relative
                   np.abs(p[:, 3] - ref[:, 3]).mean() / ref[:, 3].mean())  # profile, relative
    # Weighted: the same radius as the uniform mesh within 1 % (profile within 2.5 %).
    assert err[True][0] < 0.01 and err[True][1] < 0.025, err
    # Without weights: measurably further off (pulled towards the densely sampled crests).
    assert err[False][0] > 0.03 and err[False][0] > 3 * err[True][0], err
    assert err[False][1] > err[True][1], err
    # The area-weighted radius is near the surface average sqrt(mean r^2) = 1.0036.
    assert ref[:, 3].mean() == pytest.approx(1.0036, rel=0.02)


def test_area_weighted_axis_matches_the_uniform_mesh(meshes):
    """The axis stays on the z axis within a few % of the radius."""
    (Vu, Fu), (Vd, Fd) = meshes
    su = skeletonize(Vu, Fu, spacing=SPACING, refit_mapping=False, **ISOLATE)
    sd = skeletonize(Vd, Fd, spacing=SPACING, refit_mapping=False, **ISOLATE)
    assert body_axis_offset(sd).max() < 0.03 and body_axis_offset(su).max() < 0.03
    pu, pd = profile(su), profile(sd)
    assert np.linalg.norm(pd[:, :2] - pu[:, :2], axis=1).max() < 0.03
