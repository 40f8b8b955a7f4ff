#!/bin/bash
# Stages a training run for a lent GPU machine (docs/research/MODELS_HISTORY.md, lever 7): the device tool sends the working tree
# (tracked files and untracked ones git does not ignore, at most 64 MiB with the carried paths) and keeps a machine
# only 30 s after a call, and a fresh one is bare. So the data go as residue-train's own export, packed at fp16 into
# two halves that each fit a call, and the large tracked folders (weights, figures: 111 of the tree's 113 MB) leave the
# index for the calls and come back after.
#   [PARTS=N] tools/models/gpu_stage.sh pack DIR RESIDUE_TRAIN_ARGS...  export (residue-train --export-training-set) and
#       pack into one folder per call, DIR/call1 ... DIR/call<2N>: each of the N parts of the training scenes (every
#       N-th scene) as its half 0, then its half 1; the validation scenes go with call 1. The starter set: N = 1.
#   tools/models/gpu_stage.sh slim       the large folders out of the index (and into .git/info/exclude): nothing is deleted
#   tools/models/gpu_stage.sh restore    the index and .git/info/exclude as they were
# Then: each call but the last carries DIR/call<k> and copies it to /root/stage; the last, each within the 30 s of the
# one before, carries its own, copies it there too and runs `python3 tools/models/torch_train.py train --data /root/stage/*.npz
# ... --seconds S --out $OUT/M`
# (a model file over 16 MiB comes back split: `split -b 15000000`, joined here with cat). Commit nothing between
# slim and restore.
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
cd "$repo"
large=(resources/models docs/research/models docs/images resources/examples)
marker="# gpu_stage.sh slim"
case "${1:-}" in
  pack)
    [ $# -ge 3 ] || { echo "usage: [PARTS=N] gpu_stage.sh pack DIR RESIDUE_TRAIN_ARGS..." >&2; exit 2; }
    dir=$2
    shift 2
    parts=${PARTS:-1}
    mkdir -p "$dir"
    build/release/app/residue-train/residue-train "$@" --export-training-set "$dir/export.safetensors" --force
    call=0
    for ((k = 0; k < parts; ++k)); do
      for h in 0 1; do
        call=$((call + 1))
        mkdir -p "$dir/call$call"
        val=(--no-val)
        [ "$call" = 1 ] && val=()
        /usr/bin/python3 tools/models/torch_train.py pack "$dir/export.safetensors" "$dir/call$call/part${k}_half$h.npz" \
          --part "$k/$parts" --half "$h" "${val[@]}" --force
      done
    done
    rm "$dir/export.safetensors"
    du -sm "$dir"/call* | while read -r mib folder; do
      [ "$mib" -le 58 ] ||
        echo "gpu_stage.sh: $folder is $mib MiB: with the tree it may pass a call's 64 (try PARTS=$((parts + 1)))"
    done ;;
  slim)
    ! grep -qx "$marker" .git/info/exclude 2>/dev/null || { echo "gpu_stage.sh: already slim" >&2; exit 1; }
    git diff --cached --quiet || { echo "gpu_stage.sh: the index has staged changes; commit them first" >&2; exit 1; }
    git rm -r --cached -q "${large[@]}"
    { echo "$marker"; printf '/%s/\n' "${large[@]}"; } >> .git/info/exclude
    echo "gpu_stage.sh: the tree a call sends: $(git ls-files -z | du -cb --files0-from=- | tail -1 | cut -f1) bytes" ;;
  restore)
    git reset -q
    [ -f .git/info/exclude ] && sed -i "/^$marker\$/,+${#large[@]}d" .git/info/exclude
    git status --short | head ;;
  *) echo "usage: [PARTS=N] gpu_stage.sh pack DIR RESIDUE_TRAIN_ARGS... | slim | restore" >&2; exit 2 ;;
esac
