#!/bin/bash
# Issue 16, lever 4's deciding run: `multiscale` trained from scratch with and without --demodulate (colour divided
# by the albedo before the network, multiplied back after), same data, seed, steps and recipe, side by side with
# one thread each, then scored on the project's goal (tools/research/goal_check.py: residue-v1's 30 validation scenes and
# Tungsten's Cornell box) and on the photographed validation scenes the lever is meant for.
#   tools/research/study_demod.sh WORKDIR
# Environment: STEPS (12000), SEED (17). Data: everything tools/models/finetune_full.sh trains on (its header says how to
# render it). Writes plain/demod.safetensors with their .csv logs, goal_{plain,demod}_x1.{txt,json},
# compare_x1.txt (tools/research/goal_compare.py: scene by scene) and eval_photo.{md,json}. Resumable: each run continues
# from its checkpoint folder; finished models and tables are kept.
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
work=$(realpath -m "${1:?usage: tools/research/study_demod.sh WORKDIR}")
steps=${STEPS:-12000} seed=${SEED:-17}
source "$repo/tools/models/training_data.sh"
training_data residue-v1-pseudo $training_data_default_sets
cli="$repo/build/release/app/residue-cli/residue-cli"
mkdir -p "$work" && cd "$work"

# fit NAME ARGS...: trains NAME.safetensors unless it exists (its checkpoint folder makes it resumable).
fit() {
  local name=$1; shift
  [ -f "$name.safetensors" ] && return
  "$repo/build/release/app/residue-train/residue-train" --data "${data[@]}" --arch 2,2,2,2/24,40,56,80 \
    --steps "$steps" --val-every 2000 --checkpoint-every 250 --batch 2 --patch 128 --loss l1-log+ssim \
    --autoexposure --exposure-key 1 --precise-bn 100 --freeze-bn-after 0.9 --lr 1e-3 --seed "$seed" \
    --name "$name" --threads 1 "$@" --log "$name.csv" -o "$name.safetensors" > "$name.out" 2>&1 ||
    { echo "study_demod.sh: training $name failed, see $work/$name.out" >&2; return 1; }
}
fit plain & a=$!
fit demod --demodulate & b=$!
wait $a && wait $b

for m in plain demod; do
  /usr/bin/python3 "$repo/tools/models/safetensors_meta.py" $m.safetensors --set residue.blend_tau=0 > /dev/null
  [ -f goal_${m}_x1.json ] || /usr/bin/python3 "$repo/tools/research/goal_check.py" "$work/$m.safetensors" \
    --json goal_${m}_x1.json > goal_${m}_x1.txt || true   # exit status 1 is "goal not reached", still a result
  echo "== $m"; sed -n 2,5p goal_${m}_x1.txt
done
/usr/bin/python3 "$repo/tools/research/goal_compare.py" goal_plain_x1.json goal_demod_x1.json | tee compare_x1.txt
[ -f eval_photo.json ] || "$cli" evaluate-set "$repo/.cache/datasets/residue-photo" --split validation \
  --models "$work/plain.safetensors,$work/demod.safetensors,multiscale,oidn" --md eval_photo.md --json eval_photo.json
cat eval_photo.md
