"""The result of skeletonization and its JSON form ("curveskel-skeleton/1")."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import CurveSkelError

__all__ = ["Skeleton", "FORMAT"]

FORMAT = "curveskel-skeleton/1"


@dataclass
class Skeleton:
    """A curve-skeleton with its radial function and skeleton mapping.

    Attributes
    ----------
    joints : (J, 4) float
        x, y, z, r of each joint, in the input mesh's own space.
    bones : (B, 2) int
        Joint indices (i, j) of each bone.
    bone : (n,) int
        Skeleton mapping: the bone of each input vertex, in input order.
    t : (n,) float
        Skeleton mapping: sigma(v) = t * x_i + (1 - t) * x_j for bone (i, j) (eq. 19).
    energy : list of float
        E (eq. 20; area-weighted when that option is on) after every stage of the pipeline
        (``meta["stages"]`` names them: initialise, centre, edit, fit, contain); the last is
        the E of this skeleton with this mapping. The fit's own iterations are in
        ``meta["fit_energy"]``.
    timings : dict
        Seconds per stage.
    meta : dict
        Everything else: parameters, per-component figures, quality measures.
    """

    joints: np.ndarray
    bones: np.ndarray
    bone: np.ndarray
    t: np.ndarray
    energy: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        self.joints = np.asarray(self.joints, dtype=np.float64).reshape(-1, 4)
        self.bones = np.asarray(self.bones, dtype=np.int64).reshape(-1, 2)
        self.bone = np.asarray(self.bone, dtype=np.int64).ravel()
        self.t = np.asarray(self.t, dtype=np.float64).ravel()
        self.energy = [float(e) for e in self.energy]

    # -- derived figures ---------------------------------------------------------------------
    @property
    def n_joints(self) -> int:
        return len(self.joints)

    @property
    def n_bones(self) -> int:
        return len(self.bones)

    @property
    def iterations(self) -> int:
        """Iterations of the fit of E (from the pipeline's stage log), else len(energy) - 1."""
        for st in self.meta.get("stages", []):
            if st.get("stage") == "fit" and "iterations" in st:
                return int(st["iterations"])
        return max(len(self.energy) - 1, 0)

    def sigma(self) -> np.ndarray:
        """(n, 3) skeleton point of every input vertex (eq. 19)."""
        i, j = self.bones[self.bone, 0], self.bones[self.bone, 1]
        t = self.t[:, None]
        return t * self.joints[i, :3] + (1.0 - t) * self.joints[j, :3]

    def radius_at_mapping(self) -> np.ndarray:
        """(n,) radial function at sigma(v) (eq. 17)."""
        i, j = self.bones[self.bone, 0], self.bones[self.bone, 1]
        return self.t * self.joints[i, 3] + (1.0 - self.t) * self.joints[j, 3]

    def degree(self) -> np.ndarray:
        return np.bincount(self.bones.ravel(), minlength=self.n_joints)

    def summary(self) -> dict:
        """Figures a user wants to see after a run: joints, bones, components, J0 and J (the
        objective of the first stage and of the returned skeleton), E0 (the first
        approximation's paper E), E_fit (after the last fit), E (of the returned skeleton),
        iterations, seconds."""
        e0 = self.energy[0] if self.energy else float("nan")
        e1 = self.energy[-1] if self.energy else float("nan")
        stages = self.meta.get("stages", [])
        fit = [st.get("terms", {}).get("E", st.get("energy")) for st in stages
               if st.get("stage") == "fit"]
        fit = [f for f in fit if f is not None]
        return {
            "joints": self.n_joints,
            "bones": self.n_bones,
            "components": int(self.meta.get("components", 1)),
            "J0": float(stages[0]["J"]) if stages and "J" in stages[0] else float("nan"),
            "J": float(self.meta.get("J", float("nan"))),
            "E0": e0,
            "E_fit": float(fit[-1]) if fit else e1,
            "E": e1,
            "iterations": self.iterations,
            "seconds": float(sum(self.timings.values())),
        }

    # -- JSON ----------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        e0 = self.energy[0] if self.energy else None
        return {
            "format": FORMAT,
            "joints": self.joints.tolist(),
            "bones": self.bones.tolist(),
            "mapping": {"bone": self.bone.tolist(), "t": self.t.tolist()},
            "energy": {
                "initial": e0,
                "final": self.energy[-1] if self.energy else None,
                "iterations": self.iterations,
                "history": list(self.energy),
            },
            "meta": {**_jsonable(self.meta), "timings": dict(self.timings)},
        }

    @classmethod
    def from_dict(cls, d: dict) -> "Skeleton":
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise CurveSkelError(f"not a {FORMAT} document (format={d.get('format')!r})"
                                 if isinstance(d, dict) else f"not a {FORMAT} document")
        en = d.get("energy") or {}
        history = en.get("history")
        if history is None:
            history = [x for x in (en.get("initial"), en.get("final")) if x is not None]
        meta = dict(d.get("meta") or {})
        timings = meta.pop("timings", {})
        sk = cls(joints=d["joints"], bones=d["bones"], bone=d["mapping"]["bone"],
                 t=d["mapping"]["t"], energy=history, timings=timings, meta=meta)
        sk.validate()
        return sk

    def save(self, path) -> None:
        Path(path).write_text(json.dumps(self.to_dict()))

    @classmethod
    def load(cls, path) -> "Skeleton":
        try:
            d = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise CurveSkelError(f"cannot read skeleton JSON {path}: {exc}") from exc
        return cls.from_dict(d)

    def validate(self) -> None:
        """Raise CurveSkelError if indices are out of range or arrays disagree in length."""
        J = self.n_joints
        if self.bones.size and (self.bones.min() < 0 or self.bones.max() >= J):
            raise CurveSkelError("bone joint index out of range")
        if len(self.bone) != len(self.t):
            raise CurveSkelError("mapping 'bone' and 't' differ in length")
        if self.bone.size and (self.bone.min() < 0 or self.bone.max() >= self.n_bones):
            raise CurveSkelError("mapping bone index out of range")
        if not np.all(np.isfinite(self.joints)):
            raise CurveSkelError("joints contain NaN or inf")


def _jsonable(x):
    """Numpy scalars and arrays inside meta become plain JSON values."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return x
