"""A library of mesh files for the batch tests (issue 32), generated, never committed.

:func:`make_library` writes 60 meshes in four formats under nested folders: 54 procedural
variants at several sizes (``meshes.py``'s shapes, trimesh primitives, moved and scaled
copies), three of ../shared/meshes and three of the held-out meshes (scripts/bench.py --batch
runs that library); ``make_library(folder, names=SMALL, real=False)`` writes the tests' few
coarse ones. The tests and the bench run the method with :data:`METHOD` (a coarse Detail Size:
the batch machinery, not the skeletons' detail, is under test, and the core takes seconds per
mesh at the default). :func:`make_bad` adds the three bad inputs (an empty file, a file that
crashes its worker and one that hangs, both only under the test-hook variable).
:func:`reference_digests` runs the single-file command line's ``main`` on each file (one BLAS
thread, as the batch's workers) and returns the digest of each skeleton JSON.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

import meshes as M

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "meshes"
HELDOUT = ROOT / "tests" / "data" / "heldout"
BATCH = ROOT / "scripts" / "batch.py"
#: the batch's workers run BLAS with one thread; the reference runs the same way
ONE_THREAD = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
FORMATS = (".obj", ".off", ".ply", ".stl")
BAD = {"bad/empty.obj": "", "bad/crash.obj": "crash", "bad/hang.obj": "hang"}
#: the method parameters of the batch tests and the batch bench (SkeletonParams fields), and the
#: same as command-line options
METHOD = {"spacing": 0.15}
METHOD_ARGS = [a for k, v in METHOD.items() for a in ("--" + k.replace("_", "-"), str(v))]
#: the tests' library: ten small procedural meshes (every format, nested folders)
SMALL = ("bent/bent-10-arm3", "capsules/capsule-8x8-L3", "capsules/capsule-8x8-L6",
         "capsules/capsule-12x12-L3", "moved/capsule-00", "moved/capsule-03", "prims/capsule-8",
         "prims/cylinder-12", "props/box_bar", "props/t_beam")


def _trimesh(m):
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


def procedural() -> dict:
    """name -> (V, F): 54 small procedural meshes, several shapes, sizes and positions."""
    import trimesh

    c = trimesh.creation
    out = {}
    for i, (na, nb) in enumerate([(8, 8), (12, 12), (16, 20), (24, 30)]):
        for length in (3.0, 6.0):
            out[f"capsules/capsule-{na}x{nb}-L{length:g}"] = M.capsule(n_around=na, n_body=nb,
                                                                       length=length, cap_rings=4)
    for r in (0.5, 1.5, 2.0):
        out[f"capsules/capsule-r{r:g}"] = M.capsule(radius=r, n_around=12, n_body=16, cap_rings=4)
    for nM, nm in [(24, 8), (32, 12), (48, 16)]:
        for R in (2.0, 3.0):
            out[f"tori/torus-{nM}x{nm}-R{R:g}"] = M.torus(R=R, n_major=nM, n_minor=nm)
    for n in (10, 16, 24):
        for arm in (3.0, 4.0):
            out[f"bent/bent-{n}-arm{arm:g}"] = M.bent_capsule(arm=arm, n=n, n_around=12)
    out["props/box_bar"] = M.box_bar()
    out["props/board"] = M.board()
    out["props/t_beam"] = M.t_beam()
    out["props/bent_tube"] = M.bent_tube()
    out["props/two_capsules"] = M.two_capsules()
    for s in (1, 2):
        out[f"prims/icosphere-{s}"] = _trimesh(c.icosphere(subdivisions=s))
    for count in (8, 12, 16):
        out[f"prims/capsule-{count}"] = _trimesh(c.capsule(height=3.0, radius=0.5, count=[count, count]))
    for sec in (12, 24, 32):
        out[f"prims/cylinder-{sec}"] = _trimesh(c.cylinder(radius=0.5, height=4.0, sections=sec))
    for sec in (16, 24):
        out[f"prims/cone-{sec}"] = _trimesh(c.cone(radius=1.0, height=3.0, sections=sec))
        out[f"prims/annulus-{sec}"] = _trimesh(c.annulus(r_min=1.0, r_max=1.5, height=0.5, sections=sec))
    out["prims/box"] = _trimesh(c.box())
    rng = np.random.default_rng(32)
    bases = [("capsule", M.capsule(n_around=12, n_body=12, cap_rings=4)),
             ("torus", M.torus(n_major=24, n_minor=8)),
             ("bent", M.bent_capsule(n=12, n_around=12))]
    for k in range(13):                          # moved, turned and scaled copies
        name, (V, F) = bases[k % 3]
        Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        V = (V @ Q.T) * rng.uniform(0.05, 20.0) + rng.normal(scale=50.0, size=3)
        out[f"moved/{name}-{k:02d}"] = (V, F)
    return out


def make_library(folder: Path, names=None, real: bool = True) -> list[str]:
    """Write the 60 meshes under ``folder`` (``names``: only those procedural ones; ``real``:
    the shared and held-out ones too); returns their paths relative to it, sorted."""
    import trimesh

    folder.mkdir(parents=True, exist_ok=True)
    rels = []
    meshes = procedural()
    if names is not None:
        meshes = {k: meshes[k] for k in names}
    for i, (name, (V, F)) in enumerate(sorted(meshes.items())):
        rel = name + FORMATS[i % len(FORMATS)]
        path = folder / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if rel.endswith(".obj"):
            _write_obj(path, V, F)
        else:
            trimesh.Trimesh(V, F, process=False).export(path)
        rels.append(rel)
    for src, sub in () if not real else ((SHARED / "octopus.off", "shared"), (SHARED / "spot.obj", "shared"),
                     (SHARED / "hand.off", "shared"), (HELDOUT / "koala.obj", "heldout"),
                     (HELDOUT / "penguin.obj", "heldout"), (HELDOUT / "quadknot.obj", "heldout")):
        (folder / sub).mkdir(exist_ok=True)
        shutil.copy2(src, folder / sub / src.name)
        rels.append(f"{sub}/{src.name}")
    (folder / "README.txt").write_text("not a mesh: the batch ignores it\n")
    (folder / ".hidden").mkdir(exist_ok=True)
    _write_obj(folder / ".hidden" / "skipped.obj", *M.capsule(n_around=8, n_body=8))
    return sorted(rels)


def make_bad(folder: Path) -> list[str]:
    """The three bad inputs under ``folder/bad``: an empty .obj, and two small capsules whose
    first line asks a worker to crash or hang (only when the test-hook variable is set)."""
    (folder / "bad").mkdir(parents=True, exist_ok=True)
    V, F = M.capsule(n_around=8, n_body=8)
    for rel, hook in BAD.items():
        path = folder / rel
        if hook:
            _write_obj(path, V, F, first=f"# curveskel-batch-test: {hook}\n")
        else:
            path.write_text("")
    return sorted(BAD)


def _write_obj(path: Path, V, F, first: str = "") -> None:
    with open(path, "w") as fh:
        fh.write(first)
        fh.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V)
        fh.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F)


_REFERENCE = """
import json, sys
sys.path.insert(0, sys.argv[1])
from curveskel_addon.cli.skeletonize import main
from curveskel_addon.batch.records import skeleton_digest
out = {}
for src, dst in json.loads(sys.stdin.read()):
    rc = main([src, "--json", dst, "--quiet", *sys.argv[2:]])
    out[src] = skeleton_digest(json.load(open(dst))) if rc == 0 else None
print(json.dumps(out))
"""


def reference_digests(files, tmp: Path, processes: int = 2, args=METHOD_ARGS) -> dict:
    """``{path: digest}`` of each file's skeleton JSON by ``curveskel skeletonize``'s own
    ``main`` with options ``args`` (one BLAS thread, as the batch's workers), None where it
    refused. The files are shared among ``processes`` processes, each running ``main`` file
    after file."""
    tmp.mkdir(parents=True, exist_ok=True)
    pairs = [(str(f), str(tmp / f"{i}.json")) for i, f in enumerate(files)]
    env = {**os.environ, **ONE_THREAD}
    procs = [subprocess.Popen([sys.executable, "-c", _REFERENCE, str(ROOT), *args], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
             for _ in range(processes)]
    out = {}
    for k, p in enumerate(procs):
        p.stdin.write(json.dumps(pairs[k::processes]))
        p.stdin.close()
    for p in procs:
        stdout, stderr = p.stdout.read(), p.stderr.read()
        assert p.wait(timeout=1800) == 0, stderr[-3000:]
        out.update(json.loads(stdout.strip().splitlines()[-1]))
    return out


def run_batch(*args, env=None, timeout=900, **kw):
    """scripts/batch.py with ``args`` (a subprocess)."""
    return subprocess.run([sys.executable, str(BATCH), *map(str, args)], capture_output=True,
                          text=True, timeout=timeout, env={**os.environ, **(env or {})}, **kw)


def read_rows(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]


def temp_files(out: Path) -> list[str]:
    """Temporary files (``.name.tmp-PID...``) anywhere under ``out``."""
    return sorted(str(p.relative_to(out)) for p in out.rglob(".*.tmp-*"))
