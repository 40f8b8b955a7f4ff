#!/usr/bin/python3
"""render_dataset.restore_low_band, the pseudo-references' low band taken from their raw render: exact on inputs
whose answer is known (no difference, a constant relative offset, zero-mean noise finer than the box), and on a
real render: a starter scene's 512-spp reference given blotches plays the biased pseudo-reference, its own noisy
half the raw render; the restored image must be closer to the reference in total and in its 48-px band.

  test_pseudo_low_band.py REPO
"""
import os, sys

import numpy as np

repo = sys.argv[1]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(repo, "tools", "datagen"))
import exr_metrics  # noqa: E402
from checks import check, finish  # noqa: E402
from render_dataset import restore_low_band  # noqa: E402

rng = np.random.default_rng(13)
pseudo = np.exp(rng.normal(size=(48, 40, 3)))  # positive, wide range, like radiance
check(np.array_equal(restore_low_band(pseudo, pseudo, 16), pseudo), "raw == pseudo leaves it unchanged")
shifted = restore_low_band(pseudo, pseudo + 0.1 * np.sqrt(pseudo * pseudo + exr_metrics.EPS), 16)
check(np.abs(shifted - (pseudo + 0.1 * np.sqrt(pseudo * pseudo + exr_metrics.EPS))).max() < 1e-12,
      "a constant relative offset comes back exactly")
checker = ((np.indices((48, 40)).sum(0) % 2) * 2 - 1)[..., None] * 0.3  # zero mean over any even box
fine = restore_low_band(pseudo, pseudo + checker * np.sqrt(pseudo * pseudo + exr_metrics.EPS), 16)
check(np.abs(fine - pseudo).max() < 1e-12, "zero-mean noise finer than the box is not taken")

scene = os.path.join(repo, "..", "shared", "datasets", "cycles-starter", "s100")
truth = exr_metrics.layer_rgb(exr_metrics.read_exr(os.path.join(scene, "reference.exr")))
raw = exr_metrics.layer_rgb(exr_metrics.read_exr(os.path.join(scene, "noisy_a.exr")))
h, w = truth.shape[:2]
y, x = np.mgrid[0:h, 0:w] / max(h, w)
blotch = 1 + 0.25 * np.sin(2 * np.pi * 3 * x)[..., None] * np.cos(2 * np.pi * 2 * y)[..., None]  # ~40-px blotches
biased = truth * blotch
restored = restore_low_band(biased, raw, 16)


def low48(img):
    e = (img - truth) / np.sqrt(truth * truth + exr_metrics.EPS)
    return float((exr_metrics.box_mean(e, 48) ** 2).mean())


before, after = exr_metrics.relmse(biased, truth), exr_metrics.relmse(restored, truth)
print(f"s100: relMSE {before:.5f} -> {after:.5f}, 48-px band {low48(biased):.6f} -> {low48(restored):.6f}, "
      f"the raw render's {low48(raw):.6f}")
check(np.isfinite(restored).all(), "the restored image is finite")
check(after < before, "closer to the reference in total")
check(low48(restored) < 0.25 * low48(biased), "its 48-px band at least 4x closer")
finish()
