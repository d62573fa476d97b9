"""Issue 31: extreme parameter values through the command line are refused by range (one line
naming the parameter, exit 2, before any work), never a crash; each upper bound itself runs."""

from __future__ import annotations

import json

import pytest

from cli_support import run_cli, write_capsule_obj

from curveskel_addon.core.params import RULES

NUMERIC = {name: rule for name, rule in RULES.items() if rule[0] in ("int", "float")}


@pytest.fixture(scope="module")
def mesh_file(tmp_path_factory):
    return write_capsule_obj(tmp_path_factory.mktemp("params") / "capsule.obj")


def _flag(name):
    return "--" + name.replace("_", "-")


def _text(kind, v):
    return str(int(v)) if kind == "int" else repr(float(v))


def _extremes(name):
    """Values past every bound: the issue's 1e308 (and its negative), just past the upper
    bound, and (for ints) a number beyond 64 bits."""
    kind, low, high = NUMERIC[name]
    vals = ["1e308", "-1e308"] if kind == "float" else [str(10**30), str(-(10**30))]
    if high is not None:
        b = high[0] if isinstance(high, tuple) else high
        vals.append(_text(kind, b) if isinstance(high, tuple) else
                    _text(kind, b + (1 if kind == "int" else 1e-3 * max(abs(b), 1))))
    return vals


CASES = [(name, v) for name in NUMERIC for v in _extremes(name)]


def test_every_numeric_parameter_has_an_upper_bound():
    """Weights at 1e308 crashed the old method (IndexError, 'Factor is exactly singular')."""
    assert all(rule[2] is not None for rule in NUMERIC.values()), NUMERIC


@pytest.mark.parametrize("name, value", CASES, ids=[f"{n}={v}" for n, v in CASES])
def test_an_extreme_value_is_refused_by_range(mesh_file, name, value):
    r = run_cli(mesh_file, f"{_flag(name)}={value}")      # "=": argparse reads "-1e308" as a flag
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {name} must be "), r.stderr
    assert "Traceback" not in r.stderr and r.stdout == ""


@pytest.mark.parametrize("name", list(NUMERIC))
def test_the_upper_bound_itself_runs(mesh_file, tmp_path, name):
    kind, low, high = NUMERIC[name]
    b = high[0] if isinstance(high, tuple) else high
    value = b * (1 - 1e-3) if isinstance(high, tuple) else b
    out = tmp_path / "o.json"
    r = run_cli(mesh_file, _flag(name), _text(kind, value), "--json", out, "--quiet")
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    assert d["meta"]["params"][name] == pytest.approx(value) and len(d["joints"]) >= 2
