#!/usr/bin/python3
"""tools/models/temporal_init.py on the shipped multiscale file: the head's neighbour planes get the weights asked
for (zero, or the colour's shared evenly over the frames: checked against NumPy), every other tensor is kept byte
for byte, the file loads as a temporal model (residue-cli models / denoise on the committed rendered shot), the
zero-weight one denoises a frame as multiscale does, and bad inputs fail early without writing.

  test_temporal_init.py REPO RESIDUE_CLI
"""
import json, os, subprocess, sys, tempfile

import numpy as np

repo, cli = sys.argv[1], sys.argv[2]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(repo, "tools", "models"))
from safetensors_meta import read_tensors  # noqa: E402
from checks import check, finish  # noqa: E402

tool = os.path.join(repo, "tools", "models", "temporal_init.py")
still = os.path.join(repo, "resources", "models", "multiscale.safetensors")
shot = os.path.join(repo, "tests", "data", "shot")


def head(path):
    meta, tensors = read_tensors(path)
    dtype, shape, raw = tensors["head.conv.weight"]
    return np.frombuffer(raw, "<f4").reshape(shape), meta, tensors


def run(*args):
    return subprocess.run([sys.executable, tool, *args], capture_output=True, text=True)


def denoise(model, out):
    r = subprocess.run([cli, "denoise", os.path.join(shot, "noisy.####.exr"), "--frames", "3", "-m", model, "-o", out,
                        "--float", "--no-energy-correction"], capture_output=True, text=True)
    check(r.returncode == 0, f"residue-cli denoise -m {os.path.basename(model)}: {r.stdout[-500:]} {r.stderr[-500:]}")
    import OpenImageIO as oiio  # noqa: E402
    return oiio.ImageBuf(out.replace("####", "0003")).get_pixels(oiio.FLOAT)


with tempfile.TemporaryDirectory() as tmp:
    w, meta, tensors = head(still)
    zero, average = os.path.join(tmp, "zero.safetensors"), os.path.join(tmp, "average.safetensors")
    check(run(still, zero, "--share", "zero").returncode == 0, "--share zero runs")
    check(run(still, average, "--share", "average").returncode == 0, "--share average runs")
    wz, mz, tz = head(zero)
    wa, ma, _ = head(average)
    check(wz.shape == (w.shape[0], w.shape[1] + 8) + w.shape[2:], f"8 more input planes: {wz.shape}")
    check(np.array_equal(wz[:, :w.shape[1]], w) and not wz[:, w.shape[1]:].any(), "zero: the still's weights, then 0")
    share = w[:, :3] / np.float32(3)
    check(np.array_equal(wa[:, :3], share) and np.array_equal(wa[:, 9:12], share) and np.array_equal(wa[:, 13:16], share),
          "average: the colour's weights split over the frame and its two neighbours")
    check(not wa[:, 12].any() and not wa[:, 16].any() and np.array_equal(wa[:, 3:9], w[:, 3:9]),
          "average: validity planes 0, the other features' weights kept")
    check(all(tz[k] == tensors[k] for k in tensors if k != "head.conv.weight"), "every other tensor byte for byte")
    check(mz.get("residue.temporal") == "1" and ma.get("residue.exposure_key") == meta.get("residue.exposure_key"),
          "the radius is in the metadata, the still's settings kept")

    # The zero-weight model denoises frame 3 of the rendered shot as multiscale does (its neighbours add zeros).
    a = denoise(zero, os.path.join(tmp, "z.####.exr"))
    b = denoise(still, os.path.join(tmp, "m.####.exr"))
    worst = float(np.max(np.abs(a - b) / (np.abs(b) + 1e-3)))
    check(worst < 1e-4, f"the zero-weight temporal model denoises as multiscale (largest relative difference {worst})")
    c = denoise(average, os.path.join(tmp, "a.####.exr"))
    check(float(np.max(np.abs(c - b))) > 1e-3, "the shared weights read the neighbours")

    # Refusals, nothing written.
    bad = os.path.join(tmp, "bad.safetensors")
    r = run(zero, bad)
    check(r.returncode != 0 and "temporal already" in r.stderr and not os.path.exists(bad), "a temporal input is refused")
    r = run(os.path.join(repo, "resources", "models", "multiscale-color.safetensors"), bad)
    check(r.returncode != 0 and "'full'" in r.stderr and not os.path.exists(bad), "a colour-only model is refused")
    r = run(still, zero)
    check(r.returncode != 0 and "exists" in r.stderr, "an existing output is not replaced without --force")

finish()
