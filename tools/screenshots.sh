#!/usr/bin/env bash
# Screenshots of the real viewer window under Xvfb, for docs/ and the README:
#   tools/screenshots.sh [BUILD_DIR] [OUT_DIR]
# Views: side by side after a denoise, a zoomed wipe noisy|denoised, the heatmap pane with its colour bar,
# the heatmap overlaid, and a denoise in progress (tiles appearing) on the example repeated 8 x 8.
# Needs xvfb-run (Debian xvfb) and Python's OpenImageIO (python3-openimageio); the scene comes from
# ../shared/datasets (the bundled example without it).
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
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

shot() {  # shot NAME ARGS...: one window, one PNG
  local name=$1; shift
  xvfb-run -a -s "-screen 0 1700x1000x24" "$viewer" --size 1600x900 --screenshot "$out/$name.png" "$@"
}

shot viewer_side_by_side "$noisy" --reference "$scene/reference.exr" --model small --denoise \
  --screenshot-when denoised
shot viewer_wipe "$noisy" --reference "$scene/reference.exr" --model small --denoise --screenshot-when denoised \
  --layout wipe --zoom 3
shot viewer_heatmap "$noisy" --reference "$scene/reference.exr" --model small --denoise --screenshot-when denoised \
  --layout single --pane heatmap
shot viewer_overlay "$noisy" --reference "$scene/reference.exr" --model small --denoise --screenshot-when denoised \
  --heatmap overlay --layout single --pane denoised

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
tile_8x8 "$example/noisy.exr" "$tmp/room8x8.exr"
tile_8x8 "$example/reference.exr" "$tmp/room8x8_ref.exr"
shot viewer_denoising "$tmp/room8x8.exr" --reference "$tmp/room8x8_ref.exr" --model small --tile 256 --denoise \
  --screenshot-when progress:0.45 --layout single --pane denoised
ls -l "$out"/viewer_*.png
