#!/usr/bin/env bash
# Create a virtual environment and install pinned requirements. Idempotent: a stamp file records
# what was installed, so a second run with unchanged requirements does nothing.
#
#   bash scripts/bootstrap.sh [requirements-file]   # default requirements-dev.txt
#     requirements-313.txt -> .venv313/ with Python 3.13 (bpy 5.2 LTS, numpy 2; Blender 5.1+)
#     any other file       -> .venv/    with Python 3.11 (bpy 5.0.1, numpy 1.26; Blender 4.2-5.0)
#   bash scripts/bootstrap.sh --find-python 3.13   # print a Python 3.13's path, or exit 1
#
# The interpreter: $PYTHON (for .venv) or $PYTHON313 (for .venv313) if set, else pythonX.Y,
# python3, python on PATH, else pyenv's versions ($PYENV_ROOT or ~/.pyenv).
set -euo pipefail
cd "$(dirname "$0")/.."

find_python() {  # find_python X.Y [explicit-path]
  local want="$1" cand
  local -a cands=()
  [ -n "${2:-}" ] && cands+=("$2")
  cands+=("python$want" python3 python)
  local root="${PYENV_ROOT:-$HOME/.pyenv}"
  for cand in "$root"/versions/"$want"*/bin/python"$want"; do
    [ -x "$cand" ] && cands+=("$cand")
  done
  for cand in "${cands[@]}"; do
    if command -v "$cand" >/dev/null 2>&1 &&
       "$cand" -c "import sys; sys.exit(sys.version_info[:2] != tuple(map(int, '$want'.split('.'))))" \
         >/dev/null 2>&1; then
      command -v "$cand"
      return 0
    fi
  done
  return 1
}

if [ "${1:-}" = "--find-python" ]; then
  want="${2:?usage: bootstrap.sh --find-python X.Y}"
  if [ "$want" = 3.13 ]; then explicit="${PYTHON313:-}"; else explicit="${PYTHON:-}"; fi
  find_python "$want" "$explicit"
  exit
fi

req="${1:-requirements-dev.txt}"
case "$(basename "$req")" in
  requirements-313.txt) venv=.venv313; want=3.13; var=PYTHON313
    why="bpy 5.2 and Blender 5.1+ use it" ;;
  *) venv=.venv; want=3.11; var=PYTHON
    why="Blender 4.2-5.0 and the bpy 5.0.1 wheel use it" ;;
esac
if ! py=$(find_python "$want" "${!var:-}"); then
  echo "curveskel: $req needs Python $want ($why); set $var=/path/to/python$want" >&2
  exit 1
fi
if [ ! -x "$venv/bin/python" ]; then
  "$py" -m venv "$venv"
fi
# The stamp names a checksum of the requirement files this venv installs from (the -r chain),
# so editing another venv's file does not reinstall this one.
if [ "$venv" = .venv313 ]; then
  files=(requirements-313.txt)
else
  files=(requirements.txt requirements-dev.txt requirements-bench.txt)
fi
stamp="$venv/.installed-$(cat "${files[@]}" | cksum | cut -d' ' -f1)-$(basename "$req")"
if [ ! -f "$stamp" ]; then
  "$venv/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip
  "$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$req"
  rm -f "$venv"/.installed-*-"$(basename "$req")"
  touch "$stamp"
fi
