#!/usr/bin/python3
"""Issue 16, lever 3 (inputs from any renderer), measured without training: the same Cycles renders denoised as
Cycles wrote them, re-saved in Tungsten's conventions (one file per buffer; world-space normals and no camera,
so they cannot be made view-space; albedo with emission, as Cycles' denoising albedo already is; ray-length
depth) and in pbrt-v4's (its gbuffer film's one file: camera-space shading normals with +z along the view, depth
as the z of camera-space positions, 0 where nothing was hit; the position's x and y, dz/dx, dz/dy, u, v and the
variances are written as zeros: the loader does not read them), for each model. A model that reads renderers'
conventions well loses little between them.

  /usr/bin/python3 tools/research/conventions_study.py [--data ../shared/datasets/cycles-starter] [--scenes s158,...]
      [--models bilateral,small,base,paper,oidn] [--cli build/release/app/residue-cli/residue-cli] --out DIR

Writes DIR/<scene>/tungsten/{color,albedo,normal,depth,reference}.exr and DIR/<scene>/pbrt.exr and prints a
Markdown table (mean relMSE and SSIM per model and convention, and the relative change from Cycles'); --json FILE
keeps the per-scene numbers.
"""
import argparse, json, os, re, subprocess, sys

import numpy as np
import OpenImageIO as oiio

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "datagen"))
from exr_metrics import read_exr  # noqa: E402

L = "ViewLayer."
CONVENTIONS = ("cycles", "tungsten", "pbrt")

def oiiotool(*args):
    subprocess.run(["oiiotool", *args], check=True, capture_output=True)

def to_tungsten(noisy, reference, out):
    os.makedirs(out, exist_ok=True)
    pick = {
        "color": [("R", L + "Combined.R"), ("G", L + "Combined.G"), ("B", L + "Combined.B")],
        "albedo": [("R", L + "Denoising Albedo.R"), ("G", L + "Denoising Albedo.G"), ("B", L + "Denoising Albedo.B")],
        "normal": [("R", L + "Normal.X"), ("G", L + "Normal.Y"), ("B", L + "Normal.Z")],  # world space
        "depth": [("Y", L + "Denoising Depth.Z")],  # distance along the camera ray
    }
    for name, channels in pick.items():
        spec = ",".join(f"{new}={old}" for new, old in channels)
        oiiotool(noisy, "--ch", spec, "-d", "half", "--compression", "piz", "-o", os.path.join(out, name + ".exr"))
    oiiotool(reference, "--ch", f"R={L}Combined.R,G={L}Combined.G,B={L}Combined.B", "-d", "half",
             "--compression", "piz", "-o", os.path.join(out, "reference.exr"))

def to_pbrt(noisy, out):
    """The noisy render as pbrt-v4's gbuffer film writes one: its channels, in its order, in half."""
    src = read_exr(noisy)
    get = lambda name: src["pixels"][:, :, src["channels"].index(L + name)]
    depth = get("Depth.Z")  # planar; Cycles writes 1e10 where nothing was hit, pbrt a zero position
    zero = np.zeros_like(depth)
    channels = {"R": get("Combined.R"), "G": get("Combined.G"), "B": get("Combined.B")}
    channels.update({f"Albedo.{c}": get(f"Denoising Albedo.{c}") for c in "RGB"})
    channels.update({"P.X": zero, "P.Y": zero, "P.Z": np.where(depth >= 1e9, 0, depth), "dzdx": zero, "dzdy": zero})
    for layer in ("N", "Ns"):  # Cycles' denoising normal: camera space, +z along the view, as pbrt's camera space
        channels.update({f"{layer}.{c}": get(f"Denoising Normal.{c}") for c in "XYZ"})
    channels.update({"u": zero, "v": zero})
    channels.update({f"{v}.{c}": zero for v in ("Variance", "RelativeVariance") for c in "RGB"})
    spec = oiio.ImageSpec(depth.shape[1], depth.shape[0], len(channels), oiio.HALF)
    spec.channelnames = list(channels)
    spec.attribute("compression", "zip")
    image = oiio.ImageBuf(spec)
    image.set_pixels(oiio.ROI(), np.stack(list(channels.values()), -1).astype(np.float32))
    if not image.write(out):
        raise RuntimeError(f"cannot write {out}: {image.geterror()}")

def scores(cli, inputs, model, out, reference=None):
    args = [cli, "denoise", *inputs, "-m", model, "-o", out, "--force"]
    if reference:
        args += ["-r", reference]
    text = subprocess.run(args, check=True, capture_output=True, text=True).stdout
    row = re.search(r"^denoised\s+(\S+)\s+\S+\s+\S+\s+(\S+)", text, re.M)
    return float(row.group(1)), float(row.group(2))

def main():
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", default=os.path.join(root, "..", "shared", "datasets", "cycles-starter"))
    p.add_argument("--scenes", default="s158,s159,s160,s161,s162,s163")
    p.add_argument("--models", default="bilateral,small,base,paper,oidn")
    p.add_argument("--cli", default=os.path.join(root, "build/release/app/residue-cli/residue-cli"))
    p.add_argument("--out", required=True)
    p.add_argument("--json")
    a = p.parse_args()
    results = {}
    for scene in a.scenes.split(","):
        src = os.path.join(a.data, scene)
        tdir = os.path.join(a.out, scene, "tungsten")
        reference = os.path.join(src, "reference.exr")
        to_tungsten(os.path.join(src, "noisy_a.exr"), reference, tdir)
        pbrt = os.path.join(a.out, scene, "pbrt.exr")
        to_pbrt(os.path.join(src, "noisy_a.exr"), pbrt)
        for model in a.models.split(","):
            row = {"scene": scene,
                   "cycles": scores(a.cli, [os.path.join(src, "noisy_a.exr")], model,
                                    os.path.join(a.out, scene, f"cycles_{model}.exr"), reference),
                   "tungsten": scores(a.cli, [tdir], model, os.path.join(a.out, scene, f"tungsten_{model}.exr")),
                   "pbrt": scores(a.cli, [pbrt], model, os.path.join(a.out, scene, f"pbrt_{model}.exr"), reference)}
            results.setdefault(model, []).append(row)
            print(f"{scene} {model}: " + ", ".join(f"{k} {row[k][0]:.5f} / {row[k][1]:.4f}" for k in CONVENTIONS),
                  file=sys.stderr)
    print("| model | relMSE, Cycles conventions | Tungsten's | change | pbrt-v4's | change | SSIM, Cycles | Tungsten | pbrt-v4 |")
    print("|---|---|---|---|---|---|---|---|---|")
    for model, rows in results.items():
        rel = {k: sum(r[k][0] for r in rows) / len(rows) for k in CONVENTIONS}
        ssim = {k: sum(r[k][1] for r in rows) / len(rows) for k in CONVENTIONS}
        print(f"| `{model}` | {rel['cycles']:.5f} | " +
              " | ".join(f"{rel[k]:.5f} | {100 * (rel[k] / rel['cycles'] - 1):+.1f} %" for k in CONVENTIONS[1:]) +
              " | " + " | ".join(f"{ssim[k]:.4f}" for k in CONVENTIONS) + " |")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(results, f, indent=1)

if __name__ == "__main__":
    sys.exit(main())
