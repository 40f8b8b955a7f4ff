#!/usr/bin/env bash
# Smoke test of the data generator against residue-cli: renders ONE tiny scene (32x32, 2 spp noisy, 16 spp
# reference) with render_dataset.py into a temporary folder, then checks that
#   residue-cli info   recognises noisy_a.exr as a Blender Cycles render, and
#   residue-cli eval   gives the same relMSE of noisy_a against the reference as scene.json (3 significant digits).
# Usage: smoke_test.sh CLI_PATH      (ctest: datagen_smoke). Exit 77 (skipped) without /usr/bin/blender.
# Environment: RESIDUE_SMOKE_SEED (default 1000, an interior; odd seeds are open-air scenes),
#              RESIDUE_SMOKE_KEEP=1 keeps the temporary folder.
set -euo pipefail

cli=${1:?usage: smoke_test.sh CLI_PATH}
blender=/usr/bin/blender
py=/usr/bin/python3
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
seed=${RESIDUE_SMOKE_SEED:-1000}

if [ ! -x "$blender" ]; then
  echo "datagen_smoke: SKIP, no $blender (apt-get install blender)"
  exit 77
fi
if ! "$py" -c "import numpy, OpenImageIO" 2>/dev/null; then
  echo "datagen_smoke: SKIP, $py lacks numpy or OpenImageIO (python3-numpy python3-openimageio)"
  exit 77
fi

dir=$(mktemp -d "${TMPDIR:-/tmp}/residue-datagen-smoke.XXXXXX")
if [ "${RESIDUE_SMOKE_KEEP:-0}" = 1 ]; then
  echo "datagen_smoke: keeping $dir"
else
  trap 'rm -rf "$dir"' EXIT
fi

fail() {
  echo "datagen_smoke: FAIL: $*" >&2
  exit 1
}

"$py" "$here/render_dataset.py" --out "$dir" --seeds "$seed" --res 32 --spp 2 --ref-spp 16 --val-ref-spp 16 --threads 2 ||
  { cat "$dir/logs/s$seed.log" >&2 || true; fail "render_dataset.py failed"; }
scene="$dir/s$seed"
for f in noisy_a.exr noisy_b.exr reference.exr scene.json; do
  [ -f "$scene/$f" ] || fail "missing $scene/$f"
done
[ -f "$dir/index.json" ] || fail "missing $dir/index.json"

info=$("$cli" info "$scene/noisy_a.exr") || fail "residue-cli info exited $?"
echo "$info"
grep -q "Blender Cycles" <<<"$info" || fail "residue-cli info does not report 'Blender Cycles'"

"$cli" eval "$scene/noisy_a.exr" --reference "$scene/reference.exr" --json >"$dir/eval.json" ||
  fail "residue-cli eval exited $?"

"$py" - "$scene/scene.json" "$dir/eval.json" <<'EOF'
import json
import sys

with open(sys.argv[1]) as f:
    scene = json.load(f)
with open(sys.argv[2]) as f:
    ev = json.load(f)
a = float(scene["metrics"]["relmse_noisy_a"])
b = float(ev["rows"][0]["relmse"])
same = f"{a:.3g}" == f"{b:.3g}" or abs(a - b) <= 5e-4 * max(abs(a), abs(b))
print(f"datagen_smoke: relMSE noisy_a: scene.json {a:.6g}, residue-cli eval {b:.6g} -> "
      f"{'agree' if same else 'DIFFER'} to 3 significant digits")
for key in ("spp", "sampling_seeds", "camera", "metrics", "files"):
    if key not in scene:
        print(f"datagen_smoke: scene.json lacks '{key}'")
        sys.exit(1)
if not scene["metrics"]["all_finite"]:
    print("datagen_smoke: non-finite pixels in the renders")
    sys.exit(1)
sys.exit(0 if same else 1)
EOF
echo "datagen_smoke: OK ($scene)"
