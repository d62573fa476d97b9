"""A preview camera framed on what it shows, at any size, and a blank picture told apart. No bpy.

``fit_camera`` places a perspective camera of a given orientation and field of view as close as it
can while every point (and every ball around a point) lies inside the frame, and sets the clip
distances from the nearest and farthest of them: Blender's defaults (0.1 .. 1000) show nothing of a
mesh 1,500 units across or 0.001 across. ``picture_coverage`` measures how much of a rendered
picture differs from its background, so a preview that shows nothing is an error, not a file.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .core.errors import CurveSkelError

__all__ = ["CameraFit", "fit_camera", "half_fov", "view_angles", "picture_coverage",
           "FILL", "BLANK_FRACTION", "BACKGROUND_TOLERANCE"]

#: The framed points reach this share of the half-frame (a margin of 10 % each side).
FILL = 0.9
#: A picture where fewer than this share of the pixels differ from the background is blank.
BLANK_FRACTION = 0.001
#: A pixel differs from the background by more than this in some channel (0..1; 8-bit PNG steps
#: are 1/255).
BACKGROUND_TOLERANCE = 0.02


@dataclass(frozen=True)
class CameraFit:
    """Where the camera goes and what it clips (world units).

    location : (3,) float
    distance : float
        From the camera to the framed points' centre plane, along the view.
    near, far : float
        The nearest and farthest distance along the view of any framed point or ball.
    clip_start, clip_end : float
        ``near / 2`` (at least ``far * 1e-6``) and ``far * 1.5``: everything framed is rendered.
    """

    location: np.ndarray
    distance: float
    near: float
    far: float
    clip_start: float
    clip_end: float


def half_fov(lens: float, sensor: float, width: int, height: int) -> tuple[float, float]:
    """tan of the horizontal and vertical half angles of view of a camera with focal length
    ``lens`` and sensor size ``sensor`` (mm) rendering ``width`` x ``height`` pixels, the sensor
    fitted to the longer side (Blender's sensor fit AUTO, square pixels)."""
    t = 0.5 * sensor / lens
    if width >= height:
        return t, t * height / width
    return t * width / height, t


def view_angles(points) -> tuple[float, float, float]:
    """Euler XYZ angles (radians) of the preview's view: three-quarter, 18 degrees from above,
    looking across the longer horizontal side of ``points`` (n, 3)."""
    ext = np.ptp(np.asarray(points, float).reshape(-1, 3), axis=0)
    return np.radians(72.0), 0.0, np.radians(125.0 if ext[1] > ext[0] else 35.0)


def fit_camera(points, rotation, tan_x: float, tan_y: float, *, radii=None,
               fill: float = FILL) -> CameraFit:
    """The nearest camera position from which every point (with its ball) is in the frame.

    Parameters
    ----------
    points : (n, 3) float
        World positions to frame.
    rotation : (3, 3) float
        The camera's orientation: its columns are the camera's x (right), y (up) and z axes in
        the world; it looks along -z.
    tan_x, tan_y : float
        tan of the half angles of view (:func:`half_fov`).
    radii : (n,) float, optional
        A ball around each point that must be in the frame too (the silhouette's joints).
    fill : float in (0, 1]
        The share of the half-frame the framed points may reach.

    Returns
    -------
    CameraFit

    Raises
    ------
    CurveSkelError
        No points, a non-finite one, or nothing of any size to frame.

    Notes
    -----
    In camera axes (p = R^T x), a camera at (a, b, e) sees a point at depth d = e - p_z; it lies
    inside the right and left planes of the frame when a + t e >= p_x + t p_z + r sqrt(1 + t^2)
    and -a + t e >= -p_x + t p_z + r sqrt(1 + t^2) (t = fill * tan_x; r the ball's radius). With
    U and L the maxima of the right-hand sides, the smallest e is (U + L) / 2t at a = (U - L) / 2;
    the same for y and b, and the camera takes the larger e of the two.
    """
    P = np.asarray(points, float).reshape(-1, 3)
    r = np.zeros(len(P)) if radii is None else np.broadcast_to(np.asarray(radii, float), (len(P),))
    if not len(P):
        raise CurveSkelError("nothing to frame: no vertices")
    if not (np.isfinite(P).all() and np.isfinite(r).all()):
        raise CurveSkelError("cannot frame the preview: a vertex or radius is not finite")
    size = float(np.linalg.norm(np.ptp(P, axis=0))) + 2.0 * float(r.max())
    if not size > 0:
        raise CurveSkelError("nothing to frame: every vertex is at one point")
    R = np.asarray(rotation, float).reshape(3, 3)
    local = P @ R
    offset, need = [], []
    for axis, t in ((0, tan_x * fill), (1, tan_y * fill)):
        k = r * np.sqrt(1.0 + t * t)
        U = np.max(local[:, axis] + t * local[:, 2] + k)
        L = np.max(-local[:, axis] + t * local[:, 2] + k)
        offset.append(0.5 * (U - L))
        need.append(0.5 * (U + L) / t)
    e = max(need)
    depth = e - local[:, 2]
    near = float(np.min(depth - r))
    far = float(np.max(depth + r))
    centre = 0.5 * (local[:, 2].max() + local[:, 2].min())
    return CameraFit(location=R @ np.array([offset[0], offset[1], e]), distance=float(e - centre),
                     near=near, far=far, clip_start=max(0.5 * near, 1e-6 * far), clip_end=1.5 * far)


def picture_coverage(rgba, tolerance: float = BACKGROUND_TOLERANCE) -> dict:
    """How much of a picture shows something other than its background.

    Parameters
    ----------
    rgba : (h, w, 3 or 4) float in [0, 1]
        The picture (alpha ignored); the background is the median colour of its border.
    tolerance : float
        A pixel differs when some channel is further than this from the background.

    Returns
    -------
    dict
        ``fraction`` of the pixels that differ, ``centre`` (x, y) of those pixels and their
        bounding ``box`` (x0, y0, x1, y1), as fractions of the width and height (rows in the
        array's order; None when no pixel differs), ``background`` (3,).
    """
    img = np.asarray(rgba, float)[..., :3]
    h, w = img.shape[:2]
    border = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
    bg = np.median(border, axis=0)
    mask = np.abs(img - bg).max(axis=2) > tolerance
    fraction = float(mask.mean()) if mask.size else 0.0
    if not mask.any():
        return {"fraction": fraction, "centre": None, "box": None, "background": bg}
    ys, xs = np.nonzero(mask)
    return {"fraction": fraction, "background": bg,
            "centre": ((xs.mean() + 0.5) / w, (ys.mean() + 0.5) / h),
            "box": (xs.min() / w, ys.min() / h, (xs.max() + 1) / w, (ys.max() + 1) / h)}
