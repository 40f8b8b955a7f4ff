#!/usr/bin/python3
"""tools/datagen/exr_metrics.py, the tools' one Python copy of the metrics, pinned to core's numbers: relMSE, MSE and
PSNR (which goes through the filmic tonemap, so the curve is pinned too) on real EXRs against what
`residue-cli eval --json` reports for the same files: the bundled room, a starter scene's Cycles layers, and an
image written here with NaN, Inf and negative pixels (left out, or clamped by the tonemap, as core does).

  test_exr_metrics.py REPO RESIDUE_CLI
"""
import json, math, os, subprocess, sys, tempfile

import numpy as np
import OpenImageIO as oiio

repo, cli = sys.argv[1], sys.argv[2]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(repo, "tools", "datagen"))
import exr_metrics  # noqa: E402
from checks import check, finish  # noqa: E402


def core_scores(test, reference):
    r = subprocess.run([cli, "eval", test, "--reference", reference, "--json"], capture_output=True, text=True)
    check(r.returncode == 0, f"residue-cli eval {test}: {r.stderr.strip()}")
    return json.loads(r.stdout)["rows"][0] if r.returncode == 0 else {}


def write_rgb(path, rgb):
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(rgb.shape[1], rgb.shape[0], 3, "float"))
    out.write_image(np.ascontiguousarray(rgb, dtype=np.float32))
    out.close()


def compare(what, test_path, ref_path, x, r):
    core = core_scores(test_path, ref_path)
    if not core:
        return
    ours = {"relmse": exr_metrics.relmse(x, r), "mse": exr_metrics.mse(x, r), "psnr": exr_metrics.psnr(x, r)}
    for k, v in ours.items():
        close = math.isclose(v, core[k], rel_tol=1e-9, abs_tol=1e-12)
        check(close, f"{what}: {k} {v!r} is core's {core[k]!r}")
    check(int(exr_metrics.finite_pixels(x, r).sum()) == core["pixels"],
          f"{what}: {int(exr_metrics.finite_pixels(x, r).sum())} pixels entered, core counts {core['pixels']}")


room = os.path.join(repo, "resources", "examples", "room")
compare("bundled room", os.path.join(room, "noisy.exr"), os.path.join(room, "reference.exr"),
        exr_metrics.layer_rgb(exr_metrics.read_exr(os.path.join(room, "noisy.exr")), exr_metrics.COMBINED),
        exr_metrics.layer_rgb(exr_metrics.read_exr(os.path.join(room, "reference.exr")), exr_metrics.COMBINED))

scene = os.path.join(repo, "..", "shared", "datasets", "cycles-starter", "s100")
compare("starter s100", os.path.join(scene, "noisy_a.exr"), os.path.join(scene, "reference.exr"),
        exr_metrics.layer_rgb(exr_metrics.read_exr(os.path.join(scene, "noisy_a.exr")), exr_metrics.COMBINED),
        exr_metrics.layer_rgb(exr_metrics.read_exr(os.path.join(scene, "reference.exr")), exr_metrics.COMBINED))

with tempfile.TemporaryDirectory() as tmp:
    rng = np.random.default_rng(7)
    r = np.exp(rng.normal(size=(40, 52, 3)) * 1.5)  # radiance over a wide range, some above the white point 11.2
    x = r * np.exp(rng.normal(size=r.shape) * 0.3) - 0.05  # noisy, a few negatives
    x[3, 4, 1], x[10, 20, 0], r[30, 7, 2] = np.nan, np.inf, -np.inf
    x, r = x.astype(np.float32).astype(np.float64), r.astype(np.float32).astype(np.float64)
    write_rgb(os.path.join(tmp, "x.exr"), x)
    write_rgb(os.path.join(tmp, "r.exr"), r)
    back = exr_metrics.layer_rgb(exr_metrics.read_exr(os.path.join(tmp, "x.exr")), None)
    check(np.array_equal(back, x, equal_nan=True), "a float EXR reads back as written")
    compare("non-finite and negative pixels", os.path.join(tmp, "x.exr"), os.path.join(tmp, "r.exr"), x, r)
    check(exr_metrics.finite_pixels(x, r).sum() == x.shape[0] * x.shape[1] - 3, "three pixels are left out")

# The curve itself at points whose value is known: 0 and below give 0, the white point and above 1.
t = exr_metrics.tonemap(np.array([-1.0, 0.0, 11.2, 1e30, np.nan]))
check(np.abs(t - [0.0, 0.0, 1.0, 1.0, 0.0]).max() < 1e-15, f"tonemap at -1, 0, 11.2, 1e30, NaN: {list(t)}")
finish()
