# Sourced by tools/finetune_full.sh and tools/study_demod.sh: the data folders issue 16's runs train on, in one
# place, so that a study trains on exactly the scenes the fine-tune does.
# training_data V1_PSEUDO: fills the array `data` with residue-v1, V1_PSEUDO (a folder of .cache/datasets, e.g.
# residue-v1-pseudo), residue-pseudo, residue-photo and residue-photo-plain (each skipped with a warning when it has
# no index.json), then the shared starter set.
# Render them with tools/render_training_data.sh.
training_data() {
  local repo d
  repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
  data=()
  for d in residue-v1 "$1" residue-pseudo residue-photo residue-photo-plain; do
    d=$(cd "$repo/.cache/datasets" && realpath -m "$d")
    [ -f "$d/index.json" ] && data+=("$d") || echo "$(basename "$0"): $d is missing; training without it" >&2
  done
  data+=("$(realpath "$repo/../shared/datasets/cycles-starter")")
}
