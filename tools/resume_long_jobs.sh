#!/usr/bin/env bash
# Issue 16's queue of long jobs, run one after another in the background and resumed across sessions. Every step
# is resumable and passes quickly once done, so running this at the start of a session (on the same machine: the
# data and checkpoints live in .cache) picks up where the last session was cut off. One job at a time: training
# beside the renderer runs 5-6x slower (docs/MODELS.md, "Training speed"). The queue (GOAL_JOURNAL.md, sessions 18-19):
#   1. the data: residue-v1's 30 validation scenes and residue-v1-pseudo's 189 training scenes
#      (tools/render_training_data.sh)
#   2. lever 2c's long run: the shipped network grown by a fifth level, 14000 steps (about 2 hours,
#      so that it ends and is scored within one session), on those and the starter set (247 training scenes;
#      .cache/train/lever2c-14k; done in session 19: a tie, not adopted)
#   3. the next lever's data: residue-v1-pseudo's 150 interiors with rendered 512-spp references
#      (.cache/datasets/residue-v1-true, about 6 hours)
# Each fine-tune is tools/finetune_full.sh with the settings below, recorded in its folder: it scores itself with
# tools/goal_check.py when done.
#   tools/resume_long_jobs.sh      starts the queue in the background; log .cache/long_jobs.log
# A second queue is refused while one runs (or while a job it started still does). Issue 5's zoo is reproduced by
# tools/train_zoo.sh directly (MODELS.md, "Reproduce").
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
cd "$repo"
mkdir -p .cache
for tool in build/release/app/residue-cli/residue-cli build/release/app/residue-train/residue-train; do
  [ -x "$tool" ] || { echo "resume_long_jobs: $repo/$tool is not built (tools/setup.sh builds it)" >&2; exit 1; }
done
if [ "${1:-}" != --foreground ]; then
  setsid nohup "$repo/tools/resume_long_jobs.sh" --foreground >> .cache/long_jobs.log 2>&1 < /dev/null &
  echo "resume_long_jobs: the queue runs in the background (log $repo/.cache/long_jobs.log)"
  exit 0
fi
exec 9> .cache/long_jobs.lock  # held by every job the queue starts, so a stray job also keeps a second one out
flock -n 9 || { echo "resume_long_jobs: a queue is already running"; exit 1; }
step() { echo "== $(date -u +%FT%TZ) $*"; }

# bf16: 1.6x faster than fp32 on the Zen 5 CPU these runs started on (slower on the Intel one; a run keeps the
# precision it started with). No extra sets: the photographed, plain and noisy-interior sets are left out.
ft=(env PRECISION=bf16 EXTRA_SETS= tools/finetune_full.sh)
step "data"
tools/render_training_data.sh validation residue-v1-pseudo
step "lever 2c: the long run"
GROW=1 ARCH=2,2,2,2,1/24,40,56,80,112 PATCH=256 BATCH=1 STEPS=14000 "${ft[@]}" .cache/train/lever2c-14k
step "the next lever's data: interiors with rendered references"
tools/render_training_data.sh residue-v1-true
step "done"
