#!/bin/bash
# tools/finetune_full.sh keeps a run's settings across sessions: resuming with a setting that differs from the one
# recorded in WORKDIR/settings.env is refused before anything runs, and the record is left as it was. The script
# runs from a copy in an empty tree, so that a broken refusal fails for want of data instead of training for hours.
#   test_finetune_settings.sh REPO
set -uo pipefail
tree=$(mktemp -d)
trap 'rm -rf "$tree"' EXIT
mkdir -p "$tree/tools" "$tree/work"
cp "$1/tools/finetune_full.sh" "$1/tools/training_data.sh" "$tree/tools/"
repo=$tree work=$tree/work
printf '%s\n' STEPS=24000 LOWBAND_WEIGHT=0 GROW=1 > "$work/settings.env"
cp "$work/settings.env" "$work/recorded"
fail=0
out=$(LOWBAND_WEIGHT=8 "$repo/tools/finetune_full.sh" "$work" 2>&1); rc=$?
[ "$rc" = 2 ] || { echo "FAIL: a changed setting gave exit status $rc, not 2: $out"; fail=1; }
grep -q "started with LOWBAND_WEIGHT=0; not resuming it with LOWBAND_WEIGHT=8" <<< "$out" ||
  { echo "FAIL: the refusal does not name the setting: $out"; fail=1; }
out=$(STEPS=5000 "$repo/tools/finetune_full.sh" "$work" 2>&1); rc=$?
[ "$rc" = 2 ] && grep -q "STEPS=24000" <<< "$out" || { echo "FAIL: a changed STEPS was not refused ($rc): $out"; fail=1; }
cmp -s "$work/settings.env" "$work/recorded" || { echo "FAIL: the record changed"; fail=1; }
[ -z "$(ls "$work" | grep -v -x -e settings.env -e recorded)" ] || { echo "FAIL: the refused runs wrote files"; fail=1; }
[ "$fail" = 0 ] && echo ok
exit "$fail"
