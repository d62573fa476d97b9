"""curveskel_addon.framing (no bpy): the preview camera framed at any size, a blank picture told
apart."""

import numpy as np
import pytest

from curveskel_addon.core import CurveSkelError
from curveskel_addon.framing import FILL, fit_camera, half_fov, picture_coverage, view_angles


def rotation(ax, ay, az):
    """Blender's Euler XYZ as a matrix (columns: the camera's axes in the world)."""
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    X = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Z @ Y @ X


def projected(P, fit, R):
    """(x / depth, y / depth, depth) of points P seen from the fitted camera."""
    q = (P - fit.location) @ R
    d = -q[:, 2]
    return q[:, 0] / d, q[:, 1] / d, d


@pytest.fixture
def cloud():
    rng = np.random.default_rng(3)
    return rng.normal(size=(500, 3)) * [2.0, 0.5, 1.0] + [3.0, -1.0, 2.0]


@pytest.mark.parametrize("angles", [(np.radians(72), 0.0, np.radians(35)), (0.3, -0.8, 2.0)])
def test_every_point_in_the_frame_and_the_frame_tight(cloud, angles):
    R = rotation(*angles)
    tx, ty = half_fov(50.0, 36.0, 640, 480)
    fit = fit_camera(cloud, R, tx, ty)
    x, y, d = projected(cloud, fit, R)
    assert d.min() > 0
    assert np.abs(x).max() <= FILL * tx * (1 + 1e-9) and np.abs(y).max() <= FILL * ty * (1 + 1e-9)
    # the nearer camera: on one axis both sides are touched (a camera any nearer cuts a point off)
    tight = [np.isclose(v.max(), FILL * t) and np.isclose(-v.min(), FILL * t) for v, t in ((x, tx), (y, ty))]
    assert any(tight)
    assert fit.clip_start < d.min() and fit.clip_end > d.max()
    assert np.isclose(fit.near, d.min()) and np.isclose(fit.far, d.max())


@pytest.mark.parametrize("scale", [1500.0, 0.001, 1e-6])
def test_framing_follows_the_size(cloud, scale):
    """Scaled and moved, the camera scales and moves with the points, its clip distances too:
    the same picture at 1,500 units or 0.001 (Blender's 0.1 .. 1000 defaults see neither)."""
    R = rotation(np.radians(72), 0.0, np.radians(35))
    tx, ty = half_fov(50.0, 36.0, 640, 480)
    ref = fit_camera(cloud, R, tx, ty)
    shift = np.array([10.0, -7.0, 3.0]) * scale
    fit = fit_camera(cloud * scale + shift, R, tx, ty)
    assert np.allclose(fit.location, ref.location * scale + shift, rtol=1e-9, atol=1e-9 * scale)
    for k in ("distance", "near", "far", "clip_start", "clip_end"):
        assert np.isclose(getattr(fit, k), getattr(ref, k) * scale, rtol=1e-9)
    if scale == 1500.0:
        assert fit.far > 1000.0                        # beyond Blender's default clip end
    if scale == 0.001:
        assert fit.near < 0.1                          # nearer than its default clip start


def test_balls_are_framed_whole():
    """A ball around each point stays inside the frame (sampled on its surface)."""
    rng = np.random.default_rng(5)
    C = rng.uniform(-1, 1, size=(40, 3))
    r = rng.uniform(0.05, 0.6, size=40)
    R = rotation(np.radians(72), 0.0, np.radians(125))
    tx, ty = half_fov(50.0, 36.0, 480, 640)            # portrait
    fit = fit_camera(C, R, tx, ty, radii=r)
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    S = (C[:, None, :] + r[:, None, None] * u[None]).reshape(-1, 3)
    x, y, d = projected(S, fit, R)
    assert d.min() > fit.clip_start and d.max() < fit.clip_end
    assert np.abs(x).max() <= FILL * tx and np.abs(y).max() <= FILL * ty
    assert max(np.abs(x).max() / tx, np.abs(y).max() / ty) > 0.97 * FILL    # and not far off
    assert fit.near <= d.min() + 1e-9                  # the balls' nearest points are counted


def test_half_fov_fits_the_sensor_to_the_longer_side():
    assert half_fov(50.0, 36.0, 640, 480) == pytest.approx((0.36, 0.27))
    assert half_fov(50.0, 36.0, 480, 640) == pytest.approx((0.27, 0.36))


def test_view_looks_across_the_longer_side():
    wide_x = np.array([[0, 0, 0], [4, 1, 1.0]])
    assert view_angles(wide_x)[2] == pytest.approx(np.radians(35))
    assert view_angles(wide_x[:, [1, 0, 2]])[2] == pytest.approx(np.radians(125))


@pytest.mark.parametrize("P", [np.zeros((0, 3)), np.ones((5, 3)), np.array([[0, 0, 0], [np.nan, 1, 1]])])
def test_nothing_to_frame_is_refused(P):
    with pytest.raises(CurveSkelError):
        fit_camera(P, np.eye(3), 0.3, 0.2)


def test_picture_coverage():
    h, w = 60, 80
    bg = np.array([0.85, 0.86, 0.9])
    img = np.ones((h, w, 4))
    img[..., :3] = bg
    blank = picture_coverage(img)
    assert blank["fraction"] == 0 and blank["centre"] is None and np.allclose(blank["background"], bg)
    img[..., :3] += 0.01 * np.sin(np.arange(w))[None, :, None]       # below the tolerance
    assert picture_coverage(img)["fraction"] == 0
    img[10:30, 50:70, 0] = 0.2                                       # a 20 x 20 square
    c = picture_coverage(img)
    assert c["fraction"] == pytest.approx(400 / (h * w))
    assert c["centre"] == pytest.approx((60 / 80, 20 / 60))
    assert c["box"] == pytest.approx((50 / 80, 10 / 60, 70 / 80, 30 / 60))
