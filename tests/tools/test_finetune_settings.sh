#!/bin/bash
# tools/models/finetune_full.sh keeps a run's settings and data from one start to the next: resuming with a setting that differs from
# the one recorded in WORKDIR/settings.env is refused before anything runs, and the record is left as it was; the
# data folders' scene counts are recorded in WORKDIR/data.txt when it starts, and a resumed run whose folders hold
# other counts is refused. The script runs from a copy in a tree without a model or a trainer, so that a broken
# refusal fails for want of them instead of training for hours.
#   test_finetune_settings.sh REPO
set -uo pipefail
top=$(mktemp -d)
trap 'rm -rf "$top"' EXIT
tree=$top/repo
mkdir -p "$tree/tools/models" "$tree/work"
cp "$1/tools/models/finetune_full.sh" "$1/tools/models/training_data.sh" "$tree/tools/models/"
repo=$tree work=$tree/work
printf '%s\n' STEPS=24000 LOWBAND_WEIGHT=0 GROW=1 > "$work/settings.env"
cp "$work/settings.env" "$work/recorded"
fail=0
out=$(LOWBAND_WEIGHT=8 "$repo/tools/models/finetune_full.sh" "$work" 2>&1); rc=$?
[ "$rc" = 2 ] || { echo "FAIL: a changed setting gave exit status $rc, not 2: $out"; fail=1; }
grep -q "started with LOWBAND_WEIGHT=0; not resuming it with LOWBAND_WEIGHT=8" <<< "$out" ||
  { echo "FAIL: the refusal does not name the setting: $out"; fail=1; }
out=$(STEPS=5000 "$repo/tools/models/finetune_full.sh" "$work" 2>&1); rc=$?
[ "$rc" = 2 ] && grep -q "STEPS=24000" <<< "$out" || { echo "FAIL: a changed STEPS was not refused ($rc): $out"; fail=1; }
cmp -s "$work/settings.env" "$work/recorded" || { echo "FAIL: the record changed"; fail=1; }
[ -z "$(ls "$work" | grep -v -x -e settings.env -e recorded)" ] || { echo "FAIL: the refused runs wrote files"; fail=1; }

# The data: residue-v1 (validation), a residue-v1-pseudo of 2 training scenes and the starter set's 3 scene folders.
index() { printf '{"counts": {"%s": %d}, "scenes": []}\n' "$2" "$3" > "$tree/.cache/datasets/$1/index.json"; }
mkdir -p "$tree/.cache/datasets/residue-v1" "$tree/.cache/datasets/residue-v1-pseudo" \
  "$top/shared/datasets/cycles-starter/"{s1,s2,s3}
index residue-v1 validation 30
index residue-v1-pseudo train 2
data_work=$tree/data_work
out=$(EXTRA_SETS= "$repo/tools/models/finetune_full.sh" "$data_work" 2>&1)  # fails later: no model to start from
expected="$tree/.cache/datasets/residue-v1 validation=30
$tree/.cache/datasets/residue-v1-pseudo train=2
$top/shared/datasets/cycles-starter scenes=3"
[ "$(cat "$data_work/data.txt" 2>/dev/null)" = "$expected" ] ||
  { echo "FAIL: data.txt is not the folders and their counts: $(cat "$data_work/data.txt" 2>&1); $out"; fail=1; }
index residue-v1-pseudo train 3  # the set rendered further between two starts
out=$("$repo/tools/models/finetune_full.sh" "$data_work" 2>&1); rc=$?
[ "$rc" = 2 ] && grep -q "training data changed" <<< "$out" && grep -q "residue-v1-pseudo train=2" <<< "$out" &&
  grep -q "residue-v1-pseudo train=3" <<< "$out" ||
  { echo "FAIL: a resumed run on changed data was not refused with both counts ($rc): $out"; fail=1; }
[ ! -e "$data_work/run.out" ] || { echo "FAIL: the refused run started the trainer"; fail=1; }
[ "$fail" = 0 ] && echo ok
exit "$fail"
