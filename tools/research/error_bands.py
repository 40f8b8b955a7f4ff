#!/usr/bin/python3
"""Where one model's error differs from another's: each scene's relMSE split by spatial frequency and by pixel
class, per scene kind (interior / exterior), for two or more models on a data set's scenes; and each scene's SSIM loss
(1 - SSIM) split by the same pixel classes.

  /usr/bin/python3 tools/research/error_bands.py DATASET --models best,oidn [--split validation] [--widths 4,16,48]
      [--json OUT.json] [--cli build/release/app/residue-cli/residue-cli] [--work DIR]

Each model denoises each scene's first half (`residue-cli denoise SCENE/noisy_a.exr -m MODEL`) into --work (a
temporary folder by default) as SCENE_MODEL.exr, MODEL's file name without its folder; an output already there is
reused, so a --work folder serves one set of models (a changed file under the same name needs a new one). The relative error
e = (x - r) / sqrt(r^2 + eps) (so that mean(e^2) is the scene's relMSE, eps 0.01) is split at each width W into
its W x W box mean ("low": blotches, shading bias, anything wider than W pixels) and the rest ("high": noise
and detail); each part's mean square is reported. The pixel classes come from the reference and the first
half's AOVs: dark (luminance < 0.05), bright (>= 1), edges of the albedo or normal, edges of the lighting only
(the reference's log gradient where albedo and normal are flat), and flat. Each number is a mean over the
scenes of a kind of that part's contribution to the scene's relMSE.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "datagen"))
from exr_metrics import EPS, box_mean, layer_rgb, luminance, read_exr  # noqa: E402

LAYER = "ViewLayer"


def gradient(a):
    gy, gx = np.gradient(a, axis=(0, 1))
    return np.sqrt((gx ** 2 + gy ** 2).sum(-1))


def pixel_classes(reference, noisy):
    albedo = layer_rgb(noisy, f"{LAYER}.Denoising Albedo")
    normal = noisy["pixels"][:, :, [noisy["channels"].index(f"{LAYER}.Denoising Normal.{c}") for c in "XYZ"]]
    lum = luminance(reference)
    edge = (gradient(albedo) > 0.15) | (gradient(normal) > 0.3)
    lighting = (gradient(np.log1p(np.maximum(reference, 0))) > 0.15) & ~edge
    return {"dark": lum < 0.05, "bright": lum >= 1, "albedo/normal edge": edge, "lighting edge only": lighting,
            "flat": ~edge & ~lighting}


def ssim_map(cli, image, reference, work):
    """residue-cli's per-pixel SSIM map of IMAGE against REFERENCE (float EXR in WORK; one already there is reused,
    like the denoised image it was made from)."""
    found = [f for f in os.listdir(work) if f.endswith("_ssim.exr")]
    if not found:
        subprocess.run([cli, "eval", image, "-r", reference, "--maps-dir", work, "--map-format", "exr", "--force"],
                       check=True, stdout=subprocess.DEVNULL)
        found = [f for f in os.listdir(work) if f.endswith("_ssim.exr")]
    name = found[0]
    return read_exr(os.path.join(work, name))["pixels"][:, :, 0].astype(np.float64)


def scene_bands(x, r, classes, widths, ssim=None):
    """The relMSE's parts by frequency and by class; with SSIM (a per-pixel map), 1 - SSIM's parts by class."""
    e = (x - r) / np.sqrt(r * r + EPS)
    e2 = (e * e).mean(-1)
    out = {"relmse": float(e2.mean())}
    for w in widths:
        low = box_mean(e, w)
        out[f"low {w}"] = float((low * low).mean())
        out[f"high {w}"] = float(((e - low) ** 2).mean())
    for name, mask in classes.items():
        out[name] = float(e2[mask].sum() / e2.size)
    if ssim is not None:
        # The pixels whose 11 x 11 window lies inside the image: the ones the scene's SSIM averages.
        inner = np.zeros(ssim.shape, bool)
        inner[5:-5, 5:-5] = True
        if not inner.any():
            inner[:] = True
        loss = 1 - ssim
        out["1-SSIM"] = float(loss[inner].mean())
        for name, mask in classes.items():
            out[f"1-SSIM {name}"] = float(loss[inner & mask].sum() / inner.sum())
    return out


def main():
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dataset")
    p.add_argument("--models", required=True, help="comma-separated, as -m takes them (aliases included)")
    p.add_argument("--split", default="validation", choices=["all", "train", "validation"])
    p.add_argument("--widths", default="4,16,48")
    p.add_argument("--json")
    p.add_argument("--cli", default=os.path.join(root, "build/release/app/residue-cli/residue-cli"))
    p.add_argument("--work")
    a = p.parse_args()
    models = a.models.split(",")
    widths = [int(w) for w in a.widths.split(",")]
    index = json.load(open(os.path.join(a.dataset, "index.json")))
    scenes = [s for s in index["scenes"] if a.split == "all" or s["split"] == a.split]
    if not scenes:
        sys.exit(f"error_bands: {a.dataset}: no {a.split} scenes in index.json")

    work = a.work or tempfile.mkdtemp(prefix="error_bands_")
    os.makedirs(work, exist_ok=True)
    rows = []
    for s in scenes:
        folder = os.path.join(a.dataset, s["folder"])
        noisy = read_exr(os.path.join(folder, "noisy_a.exr"))
        reference = layer_rgb(read_exr(os.path.join(folder, "reference.exr")))
        classes = pixel_classes(reference, noisy)
        row = {"scene": s["folder"], "kind": s["kind"], "spp": s["spp"], "models": {}}
        for m in models:
            out = os.path.join(work, f"{s['folder']}_{os.path.basename(m)}.exr")
            if not os.path.exists(out):
                subprocess.run([a.cli, "denoise", os.path.join(folder, "noisy_a.exr"), "-m", m, "-o", out, "--force"],
                               check=True, stdout=subprocess.DEVNULL)
            x = read_exr(out)["pixels"][:, :, :3].astype(np.float64)
            maps = os.path.join(work, f"{s['folder']}_{os.path.basename(m)}_maps")
            os.makedirs(maps, exist_ok=True)
            ssim = ssim_map(a.cli, out, os.path.join(folder, "reference.exr"), maps)
            row["models"][m] = scene_bands(x, reference, classes, widths, ssim)
        rows.append(row)
        print(f"error_bands: {s['folder']} " + " ".join(f"{m} {row['models'][m]['relmse']:.5f}" for m in models),
              file=sys.stderr)

    keys = list(rows[0]["models"][models[0]].keys())
    summary = {}
    for kind in sorted({r["kind"] for r in rows}):
        group = [r for r in rows if r["kind"] == kind]
        summary[kind] = {m: {k: float(np.mean([r["models"][m][k] for r in group])) for k in keys} for m in models}
        print(f"\n{kind}s ({len(group)} scenes): mean contribution to relMSE (to 1 - SSIM in the rows so named)" +
              (f"; last column {models[0]} against {models[1]}" if len(models) > 1 else ""))
        print(f"| part | {' | '.join(models)} |" + (" ratio |" if len(models) > 1 else ""))
        print("|---|" + "---|" * (len(models) + (len(models) > 1)))
        for k in keys:
            vals = [summary[kind][m][k] for m in models]
            ratio = f" {vals[0] / vals[1]:.3f} |" if len(models) > 1 and vals[1] > 0 else ""
            print(f"| {k} | " + " | ".join(f"{v:.6f}" for v in vals) + " |" + ratio)
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"dataset": a.dataset, "split": a.split, "models": models, "widths": widths, "eps": EPS,
                       "summary": summary, "scenes": rows}, f, indent=1)


if __name__ == "__main__":
    main()
