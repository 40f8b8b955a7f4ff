# Sourced by tools/models/finetune_full.sh and tools/research/study_demod.sh: the data folders issue 16's runs train on, in one
# place, so that a study trains on exactly the scenes the fine-tune does.
# training_data SET...: fills the array `data` with residue-v1 (its 30 validation scenes: the trainer's monitor),
# each SET (a folder of .cache/datasets: residue-v1-pseudo or a fixed subset of it, residue-pseudo, residue-photo,
# residue-photo-plain; skipped with a warning when it has no index.json), then the shared starter set.
# Render them with tools/models/render_training_data.sh.
training_data_default_sets="residue-pseudo residue-photo residue-photo-plain"  # after residue-v1-pseudo
training_data() {
  local repo d
  repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
  data=()
  for d in residue-v1 "$@"; do
    d=$(cd "$repo/.cache/datasets" && realpath -m "$d")
    [ -f "$d/index.json" ] && data+=("$d") || echo "$(basename "$0"): $d is missing; training without it" >&2
  done
  data+=("$(realpath "$repo/../shared/datasets/cycles-starter")")
}

# training_data_summary: one line per folder of `data`: the folder and its scene counts (index.json's "counts", or
# the number of scene folders where it has none), so that a run resumed after a restart can tell whether the
# data it trains on is still what it started with.
training_data_summary() {
  /usr/bin/python3 - "${data[@]}" <<'PY'
import json, pathlib, sys
for d in map(pathlib.Path, sys.argv[1:]):
    index = d / "index.json"
    counts = json.loads(index.read_text())["counts"] if index.exists() else \
        {"scenes": sum(1 for s in d.iterdir() if s.is_dir() and s.name.startswith("s"))}
    print(d, " ".join(f"{k}={v}" for k, v in sorted(counts.items())))
PY
}
