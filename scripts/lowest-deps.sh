#!/usr/bin/env bash
# The lowest-versions check: every dependency of Hearth (core and every optional extra) at
# the lowest version pyproject.toml allows, in a fresh virtual environment; then
# every module is imported and `hearth validate`, `hearth show` and `hearth run` are run on
# the shipped demo home and missions. A floor that is too low fails here.
#
#   scripts/lowest-deps.sh [VENV]    (default: a temporary directory, removed afterwards)
#
# Wheels only (a floor without a wheel for this Python fails at once instead of compiling).
# Downloads come from the package index (pip's cache keeps them for the next run). Hearth
# itself is not installed: the checkout is put on PYTHONPATH.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
python=${PYTHON:-python3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
venv=${1:-$work/venv}

"$python" -m venv "$venv"
py="$venv/bin/python"
"$py" "$root/scripts/lowest_pins.py" "$root/pyproject.toml" > "$work/lowest.txt"
echo "lowest-deps: $(tr '\n' ' ' < "$work/lowest.txt")"
# No constraints file here (the point is other versions than the tested ones); pip's global
# configuration still applies.
"$py" -m pip install -q --disable-pip-version-check --only-binary :all: -r "$work/lowest.txt"
"$py" -m pip check >/dev/null || { "$py" -m pip check >&2; echo "lowest-deps: the lowest versions conflict" >&2; exit 1; }
mismatch=$("$py" - "$work/lowest.txt" <<'PY'
import sys
from importlib.metadata import version
for line in open(sys.argv[1]):
    name, want = line.strip().split("==")
    if version(name) != want:
        print(f"{name} {version(name)} (wanted {want})")
PY
)
if [ -n "$mismatch" ]; then
  echo "lowest-deps: pip installed other versions than the lowest: $mismatch" >&2
  exit 1
fi

cd "$work"     # away from the checkout: only PYTHONPATH finds Hearth
export PYTHONPATH="$root" MPLBACKEND=Agg
"$py" "$root/scripts/import_all.py"
"$py" -m hearth validate "$root/data/demo_home/world.xml" "$root"/missions/*.yaml
"$py" -m hearth show "$root/missions/fetch_object.yaml" > /dev/null
"$py" -m hearth run "$root/missions/go_to_rest.yaml" --runs-dir "$work/runs" --quiet
echo "lowest-deps: ok"
