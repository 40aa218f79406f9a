#!/usr/bin/env bash
# Build the sdist and the wheel, install the wheel alone in a fresh virtual environment and
# run a shipped scenario by bare name from a folder outside the source tree.
#
#   tools/check_wheel.sh [PYTHON]      # PYTHON: an interpreter with `build` (default python3)
#
# Needs package-index access (the wheel's dependencies are installed from it). Exit 0 and a
# last line "wheel ok: ..." when everything works; the wheel is left in dist/.
set -euo pipefail
# The wheel on its own: nothing from the caller's environment may supply the package.
unset PYTHONPATH PYTHONHOME PYTHONUSERBASE PIP_TARGET PIP_PREFIX
export PYTHONNOUSERSITE=1

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
py="${1:-python3}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

echo "== build (sdist, then the wheel from the sdist)"
rm -rf "$root/dist"
"$py" -m build --outdir "$root/dist" "$root" > "$work/build.log" 2>&1 \
    || { tail -40 "$work/build.log"; exit 1; }
wheel="$(ls "$root"/dist/*.whl)"
echo "$wheel"
# The listing once, into a file: `grep -q` on a pipe stops reading early, and the lister's
# broken pipe would fail the check under pipefail.
"$py" -m zipfile -l "$wheel" > "$work/listing.txt"
grep -q "warerover_phys/_layouts/paper_homogeneous.yaml" "$work/listing.txt" \
    || { echo "the wheel holds no packaged layouts"; exit 1; }
grep -q "warerover_phys/_layouts/maps/paper_20x15.yaml" "$work/listing.txt" \
    || { echo "the wheel holds no packaged layout maps"; exit 1; }
grep -q "warerover_phys/planning/weights/learned_v1.npz" "$work/listing.txt" \
    || { echo "the wheel holds no learned-planner weights"; exit 1; }
grep -q "warerover_phys/serve/static/index.html" "$work/listing.txt" \
    || { echo "the wheel holds no browser page"; exit 1; }

echo "== install into a fresh venv"
"$py" -m venv "$work/venv"
"$work/venv/bin/python" -m pip install --quiet --upgrade pip > /dev/null
"$work/venv/bin/python" -m pip install --quiet "$wheel"

echo "== run shipped scenarios by name, outside the source tree"
cd "$work"
"$work/venv/bin/warerover" check paper_fault
"$work/venv/bin/warerover" run paper_homogeneous --json --quiet --out "$work/run" > "$work/m.json"
"$work/venv/bin/python" - "$work/m.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
assert m["success_rate"] == 1.0 and m["orders_completed"] == 20, m
print(f"paper_homogeneous: SR {m['success_rate']}, TP {m['throughput']:.3f}, {m['ticks']} ticks")
PY
"$work/venv/bin/warerover" run paper_homogeneous --planner learned --json --quiet \
    --out "$work/run-learned" > /dev/null
echo "paper_homogeneous with the learned planner (packaged weights): ok"
"$work/venv/bin/python" -c "import warerover_phys, sys; \
    assert 'site-packages' in warerover_phys.__file__, warerover_phys.__file__"
set +e
"$work/venv/bin/warerover" run no_such_scenario --json > /dev/null 2> "$work/err"
rc=$?
set -e
[ "$rc" -eq 2 ] || { echo "a missing scenario should exit 2 (got $rc)"; cat "$work/err"; exit 1; }
echo "wheel ok: $(basename "$wheel")"
