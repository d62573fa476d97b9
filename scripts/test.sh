#!/usr/bin/env bash
# Set everything up (first run) and run the whole test suite, core tests and headless Blender
# tests, on both Pythons Blender uses:
#   .venv/     Python 3.11, bpy 5.0.1, numpy 1.26   (Blender 4.2 - 5.0)
#   .venv313/  Python 3.13, bpy 5.2.3 LTS, numpy 2  (Blender 5.1 +), when a Python 3.13 is found
#              (PATH or pyenv; PYTHON313=/path/to/python3.13 to choose, CURVESKEL_SKIP_313=1 to skip)
# Each venv is created once and re-used (stamp files, scripts/bootstrap.sh). The first run is the
# whole suite; the second the Blender tests and the core's numeric kernels (CURVESKEL_FULL_313=1:
# the whole suite there too). Extra arguments go to both pytest runs instead. The last line is one pytest-style summary of both runs; the exit status is
# non-zero if either run fails.
set -uo pipefail
cd "$(dirname "$0")/.."
bash scripts/bootstrap.sh requirements-dev.txt || exit
reports=$(mktemp -d)
trap 'rm -rf "$reports"' EXIT

run() {  # run NAME PYTHON [pytest args]: pytest with a JUnit report and its wall time in $reports
  local name="$1" py="$2" t0 status
  t0=$(date +%s.%N)
  shift 2
  "$py" -m pytest -q --junitxml="$reports/$name.xml" "$@"
  status=$?
  echo "$t0 $(date +%s.%N)" > "$reports/$name.seconds"
  return $status
}

echo "== bpy 5.0.1, Python 3.11, numpy 1.26 (.venv/)"
run 1-bpy-5.0.1-py3.11 .venv/bin/python "$@"
rc=$?

if [ -n "${CURVESKEL_SKIP_313:-}" ]; then
  echo "curveskel: CURVESKEL_SKIP_313 is set: the bpy 5.2.3 / Python 3.13 tests are skipped"
elif ! bash scripts/bootstrap.sh --find-python 3.13 >/dev/null; then
  echo "curveskel: no Python 3.13 found (PATH, pyenv; set PYTHON313): the bpy 5.2.3 / Python 3.13 tests are skipped"
elif ! bash scripts/bootstrap.sh requirements-313.txt; then
  echo "curveskel: could not set up .venv313/ (bpy 5.2.3, Python 3.13)" >&2
  [ "$rc" -ne 0 ] || rc=1
else
  echo "== bpy 5.2.3 LTS, Python 3.13, numpy 2 (.venv313/)"
  # The method's behaviour tests (the search on many meshes: most of the suite's time) run
  # once, above; here the Blender layer and the core's numeric kernels, on numpy 2 and bpy 5.2.
  # CURVESKEL_FULL_313=1 (or any pytest arguments) runs what the first run ran.
  if [ "$#" -eq 0 ] && [ -z "${CURVESKEL_FULL_313:-}" ]; then
    set -- tests/blender tests/core/test_objective_terms.py tests/core/test_disc_sections.py \
      tests/core/test_energy.py tests/core/test_line_search.py tests/core/test_meb.py \
      tests/core/test_samples.py tests/core/test_mesh_input.py tests/core/test_mesh_files.py \
      tests/core/test_skeleton_json.py tests/core/test_structure.py tests/core/test_rows.py \
      tests/core/test_skin_weights.py tests/core/test_rig_layout.py tests/core/test_reeb.py \
      tests/core/test_pole.py tests/core/test_solvers.py
  fi
  run 2-bpy-5.2.3-py3.13 .venv313/bin/python -o cache_dir=.pytest_cache_313 "$@"
  rc313=$?
  [ "$rc" -ne 0 ] || rc=$rc313
fi

# One summary line over both runs, in pytest's words, last (CI reads it).
.venv/bin/python - "$reports" <<'EOF'
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

total = dict.fromkeys(("failed", "passed", "skipped", "xfailed", "error"), 0)
seconds = 0.0
for xml in sorted(Path(sys.argv[1]).glob("*.xml")):
    counts = dict.fromkeys(total, 0)
    for case in ET.parse(xml).iter("testcase"):
        kinds = {child.tag: child for child in case}
        skip = kinds.get("skipped")
        if "error" in kinds:
            counts["error"] += 1
        elif "failure" in kinds:
            counts["failed"] += 1
        elif skip is not None:
            counts["xfailed" if skip.get("type") == "pytest.xfail" else "skipped"] += 1
        else:
            counts["passed"] += 1
    start, end = map(float, xml.with_suffix(".seconds").read_text().split())
    wall = end - start
    seconds += wall
    label = xml.stem.split("-", 1)[1].replace("-", " ")
    ran = ", ".join(f"{n} {k}" for k, n in counts.items() if n) or "no tests ran"
    print(f"curveskel: {label}: {ran} in {wall:.1f}s")
    for k in total:
        total[k] += counts[k]
words = [f"{n} {k}" + ("s" if k == "error" and n > 1 else "") for k, n in total.items() if n]
h, rem = divmod(int(seconds), 3600)
line = f" {', '.join(words) or 'no tests ran'} in {seconds:.2f}s ({h}:{rem // 60:02d}:{rem % 60:02d}) "
print(f"{line:=^100}")
EOF
exit "$rc"
