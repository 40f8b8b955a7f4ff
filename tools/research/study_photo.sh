#!/bin/bash
# Issue 16, levers 5 (photographed textures) and 4 (albedo demodulation), measured on textured scenes.
#   tools/research/study_photo.sh WORKDIR [PHOTO=.cache/datasets/residue-photo] [PLAIN=.cache/datasets/residue-photo-plain]
# PHOTO: generator seeds rendered with photographs on the surfaces (and HDRIs through the windows), its validation
# scenes (seed % 11 == 10) the textured test set; PLAIN: the same training seeds without photographs. The rooms are
# the same (the photographs have their own random stream); each set draws its HDRIs from the same distribution, but
# not scene for scene (that stream draws the photographs first), so the sets differ in the textures and in which
# rooms see which sky:
#   R="/usr/bin/python3 tools/datagen/render_dataset.py"; H="--hdris /usr/share/blender/datafiles/studiolights/world"
#   $R --out $PHOTO --seeds 2001,2012,2023,2034,2045,2056 --photos /usr/share/wallpapers $H    # 6 validation scenes
#   $R --out $PHOTO --seeds 2000,2002-2011,2013-2017 --photos /usr/share/wallpapers $H --ref-spp 256   # 16 training
#   $R --out $PLAIN --seeds 2000,2002-2011,2013-2017 $H --ref-spp 256
# (training references at 256 spp, half residue-v1's, to fit a few hours: a noisier target adds zero-mean noise only)
# Lever 5: the shipped multiscale fine-tuned on the starter set plus PLAIN (the control) or plus PHOTO, same start,
# seed and steps. Lever 4: a flat 8/32 trained from scratch on the starter set plus PHOTO, with and without
# --demodulate. The two runs of a pair train side by side, one thread each. All are scored with the shipped
# multiscale, oidn and the bilateral filter on PHOTO's validation scenes, the starter set's six and Tungsten's
# Cornell box (blend tau 0 for every trained model). Resumable: finished models and tables are kept.
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
work=$(realpath -m "${1:?usage: tools/research/study_photo.sh WORKDIR [PHOTO] [PLAIN]}")
photo=$(realpath "${2:-$repo/.cache/datasets/residue-photo}")
plain=$(realpath "${3:-$repo/.cache/datasets/residue-photo-plain}")
starter=$(realpath "$repo/../shared/datasets/cycles-starter")
cornell=$(realpath "$repo/../shared/datasets/tungsten-example/cornell-box")
train="$repo/build/release/app/residue-train/residue-train"
cli="$repo/build/release/app/residue-cli/residue-cli"
mkdir -p "$work" && cd "$work"
cp -n "$repo/resources/models/multiscale.safetensors" init.safetensors

# fit NAME ARGS...: trains NAME.safetensors unless it exists (its checkpoint folder makes it resumable).
fit() {
  local name=$1; shift
  [ -f "$name.safetensors" ] || "$train" "$@" --threads 1 --log "$name.csv" -o "$name.safetensors" > "$name.out" 2>&1 ||
    { echo "study_photo.sh: training $name failed, see $work/$name.out" >&2; return 1; }
}
# pair A B: waits for two background fits and fails if either did.
pair() { wait "$1" && wait "$2"; }
ms=(--arch 2,2,2,2/24,40,56,80 --steps "${MS_STEPS:-1500}" --val-every 500 --checkpoint-every 250 --bf16 --batch 2
    --patch 128 --loss l1-log+ssim --autoexposure --exposure-key 1 --seed 14 --precise-bn 100 --freeze-bn-after 0.9
    --init-from "$work/init.safetensors" --lr 3e-4 --name multiscale)
fit control --data "$starter" "$plain" "${ms[@]}" & a=$!
fit photo --data "$starter" "$photo" "${ms[@]}" & b=$!
pair $a $b
flat=(--data "$starter" "$photo" --arch 8/32 --steps "${FLAT_STEPS:-2000}" --batch 8 --patch 64 --bf16 --val-every 1000
      --seed 7)
fit flat "${flat[@]}" & a=$!
fit flat_demod "${flat[@]}" --demodulate & b=$!
pair $a $b

models=(control photo flat flat_demod)
for m in "${models[@]}"; do
  /usr/bin/python3 "$repo/tools/models/safetensors_meta.py" $m.safetensors --set residue.blend_tau=0 > /dev/null
done
list=$(printf "$work/%s.safetensors," "${models[@]}")multiscale,oidn,bilateral
[ -f eval_photo.json ] || "$cli" evaluate-set "$photo" --split validation --models "$list" --md eval_photo.md --json eval_photo.json
# -m best's view of the textured scenes: multiscale and oidn, both as self-ensembles x8.
[ -f eval_photo_x8.json ] || "$cli" evaluate-set "$photo" --split validation --models multiscale,oidn --ensembles 8 \
  --md eval_photo_x8.md --json eval_photo_x8.json
[ -f eval_starter.json ] || "$cli" evaluate-set "$starter" --last 6 --models "$list" --md eval_starter.md --json eval_starter.json
# The Cornell box: the metrics table's "denoised" row (relMSE, MSE, PSNR, SSIM).
for m in "${models[@]/%/.safetensors}" multiscale oidn bilateral; do
  "$cli" denoise "$cornell" -m "$m" -o "$work/cornell.exr" --force | awk -v m="$(basename "$m" .safetensors)" \
    '$1 == "denoised" {print m, "relMSE", $2, "SSIM", $5}'
done | tee cornell.txt
rm -f cornell.exr
