#!/bin/bash
# The skip-converged study's renders (tools/research/skip_converged.py): Cycles' adaptive sampler on the noisy
# halves (noise threshold 0.01, Blender's default, at most 128 spp each), a 256-spp reference without it.
# Resumable: a scene whose folder exists is done (each renders into a temporary folder, renamed at the end).
#   bash tools/research/render_adaptive.sh OUT [RES] [THREADS] [SEED ...]   (defaults: 768, 2, 160 161 163 165 167 169 171)
set -euo pipefail
out=$1; res=${2:-768}; threads=${3:-2}; shift $(( $# < 3 ? $# : 3 ))
seeds=("$@"); [ ${#seeds[@]} -gt 0 ] || seeds=(160 161 163 165 167 169 171)
here=$(cd "$(dirname "$0")/../datagen" && pwd)
mkdir -p "$out"
for s in "${seeds[@]}"; do
  [ -d "$out/s$s" ] && continue
  tmp="$out/.tmp-s$s"; rm -rf "$tmp"
  blender -b --factory-startup -noaudio -t "$threads" --python "$here/make_scene.py" -- --scene-seed "$s" \
    --renders 128:1001,128:1002,256:1007 --adaptive-threshold 0.01 --res "$res" --threads "$threads" \
    --outdir "$tmp" > "$out/s$s.log" 2>&1
  mv "$tmp" "$out/s$s"
done
