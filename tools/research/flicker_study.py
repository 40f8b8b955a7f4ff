#!/usr/bin/env python3
"""Flicker of per-frame denoising: each model denoises every frame of a shot (tools/datagen/render_animation.py),
`residue-cli eval` scores the sequence (per-frame relMSE/SSIM and the temporal relMSE, core/metrics/temporal.h),
and a strip of frames is drawn (noisy, some models, reference; a crop, consecutive frames side by side).

A shot whose references have noise of their own (the moving camera: one reference per frame) adds that noise to
every score: relMSE(x, r) = relMSE(x, truth) + s2 and temporal(x, r) = temporal(x, truth) + 2 s2, s2 being the
references' own relMSE. With a second, independent reference per frame (render_animation.py --second-reference:
reference_b.####.exr) the study measures it, relMSE(r_b, r) = 2 s2 and temporal(r_b, r) = 4 s2, and reports
the scores with that floor subtracted as well.

    /usr/bin/python3 tools/research/flicker_study.py --shots /work/datasets/anim/static,/work/datasets/anim/move \\
        --models bilateral,tiny,small,base,paper,oidn --out docs/research/models/flicker
"""
import argparse
import json
import os
import subprocess

import numpy as np
import OpenImageIO as oiio


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
    return r.stdout


def rgb(path):
    return oiio.ImageBuf(path).get_pixels(oiio.FLOAT)[..., :3]


def display(img):
    img = np.clip(img, 0, None)
    return np.clip(np.where(img <= 0.0031308, 12.92 * img, 1.055 * np.power(img, 1 / 2.4) - 0.055), 0, 1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--shots", required=True)
    ap.add_argument("--models", default="bilateral,tiny,small,base,paper,oidn")
    ap.add_argument("--cli", default="build/release/app/residue-cli/residue-cli")
    ap.add_argument("--work", default="/tmp/residue-flicker")
    ap.add_argument("--out", required=True, help="OUT.json, OUT.md and OUT_<shot>.png are written")
    ap.add_argument("--strip-models", default="small,oidn")
    ap.add_argument("--crop", default="96,96,96,96", help="x,y,w,h of the strip's crop")
    ap.add_argument("--strip-frames", type=int, default=4)
    args = ap.parse_args()
    results = {}
    for shot in args.shots.split(","):
        name = os.path.basename(shot.rstrip("/"))
        results[name] = {}
        noisy = os.path.join(shot, "noisy.####.exr")
        ref = os.path.join(shot, "reference.####.exr")
        base_eval = json.loads(run([args.cli, "eval", "--json", noisy, "-r", ref]))
        results[name]["noisy"] = {"relmse": base_eval["mean"]["noisy"]["relmse"], "ssim": base_eval["mean"]["noisy"]["ssim"],
                                  "temporal_relmse": base_eval["temporal_relmse"]["noisy"], "flicker_ratio": 1.0}
        floor = None
        if os.path.exists(os.path.join(shot, "reference_b.0001.exr")):
            b = json.loads(run([args.cli, "eval", "--json", os.path.join(shot, "reference_b.####.exr"), "-r", ref]))
            floor = {"relmse": b["mean"]["noisy"]["relmse"] / 2, "temporal_relmse": b["temporal_relmse"]["noisy"] / 2}
            results[name]["reference noise (floor)"] = dict(floor, ssim=float("nan"), flicker_ratio=float("nan"))
        for model in args.models.split(","):
            out_dir = os.path.join(args.work, name, model)
            os.makedirs(out_dir, exist_ok=True)
            run([args.cli, "denoise", noisy, "-o", os.path.join(out_dir, "den.####.exr"), "-m", model, "--float", "--force"])
            e = json.loads(run([args.cli, "eval", "--json", noisy, "-r", ref, "--denoised", os.path.join(out_dir, "den.####.exr")]))
            results[name][model] = {"relmse": e["mean"]["denoised"]["relmse"], "ssim": e["mean"]["denoised"]["ssim"],
                                    "temporal_relmse": e["temporal_relmse"]["denoised"], "flicker_ratio": e["flicker_ratio"]}
            if floor:
                results[name][model]["relmse_less_floor"] = results[name][model]["relmse"] - floor["relmse"]
                results[name][model]["temporal_less_floor"] = results[name][model]["temporal_relmse"] - floor["temporal_relmse"]
            print(name, model, results[name][model], flush=True)
        # The strip: rows noisy, the strip models, reference; columns consecutive frames of the crop.
        x, y, w, h = (int(v) for v in args.crop.split(","))
        rows = []
        for label in ["noisy"] + args.strip_models.split(",") + ["reference"]:
            tiles = []
            for f in range(1, args.strip_frames + 1):
                if label == "noisy":
                    path = os.path.join(shot, f"noisy.{f:04d}.exr")
                elif label == "reference":
                    path = os.path.join(shot, f"reference.{f:04d}.exr")
                else:
                    path = os.path.join(args.work, name, label, f"den.{f:04d}.exr")
                tiles.append(display(rgb(path)[y:y + h, x:x + w]))
                tiles.append(np.ones((h, 2, 3)))
            rows.append(np.concatenate(tiles[:-1], axis=1))
            rows.append(np.ones((2, rows[-1].shape[1], 3)))
        strip = (np.concatenate(rows[:-1], axis=0) * 255 + 0.5).astype(np.uint8)
        strip = np.repeat(np.repeat(strip, 2, axis=0), 2, axis=1)  # 2x, nearest: the grain stays visible
        spec = oiio.ImageSpec(strip.shape[1], strip.shape[0], 3, "uint8")
        o = oiio.ImageOutput.create(f"{args.out}_{name}.png")
        o.open(f"{args.out}_{name}.png", spec)
        o.write_image(strip)
        o.close()
    with open(args.out + ".json", "w") as f:
        json.dump(results, f, indent=1)
    with open(args.out + ".md", "w") as f:
        for name, r in results.items():
            f.write(f"Shot `{name}` (mean over frames; temporal relMSE over consecutive pairs; flicker ratio = "
                    "temporal relMSE / the noisy input's; flickering share = temporal / (2 relMSE), the part of the "
                    "error that changes from frame to frame)\n\n")
            floored = any("relmse_less_floor" in v for v in r.values())
            extra = " relMSE - floor | temporal - floor | flickering share |" if floored else " flickering share |"
            f.write("| | relMSE | SSIM | temporal relMSE | flicker ratio |" + extra + "\n")
            f.write("|---" * (5 + extra.count("|")) + "|\n")
            for model, v in r.items():
                row = f"| {model} | {v['relmse']:.5f} | {v['ssim']:.4f} | {v['temporal_relmse']:.6f} | {v['flicker_ratio']:.4f} |"
                if floored and "relmse_less_floor" in v:
                    share = v["temporal_less_floor"] / (2 * v["relmse_less_floor"])
                    row += f" {v['relmse_less_floor']:.5f} | {v['temporal_less_floor']:.6f} | {share:.2f} |"
                elif floored:
                    row += " | | |"
                else:
                    row += f" {v['temporal_relmse'] / (2 * v['relmse']):.2f} |"
                f.write(row + "\n")
            f.write("\n")
    print(open(args.out + ".md").read())


if __name__ == "__main__":
    main()
