#!/bin/bash
# Issue 16, lever 5 at full scale: the shipped multiscale fine-tuned with the relMSE term on every training scene we
# have (residue-v1's 300 training seeds with pseudo-referenced interiors, the pseudo-referenced noisy interiors,
# the photographed and plain sets, the starter set), averaged 0.6 / 0.4 with its start (the recipe that won in
# 2026-11-26 and 2026-11-27: docs/research/MODELS_HISTORY.md levers 1b and 5), then scored by tools/research/goal_check.py x1 and x8 beside the start.
#   tools/models/finetune_full.sh WORKDIR
# Writes start/run/soup.safetensors, goal_{start,run,soup}_x{1,8}.{txt,json} and bands.{md,json} (error_bands.py).
# Data: tools/models/render_training_data.sh renders every folder it trains on (tools/models/training_data.sh), each with the
# command that made it (resumable; 4-7 h on 2 cores).
# The trainer's validation is the cards' 36 scenes (residue-v1's 30 and the starter set's last 6): it only
# monitors; the verdict is goal_check's. Environment: STEPS (5000), LR (1e-4), RELMSE_WEIGHT (2), LOWBAND_WEIGHT
# (0; LOWBAND_WIDTH 16: the relMSE of box means, the error's low band), EDGE_SSIM_WEIGHT (0: 1 - SSIM on the
# albedo/normal edge pixels counted again, residue-train --edge-ssim-weight), SEED (16),
# THREADS (2), PRECISION (fp32, or bf16: slower on the Intel CPU measured, faster on Zen; MODELS.md "Training
# speed"); ARCH (2,2,2,2/24,40,56,80: the shipped one, so --init-from) with WIDEN=1 for a wider ARCH that starts as
# the shipped network (--widen-from), or GROW=1 for an ARCH one level deeper that starts as it (--grow-from); PATCH
# (128) and BATCH (2); V1_PSEUDO (.cache/datasets/residue-v1-pseudo: another folder of that set, e.g.
# a fixed subset for an A/B) and EXTRA_SETS (residue-pseudo residue-photo residue-photo-plain, the other training
# folders; empty for none); TEACHER (empty; a model name or file, e.g. start.safetensors: distilled targets,
# residue-train --teacher) with TEACHER_WEIGHT (0.5) and TEACHER_ENSEMBLE (8). Resumable: the run continues from
# its checkpoint folder, finished files and tables are kept. A run spans several starts, so its settings are written to
# WORKDIR/settings.env when it starts and read from there when it resumes: `tools/models/finetune_full.sh WORKDIR` alone
# resumes it, and a setting given that differs from the recorded one is refused rather than silently changing the
# schedule, the loss or the shape half-way. So is data that changed: the folders and their scene counts are
# written to WORKDIR/data.txt when training starts, and a resumed run whose folders hold other counts (a set
# rendered further, or lost with a machine) stops there.
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
work=$(realpath -m "${1:?usage: tools/models/finetune_full.sh WORKDIR}")
source "$repo/tools/models/training_data.sh"
settings=(STEPS=5000 LR=1e-4 RELMSE_WEIGHT=2 LOWBAND_WEIGHT=0 LOWBAND_WIDTH=16 EDGE_SSIM_WEIGHT=0 SEED=16 PRECISION=fp32
          ARCH=2,2,2,2/24,40,56,80 WIDEN=0 GROW=0 PATCH=128 BATCH=2 V1_PSEUDO=residue-v1-pseudo
          "EXTRA_SETS=$training_data_default_sets" TEACHER= TEACHER_WEIGHT=0.5 TEACHER_ENSEMBLE=8)  # NAME=default
mkdir -p "$work"
if [ -f "$work/settings.env" ]; then
  while IFS='=' read -r k v; do
    if [ -n "${!k+set}" ] && [ "${!k}" != "$v" ]; then
      echo "finetune_full.sh: $work was started with $k=$v; not resuming it with $k=${!k}" >&2
      exit 2
    fi
    printf -v "$k" '%s' "$v"
  done < "$work/settings.env"
fi
for kv in "${settings[@]}"; do
  k=${kv%%=*}
  [ -n "${!k+set}" ] || printf -v "$k" '%s' "${kv#*=}"
done
[ -f "$work/settings.env" ] || for kv in "${settings[@]}"; do k=${kv%%=*}; echo "$k=${!k}"; done > "$work/settings.env"
# shellcheck disable=SC2086  # EXTRA_SETS is a list of words
training_data "$V1_PSEUDO" $EXTRA_SETS
cd "$work"
if [ ! -f run.safetensors ]; then  # still training: the data must be what the run started with
  training_data_summary > data.now
  [ -f data.txt ] || cp data.now data.txt
  if ! cmp -s data.txt data.now; then
    { echo "finetune_full.sh: the training data changed since $work started; as it started (data.txt):"
      sed 's/^/  /' data.txt; echo "now:"; sed 's/^/  /' data.now
      echo "restore those folders, or start a new WORKDIR"; } >&2
    exit 2
  fi
  rm data.now
fi
cp -n "$repo/resources/models/multiscale.safetensors" start.safetensors
start=(--init-from start.safetensors) base=start
[ "$WIDEN" = 1 ] && start=(--widen-from start.safetensors) base=start_reshaped
[ "$GROW" = 1 ] && start=(--grow-from start.safetensors) base=start_reshaped
precision=() teacher=()
[ -z "$TEACHER" ] ||
  teacher=(--teacher "$TEACHER" --teacher-weight "$TEACHER_WEIGHT" --teacher-ensemble "$TEACHER_ENSEMBLE")
case "$PRECISION" in fp32) ;; bf16) precision=(--bf16) ;; *) echo "finetune_full.sh: PRECISION is fp32 or bf16" >&2; exit 2 ;; esac
train() {  # NAME STEPS: NAME.safetensors, its log and checkpoint
  [ -f "$1.safetensors" ] && return
  "$repo/build/release/app/residue-train/residue-train" --data "${data[@]}" --arch "$ARCH" \
    --steps "$2" --val-every 1000 --checkpoint-every 250 --batch "$BATCH" --patch "$PATCH" \
    --loss l1-log+ssim --relmse-weight "$RELMSE_WEIGHT" --lowband-weight "$LOWBAND_WEIGHT" \
    --lowband-width "$LOWBAND_WIDTH" --edge-ssim-weight "$EDGE_SSIM_WEIGHT" --autoexposure --exposure-key 1 \
    --seed "$SEED" --freeze-bn-after 0 "${start[@]}" --lr "$LR" --name multiscale \
    --threads "${THREADS:-2}" "${precision[@]}" "${teacher[@]}" --log "$1.csv" -o "$1.safetensors" > "$1.out" 2>&1 ||
    { echo "finetune_full.sh: training failed, see $work/$1.out" >&2; exit 1; }
}
# A widened or grown run averages with its own start (the shipped network in the new shape, computing what it
# computes; new channels or level as initialised): 0 steps.
[ "$base" = start ] || train start_reshaped 0
train run "$STEPS"
[ -f soup.safetensors ] || /usr/bin/python3 "$repo/tools/models/average_weights.py" soup.safetensors \
  $base.safetensors:0.6 run.safetensors:0.4
for m in run soup; do
  /usr/bin/python3 "$repo/tools/models/safetensors_meta.py" $m.safetensors --set residue.blend_tau=0 > /dev/null
done
for m in start run soup; do
  for e in 1 8; do
    [ -f goal_${m}_x$e.json ] || /usr/bin/python3 "$repo/tools/research/goal_check.py" "$work/$m.safetensors" --ensemble $e \
      --json goal_${m}_x$e.json > goal_${m}_x$e.txt || true   # exit status 1 is "goal not reached", still a result
    echo "== $m x$e"; sed -n 2,5p goal_${m}_x$e.txt
  done
done
# Where the error moved: interiors' low frequencies (48 px) are where OIDN leads (docs/research/MODELS_HISTORY.md lever 2).
[ -f bands.md ] || /usr/bin/python3 "$repo/tools/research/error_bands.py" "$repo/.cache/datasets/residue-v1" --widths 16,48 \
  --models "$work/start.safetensors,$work/run.safetensors,$work/soup.safetensors,oidn" --work "$work/bands" \
  --json bands.json > bands.md
cat bands.md
