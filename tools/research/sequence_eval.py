#!/usr/bin/python3
"""Sequence evaluation over a shot data set's validation shots (issue 51): every model denoises every frame of
every validation shot (`residue-cli denoise noisy.####.exr`, a temporal model with its neighbours), `residue-cli
eval` scores each sequence (per-frame relMSE and SSIM, the temporal relMSE in both forms, core/metrics/temporal.h),
and a table per model: the means over the shots, the temporal error against per-frame `multiscale`'s, s/MP.

    /usr/bin/python3 tools/research/sequence_eval.py /work/datasets/residue-shots-v1 \\
        --models multiscale,oidn,bilateral,multiscale-temporal --out docs/research/temporal/eval_shots_v1

A model is a name or file, as -m takes it; NAME+blend (or NAME+blend0.25, a tolerance) runs it with
--temporal-blend. Outputs go to a work folder (--work, reused: a sequence already
denoised is not denoised again unless --redo); OUT.json holds every number and OUT.md the table.
"""
import argparse
import json
import math
import os
import platform
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"sequence_eval: {' '.join(cmd)} failed ({r.returncode}):\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
    return r.stdout


def cpu_name():
    try:
        with open("/proc/cpuinfo") as f:
            info = f.read()
        name = next(l.split(":", 1)[1].strip() for l in info.splitlines() if l.startswith("model name"))
        family = next(l.split(":", 1)[1].strip() for l in info.splitlines() if l.startswith("cpu family"))
        return f"{name} (family {family}), {os.cpu_count()} cores"
    except (OSError, StopIteration):
        return platform.processor() or "unknown CPU"


def split_blend(model):
    """'NAME+blend' or 'NAME+blend0.25': the model and the --temporal-blend options it is run with."""
    name, plus, blend = model.partition("+blend")
    if not plus:
        return model, []
    return name, ["--temporal-blend"] + (["--blend-tolerance", blend] if blend else [])


def label(model):
    name, extra = split_blend(model)
    base = os.path.splitext(os.path.basename(name))[0] if name.endswith(".safetensors") else name
    return base + model[len(name):] if extra else base


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shots", help="a shot data set (tools/datagen/render_shots.py: index.json, s<seed>/)")
    ap.add_argument("--models", required=True, help="comma-separated: names or .safetensors files, as -m takes them")
    ap.add_argument("--out", required=True, help="OUT.json and OUT.md are written")
    ap.add_argument("--work", default="/tmp/residue-sequence-eval")
    ap.add_argument("--cli", default=os.path.join(ROOT, "build/release/app/residue-cli/residue-cli"))
    ap.add_argument("--split", default="validation", choices=("validation", "train"))
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--redo", action="store_true")
    a = ap.parse_args()

    with open(os.path.join(a.shots, "index.json")) as f:
        index = json.load(f)
    shots = [s for s in index["shots"] if s["split"] == a.split]
    if not shots:
        sys.exit(f"sequence_eval: {a.shots} has no {a.split} shots")
    models = a.models.split(",")
    # The references' own noise (tools/datagen/second_references.py): relMSE(r_b, r) = 2 s2 and temporal(r_b, r) =
    # 4 s2, so a score's floor is half the pair's; a shot without second references has none.
    floors = {}
    for s in shots:
        shot_dir = os.path.join(a.shots, s["folder"])
        if all(os.path.isfile(os.path.join(shot_dir, f"reference_b.{f:04d}.exr")) for f in range(1, s["frames"] + 1)):
            ev = json.loads(run([a.cli, "eval", os.path.join(shot_dir, "noisy.####.exr"), "-r",
                                 os.path.join(shot_dir, "reference.####.exr"), "-d",
                                 os.path.join(shot_dir, "reference_b.####.exr"), "--json"]))
            floors[s["folder"]] = {"relmse": ev["mean"]["denoised"]["relmse"] / 2,
                                   "temporal": ev["temporal_relmse_symmetric"]["denoised"] / 2,
                                   "along_motion": ev["temporal_relmse_compensated"]["denoised"] / 2}
    results = {"data": os.path.abspath(a.shots), "split": a.split, "cpu": cpu_name(), "models": {}}
    for m in models:
        per_shot = []
        for s in shots:
            shot_dir = os.path.join(a.shots, s["folder"])
            out_dir = os.path.join(a.work, label(m), s["folder"])
            os.makedirs(out_dir, exist_ok=True)
            summary = os.path.join(out_dir, "summary.json")
            if a.redo or not os.path.exists(summary):
                name, blend = split_blend(m)
                cmd = [a.cli, "denoise", os.path.join(shot_dir, "noisy.####.exr"), "-o",
                       os.path.join(out_dir, "den.####.exr"), "-m", name, "--summary", summary, "--force"] + blend
                if a.threads:
                    cmd += ["--threads", str(a.threads)]
                run(cmd)
            with open(summary) as f:
                den = json.load(f)
            ev = json.loads(run([a.cli, "eval", os.path.join(shot_dir, "noisy.####.exr"), "-r",
                                 os.path.join(shot_dir, "reference.####.exr"), "-d",
                                 os.path.join(out_dir, "den.####.exr"), "--json"]))
            per_shot.append({
                "shot": s["folder"], "kind": s.get("kind"), "move": s.get("shot"), "spp": s.get("spp"),
                "frames": ev["frames_scored"],
                "relmse": ev["mean"]["denoised"]["relmse"], "ssim": ev["mean"]["denoised"]["ssim"],
                "noisy_relmse": ev["mean"]["noisy"]["relmse"],
                "temporal": ev["temporal_relmse_symmetric"]["denoised"],
                "temporal_noisy": ev["temporal_relmse_symmetric"]["noisy"],
                "temporal_asymmetric": ev["temporal_relmse"]["denoised"],
                # the error's change on each surface, frame t-1's warped to t (not its motion across pixels)
                "along_motion": ev.get("temporal_relmse_compensated", {}).get("denoised"),
                "s_per_mp": den["s_per_mp"],
                # relMSE on the pixels a neighbouring frame does not show (ghosting would show here)
                "disoccluded": ev.get("disoccluded", {}).get("denoised_relmse"),
                "disoccluded_pixels": ev.get("disoccluded", {}).get("pixels", 0),
            })
            if s["folder"] in floors:  # the score above the references' own noise
                f = floors[s["folder"]]
                per_shot[-1]["floor"] = f
                per_shot[-1]["relmse_above_floor"] = per_shot[-1]["relmse"] - f["relmse"]
                per_shot[-1]["temporal_above_floor"] = per_shot[-1]["temporal"] - f["temporal"]
                per_shot[-1]["along_motion_above_floor"] = per_shot[-1]["along_motion"] - f["along_motion"]
            print(f"{label(m):24s} {s['folder']}  relMSE {per_shot[-1]['relmse']:.5f}  SSIM {per_shot[-1]['ssim']:.4f}"
                  f"  temporal {per_shot[-1]['temporal']:.5f}  {den['s_per_mp']:.2f} s/MP", flush=True)
        n = len(per_shot)
        mean = {k: sum(p[k] for p in per_shot) / n for k in ("relmse", "ssim", "temporal", "temporal_asymmetric", "s_per_mp")}
        mean["along_motion"] = (sum(p["along_motion"] for p in per_shot) / n
                                if all(p["along_motion"] is not None for p in per_shot) else None)
        # disoccluded pixels: every shot's pooled, weighted by its count
        px = sum(p["disoccluded_pixels"] for p in per_shot)
        mean["disoccluded"] = (sum(p["disoccluded"] * p["disoccluded_pixels"] for p in per_shot if p["disoccluded"] is not None)
                               / px) if px else None
        results["models"][label(m)] = {"model": m, "mean": mean, "per_shot": per_shot}

    base = results["models"].get("multiscale")
    oidn = results["models"].get("oidn")
    # Shots differ by orders of magnitude in error (a dim interior at 4 spp against an open-air shot at 32): the
    # means are led by the worst shot, so the ratios are also given shot by shot and averaged geometrically.
    def shot_ratio(r, ref, k):
        if not ref:
            return None
        logs = [math.log(p[k] / q[k]) for p, q in zip(r["per_shot"], ref["per_shot"]) if p[k] and q[k] and p[k] > 0 and q[k] > 0]
        return math.exp(sum(logs) / len(logs)) if logs else None

    for r in results["models"].values():
        r["per_shot_ratio"] = {"temporal_vs_multiscale": shot_ratio(r, base, "temporal"),
                               "temporal_vs_oidn": shot_ratio(r, oidn, "temporal"),
                               "relmse_vs_oidn": shot_ratio(r, oidn, "relmse"),
                               "disoccluded_vs_multiscale": shot_ratio(r, base, "disoccluded"),
                               "along_motion_vs_multiscale": shot_ratio(r, base, "along_motion")}
    lines = [f"Validation shots of `{os.path.basename(os.path.normpath(a.shots))}` ({len(shots)} shots, "
             f"{sum(p['frames'] for p in next(iter(results['models'].values()))['per_shot'])} frames), "
             f"{results['cpu']}. Means over the shots; temporal: the symmetric temporal relMSE (core/metrics/temporal.h), "
             "the change of the error between consecutive frames at each pixel.", "",
             "Ratios: of the means, and in brackets the geometric mean of the shots' own ratios. s/MP: the denoise's "
             "own time as its run's summary says, on a machine that may have been doing other work: the speeds to "
             "compare are `residue-cli bench`'s.", "",
             "Along the motion: the temporal relMSE with frame t-1's error warped to t (`residue-cli eval`'s "
             "`temporal_relmse_compensated`), on the pixels t-1 shows: how the error on each surface changes, not "
             "its motion across the pixels.", "",
             "Disoccluded: relMSE on the pixels that frame t-1 or t+1 does not show (`residue-cli eval` on a sequence: "
             "off screen, or another depth or normal there), pooled over the shots; where a temporal model would ghost.", "",
             "| model | relMSE | SSIM | temporal | temporal / `multiscale`'s | temporal / `oidn`'s | relMSE / `oidn`'s | "
             "along the motion | along / `multiscale`'s | disoccluded | disoccluded / `multiscale`'s | s/MP |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, r in results["models"].items():
        m = r["mean"]
        pr = r["per_shot_ratio"]

        def rel(ref, k, key):
            return f"{m[k] / ref['mean'][k]:.2f} ({pr[key]:.2f})" if ref and pr[key] else ""
        lines.append(f"| `{name}` | {m['relmse']:.5f} | {m['ssim']:.4f} | {m['temporal']:.5f} | {rel(base, 'temporal', 'temporal_vs_multiscale')} | "
                     f"{rel(oidn, 'temporal', 'temporal_vs_oidn')} | {rel(oidn, 'relmse', 'relmse_vs_oidn')} | "
                     f"{m['along_motion'] or 0:.5f} | {rel(base, 'along_motion', 'along_motion_vs_multiscale')} | "
                     f"{m['disoccluded'] or 0:.5f} | {rel(base, 'disoccluded', 'disoccluded_vs_multiscale')} | {m['s_per_mp']:.2f} |")
    lines += ["", "Per shot (relMSE / SSIM / temporal):", "",
              "| model | " + " | ".join(f"{p['shot']} ({p['kind']}, {p['move']}, {p['spp']} spp)"
                                      for p in next(iter(results['models'].values()))['per_shot']) + " |",
              "|---|" + "---|" * len(shots)]
    for name, r in results["models"].items():
        lines.append(f"| `{name}` | " + " | ".join(f"{p['relmse']:.4f} / {p['ssim']:.3f} / {p['temporal']:.4f}"
                                                  for p in r["per_shot"]) + " |")
    if floors:
        lines += ["", f"Above the references' floor (the {len(floors)} shots with second references, "
                      "tools/datagen/second_references.py: each score minus half its reference pair's):", "",
                  "| model | " + " | ".join(f"{f}: relMSE / temporal" for f in floors) +
                  " | temporal above the floor / `multiscale`'s (geometric mean) |",
                  "|---|" + "---|" * (len(floors) + 1)]
        for name, r in results["models"].items():
            cells = {p["shot"]: p for p in r["per_shot"] if "floor" in p}
            ratios = [cells[f]["temporal_above_floor"] / q["temporal_above_floor"]
                      for f in floors for q in base["per_shot"] if q["shot"] == f
                      and q["temporal_above_floor"] > 0 and cells[f]["temporal_above_floor"] > 0] if base else []
            g = math.exp(sum(math.log(x) for x in ratios) / len(ratios)) if ratios else None
            r["temporal_above_floor_vs_multiscale"] = g
            lines.append(f"| `{name}` | " + " | ".join(f"{cells[f]['relmse_above_floor']:.5f} / "
                                                      f"{cells[f]['temporal_above_floor']:.5f}" for f in floors) +
                         (f" | {g:.2f} |" if g else " | |"))
        results["floors"] = floors
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    with open(a.out + ".json", "w") as f:
        json.dump(results, f, indent=1)
    with open(a.out + ".md", "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
