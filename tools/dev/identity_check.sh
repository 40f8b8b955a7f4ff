#!/usr/bin/env bash
# Bit-identity across a change that must not alter any output (a refactor): denoises the Cornell box (Tungsten,
# from ../shared) and the bundled room with every shipped model, both OIDN modes, the bilateral filter, an
# ensemble, a strength, a region, both backends and bf16, and the temporal model on a rendered shot, and writes the EXRs to DIR. Run it before the change
# with `capture DIR`, after it with `compare DIR`: every file must equal its twin to the last bit
# (oiiotool --diff --fail 0), and the listing says which differ.
#   tools/dev/identity_check.sh capture /tmp/identity-before
#   tools/dev/identity_check.sh compare /tmp/identity-before
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
cli=${RESIDUE_CLI:-$repo/build/release/app/residue-cli/residue-cli}
mode=${1:?capture|compare}; dir=${2:?DIR}
cornell=$repo/../shared/datasets/tungsten-example/cornell-box
room=$repo/resources/examples/room/noisy.exr
out=$dir; [ "$mode" = compare ] && out=$dir.after
rm -rf "$out"; mkdir -p "$out"
# name | input | options
cases=()
for m in base base-albedo-normal base-color multiscale multiscale-albedo-normal multiscale-color \
         paper small tiny oidn oidn-cleanaux bilateral best; do
  cases+=("room-$m|$room|-m $m")
done
cases+=("room-multiscale-bf16|$room|-m multiscale --precision bf16"
        "room-multiscale-onednn|$room|-m multiscale --backend onednn"
        "room-base-x4|$room|-m base --ensemble 4"
        "room-oidn-bf16|$room|-m oidn --precision bf16"
        "room-multiscale-s05|$room|-m multiscale --strength 0.5"
        "room-bilateral-s05-roi|$room|-m bilateral --strength 0.5 --roi 20,30,100,90"
        "room-multiscale-roi|$room|-m multiscale --roi 20,30,100,90"
        "room-base-tile32|$room|-m base --tile 32"
        "cornell-multiscale|$cornell|-m multiscale"
        "cornell-multiscale-bf16|$cornell|-m multiscale --precision bf16"
        "cornell-oidn|$cornell|-m oidn"
        "cornell-oidn-cleanaux|$cornell|-m oidn-cleanaux"
        "cornell-oidn-cleanaux-bf16|$cornell|-m oidn-cleanaux --precision bf16"
        "cornell-best|$cornell|-m best"
        "cornell-bilateral|$cornell|-m bilateral"
        "cornell-base-color|$cornell|-m base-color --backend onednn"
        "cornell-base-variance|$cornell|-m base-variance"
        "cornell-small-streamed|$cornell|-m small --max-memory 4 --no-energy-correction")
for c in "${cases[@]}"; do
  IFS='|' read -r name input opts <<< "$c"
  # shellcheck disable=SC2086
  "$cli" denoise "$input" -o "$out/$name.exr" --float $opts > "$out/$name.log" 2>&1 || echo "FAILED $name (see $out/$name.log)"
done
# A sequence: the temporal model on frames of the committed rendered shot, with their neighbours.
"$cli" denoise "$repo/tests/data/shot/noisy.####.exr" --temporal --frames 1-3 -o "$out/shot-temporal.####.exr" --float \
  > "$out/shot-temporal.log" 2>&1 || echo "FAILED shot-temporal (see $out/shot-temporal.log)"
[ "$mode" = capture ] && { echo "captured $(ls "$out"/*.exr | wc -l) outputs in $out"; exit 0; }
bad=0
for f in "$dir"/*.exr; do
  n=$(basename "$f")
  if ! oiiotool --diff --fail 0 --failpercent 0 "$f" "$out/$n" > /dev/null 2>&1; then echo "DIFFERS $n"; bad=$((bad + 1)); fi
done
echo "$(ls "$dir"/*.exr | wc -l) outputs compared, $bad differ"
[ "$bad" = 0 ]
