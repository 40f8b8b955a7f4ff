#!/usr/bin/env bash
# Starts (or resumes) the two long background jobs of issue 5 side by side, at the same lowered priority so
# they share the cores: rendering the data set, and training the zoo on it. Both pick up where they stopped
# (the renderer skips finished scenes; each model resumes from its checkpoint and is skipped when done).
#
#   tools/resume_long_jobs.sh [DATASET_DIR] [ZOO_DIR] [LOG_DIR]
#   defaults: /work/datasets/residue-v1 /work/train/zoo /work/logs
#
# The zoo is trained on the finished set only (the models must be trained on all of it): until every one of
# the 330 scenes has its reference, only the renderer runs, and the zoo starts when it has finished them; ZOO_NOW=1
# trains beside it anyway.
# Environment: ZOO_MODELS, passed to train_zoo.sh (its default: the whole zoo in order).
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
data=$(realpath -m "${1:-/work/datasets/residue-v1}")  # absolute: the running renderer is found by it
zoo=$(realpath -m "${2:-/work/train/zoo}")
logs=$(realpath -m "${3:-/work/logs}")
mkdir -p "$data" "$zoo" "$logs"
cd "$repo"
start_zoo() {
  ZOO_BF16=1 nohup nice -n 10 tools/train_zoo.sh "$zoo" "$data" "$repo/../shared/datasets/cycles-starter" \
    >>"$logs/zoo.out" 2>&1 &
}
renderer=$(pgrep -f -o "^/usr/bin/python3 tools/datagen/render_dataset.py --out $data" || true)
if [ -n "$renderer" ]; then
  echo "resume_long_jobs: the renderer is already running"
else
  nohup nice -n 10 /usr/bin/python3 tools/datagen/render_dataset.py --out "$data" --seeds 1000-1329 \
    >>"$logs/render.out" 2>&1 &
  renderer=$!
  echo "resume_long_jobs: renderer started (log $logs/render.out)"
fi
rendered=$(find "$data" -mindepth 2 -maxdepth 2 -name reference.exr | wc -l)
if pgrep -f "train_zoo.sh $zoo" >/dev/null; then
  echo "resume_long_jobs: the zoo training is already running"
elif [ "$rendered" -lt 330 ] && [ "${ZOO_NOW:-0}" != 1 ]; then
  # The zoo starts by itself once the renderer ends with all 330 scenes (in this shell's process group: it lives as
  # long as the session does, and a later call starts it again).
  (
    while kill -0 "$renderer" 2>/dev/null; do sleep 60; done
    [ "$(find "$data" -mindepth 2 -maxdepth 2 -name reference.exr | wc -l)" -ge 330 ] && start_zoo
  ) >/dev/null 2>&1 &
  echo "resume_long_jobs: $rendered of 330 scenes rendered; the zoo starts when the renderer finishes them (ZOO_NOW=1 to start it now)"
else
  start_zoo
  echo "resume_long_jobs: zoo training started (logs $zoo/<model>.out, $logs/zoo.out)"
fi
