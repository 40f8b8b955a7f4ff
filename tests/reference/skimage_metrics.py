#!/usr/bin/python3
"""Independent float64 reference for Residue's image metrics, built on scikit-image and NumPy.

Run it with Debian's /usr/bin/python3 (it has numpy, scikit-image and the OpenImageIO bindings).

  skimage_metrics.py [--channels R,G,B] [--eps 0.01] TEST.exr REF.exr [TEST.exr REF.exr ...]
      Prints a JSON list, one object per pair.
  skimage_metrics.py --synthetic WIDTH HEIGHT
      Prints one JSON object for the synthetic pair below (what tests/fixtures/metrics_expected.json holds).

Each object has: mse, relmse (linear), ssim and psnr (tonemapped), ssim_linear and psnr_linear, width, height.
SSIM is skimage.metrics.structural_similarity(gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
data_range=1.0, channel_axis=-1), on float64 arrays. Non-finite values are not handled (none of the inputs
used here has any). Non-finite scores are written as null.
"""

import argparse
import json
import math
import sys

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

# Hable / Uncharted-2 filmic curve, normalised at 11.2, then the sRGB OETF (core/metrics/tonemap.h).
A, B, C, D, E, F = 0.15, 0.50, 0.10, 0.20, 0.02, 0.30
WHITE = 11.2


def hable(x):
    return (x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F) - E / F


def tonemap(x):
    x = np.asarray(x, dtype=np.float64)
    x = np.where(np.isnan(x) | (x <= 0.0), 0.0, x)
    x = np.minimum(x, WHITE)  # f is increasing: everything above the white point maps to 1
    t = np.clip(hable(x) / hable(WHITE), 0.0, 1.0)
    t = np.where(x >= WHITE, 1.0, t)
    v = np.where(t < 0.0031308, 12.92 * t, 1.055 * np.power(t, 1.0 / 2.4) - 0.055)
    return np.clip(v, 0.0, 1.0)


def scores(test, ref, eps):
    test = np.asarray(test, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    ssim_args = dict(gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1.0,
                     channel_axis=-1)
    test_t, ref_t = tonemap(test), tonemap(ref)
    with np.errstate(divide="ignore"):
        out = {
            "width": int(test.shape[1]),
            "height": int(test.shape[0]),
            "eps": eps,
            "mse": float(np.mean((test - ref) ** 2)),
            "relmse": float(np.mean((test - ref) ** 2 / (ref ** 2 + eps))),
            "ssim": float(structural_similarity(test_t, ref_t, **ssim_args)),
            "psnr": float(peak_signal_noise_ratio(ref_t, test_t, data_range=1.0)),
            "ssim_linear": float(structural_similarity(test, ref, **ssim_args)),
            "psnr_linear": float(peak_signal_noise_ratio(ref, test, data_range=1.0)),
        }
    return {k: (v if not isinstance(v, float) or math.isfinite(v) else None) for k, v in out.items()}


def read_rgb(path, channels):
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(path)
    if buf.has_error:
        raise SystemExit(f"cannot read {path}: {buf.geterror()}")
    names = list(buf.spec().channelnames)
    missing = [c for c in channels if c not in names]
    if missing:
        raise SystemExit(f"{path} has no channel(s) {missing}; it has {names}")
    pixels = buf.get_pixels(oiio.FLOAT)  # (height, width, channels) float32
    return pixels[:, :, [names.index(c) for c in channels]].astype(np.float64)


# The synthetic pair, reproduced bit for bit by tests/test_metrics.cpp: an integer hash mod 2^32 gives values
# that are exact in float32. reference = k / 1024 in [0, 4), test = reference + j / 4096 with j in [-1024, 1024).
def hash32(x, y, c, seed):
    m = 0xFFFFFFFF
    v = ((x * 73856093) ^ (y * 19349663) ^ (c * 83492791) ^ (seed * 2654435761)) & m
    v ^= v >> 13
    v = (v * 0x5BD1E995) & m
    v ^= v >> 15
    return v


def synthetic(width, height):
    ref = np.zeros((height, width, 3))
    test = np.zeros((height, width, 3))
    for y in range(height):
        for x in range(width):
            for c in range(3):
                r = (hash32(x, y, c, 1) % 4096) / 1024.0
                ref[y, x, c] = r
                test[y, x, c] = r + ((hash32(x, y, c, 2) % 2048) - 1024) / 4096.0
    return test, ref


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--channels", default="ViewLayer.Combined.R,ViewLayer.Combined.G,ViewLayer.Combined.B")
    ap.add_argument("--eps", type=float, default=0.01)
    ap.add_argument("--synthetic", nargs=2, type=int, metavar=("WIDTH", "HEIGHT"))
    ap.add_argument("files", nargs="*", help="TEST REF pairs")
    args = ap.parse_args()
    if args.synthetic:
        test, ref = synthetic(*args.synthetic)
        result = scores(test, ref, args.eps)
        result["generator"] = "tests/reference/skimage_metrics.py --synthetic %d %d" % tuple(args.synthetic)
        json.dump(result, sys.stdout, indent=1)
        print()
        return
    if not args.files or len(args.files) % 2:
        ap.error("give TEST REF pairs")
    channels = args.channels.split(",")
    results = []
    for test_path, ref_path in zip(args.files[0::2], args.files[1::2]):
        result = scores(read_rgb(test_path, channels), read_rgb(ref_path, channels), args.eps)
        result["test"], result["reference"] = test_path, ref_path
        results.append(result)
    json.dump(results, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
