#!/usr/bin/env python3
"""Denoising strength against error: relMSE and SSIM of the blend s*denoised + (1-s)*noisy, per strength.

For each scene of a data set in the starter layout (sNNN/noisy_a.exr, sNNN/reference.exr) the model runs once
(`residue-cli denoise --float`, strength 1 and 0), the blends are made here and scored by `residue-cli eval`
(the project's metrics). Writes a JSON with the mean and per-scene numbers, and a Markdown table.

    /usr/bin/python3 tools/research/strength_curve.py --data ../shared/datasets/cycles-starter --model small \\
        --cli build/release/app/residue-cli/residue-cli --out docs/research/models/strength_curve_starter_small
"""
import argparse
import json
import os
import subprocess
import tempfile

import numpy as np
import OpenImageIO as oiio


def read_rgb(path):
    buf = oiio.ImageBuf(path)
    return buf.get_pixels(oiio.FLOAT)[..., :3], buf.spec()


def write_rgb(path, pixels, spec):
    out_spec = oiio.ImageSpec(spec.width, spec.height, 3, "float")
    out_spec.channelnames = ("R", "G", "B")
    out_spec.x, out_spec.y = spec.x, spec.y
    out_spec.full_width, out_spec.full_height = spec.full_width, spec.full_height
    out = oiio.ImageOutput.create(path)
    out.open(path, out_spec)
    out.write_image(np.ascontiguousarray(pixels, dtype=np.float32))
    out.close()


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True)
    ap.add_argument("--model", default="small")
    ap.add_argument("--cli", default="build/release/app/residue-cli/residue-cli")
    ap.add_argument("--strengths", default="0,0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9,0.95,1")
    ap.add_argument("--out", required=True, help="path without extension: OUT.json and OUT.md are written")
    args = ap.parse_args()
    strengths = [float(s) for s in args.strengths.split(",")]
    scenes = sorted(d for d in os.listdir(args.data) if os.path.isfile(os.path.join(args.data, d, "reference.exr")))
    per_scene = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scene in scenes:
            noisy_path = os.path.join(args.data, scene, "noisy_a.exr")
            ref_path = os.path.join(args.data, scene, "reference.exr")
            ends = {}
            for s in (0, 1):
                path = os.path.join(tmp, f"{scene}_{s}.exr")
                subprocess.run([args.cli, "denoise", noisy_path, "-m", args.model, "-o", path, "--float",
                                "--strength", str(s), "--force"], check=True, capture_output=True)
                ends[s] = read_rgb(path)
            noisy, spec = ends[0]
            denoised, _ = ends[1]
            rows = []
            for s in strengths:
                path = os.path.join(tmp, f"{scene}_blend.exr")
                write_rgb(path, s * denoised + (1 - s) * noisy, spec)
                r = subprocess.run([args.cli, "eval", "--json", noisy_path, "-r", ref_path, "--denoised", path],
                                   check=True, capture_output=True, text=True)
                row = json.loads(r.stdout)["rows"][1]
                rows.append({"strength": s, "relmse": row["relmse"], "ssim": row["ssim"]})
            per_scene[scene] = rows
            print(scene, " ".join(f"{x['strength']}:{x['relmse']:.4f}" for x in rows), flush=True)
    mean = []
    for i, s in enumerate(strengths):
        mean.append({"strength": s,
                     "relmse": float(np.mean([per_scene[k][i]["relmse"] for k in scenes])),
                     "ssim": float(np.mean([per_scene[k][i]["ssim"] for k in scenes])),
                     "scenes_best_relmse": sum(1 for k in scenes if min(per_scene[k], key=lambda x: x["relmse"])["strength"] == s)})
    with open(args.out + ".json", "w") as f:
        json.dump({"data": os.path.abspath(args.data), "model": args.model, "scenes": len(scenes), "mean": mean,
                   "per_scene": per_scene}, f, indent=1)
    with open(args.out + ".md", "w") as f:
        f.write(f"Strength curve: `{args.model}` on {len(scenes)} scenes of {os.path.basename(os.path.abspath(args.data))} "
                "(noisy_a against the reference; mean over scenes)\n\n")
        f.write("| strength | relMSE | SSIM | scenes whose best relMSE is here |\n|---|---|---|---|\n")
        for m in mean:
            f.write(f"| {m['strength']:.2f} | {m['relmse']:.5f} | {m['ssim']:.4f} | {m['scenes_best_relmse']} |\n")
    print(open(args.out + ".md").read())


if __name__ == "__main__":
    main()
