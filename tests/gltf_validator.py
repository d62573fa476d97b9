"""The Khronos glTF Validator (npm package ``gltf-validator``) for the tests, when node is present.

The version is pinned in ``tests/tools/package.json`` and ``package-lock.json`` (with its
integrity hash); :func:`validator` installs it once with ``npm ci`` into
``tests/tools/node_modules/`` (git-ignored; ``.ci/run`` does the same before the tests). Without
node, without npm, or with no registry (offline), it returns the reason instead, and the tests
skip with it. ``CURVESKEL_GLTF_VALIDATOR`` may name a folder whose ``node_modules`` already holds
the package.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

__all__ = ["TOOLS", "PINNED", "validator", "validate", "counts"]

TOOLS = Path(__file__).resolve().parent / "tools"
PINNED = json.loads((TOOLS / "package.json").read_text())["dependencies"]["gltf-validator"]

# Reads a .glb/.gltf, prints the validator's report (JSON) on stdout.
_SCRIPT = r"""
const [pkg, file] = process.argv.slice(1);
const validator = require(pkg);
const fs = require('fs');
const path = require('path');
validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: path.basename(file), maxIssues: 0,
    externalResourceFunction: (uri) => new Promise((resolve, reject) =>
        fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)),
                    (err, data) => err ? reject(err.toString()) : resolve(new Uint8Array(data)))),
}).then(r => console.log(JSON.stringify(r)))
  .catch(e => { console.error(String(e)); process.exit(2); });
"""

_found: tuple | None = None


def _installed(folder: Path) -> Path | None:
    pkg = folder / "node_modules" / "gltf-validator"
    try:
        version = json.loads((pkg / "package.json").read_text())["version"]
    except (OSError, ValueError, KeyError):
        return None
    return pkg if version == PINNED else None


def validator() -> tuple[Path | None, str]:
    """(the installed package's folder, "") or (None, why it is not available). Installs the
    pinned version on first use when npm is there; remembered for the session."""
    global _found
    if _found is None:
        _found = _find()
    return _found


def _find() -> tuple[Path | None, str]:
    if shutil.which("node") is None:
        return None, "node is not installed: the Khronos glTF validator cannot run"
    extra = os.environ.get("CURVESKEL_GLTF_VALIDATOR")
    for folder in filter(None, [extra and Path(extra), TOOLS]):
        pkg = _installed(folder)
        if pkg is not None:
            return pkg, ""
    if shutil.which("npm") is None:
        return None, f"npm is not installed: cannot install gltf-validator@{PINNED}"
    try:
        res = subprocess.run(["npm", "ci", "--prefix", str(TOOLS), "--no-audit", "--no-fund",
                              "--ignore-scripts", "--fetch-retries=1", "--fetch-timeout=30000"],
                             capture_output=True, text=True, timeout=240)
    except (subprocess.SubprocessError, OSError) as exc:
        return None, f"npm ci of gltf-validator@{PINNED} failed: {exc}"
    pkg = _installed(TOOLS)
    if pkg is None:
        said = [ln for ln in res.stderr.splitlines() if ln.startswith("npm error")
                and "complete log" not in ln][:2] or ["no message"]
        return None, (f"npm could not install gltf-validator@{PINNED} (offline?): rc {res.returncode}, "
                      + "; ".join(said))
    return pkg, ""


def validate(path) -> dict:
    """The validator's report on the file ``path``: ``issues`` holds ``numErrors``,
    ``numWarnings``, ``numInfos``, ``numHints`` and ``messages`` (every one: no cap).
    Raises RuntimeError when the validator is not available or fails to run."""
    pkg, why = validator()
    if pkg is None:
        raise RuntimeError(why)
    res = subprocess.run(["node", "-e", _SCRIPT, str(pkg), str(Path(path).resolve())],
                         capture_output=True, text=True, timeout=300)
    if res.returncode != 0:
        raise RuntimeError(f"gltf-validator failed on {path}: {res.stderr.strip()}")
    return json.loads(res.stdout)


def counts(report: dict) -> dict:
    """{"errors", "warnings", "infos", "hints"} of a report."""
    issues = report["issues"]
    return {k.lower(): issues[f"num{k}"] for k in ("Errors", "Warnings", "Infos", "Hints")}


if __name__ == "__main__":      # python tests/gltf_validator.py FILE...: counts and messages
    import sys

    for f in sys.argv[1:]:
        rep = validate(f)
        print(f, counts(rep))
        for m in rep["issues"]["messages"]:
            print("   ", m["severity"], m["code"], m.get("pointer", ""), m["message"])
