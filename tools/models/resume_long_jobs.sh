#!/usr/bin/env bash
# Issue 16's queue of long jobs, run one after another in the background and resumed where they stopped. Every step
# is resumable and passes quickly once done, so running this after a restart (on the same machine: the
# data and checkpoints live in .cache) picks up where the last run was cut off. One job at a time: training
# beside the renderer runs 5-6x slower (docs/research/MODELS_HISTORY.md, "Training speed"). The queue (GOAL_JOURNAL.md, 2026-11-28):
#   1. residue-v1's 30 validation scenes (tools/research/goal_check.py and every model card score on them)
#   2. a test set: 10 of those validation scenes with fireflies kept (no indirect clamp, caustics), as an unclamped
#      path tracer leaves them (.cache/datasets/residue-v1-fireflies, about 30 min; 2026-11-29; scored by
#      tools/research/compare_conditions.py against the same scenes as rendered for training, docs/research/MODELS_HISTORY.md lever 3e)
#   3. the next lever's data: residue-v1-pseudo's 150 interiors with rendered 512-spp references, then its 39
#      open-air scenes (.cache/datasets/residue-v1-true; on the idle Intel Xeon of 2026-11-28 to 2026-11-29 about 2.5 minutes
#      an interior, about 7 hours in all; beside a training run 5-10x that)
#   4. residue-v1-pseudo (its 39 open-air scenes have rendered references too; its interiors pseudo-references)
#   5. the other training sets tools/models/finetune_full.sh trains on (residue-photo, residue-pseudo, residue-photo-plain;
#      about 1.7 h; the photographs need `apt-get install plasma-workspace-wallpapers`, which tools/setup.sh leaves
#      out), so that the fine-tune on residue-v1-true (issue 16's next lever for x1) has all its data
#   6. issue 51's shots for a temporal denoiser: /work/datasets/residue-shots-v1, 48 shots of 16 frames (seeds
#      8000-8047, validation 8007/8018/8029/8040 first; tools/datagen/README.md, "Shots and motion vectors"); started
#      on its own on 2026-12-01, so this step resumes it, or waits for that run (--wait) and passes
# Done and so out of the queue: lever 2c's long run (2026-11-28: a tie with the shipped network, not adopted;
# `GROW=1 ARCH=2,2,2,2,1/24,40,56,80,112 PATCH=256 BATCH=1 STEPS=14000 PRECISION=bf16 EXTRA_SETS=
# tools/models/finetune_full.sh .cache/train/lever2c-14k`). A fine-tune added back here goes through
# tools/models/finetune_full.sh, which records its settings in its folder and scores itself with tools/research/goal_check.py.
#   tools/models/resume_long_jobs.sh      starts the queue in the background; log .cache/long_jobs.log
# A second queue is refused while one runs (or while a job it started still does). Issue 5's zoo is reproduced by
# tools/models/train_zoo.sh directly (MODELS.md, "Reproduce").
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
cd "$repo"
mkdir -p .cache
for tool in build/release/app/residue-cli/residue-cli build/release/app/residue-train/residue-train; do
  [ -x "$tool" ] || { echo "resume_long_jobs: $repo/$tool is not built (tools/setup.sh builds it)" >&2; exit 1; }
done
if [ "${1:-}" != --foreground ]; then
  setsid nohup "$repo/tools/models/resume_long_jobs.sh" --foreground >> .cache/long_jobs.log 2>&1 < /dev/null &
  echo "resume_long_jobs: the queue runs in the background (log $repo/.cache/long_jobs.log)"
  exit 0
fi
exec 9> .cache/long_jobs.lock  # held by every job the queue starts, so a stray job also keeps a second one out
flock -n 9 || { echo "resume_long_jobs: a queue is already running"; exit 1; }
step() { echo "== $(date -u +%FT%TZ) $*"; }

step "data: the validation scenes"
tools/models/render_training_data.sh validation
step "a test set: validation scenes with fireflies kept"
tools/models/render_training_data.sh residue-v1-fireflies
step "the next lever's data: interiors with rendered references"
tools/models/render_training_data.sh residue-v1-true
step "data: residue-v1-pseudo"
tools/models/render_training_data.sh residue-v1-pseudo
step "data: the other training sets"
tools/models/render_training_data.sh residue-photo residue-pseudo residue-photo-plain
step "data: shots for a temporal denoiser (issue 51)"
mkdir -p /work/datasets
/usr/bin/python3 tools/datagen/render_shots.py --out /work/datasets/residue-shots-v1 --seeds 8000-8047 --threads 1 --wait
step "data: second references of the validation shots (the references' floor, issue 51)"
/usr/bin/python3 tools/datagen/second_references.py /work/datasets/residue-shots-v1 --threads 1
step "done"
