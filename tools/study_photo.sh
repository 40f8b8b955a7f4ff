#!/bin/bash
# Issue 16, lever 5 (photographed textures): the shipped multiscale fine-tuned 5000 steps with and without the
# photographed scenes (same start, seed and recipe), each scored by goal_check.py on residue-v1's 30 validation
# scenes (+ the Cornell box) and on the photo set's own validation scenes. Resumable: finished models are kept.
#   tools/study_photo.sh WORKDIR [V1=.cache/datasets/residue-v1] [PHOTO=.cache/datasets/residue-photo]
# The photo set: tools/datagen/render_dataset.py --out .cache/datasets/residue-photo --seeds 2000-2109
#   --photos /usr/share/wallpapers --hdris /usr/share/blender/datafiles/studiolights/world
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
work=$(realpath -m "${1:?usage: tools/study_photo.sh WORKDIR [V1] [PHOTO]}")
v1=$(realpath "${2:-$repo/.cache/datasets/residue-v1}")
photo=$(realpath "${3:-$repo/.cache/datasets/residue-photo}")
starter=$(realpath "$repo/../shared/datasets/cycles-starter")
train="$repo/build/release/app/residue-train/residue-train"
mkdir -p "$work" && cd "$work"
cp -n "$repo/resources/models/multiscale.safetensors" init.safetensors
common=(--arch 2,2,2,2/24,40,56,80 --steps 5000 --val-every 1000 --checkpoint-every 250 --bf16 --batch 2 --patch 128
        --loss l1-log+ssim --autoexposure --exposure-key 1 --seed 12 --precise-bn 100 --freeze-bn-after 0.9
        --init-from "$work/init.safetensors" --lr 3e-4 --name multiscale)
[ -f control.safetensors ] || "$train" --data "$v1" "$starter" "${common[@]}" --log control.csv -o control.safetensors > control.out 2>&1
[ -f photo.safetensors ] || "$train" --data "$v1" "$starter" "$photo" "${common[@]}" --log photo.csv -o photo.safetensors > photo.out 2>&1
for m in control photo; do
  /usr/bin/python3 "$repo/tools/safetensors_meta.py" $m.safetensors --set residue.blend_tau=0 --set name=multiscale > /dev/null
  for ds in "$v1" "$photo"; do
    out=goal_${m}_$(basename "$ds")
    (cd "$repo" && /usr/bin/python3 tools/goal_check.py "$work/$m.safetensors" --dataset "$ds" --json "$work/$out.json") > $out.txt || true
  done
done
grep -H "mean relMSE\|mean SSIM" goal_*.txt
