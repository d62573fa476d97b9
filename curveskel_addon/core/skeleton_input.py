"""A skeleton from outside curveskel, checked: joints, bones and (when given) radii.

:func:`evaluate` and :func:`refine` (:mod:`.evaluation`, :mod:`.refinement`) take any curve-skeleton
of a mesh, not only curveskel's own. It may come as

* a :class:`.skeleton.Skeleton` (curveskel's result, or its JSON read back);
* a mapping: curveskel's JSON (``{"format": "curveskel-skeleton/1", "joints": [[x, y, z, r],
  ...], "bones": ...}``) or a plain ``{"joints": [[x, y, z], ...], "bones": [[i, j], ...]}``
  (joints with or without a radius);
* a pair ``(joints, bones)`` of arrays, joints ``(J, 3)`` or ``(J, 4)``;
* an :class:`OutsideSkeleton` (the Blender layer builds one from an armature).

Every defect is one :class:`CurveSkelError` naming it (a bone index out of range, a bone from a
joint to itself, a bone listed twice, coordinates that are not finite numbers, no bone at all),
so the command line and Blender can show it as it is. Nothing here is a measure of the shape:
whether the bones lie in the mesh is decided against the mesh (:mod:`.evaluation`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import CurveSkelError
from .skeleton import FORMAT, Skeleton

__all__ = ["OutsideSkeleton", "as_outside_skeleton", "load_outside_skeleton"]


@dataclass(frozen=True, eq=False)
class OutsideSkeleton:
    """A curve-skeleton to evaluate or refine.

    Attributes
    ----------
    joints : (J, 3) float
        Joint positions, in the mesh's own space.
    bones : (B, 2) int
        Joint indices of each bone; at least one bone.
    radii : (J,) float or None
        The radius at each joint, if the skeleton has them (else they are fitted).
    """

    joints: np.ndarray
    bones: np.ndarray
    radii: np.ndarray | None = None

    def __post_init__(self):
        joints, bones, radii = _checked(self.joints, self.bones, self.radii)
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "bones", bones)
        object.__setattr__(self, "radii", radii)

    @property
    def n_joints(self) -> int:
        return len(self.joints)

    @property
    def used(self) -> np.ndarray:
        """(J,) bool: the joints some bone uses (a joint of no bone explains nothing)."""
        out = np.zeros(len(self.joints), bool)
        out[self.bones.ravel()] = True
        return out


def as_outside_skeleton(skeleton) -> OutsideSkeleton:
    """Any accepted form of a skeleton (module doc) as an :class:`OutsideSkeleton`.

    Parameters
    ----------
    skeleton : OutsideSkeleton, Skeleton, dict or (joints, bones)

    Returns
    -------
    OutsideSkeleton

    Raises
    ------
    CurveSkelError
        When the skeleton is not one of the accepted forms or is not a valid graph.
    """
    if isinstance(skeleton, OutsideSkeleton):
        return skeleton
    if isinstance(skeleton, Skeleton):
        return _from_rows(skeleton.joints, skeleton.bones)
    if isinstance(skeleton, dict):
        return _from_mapping(skeleton)
    if isinstance(skeleton, (tuple, list)) and len(skeleton) == 2:
        return _from_rows(*skeleton)
    raise CurveSkelError("a skeleton must be a curveskel Skeleton, a JSON object with 'joints' "
                         "and 'bones', or a pair (joints, bones); got "
                         f"{type(skeleton).__name__}")


def load_outside_skeleton(path) -> OutsideSkeleton:
    """A skeleton JSON file (curveskel's format or the plain ``{"joints", "bones"}``).

    Raises
    ------
    CurveSkelError
        A missing or unreadable file, invalid JSON, or an invalid skeleton; the message names
        the file.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise CurveSkelError(f"cannot read skeleton {path}: {exc.strerror or exc}") from exc
    except json.JSONDecodeError as exc:
        raise CurveSkelError(f"skeleton {path} is not valid JSON: {exc}") from exc
    try:
        return as_outside_skeleton(data)
    except CurveSkelError as exc:
        raise CurveSkelError(f"skeleton {path}: {exc}") from exc


def _from_mapping(d: dict) -> OutsideSkeleton:
    fmt = d.get("format")
    if fmt is not None and fmt != FORMAT:
        raise CurveSkelError(f"unknown skeleton format {fmt!r} (expected {FORMAT!r} or none)")
    missing = [k for k in ("joints", "bones") if k not in d]
    if missing:
        raise CurveSkelError(f"the skeleton has no {' and no '.join(repr(k) for k in missing)}")
    return _from_rows(d["joints"], d["bones"])


def _from_rows(joints, bones) -> OutsideSkeleton:
    """Joints of 3 columns (no radii) or 4 (x, y, z, r), and bones."""
    J = _array(joints, "joints", np.float64)
    if J.ndim != 2 or J.shape[1] not in (3, 4):
        raise CurveSkelError("joints must be rows of [x, y, z] or [x, y, z, r], got an array "
                             f"of shape {J.shape}")
    return OutsideSkeleton(J[:, :3], bones, J[:, 3] if J.shape[1] == 4 else None)


def _array(x, name, dtype):
    try:
        return np.array(x, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise CurveSkelError(f"{name} must be a table of numbers ({exc})") from exc


def _checked(joints, bones, radii):
    J = _array(joints, "joints", np.float64)
    if J.ndim != 2 or J.shape[1] != 3:
        raise CurveSkelError(f"joints must be rows of [x, y, z], got an array of shape {J.shape}")
    if not np.all(np.isfinite(J)):
        bad = int(np.flatnonzero(~np.isfinite(J).all(1))[0])
        raise CurveSkelError(f"joint {bad} has a coordinate that is not a finite number")
    raw = _array(bones, "bones", np.float64)
    if raw.size == 0:
        raise CurveSkelError("the skeleton has no bones: nothing to evaluate")
    if raw.ndim != 2 or raw.shape[1] != 2:
        raise CurveSkelError(f"bones must be pairs [i, j] of joint indices, got an array of shape {raw.shape}")
    if not np.all(np.isfinite(raw)) or np.any(raw != np.round(raw)):
        raise CurveSkelError("bones must hold integer joint indices")
    B = raw.astype(np.int64)
    out = np.flatnonzero((B < 0).any(1) | (B >= len(J)).any(1))
    if len(out):
        b = int(out[0])
        raise CurveSkelError(f"bone {b} joins joints {B[b, 0]} and {B[b, 1]}, but the skeleton "
                             f"has {len(J)} joints (indices 0 to {len(J) - 1})")
    loop = np.flatnonzero(B[:, 0] == B[:, 1])
    if len(loop):
        raise CurveSkelError(f"bone {int(loop[0])} joins joint {B[loop[0], 0]} to itself")
    key = np.sort(B, axis=1)
    _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
    if np.any(count > 1):
        twice = key[first[np.argmax(count > 1)]]
        raise CurveSkelError(f"joints {twice[0]} and {twice[1]} are joined by more than one bone")
    R = None
    if radii is not None:
        R = _array(radii, "radii", np.float64).ravel()
        if len(R) != len(J):
            raise CurveSkelError(f"{len(R)} radii for {len(J)} joints")
        if not np.all(np.isfinite(R)):
            raise CurveSkelError(f"the radius of joint {int(np.flatnonzero(~np.isfinite(R))[0])} "
                                 "is not a finite number")
        R = np.abs(R)                  # r enters J squared, as in the paper
        R.flags.writeable = False
    J.flags.writeable = False
    B.flags.writeable = False
    return J, B, R
