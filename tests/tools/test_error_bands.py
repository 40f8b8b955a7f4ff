#!/usr/bin/python3
"""tools/research/error_bands.py: the box mean against a naive float64 one, the frequency split on errors whose answer is
known (a constant error is all low, a 2-px checkerboard all high), and the whole tool on the bundled room laid out
as a one-scene data set, where its relMSE must equal residue-cli's own for the same model.

  test_error_bands.py REPO RESIDUE_CLI
"""
import json, os, shutil, subprocess, sys, tempfile

import numpy as np

repo, cli = sys.argv[1], sys.argv[2]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(repo, "tools", "research"))
import error_bands  # noqa: E402
from checks import check, finish  # noqa: E402
from goal_check import denoised_scores  # noqa: E402

rng = np.random.default_rng(4)
e = rng.normal(size=(23, 31, 3))
for w in (1, 4, 7, 16):
    # Naive: mirror the border as np.pad's "reflect" does, then average each w x w window.
    p = np.pad(e, ((w // 2, w - 1 - w // 2), (w // 2, w - 1 - w // 2), (0, 0)), mode="reflect")
    naive = np.array([[p[y:y + w, x:x + w].mean(axis=(0, 1)) for x in range(31)] for y in range(23)])
    check(np.abs(error_bands.box_mean(e, w) - naive).max() < 1e-12, f"box mean, width {w}")

r = np.full((32, 32, 3), 0.5)
classes = {"all": np.ones((32, 32), bool)}
flat = error_bands.scene_bands(r * 1.1, r, classes, [4, 16])  # a constant relative error
check(abs(flat["low 16"] - flat["relmse"]) < 1e-12 and flat["high 16"] < 1e-20, f"constant error: {flat}")
checker = ((np.indices((32, 32)).sum(0) % 2) * 2 - 1)[..., None] * 0.05
bands = error_bands.scene_bands(r + checker, r, classes, [4, 16])
check(bands["low 4"] < 1e-20 and abs(bands["high 4"] - bands["relmse"]) < 1e-12, f"checkerboard error: {bands}")
check(abs(bands["all"] - bands["relmse"]) < 1e-12, "a class of every pixel holds the whole relMSE")

with tempfile.TemporaryDirectory() as tmp:
    data = os.path.join(tmp, "set")
    os.makedirs(os.path.join(data, "s0"))
    room = os.path.join(repo, "resources", "examples", "room")
    shutil.copy(os.path.join(room, "noisy.exr"), os.path.join(data, "s0", "noisy_a.exr"))
    shutil.copy(os.path.join(room, "reference.exr"), os.path.join(data, "s0", "reference.exr"))
    with open(os.path.join(data, "index.json"), "w") as f:
        json.dump({"scenes": [{"folder": "s0", "split": "validation", "kind": "interior", "spp": 8}]}, f)
    out = os.path.join(tmp, "bands.json")
    run = subprocess.run([sys.executable, os.path.join(repo, "tools", "research", "error_bands.py"), data, "--models",
                          "multiscale,bilateral", "--json", out, "--cli", cli, "--work", os.path.join(tmp, "w")],
                         capture_output=True, text=True)
    check(run.returncode == 0, f"the tool runs: {run.stderr}")
    result = json.load(open(out))
    scene = result["scenes"][0]["models"]
    # residue-cli's relMSE of the same denoise.
    text = subprocess.run([cli, "denoise", os.path.join(data, "s0", "noisy_a.exr"), "--reference",
                           os.path.join(data, "s0", "reference.exr"), "-m", "multiscale", "-o",
                           os.path.join(tmp, "d.exr")], check=True, capture_output=True, text=True).stdout
    scores = denoised_scores(text)
    check(abs(scene["multiscale"]["relmse"] / scores["relmse"] - 1) < 1e-3,
          f"relMSE {scene['multiscale']['relmse']} against residue-cli's {scores['relmse']}")
    # residue-cli's SSIM of the same denoise, to full precision.
    ssim = json.loads(subprocess.run([cli, "eval", os.path.join(tmp, "d.exr"), "-r", os.path.join(data, "s0",
                                      "reference.exr"), "--json"], check=True, capture_output=True,
                                     text=True).stdout)["rows"][0]["ssim"]
    check(abs(1 - scene["multiscale"]["1-SSIM"] - ssim) < 1e-7,
          f"1 - SSIM loss {1 - scene['multiscale']['1-SSIM']} against residue-cli's SSIM {ssim}")
    for m in ("multiscale", "bilateral"):
        parts = scene[m]
        classes_sum = parts["albedo/normal edge"] + parts["lighting edge only"] + parts["flat"]
        check(abs(classes_sum - parts["relmse"]) < 1e-9 * max(1, parts["relmse"]) + 1e-12,
              f"{m}: edges, lighting edges and flat pixels partition the relMSE")
        ssim_sum = parts["1-SSIM albedo/normal edge"] + parts["1-SSIM lighting edge only"] + parts["1-SSIM flat"]
        check(abs(ssim_sum - parts["1-SSIM"]) < 1e-9, f"{m}: and 1 - SSIM: {ssim_sum} against {parts['1-SSIM']}")
        check(0 < parts["1-SSIM"] < 1, f"{m}: 1 - SSIM in (0, 1): {parts['1-SSIM']}")
    check(scene["multiscale"]["relmse"] < scene["bilateral"]["relmse"], "multiscale beats the bilateral filter")
    check(result["summary"]["interior"]["multiscale"]["relmse"] == scene["multiscale"]["relmse"], "one scene's mean")
    bad = subprocess.run([sys.executable, os.path.join(repo, "tools", "research", "error_bands.py"), data, "--models",
                          "multiscale", "--split", "train", "--cli", cli], capture_output=True, text=True)
    check(bad.returncode != 0 and "no train scenes" in bad.stderr, f"an empty split is refused: {bad.stderr}")

finish()
