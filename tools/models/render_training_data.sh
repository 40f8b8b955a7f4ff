#!/bin/bash
# Renders the data folders of issue 16's runs (tools/models/training_data.sh) as they stood at 2026-11-28, each with the
# command that made it, so that a fresh machine trains on the same 315 scenes (189 residue-v1-pseudo + 36
# residue-pseudo + 16 residue-photo + 16 residue-photo-plain + the starter set's 58) and validates on the same 42
# (residue-v1's 30, residue-photo's 6, the starter set's last 6). residue-v1 holds only its 30 validation seeds
# since 2026-11-27: its 300 training seeds were trained on only as residue-v1-pseudo's copies, 189 of them.
#   tools/models/render_training_data.sh [SET...]   SET: validation, residue-v1-pseudo, residue-photo, residue-pseudo,
#                                            residue-photo-plain or all (the default: all five, in that order),
#                                            or residue-v1-true (not in all: the 2026-11-28 next lever, below),
#                                            or residue-v1-fireflies (not in all: a test set, 2026-11-29)
# The order is the order of use: residue-v1's 30 validation scenes (1024-spp references; tools/research/goal_check.py scores
# on them), then the bulk of the training scenes (more residue-v1 scenes is the one data lever that measured gains,
# docs/research/MODELS_HISTORY.md lever 5), then the photographed set (its 6 validation scenes are study_photo.sh's and study_demod.sh's
# textured test set), the noisy interiors, the plain control set. Each step is resumable: render_dataset.py skips
# scenes whose scene.json exists, so run the same command again after an interruption. Times on 2 idle cores
# (MODELS.md, tools/datagen/README.md; about double beside other work): validation 40-100 min;
# residue-v1-pseudo 1.5-3.5 h (its interiors 30-75 s each); residue-photo and residue-photo-plain about 0.7 and
# 0.3 h (not recorded: estimated from the per-scene times); residue-pseudo 0.7 h (70 s a scene). About 4-7 h in all.
# Needs Blender, residue-cli built (the pseudo-references) and plasma-workspace-wallpapers (the photographs).
# Not exact from the repository:
# - residue-v1-pseudo's 189 seeds are not listed anywhere; they follow from the recorded counts: the render ran in
#   seed order (its first 61: 30 interiors + 31 open-air), then interiors first from 2026-11-27 (47 + 39 at the
#   86-scene snapshot), all 150 interiors by 2026-11-27, nothing after. Its pseudo-references came from multiscale
#   as shipped in b18b439 (its weights are HEAD's, but it ran at exposure key 1 where HEAD's runs at 1.4, so that
#   file is taken from git as the teacher), without their low band; 2026-11-27 restored the snapshot's 47 (the first 47
#   interiors, --restore-low-band in seed order), i.e. the default --pseudo-ref-low-band 16 here, the other 103 not.
# - residue-pseudo (2026-11-27) was rendered between 878c1ff and 9a82ee7, when the shipped multiscale was
#   d7253a6's (the 2026-11-26), before the low band existed: that file is taken from git as its teacher.
# - The teachers are files from git, but the denoise around them is today's residue-cli.
# - Re-renders are close, not bit-exact (docs/research/models/GOAL_JOURNAL.md, 2026-11-27); pseudo-references also depend
#   on residue-cli.
# Not rendered: the other 111 open-air seeds of residue-v1 (odd 1087-1329; `seeds 1087 1329 2` into
# residue-v1-pseudo, not done by 2026-11-28) and the residue-v1-pseudo-86 snapshot of 2026-11-27.
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
cd "$repo"
R=(/usr/bin/python3 tools/datagen/render_dataset.py)
D=.cache/datasets
H=(--hdris /usr/share/blender/datafiles/studiolights/world)
P=(--photos /usr/share/wallpapers)
train_photo=2000,2002-2011,2013-2017   # tools/research/study_photo.sh: 16 training seeds (2001, 2012 are validation)

# seeds FROM TO STEP: FROM, FROM+STEP, ... TO without the validation seeds (seed % 11 == 10), comma-separated.
seeds() {
  local s out=()
  for ((s = $1; s <= $2; s += $3)); do ((s % 11 == 10)) || out+=("$s"); done
  (IFS=,; echo "${out[*]}")
}
photos() {
  [ -d /usr/share/wallpapers ] ||
    { echo "render_training_data.sh: no /usr/share/wallpapers (apt-get install plasma-workspace-wallpapers)" >&2
      exit 2; }
}

# teacher COMMIT: the shipped multiscale as it was at COMMIT (a pseudo-reference set's teacher), cached in .cache/models.
teacher() {
  local file=.cache/models/multiscale-$1.safetensors
  mkdir -p .cache/models
  [ -f "$file" ] ||
    { git show "$1:resources/models/multiscale.safetensors" > "$file.tmp" && mv "$file.tmp" "$file"; }
  echo "$file"
}

render() {
  case "$1" in
    validation)  # 1000, 1011, ..., 1319; default spp 4,8,16,32 and 1024-spp references
      "${R[@]}" --out $D/residue-v1 --seeds "$(seq -s, 1000 11 1329)" ;;
    residue-v1-pseudo)  # 150 interiors (pseudo-references: 128 spp, multiscale x8), 39 open-air (512-spp references)
      local teacher
      teacher=$(teacher b18b439)
      "${R[@]}" --out $D/residue-v1-pseudo --seeds "$(seeds 1002 1102 2)" --pseudo-ref "$teacher"
      "${R[@]}" --out $D/residue-v1-pseudo --seeds "$(seeds 1104 1328 2)" --pseudo-ref "$teacher" \
        --pseudo-ref-low-band 0
      "${R[@]}" --out $D/residue-v1-pseudo --seeds "$(seeds 1001 1085 2)" ;;
    residue-v1-true)  # residue-v1-pseudo's 150 interiors with rendered 512-spp references, not pseudo-references:
      # every fine-tune on the pseudo-referenced ones ended behind its start (GOAL_JOURNAL.md, 2026-11-28); then its
      # 39 open-air scenes (rendered references there too), so that this one folder is residue-v1-pseudo's 189 scenes
      # with true references: V1_PSEUDO=residue-v1-true tools/models/finetune_full.sh. About 1.5-4.5 min an interior (2.5
      # on average) and 1.5 an open-air scene on 2 idle cores (the reference; Intel Xeon, 2026-11-29), about 7 h in all.
      "${R[@]}" --out $D/residue-v1-true --seeds "$(seeds 1002 1328 2)"
      "${R[@]}" --out $D/residue-v1-true --seeds "$(seeds 1001 1085 2)" ;;
    residue-v1-fireflies)  # 10 of the 30 validation scenes (5 interiors, 5 open air; the quicker ones) as an
      # unclamped path tracer leaves them: no indirect clamp, caustics and sharp glossy reflections kept, in noisy and
      # reference alike (the 2026-11-29 probe of renders from other renderers; docs/research/MODELS_HISTORY.md lever 3e). About 30 min.
      "${R[@]}" --out $D/residue-v1-fireflies --seeds 1000,1066,1132,1176,1242,1055,1077,1121,1165,1297 \
        --clamp-indirect 0 --caustics ;;
    residue-photo)  # 6 validation scenes (1024 spp), 16 training scenes with 256-spp references
      photos
      "${R[@]}" --out $D/residue-photo --seeds 2001,2012,2023,2034,2045,2056 "${P[@]}" "${H[@]}"
      "${R[@]}" --out $D/residue-photo --seeds $train_photo "${P[@]}" "${H[@]}" --ref-spp 256 ;;
    residue-pseudo)  # 36 interiors, 2-16 spp, pseudo-references by 2026-11-26's multiscale
      photos
      local teacher
      teacher=$(teacher d7253a6)
      "${R[@]}" --out $D/residue-pseudo --seeds "$(seeds 3000 3078 2)" --spp 2,4,8,16 "${P[@]}" "${H[@]}" \
        --pseudo-ref $teacher --pseudo-ref-low-band 0 ;;
    residue-photo-plain)  # residue-photo's 16 training seeds without photographs (HDRIs kept)
      "${R[@]}" --out $D/residue-photo-plain --seeds $train_photo "${H[@]}" --ref-spp 256 ;;
    *) echo "render_training_data.sh: unknown set $1 (validation, residue-v1-pseudo, residue-photo, residue-pseudo," \
         "residue-photo-plain, all, residue-v1-true, residue-v1-fireflies)" >&2; exit 2 ;;
  esac
}

[ $# -eq 0 ] || [ "$*" = all ] && set -- validation residue-v1-pseudo residue-photo residue-pseudo residue-photo-plain
for s in "$@"; do
  echo "== $s"
  render "$s"
done
