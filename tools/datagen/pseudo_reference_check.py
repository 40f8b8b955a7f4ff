#!/usr/bin/python3
"""How far is a pseudo-reference (render_dataset.py --pseudo-ref) from the truth?

  /usr/bin/python3 tools/datagen/pseudo_reference_check.py DATASET [--model multiscale] [--spp 128] \
      [--ensemble 8] [--low-band 16] [--scenes s1000,...] [--reuse] [--work DIR] --out OUT

For each validation scene of DATASET (they have true references, 1024 spp), renders the input that
render_dataset.py --pseudo-ref would render for a training scene (the same scene, --spp samples, sampling seed
1009, full AOVs), denoises it with --model as a self-ensemble and scores it against the true reference with
residue-cli's metrics. The true reference is itself noisy, so the raw render's relMSE against it (e_spp + e_ref,
both zero-mean noise, e_N = c / N) also estimates how far a 1024-spp and a 512-spp render are from the truth; the
pseudo-reference's own distance is its relMSE minus e_1024 (its error and the reference's noise are independent).
It also scores the pseudo-reference with its --low-band box means from the raw render (what render_dataset.py
writes by default), and each version's low spatial frequencies. --reuse keeps renders already in --work.
Writes OUT.json and OUT.md.
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys

import numpy as np

import exr_metrics
import render_dataset


def metrics_rows(text):
    """residue-cli denoise's metric table: {row: (relMSE, SSIM)} for the 'noisy' and 'denoised' rows."""
    rows = {}
    for line in text.splitlines():
        m = re.match(r"^(noisy|denoised)\s+(\S+)\s+\S+\s+\S+\s+(\S+)", line)
        if m:
            rows[m.group(1)] = (float(m.group(2)), float(m.group(3)))
    return rows


def check_scene(args, scene_dir, work):
    with open(os.path.join(scene_dir, "scene.json")) as f:
        doc = json.load(f)
    seed = doc["scene_seed"] if "scene_seed" in doc else int(os.path.basename(scene_dir)[1:])
    out = os.path.join(work, f"s{seed}")
    if not (args.reuse and os.path.isfile(os.path.join(out, "pseudo_input.exr"))):
        shutil.rmtree(out, ignore_errors=True)
        os.makedirs(out)
        # The last render of make_scene.py is a reference (Combined only): a 1-spp placeholder, unused.
        renders = f"{args.spp}:{render_dataset.SEEDS['pseudo']},1:{render_dataset.SEEDS['reference']}"
        cmd = render_dataset.make_scene_command(
            args.blender, args.threads, seed, renders, out, doc["resolution"][0],
            ["--names", "pseudo_input,placeholder"] + render_dataset.scene_flags(doc))
        with open(os.path.join(out, "blender.log"), "w") as logf:
            if subprocess.call(cmd, stdout=logf, stderr=subprocess.STDOUT) != 0:
                sys.exit(f"pseudo_reference_check: Blender failed on s{seed}, see {out}/blender.log")
    reference = os.path.join(scene_dir, "reference.exr")
    denoise = subprocess.run([args.cli, "denoise", os.path.join(out, "pseudo_input.exr"), "-m", args.model,
                              "--ensemble", str(args.ensemble), "-r", reference, "--threads", str(args.threads),
                              "--float", "--force", "-o", os.path.join(out, "pseudo_reference.exr")],
                             capture_output=True, text=True)
    rows = metrics_rows(denoise.stdout)
    if denoise.returncode != 0 or set(rows) != {"noisy", "denoised"}:
        sys.exit(f"pseudo_reference_check: residue-cli failed on s{seed}: {denoise.stderr.strip()}")
    raw, pseudo = rows["noisy"], rows["denoised"]
    c = raw[0] / (1.0 / args.spp + 1.0 / 1024)  # relMSE = c / spp for a raw render (noise only)
    e1024 = c / 1024
    # The same pseudo-reference with its low band from the raw render (render_dataset.py --pseudo-ref-low-band),
    # and each version's error split at 16 and 48 px (error_bands.py's split: the box mean of the relative error).
    raw_color = exr_metrics.layer_rgb(exr_metrics.read_exr(os.path.join(out, "pseudo_input.exr")))
    pseudo_color = exr_metrics.layer_rgb(exr_metrics.read_exr(os.path.join(out, "pseudo_reference.exr")), None)
    truth = exr_metrics.layer_rgb(exr_metrics.read_exr(reference))
    versions = {"raw": raw_color, "pseudo": pseudo_color,
                "restored": render_dataset.restore_low_band(pseudo_color, raw_color, args.low_band)}
    bands = {}
    for name, x in versions.items():
        e = (x - truth) / np.sqrt(truth * truth + exr_metrics.EPS)
        for w in (16, 48):
            bands[f"low{w}_{name}_vs_ref"] = float((exr_metrics.box_mean(e, w) ** 2).mean())
    return dict(bands, **{
        "scene": f"s{seed}",
        "kind": doc.get("kind"),
        "noisy_spp": doc["spp"]["noisy_a"],
        "relmse_raw_vs_ref": raw[0],
        "relmse_pseudo_vs_ref": pseudo[0],
        "ssim_pseudo_vs_ref": pseudo[1],
        "est_relmse_ref1024_vs_truth": e1024,
        "est_relmse_ref512_vs_truth": c / 512,
        "est_relmse_pseudo_vs_truth": max(pseudo[0] - e1024, 0.0),
        "relmse_restored_vs_ref": exr_metrics.relmse(versions["restored"], truth),
    })


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dataset")
    p.add_argument("--model", default="multiscale")
    p.add_argument("--spp", type=int, default=128)
    p.add_argument("--ensemble", type=int, default=8, choices=[1, 2, 4, 8])
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--blender", default="/usr/bin/blender")
    p.add_argument("--cli", default=render_dataset.DEFAULT_CLI)
    p.add_argument("--work", default="/tmp/residue-pseudo-check")
    p.add_argument("--low-band", type=int, default=16, metavar="PX",
                   help="also score the pseudo-reference with its PX x PX box-mean band from the raw render")
    p.add_argument("--scenes", help="comma-separated validation scenes to check (default: all of them)")
    p.add_argument("--reuse", action="store_true", help="keep a scene's render already in --work (re-denoised)")
    p.add_argument("--out", required=True, help="OUT.json and OUT.md are written")
    args = p.parse_args()
    with open(os.path.join(args.dataset, "index.json")) as f:
        scenes = [s["folder"] for s in json.load(f)["scenes"] if s["split"] == "validation"]
    if args.scenes:
        unknown = sorted(set(args.scenes.split(",")) - set(scenes))
        if unknown:
            sys.exit(f"pseudo_reference_check: {', '.join(unknown)} not among {args.dataset}'s validation scenes")
        scenes = [s for s in scenes if s in args.scenes.split(",")]
    if not scenes:
        sys.exit(f"pseudo_reference_check: {args.dataset} has no validation scenes in its index.json")
    results = []
    for name in scenes:
        results.append(check_scene(args, os.path.join(args.dataset, name), args.work))
        r = results[-1]
        print(f"{r['scene']} {r['kind']:8s} pseudo relMSE {r['relmse_pseudo_vs_ref']:.5f} SSIM "
              f"{r['ssim_pseudo_vs_ref']:.4f}  raw {args.spp} spp {r['relmse_raw_vs_ref']:.5f}  est. vs truth: "
              f"pseudo {r['est_relmse_pseudo_vs_truth']:.5f}, 512 spp {r['est_relmse_ref512_vs_truth']:.5f}",
              flush=True)
    keys = ["relmse_pseudo_vs_ref", "ssim_pseudo_vs_ref", "relmse_raw_vs_ref", "est_relmse_ref1024_vs_truth",
            "est_relmse_ref512_vs_truth", "est_relmse_pseudo_vs_truth", "relmse_restored_vs_ref"] + \
        [f"low{w}_{n}_vs_ref" for w in (16, 48) for n in ("raw", "pseudo", "restored")]
    mean = {k: sum(r[k] for r in results) / len(results) for k in keys}
    with open(args.out + ".json", "w") as f:
        json.dump({"dataset": os.path.abspath(args.dataset), "model": args.model, "spp": args.spp,
                   "ensemble": args.ensemble, "low_band": args.low_band, "scenes": results, "mean": mean}, f,
                  indent=1)
    with open(args.out + ".md", "w") as f:
        f.write(f"Pseudo-references ({args.spp} spp denoised by `{args.model}` x{args.ensemble}) against the true "
                f"1024-spp references of `{os.path.basename(os.path.abspath(args.dataset))}`'s validation scenes "
                f"(`tools/datagen/pseudo_reference_check.py`). Estimated distances to the truth assume relMSE = "
                f"c / spp for a raw render. Restored: the pseudo-reference with its {args.low_band}-px box-mean "
                f"band from the raw render (render_dataset.py --pseudo-ref-low-band). Low 16 / 48: the mean "
                f"square of the relative error's 16- and 48-px box means, as in tools/research/error_bands.py.\n\n")
        f.write("| scene | kind | noisy spp | pseudo relMSE / SSIM vs ref | raw relMSE vs ref | est. vs truth: "
                "1024 spp | 512 spp | pseudo | restored relMSE vs ref | low 48: raw / pseudo / restored |\n"
                "|---|---|---|---|---|---|---|---|---|---|\n")
        for r in results + [dict(mean, scene="mean", kind="", noisy_spp="")]:
            f.write(f"| {r['scene']} | {r['kind']} | {r['noisy_spp']} | {r['relmse_pseudo_vs_ref']:.5f} / "
                    f"{r['ssim_pseudo_vs_ref']:.4f} | {r['relmse_raw_vs_ref']:.5f} | "
                    f"{r['est_relmse_ref1024_vs_truth']:.5f} | {r['est_relmse_ref512_vs_truth']:.5f} | "
                    f"{r['est_relmse_pseudo_vs_truth']:.5f} | {r['relmse_restored_vs_ref']:.5f} | "
                    f"{r['low48_raw_vs_ref']:.6f} / {r['low48_pseudo_vs_ref']:.6f} / "
                    f"{r['low48_restored_vs_ref']:.6f} |\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
