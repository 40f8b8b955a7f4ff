#!/usr/bin/env bash
# Screenshots of the real viewer window under Xvfb, for docs/ and the README:
#   tools/dev/screenshots.sh [BUILD_DIR] [OUT_DIR]
# Views, at 1280x720 (the smallest screen the viewer is made for): Tungsten's Cornell box with NFOR's result added
# beside `base` and OIDN; three results and the reference with a row of
# scores per result; a zoomed wipe between two models; the heatmap pane with its shared range and colour bar;
# the heatmap overlaid; a denoise in progress (tiles appearing) on the example repeated 8 x 8; and the comparison
# sheet an export-all writes. RESIDUE_SCREEN=1920x1080 takes them at that size instead.
# Needs xvfb-run (Debian xvfb) and Python's OpenImageIO (python3-openimageio); the scene comes from
# ../shared/datasets (the bundled example without it).
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$repo/build/release}
out=${2:-$repo/docs/images}
viewer=$build/app/residue/residue
scene=${RESIDUE_SCREENSHOT_SCENE:-$repo/../shared/datasets/cycles-starter/s160}
example=$repo/resources/examples/room
[ -x "$viewer" ] || { echo "screenshots: no viewer at $viewer (build first)" >&2; exit 1; }
command -v xvfb-run >/dev/null || { echo "screenshots: xvfb-run missing (apt-get install xvfb)" >&2; exit 1; }
[ -f "$scene/noisy_a.exr" ] || scene=$example  # without the shared data set, the bundled example
noisy=$scene/noisy_a.exr; [ -f "$noisy" ] || noisy=$scene/noisy.exr
mkdir -p "$out"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
export OMP_WAIT_POLICY=passive

screen=${RESIDUE_SCREEN:-1280x720}
suffix=""; [ "$screen" = 1280x720 ] || suffix="_$screen"  # the other size beside, not over, the 1280x720 shots
only=${RESIDUE_SHOTS:-}  # e.g. "viewer_renders viewer_channel": only these
shot() {  # shot NAME ARGS...: one window filling the screen, one PNG
  local name=$1; shift
  if [ -n "$only" ] && [[ " $only " != *" $name "* ]]; then return 0; fi
  RESIDUE_SETTINGS_ISOLATED=1 xvfb-run -a -s "-screen 0 ${screen}x24" "$viewer" --no-ipc --size "$screen" \
    --screenshot "$out/$name$suffix.png" "$@"
}
ref=(--reference "$scene/reference.exr")

shot viewer_results "$noisy" "${ref[@]}" --model tiny,base,oidn --denoise --screenshot-when denoised --tab results
# A region: each result's name beside its region's scores.
shot viewer_region "$noisy" "${ref[@]}" --model tiny,oidn --denoise --screenshot-when denoised --roi 60,70,90,60 \
  --tab results
# The image list: four renders open, the first shown with its result and region.
starter=$repo/../shared/datasets/cycles-starter
others=(); for s in s158 s101; do [ -f "$starter/$s/noisy_a.exr" ] && others+=(--open "$starter/$s/noisy_a.exr"); done
shot viewer_renders "$noisy" "${ref[@]}" "${others[@]}" --open "$example/noisy.exr" --model tiny --denoise \
  --screenshot-when denoised --roi 60,70,90,60 --tab renders
# One channel alone (luminance, as grey through the view), in the dark theme.
shot viewer_channel "$noisy" "${ref[@]}" --model tiny --denoise --screenshot-when denoised --channel luminance \
  --theme dark --tab results
# The signed difference of A against B (D): blue where A is darker, red where it is brighter.
shot viewer_difference "$noisy" "${ref[@]}" --model tiny,oidn --denoise --ab 1,2 --screenshot-when denoised \
  --heatmap-of a-vs-b --heatmap-kind diff --layout single --pane heatmap --tab heatmap
shot viewer_wipe "$noisy" "${ref[@]}" --model small,oidn --denoise --ab 1,2 --screenshot-when denoised \
  --layout wipe --zoom 2.5 --tab results
shot viewer_heatmap "$noisy" "${ref[@]}" --model small,oidn --denoise --ab 1,2 --screenshot-when denoised \
  --tab heatmap --export-all "$tmp/export"
if [ -f "$tmp/export/comparison.png" ]; then cp "$tmp/export/comparison.png" "$out/viewer_comparison_sheet$suffix.png"; fi
# Another renderer's render with NFOR's result added beside ours and OIDN's (Tungsten's Cornell box).
cornell=$repo/../shared/datasets/tungsten-example/cornell-box
if [ -f "$cornell/nfor.exr" ]; then
  shot viewer_compare_nfor "$cornell" --add "$cornell/nfor.exr" --model base,oidn --denoise --screenshot-when denoised \
    --tab results
  # HDR-FLIP beside relMSE and SSIM, and its map of OIDN's result (magma, as NVIDIA's tool draws it).
  shot viewer_flip "$cornell" --add "$cornell/nfor.exr" --model multiscale,oidn --denoise --screenshot-when denoised \
    --layout all --heatmap pane --heatmap-kind flip --tab results
fi

# A sequence (the committed 6-frame Cycles shot): every frame denoised by the temporal model, the temporal map.
shot viewer_sequence "$repo/tests/data/shot/noisy.0003.exr" --model multiscale-temporal --denoise --every-frame \
  --heatmap-kind temporal --screenshot-when denoised --tab results

# A denoise in progress needs a render that takes a while: the example repeated 8 x 8 (1536 x 1536; repeated,
# not upscaled, so that the noise stays per-pixel), every channel and its name kept.
tile_8x8() {
  /usr/bin/python3 - "$1" "$2" <<'PY'
import sys, numpy as np, OpenImageIO as oiio
src = oiio.ImageInput.open(sys.argv[1]); spec = src.spec()
pixels = np.tile(src.read_image(oiio.FLOAT), (8, 8, 1)); src.close()
out_spec = oiio.ImageSpec(spec.width * 8, spec.height * 8, spec.nchannels, oiio.HALF)
out_spec.channelnames = spec.channelnames
for a in spec.extra_attribs:
    if a.name in ("Note", "worldToCamera"): out_spec.attribute(a.name, a.type, a.value)
out = oiio.ImageOutput.create(sys.argv[2]); out.open(sys.argv[2], out_spec); out.write_image(pixels); out.close()
PY
}
if [ -z "$only" ] || [[ " $only " == *" viewer_denoising "* ]]; then
  tile_8x8 "$example/noisy.exr" "$tmp/room8x8.exr"
  tile_8x8 "$example/reference.exr" "$tmp/room8x8_ref.exr"
fi
shot viewer_denoising "$tmp/room8x8.exr" --reference "$tmp/room8x8_ref.exr" --model small --tile 256 --denoise \
  --screenshot-when progress:0.45 --layout single --pane denoised
ls -l "$out"/viewer_*.png
