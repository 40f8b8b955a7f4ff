#!/usr/bin/python3
"""A strip of consecutive frames of a shot (issue 51's docs): rows noisy, each model's output, the reference, then
each model's temporal error map, |e_t - e_{t-1}| with e = output - reference (mean over RGB, relative like relMSE:
divided by sqrt((r_t^2 + r_{t-1}^2) / 2 + 0.01)), on one shared scale. Reads sequence_eval.py's outputs.

    /usr/bin/python3 tools/research/temporal_strip.py /work/datasets/residue-shots-v1/s8040 \\
        --outputs /tmp/residue-sequence-eval --models multiscale,multiscale-temporal --frames 6-9 \\
        --crop 100,100,128,128 --out docs/images/temporal_strip.png
"""
import argparse
import os

import numpy as np
import OpenImageIO as oiio


def read(path):
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        raise SystemExit(f"temporal_strip: {path}: {buf.geterror()}")
    return buf.get_pixels(oiio.FLOAT)[:, :, :3]


def display(x):  # Reinhard, then sRGB
    x = np.clip(np.nan_to_num(x), 0, None)
    y = x / (1 + x)
    return np.where(y <= 0.0031308, 12.92 * y, 1.055 * np.power(y, 1 / 2.4) - 0.055)


def heat(v, top):  # black -> red -> yellow -> white
    t = np.clip(v / top, 0, 1)[..., None]
    return np.concatenate([np.clip(3 * t, 0, 1), np.clip(3 * t - 1, 0, 1), np.clip(3 * t - 2, 0, 1)], axis=-1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shot")
    ap.add_argument("--outputs", required=True, help="sequence_eval.py's --work folder")
    ap.add_argument("--models", required=True)
    ap.add_argument("--frames", default="6-9")
    ap.add_argument("--scale", type=int, default=2, help="pixel repeat")
    ap.add_argument("--crop", default="", help="x,y,w,h of the frames (default: whole)")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    lo, hi = (int(v) for v in a.frames.split("-"))
    frames = list(range(lo, hi + 1))
    shot = os.path.basename(os.path.normpath(a.shot))
    models = a.models.split(",")
    ref = {f: read(os.path.join(a.shot, f"reference.{f:04d}.exr")) for f in [lo - 1] + frames}
    noisy = {f: read(os.path.join(a.shot, f"noisy.{f:04d}.exr")) for f in frames}
    outs = {m: {f: read(os.path.join(a.outputs, m, shot, f"den.{f:04d}.exr")) for f in [lo - 1] + frames} for m in models}
    if a.crop:
        x, y, w, h = (int(v) for v in a.crop.split(","))
        cut = lambda d: {f: im[y:y + h, x:x + w] for f, im in d.items()}  # noqa: E731
        ref, noisy, outs = cut(ref), cut(noisy), {m: cut(o) for m, o in outs.items()}
    rows = [[display(noisy[f]) for f in frames]]
    rows += [[display(outs[m][f]) for f in frames] for m in models]
    rows.append([display(ref[f]) for f in frames])
    maps = {}
    for m in models:
        maps[m] = []
        for f in frames:
            e, e_prev = outs[m][f] - ref[f], outs[m][f - 1] - ref[f - 1]
            norm = np.sqrt((ref[f] ** 2 + ref[f - 1] ** 2) / 2 + 0.01)
            maps[m].append(np.mean(np.abs(e - e_prev) / norm, axis=-1))
    top = max(np.percentile(np.concatenate([x.ravel() for x in maps[m]]), 99) for m in models)
    rows += [[heat(x, top) for x in maps[m]] for m in models]
    gap = 4
    tiles = [np.concatenate(sum([[t, np.ones((t.shape[0], gap, 3))] for t in r], [])[:-1], axis=1) for r in rows]
    strip = np.concatenate(sum([[t, np.ones((gap, t.shape[1], 3))] for t in tiles], [])[:-1], axis=0)
    strip = np.repeat(np.repeat(strip, a.scale, axis=0), a.scale, axis=1).astype(np.float32)
    spec = oiio.ImageSpec(strip.shape[1], strip.shape[0], 3, oiio.UINT8)
    out = oiio.ImageOutput.create(a.out)
    if not out or not out.open(a.out, spec):
        raise SystemExit(f"temporal_strip: cannot write {a.out}: {oiio.geterror()}")
    out.write_image(np.clip(strip, 0, 1))
    out.close()
    print(f"wrote {a.out}: frames {frames} of {shot}; rows: noisy, {', '.join(models)}, reference, then the temporal "
          f"error of {', '.join(models)} (scale: 0 to {top:.3f}, the 99th percentile)")


if __name__ == "__main__":
    main()
