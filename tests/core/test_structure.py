"""The core's structure, read off its source: imports flow one way, constants live in one place.

* no import circle among the core's modules, and no import inside a function (none that
  dodges a circle, none that hides a dependency);
* the core never imports the measures, the rig, the command line, mesh files or Blender;
* ``core/geometry`` imports nothing of the core above it but the constants and the error type;
* every named number of the method is in :mod:`curveskel_addon.core.config`: at most 30 of them
  outside J's weights and the result-neutral numerics, none elsewhere (no module-level number,
  no numeric keyword default other than 0 and 1).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from curveskel_addon.core.config import CONFIG, count_constants

CORE = Path(__file__).resolve().parents[2] / "curveskel_addon" / "core"


def _modules():
    out = {}
    for path in CORE.rglob("*.py"):
        rel = path.relative_to(CORE).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(["core"] + parts)] = path
    return out


def _resolve(module, node, is_package):
    """Absolute (core-relative) names a relative ``from ... import`` refers to."""
    base = module.split(".") if is_package else module.split(".")[:-1]
    if node.level:
        base = base[:len(base) - (node.level - 1)]
        target = base + (node.module.split(".") if node.module else [])
        names = [".".join(target + [a.name]) for a in node.names]
        return [".".join(target)] + names
    return [node.module or ""]


def _imports(module, path):
    tree = ast.parse(path.read_text())
    is_package = path.name == "__init__.py"
    top, inner = set(), []
    for node in tree.body:
        if isinstance(node, ast.ImportFrom):
            top.update(_resolve(module, node, is_package))
        elif isinstance(node, ast.Import):
            top.update(a.name for a in node.names)
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for sub in ast.walk(node):
                if isinstance(sub, (ast.Import, ast.ImportFrom)):
                    inner.append((node.name, sub.lineno))
    return top, inner


MODULES = _modules()
GRAPH = {m: _imports(m, p) for m, p in MODULES.items()}


def test_no_import_inside_a_function():
    inner = {m: v[1] for m, v in GRAPH.items() if v[1]}
    assert not inner, f"imports inside functions: {inner}"


def test_no_import_circle():
    edges = {m: {t for t in GRAPH[m][0] if t in MODULES and t != m} for m in MODULES}
    # a module's package __init__ importing it is not a circle of the method: drop
    # package -> submodule edges
    for m in MODULES:
        edges[m] = {t for t in edges[m] if not t.startswith(m + ".")}
    state, stack = {}, []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for t in sorted(edges[m]):
            if state.get(t) == 1:
                raise AssertionError("import circle: " + " -> ".join(stack[stack.index(t):] + [t]))
            if t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(MODULES):
        if m not in state:
            visit(m)


@pytest.mark.parametrize("forbidden", ["bpy", "curveskel_addon.measure", "curveskel_addon.rig",
                                       "curveskel_addon.cli", "curveskel_addon.mesh_files",
                                       "measure", "rig", "cli", "mesh_files", "trimesh"])
def test_core_imports_none_of(forbidden):
    hits = [m for m, (top, _) in GRAPH.items()
            if any(t == forbidden or t.startswith(forbidden + ".") for t in top)]
    # relative imports reaching out of the core resolve to names without the "core." prefix
    assert not hits, f"{forbidden} imported by {hits}"


def test_geometry_is_a_leaf():
    allowed = ("core.geometry", "core.config", "core.errors")
    for m, (top, _) in GRAPH.items():
        if not m.startswith("core.geometry"):
            continue
        bad = [t for t in top if t.startswith("core.") and not t.startswith(allowed)]
        assert not bad, f"{m} imports {bad}"


def _numeric(node):
    if isinstance(node, ast.Constant):
        return isinstance(node.value, (int, float)) and not isinstance(node.value, bool) or \
            isinstance(node.value, bool)
    if isinstance(node, ast.UnaryOp):
        return _numeric(node.operand)
    if isinstance(node, ast.BinOp):
        return _numeric(node.left) and _numeric(node.right)
    if isinstance(node, ast.Tuple):
        return bool(node.elts) and all(_numeric(e) for e in node.elts)
    return False


def test_method_constants_are_few_and_in_config():
    assert count_constants(CONFIG) <= 30
    stray = []
    for m, path in MODULES.items():
        if m == "core.config":
            continue
        tree = ast.parse(path.read_text())
        for node in tree.body:
            if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None \
                    and _numeric(node.value):
                stray.append(f"{m}:{node.lineno}")
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                a = node.args
                for d in list(a.defaults) + [d for d in a.kw_defaults if d is not None]:
                    if _numeric(d) and not (isinstance(d, ast.Constant)
                                            and d.value in (0, 1, True, False)):
                        stray.append(f"{m}:{node.lineno} {node.name}")
    assert not stray, f"named numbers outside core/config.py: {stray}"


def test_the_count_is_what_the_config_holds():
    # a tuple counts each of its numbers; the weights and numerics do not count
    assert count_constants(CONFIG) == sum(
        len(v) if isinstance(v, tuple) else 1
        for g in ("input", "initial", "objective", "search")
        for v in vars(getattr(CONFIG, g)).values())


def test_no_benchmark_mesh_is_named_in_the_core():
    """The method's rules must hold on any mesh: no constant, comment or branch of the core
    names one of the shared benchmark meshes (their history belongs in docs/benchmarks.md)."""
    import re

    shared = Path(__file__).resolve().parents[3] / "shared" / "meshes"
    # ("hand" is a word too: "the hand" / "hand's" are checked as a phrase)
    names = {p.stem.lower() for p in shared.glob("*") if p.suffix in {".off", ".obj", ".ply", ".stl"}}
    names -= {"hand"}
    names |= {"the hand", "hand's", "armadillo", "elephant", "fertility", "homer", "horse", "octopus", "rocker",
              "3holes", "spot"}
    word = re.compile(r"(?<![a-z0-9])(" + "|".join(sorted(map(re.escape, names))) + r")(?![a-z0-9])")
    hits = [f"{p.relative_to(CORE)}:{i}: {line.strip()}"
            for p in CORE.rglob("*.py")
            for i, line in enumerate(p.read_text().lower().splitlines(), 1) if word.search(line)]
    assert not hits, "core names a benchmark mesh:\n" + "\n".join(hits)
