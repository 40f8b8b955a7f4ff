#!/usr/bin/python3
"""A grid PNG of the renders of a data set folder (one tile per s<seed>/ folder), for looking at a data set.

  /usr/bin/python3 tools/datagen/contact_sheet.py /work/datasets/residue-v1 --out sheet.png
  /usr/bin/python3 tools/datagen/contact_sheet.py DIR --image noisy_a --tile 192 --cols 8 --curve reinhard

Each tile is ViewLayer.Combined tonemapped (default: the Hable/Uncharted-2 filmic curve then sRGB, as residue-cli
eval's SSIM; --curve reinhard: x/(1+x) then sRGB), with its seed and, from scene.json, the noisy spp and
relMSE of noisy_a printed in its corner (--no-labels to leave them off). numpy + OpenImageIO only.
"""
import argparse
import json
import math
import os
import re
import sys

import numpy as np
import OpenImageIO as oiio

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import exr_metrics  # noqa: E402

# A 3x5 pixel font: enough for labels such as "s1004 8spp 0.123".
FONT = {
    "0": "111101101101111", "1": "010110010010111", "2": "111001111100111", "3": "111001111001111",
    "4": "101101111001001", "5": "111100111001111", "6": "111100111101111", "7": "111001010010010",
    "8": "111101111101111", "9": "111101111001111", ".": "000000000000010", "s": "000111100001111",
    "p": "000111101111100", " ": "000000000000000", "-": "000000111000000", "e": "000111111100111",
    "i": "010000010010010", "n": "000110101101101", "t": "010111010010011", "x": "000101010010101",
}


def label(img, text, scale, x0=2, y0=2):
    """Draws text (white on a dark box) into img (HxWx3 float in [0, 1]) at the top-left corner."""
    w = len(text) * 4 * scale + scale
    h = 7 * scale
    img[y0:y0 + h, x0:x0 + w] *= 0.25
    for k, ch in enumerate(text):
        bits = FONT.get(ch, FONT[" "])
        for i in range(5):
            for j in range(3):
                if bits[i * 3 + j] == "1":
                    y = y0 + scale + i * scale
                    x = x0 + scale + (k * 4 + j) * scale
                    img[y:y + scale, x:x + scale] = 1.0


def tonemapped(path, curve, exposure):
    rgb = exr_metrics.layer_rgb(exr_metrics.read_exr(path))
    if curve == "reinhard":
        x = np.nan_to_num(np.maximum(rgb * exposure, 0.0), nan=0.0, posinf=1e4)
        y = x / (1.0 + x)
        return np.where(y <= 0.0031308, 12.92 * y, 1.055 * np.power(y, 1.0 / 2.4) - 0.055)
    return exr_metrics.tonemap(rgb, exposure)


def resize(img, size):
    buf = oiio.ImageBuf(np.ascontiguousarray(img.astype(np.float32)))
    out = oiio.ImageBufAlgo.resize(buf, roi=oiio.ROI(0, size, 0, size, 0, 1, 0, 3))
    return np.asarray(out.get_pixels(oiio.FLOAT)).reshape(size, size, 3)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("folder")
    p.add_argument("--out", default=None, help="PNG path (default FOLDER/contact_sheet.png)")
    p.add_argument("--image", default="reference", help="which file of each scene (reference, noisy_a, ...)")
    p.add_argument("--tile", type=int, default=256)
    p.add_argument("--cols", type=int, default=0, help="columns (default: about square)")
    p.add_argument("--curve", choices=["hable", "reinhard"], default="hable")
    p.add_argument("--exposure", type=float, default=1.0)
    p.add_argument("--no-labels", action="store_true")
    p.add_argument("--seeds", default=None, help="only these seeds, A-B or A,B,C")
    a = p.parse_args()

    scenes = []
    for name in os.listdir(a.folder):
        m = re.fullmatch(r"s(\d+)", name)
        if m and os.path.isfile(os.path.join(a.folder, name, a.image + ".exr")):
            scenes.append((int(m.group(1)), os.path.join(a.folder, name)))
    scenes.sort()
    if a.seeds:
        keep = set()
        for part in a.seeds.split(","):
            lo, _, hi = part.partition("-")
            keep.update(range(int(lo), int(hi or lo) + 1))
        scenes = [s for s in scenes if s[0] in keep]
    if not scenes:
        sys.exit(f"contact_sheet: no s<seed>/{a.image}.exr under {a.folder}")
    cols = a.cols or math.ceil(math.sqrt(len(scenes)))
    rows = math.ceil(len(scenes) / cols)
    gap = 2
    sheet = np.full((rows * (a.tile + gap) + gap, cols * (a.tile + gap) + gap, 3), 0.15, np.float32)
    scale = max(1, a.tile // 96)
    for i, (seed, folder) in enumerate(scenes):
        tile = resize(tonemapped(os.path.join(folder, a.image + ".exr"), a.curve, a.exposure), a.tile)
        if not a.no_labels:
            text = f"s{seed}"
            try:
                with open(os.path.join(folder, "scene.json")) as f:
                    doc = json.load(f)
                text += f" {doc['spp']['noisy_a']}spp {doc['metrics']['relmse_noisy_a']:.3f}"
            except (OSError, KeyError, ValueError):
                pass
            label(tile, text, scale)
        r, c = divmod(i, cols)
        y, x = gap + r * (a.tile + gap), gap + c * (a.tile + gap)
        sheet[y:y + a.tile, x:x + a.tile] = tile
    out = a.out or os.path.join(a.folder, "contact_sheet.png")
    buf = oiio.ImageBuf(np.ascontiguousarray((np.clip(sheet, 0, 1) * 255 + 0.5).astype(np.uint8)))
    if not buf.write(out):
        sys.exit(f"contact_sheet: cannot write {out}: {buf.geterror()}")
    print(f"contact_sheet: {len(scenes)} scenes -> {out} ({sheet.shape[1]}x{sheet.shape[0]})")


if __name__ == "__main__":
    main()
