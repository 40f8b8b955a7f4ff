#!/usr/bin/env python3
"""Skipping what has converged (`residue-cli denoise --skip-converged RV`): time saved against error added.

For each scene folder (noisy_a.exr, noisy_b.exr, reference.exr, as tools/datagen/make_scene.py writes them, e.g.
with --adaptive-threshold for renders from Cycles' adaptive sampler), the variance of noisy_a is estimated from the
two halves, (a - b)^2 / 2 per channel (as core/aov/dataset.cpp does for the data sets), and written beside the
outputs; then `residue-cli denoise noisy_a.exr --map variance=VAR -r reference.exr` runs without the option and
with each threshold, each `--repeat` times (the fastest kept: the time is `denoise()`'s, from the "time" line),
and every output is scored by `residue-cli eval` (relMSE, SSIM, HDR-FLIP). Writes OUT.json and OUT.md.

    /usr/bin/python3 tools/research/skip_converged.py /work/datasets/adaptive/s160 /work/datasets/adaptive/s161 \\
        --model multiscale --thresholds 1e-5,3e-5,1e-4,3e-4,1e-3 --out docs/research/skip_converged
"""
import argparse
import datetime
import json
import os
import re
import subprocess
import tempfile

import numpy as np
import OpenImageIO as oiio

DEFAULT_CLI = os.path.join(os.path.dirname(__file__), "../../build/release/app/residue-cli/residue-cli")


def combined(path):
    """The beauty of a Blender multilayer EXR (ViewLayer.Combined.RGB), as float32 H x W x 3."""
    buf = oiio.ImageBuf(path)
    names = list(buf.spec().channelnames)
    idx = [names.index(f"ViewLayer.Combined.{c}") for c in "RGB"]
    return buf.get_pixels(oiio.FLOAT)[..., idx], buf.spec()


def write_variance(path, a, b, spec):
    var = 0.5 * (a - b) ** 2
    var[~np.isfinite(var)] = 0.0
    out_spec = oiio.ImageSpec(spec.width, spec.height, 3, "float")
    out_spec.channelnames = ("R", "G", "B")
    out = oiio.ImageOutput.create(path)
    out.open(path, out_spec)
    out.write_image(np.ascontiguousarray(var, dtype=np.float32))
    out.close()


def denoise(cli, scene, var, out, model, precision, threshold, repeat):
    args = [cli, "denoise", os.path.join(scene, "noisy_a.exr"), "--map", f"variance={var}", "-m", model,
            "--precision", precision, "-o", out, "-f", "--float"]
    if threshold:
        args += ["--skip-converged", repr(threshold)]
    best, kept = None, None
    for _ in range(repeat):
        text = subprocess.run(args, check=True, capture_output=True, text=True).stdout
        seconds = float(re.search(r"^time\s+([0-9.]+) s", text, re.M).group(1))
        best = seconds if best is None else min(best, seconds)
        m = re.search(r"^converged\s+([0-9.]+) %.*network on (\d+) rectangle", text, re.M)
        kept = (float(m.group(1)), int(m.group(2))) if m else (0.0, 1)
    return best, kept


def cpu_name():
    with open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return "unknown CPU"


def score(cli, image, reference):
    text = subprocess.run([cli, "eval", image, "-r", reference, "--json"], check=True, capture_output=True, text=True).stdout
    row = json.loads(text)["rows"][0]
    return {"relmse": row["relmse"], "ssim": row["ssim"], "hdr_flip": row["hdr_flip"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--model", default="multiscale")
    ap.add_argument("--precision", default="fp32")
    ap.add_argument("--thresholds", default="1e-5,3e-5,1e-4,3e-4,1e-3")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cli", default=DEFAULT_CLI)
    ap.add_argument("--out", required=True, help="OUT.json and OUT.md are written")
    args = ap.parse_args()
    thresholds = [0.0] + [float(t) for t in args.thresholds.split(",")]
    results = []
    with tempfile.TemporaryDirectory() as work:
        for scene in args.scenes:
            name = os.path.basename(os.path.normpath(scene))
            a, spec = combined(os.path.join(scene, "noisy_a.exr"))
            b, _ = combined(os.path.join(scene, "noisy_b.exr"))
            var = os.path.join(work, name + ".var.exr")
            write_variance(var, a, b, spec)
            reference = os.path.join(scene, "reference.exr")
            rows = []
            for t in thresholds:
                out = os.path.join(work, f"{name}.{t}.exr")
                seconds, (kept, regions) = denoise(args.cli, scene, var, out, args.model, args.precision, t, args.repeat)
                rows.append({"threshold": t, "seconds": seconds, "kept_percent": kept, "regions": regions,
                             **score(args.cli, out, reference)})
                print(name, rows[-1], flush=True)
            noisy = score(args.cli, os.path.join(scene, "noisy_a.exr"), reference)
            results.append({"scene": name, "width": spec.width, "height": spec.height, "noisy": noisy, "rows": rows})

    with open(args.out + ".json", "w") as f:
        json.dump({"model": args.model, "precision": args.precision, "repeat": args.repeat, "scenes": results}, f, indent=1)
    lines = [f"# `--skip-converged`: time against error ({datetime.date.today()}, {cpu_name()}, {os.cpu_count()} cores)", "",
             f"`{args.model}` {args.precision}; time is `denoise()`'s, the fastest of {args.repeat} runs; "
             "speed-up and error against the same scene without the option.", "",
             "| scene | threshold | kept as rendered | rectangles | time | speed-up | relMSE | relMSE change | SSIM | HDR-FLIP |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        base = r["rows"][0]
        for row in r["rows"]:
            t = "off" if row["threshold"] == 0 else f"{row['threshold']:g}"
            lines.append(f"| {r['scene']} | {t} | {row['kept_percent']:.1f} % | {row['regions']} | {row['seconds']:.2f} s | "
                         f"{base['seconds'] / row['seconds']:.2f}x | {row['relmse']:.5f} | "
                         f"{100 * (row['relmse'] / base['relmse'] - 1):+.2f} % | {row['ssim']:.4f} | {row['hdr_flip']:.4f} |")
    with open(args.out + ".md", "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
