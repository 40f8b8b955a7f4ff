#!/usr/bin/env bash
# Trains the shipped model zoo, resumably: each model is skipped when its file exists, and a killed run
# continues from its checkpoint (residue-train resumes from OUT.ckpt). Then evaluates every model on the
# data set's validation scenes and plots the speed-versus-accuracy curve.
#
#   tools/models/train_zoo.sh OUT_DIR DATA_DIR [DATA_DIR...]
#   e.g. tools/models/train_zoo.sh /work/train/zoo /work/datasets/residue-v1 ../shared/datasets/cycles-starter
#
# Environment: ZOO_MODELS (default "tiny small base base-albedo-normal base-color base-variance base-ft paper
# paper-ft"; base-variance reads the noise-level input; base-ft is base fine-tuned 3000 more steps with its own
# inputs, the variants' control, and is what ships as base; paper-ft is paper fine-tuned 1500 more steps the same
# way, and ships as paper; also known: base-dilated (dilations 1,2,4,8) and ms, issue 16's multi-scale network at
# OIDN's cost: 4 levels 24-80 wide, autoexposed at key 1, 2 x 128-px patches, L1 + SSIM, shipped as multiscale with
# its variants ms-albedo-normal and ms-color; docs/research/MODELS_HISTORY.md 2b-3c, GOAL_JOURNAL.md 2026-11-26;
# and post, lever 6's correction of OIDN's output, 4/32, its output conv starting at zero),
# ZOO_THREADS (2),
# ZOO_STEPS_<NAME> to override a model's steps (e.g. ZOO_STEPS_paper=2000), ZOO_BF16=1 to train with CPU autocast
# to bfloat16 (1.5-1.9x faster here), RESIDUE_BUILD (build/release).
# Every model recomputes its BN statistics over 100 batches before each validation (--precise-bn) and trains
# its last 10 % with them fixed (--freeze-bn-after): docs/MODELS.md, "Batch norm at inference".
# Copy the finished OUT_DIR/<name>.safetensors into resources/models/ (base-ft as base.safetensors, paper-ft as
# paper.safetensors, ms and its variants ms-albedo-normal and ms-color as multiscale*.safetensors, renamed with
# tools/models/safetensors_meta.py --set name=...) and run tools/models/stamp_benchmark.py.
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
out=${1:?usage: train_zoo.sh OUT_DIR DATA_DIR...}; shift
[ $# -ge 1 ] || { echo "train_zoo: give at least one data set folder" >&2; exit 2; }
build=${RESIDUE_BUILD:-$repo/build/release}
train=$build/app/residue-train/residue-train
cli=$build/app/residue-cli/residue-cli
threads=${ZOO_THREADS:-2}
mkdir -p "$out"
export OMP_WAIT_POLICY=passive

# name: architecture, feature set, steps, validation interval
declare -A arch=([tiny]=4/32 [small]=8/32 [base]=8/64 [base-albedo-normal]=8/64 [base-color]=8/64 [paper]=16/128
                 [base-variance]=8/64 [base-dilated]=8/64 [base-ft]=8/64 [paper-ft]=16/128 [ms]=2,2,2,2/24,40,56,80
                 [ms-albedo-normal]=2,2,2,2/24,40,56,80 [ms-color]=2,2,2,2/24,40,56,80 [post]=4/32)
declare -A features=([tiny]=full [small]=full [base]=full [base-albedo-normal]=color+albedo+normal
                     [base-color]=color [paper]=full [base-variance]=full+variance [base-dilated]=full
                     [base-ft]=full [paper-ft]=full [ms]=full [ms-albedo-normal]=color+albedo+normal
                     [ms-color]=color [post]=full)
declare -A steps=([tiny]=16000 [small]=16000 [base]=12000 [base-albedo-normal]=3000 [base-color]=3000 [paper]=4000
                  [base-variance]=3000 [base-dilated]=12000 [base-ft]=3000 [paper-ft]=1500 [ms]=40000 [ms-albedo-normal]=3000
                  [ms-color]=3000 [post]=10000)
ms_recipe="--batch 2 --patch 128 --loss l1-log+ssim --autoexposure --exposure-key 1 --seed 7"  # ms and its variants
declare -A extra=([base-dilated]="--dilations 1,2,4,8"
                  [ms]=$ms_recipe [ms-albedo-normal]=$ms_recipe [ms-color]=$ms_recipe
                  [post]="--prior oidn --input-skip --loss l1-log+ssim --seed 7")
# The feature-set variants of base, and the -ft runs, are fine-tuned from a trained model (--init-from: its
# weights, the input planes matched by name) at a lower peak learning rate, for a quarter to a third of its steps.
declare -A init=([base-albedo-normal]=base [base-color]=base [base-variance]=base [base-ft]=base [paper-ft]=paper
            [ms-albedo-normal]=ms [ms-color]=ms)
# Validations per run (default 10): a 16/128 validation takes 2-3 min on 2 cores, so paper-ft validates 3 times.
declare -A validations=([paper-ft]=3)

for name in ${ZOO_MODELS:-tiny small base base-albedo-normal base-color base-variance base-ft paper paper-ft}; do
  var="ZOO_STEPS_${name//-/_}"
  n=${!var:-${steps[$name]}}
  if [ -f "$out/$name.safetensors" ]; then echo "train_zoo: $name exists, skipped"; continue; fi
  warm=()
  if [ -n "${init[$name]:-}" ]; then
    src="$out/${init[$name]}.safetensors"
    [ -f "$src" ] || { echo "train_zoo: $name is fine-tuned from ${init[$name]}: train that first" >&2; exit 2; }
    warm=(--init-from "$src" --lr 3e-4)
  fi
  echo "train_zoo: $name (${arch[$name]}, ${features[$name]}, $n steps${warm:+, from ${init[$name]}})"
  "$train" --data "$@" --arch "${arch[$name]}" --features "${features[$name]}" --steps "$n" \
    --val-every $(( n / ${validations[$name]:-10} )) --checkpoint-every 250 --threads "$threads" ${ZOO_BF16:+--bf16} ${extra[$name]:-} \
    --precise-bn 100 --freeze-bn-after 0.9 "${warm[@]}" \
    --name "$name" -o "$out/$name.safetensors" \
    --log "$out/$name.csv" | tee -a "$out/$name.out"
  /usr/bin/python3 "$repo/tools/models/plot_training.py" "$out/$name.csv" "$out/${name}_training.png" || true
done

# The measured trade, on the first data set's validation scenes (its index.json), every model in OUT_DIR.
models=bilateral
for f in "$out"/*.safetensors; do models+=",$f"; done
"$cli" evaluate-set "$1" --split validation --models "$models" --precisions fp32,bf16 \
  --md "$out/eval.md" --json "$out/eval.json" --force
/usr/bin/python3 "$repo/tools/models/plot_tradeoff.py" "$out/eval.json" "$out/tradeoff.png" || true
