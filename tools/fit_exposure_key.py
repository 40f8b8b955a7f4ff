#!/usr/bin/python3
"""Fits an autoexposed model's exposure key on a data set's validation scenes and writes it into the model file
("residue.exposure_key", read by core/nn/model_file.cpp). An autoexposed model scales each render so that its
log-average luminance lands on the key before the log (MODELS.md, lever 3b); the key it was trained at need not be
the one it denoises best at: `multiscale`, trained at 1, measured 0.8 % lower relMSE at 1.4 (issue 16, session 21).
For every candidate key this runs `residue-cli evaluate-set --split validation` on a copy of the model with that
key, and keeps, among the keys whose mean SSIM is within --max-ssim-loss of the sweep's best and whose mean relMSE
is within --relmse-tolerance of the lowest, the one with the highest SSIM. Prints the whole sweep; the model's
`training` metadata keeps the key it was trained at.

  /usr/bin/python3 tools/fit_exposure_key.py resources/models/multiscale.safetensors .cache/datasets/residue-v1 \\
      [--keys 0.7,1,1.2,1.4,1.6,2,2.5] [--max-ssim-loss 0.0005] [--relmse-tolerance 0.001] [--dry-run]
"""
import argparse, json, os, shutil, subprocess, sys, tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from safetensors_meta import read_header, write_header  # noqa: E402


def with_key(src, dst, key):
    """A copy of the model file src at dst, its exposure key set to key."""
    shutil.copyfile(src, dst)
    header, data = read_header(dst)
    header["__metadata__"]["residue.exposure_key"] = f"{key:g}"
    write_header(dst, header, data)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("model")
    p.add_argument("dataset")
    p.add_argument("--keys", default="0.7,1,1.2,1.4,1.6,2,2.5")
    p.add_argument("--cli", default=os.path.join(here, "..", "build", "release", "app", "residue-cli", "residue-cli"))
    p.add_argument("--max-ssim-loss", type=float, default=0.0005,
                   help="a key may cost at most this much mean SSIM against the sweep's best")
    p.add_argument("--relmse-tolerance", type=float, default=0.001,
                   help="relative: keys within this of the lowest mean relMSE count as equal; the highest SSIM wins")
    p.add_argument("--dry-run", action="store_true", help="print the sweep, leave the model file as it is")
    a = p.parse_args()

    header, _ = read_header(a.model)
    meta = header.get("__metadata__", {})
    if meta.get("residue.autoexposure") != "1":
        sys.exit(f"fit_exposure_key: {a.model} is not autoexposed (metadata residue.autoexposure): it has no key")
    sweep = []
    with tempfile.TemporaryDirectory() as tmp:
        for key in [float(k) for k in a.keys.split(",")]:
            if key <= 0:
                sys.exit(f"fit_exposure_key: --keys: {key:g} is not a positive number")
            copy, out = os.path.join(tmp, "candidate.safetensors"), os.path.join(tmp, "eval.json")
            with_key(a.model, copy, key)
            subprocess.run([a.cli, "evaluate-set", a.dataset, "--split", "validation", "--models", copy,
                            "--json", out, "--force"], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            summary = {r["label"]: r for r in json.load(open(out))["summary"]}["candidate"]
            sweep.append((summary["mean_relmse"], key, summary["mean_ssim"]))
            print(f"key {key:<6g} mean relMSE {sweep[-1][0]:.6f}  SSIM {sweep[-1][2]:.5f}", flush=True)
    best_ssim = max(s for _, _, s in sweep)
    eligible = [r for r in sweep if r[2] >= best_ssim - a.max_ssim_loss]
    lowest = min(r[0] for r in eligible)
    best = max((r for r in eligible if r[0] <= lowest * (1 + a.relmse_tolerance)), key=lambda r: r[2])
    print(f"best key {best[1]:g} (mean relMSE {best[0]:.6f}, SSIM {best[2]:.5f}; the highest SSIM among the keys "
          f"within {a.relmse_tolerance:g} of the lowest relMSE, {lowest:.6f}, and {a.max_ssim_loss:g} of the best "
          f"SSIM, {best_ssim:.5f})")
    if a.dry_run:
        return
    header, data = read_header(a.model)
    meta = header.setdefault("__metadata__", {})
    meta["residue.exposure_key"] = f"{best[1]:g}"
    meta["exposure_key_fit"] = json.dumps({"dataset": os.path.abspath(a.dataset), "split": "validation",
                                           "max_ssim_loss": a.max_ssim_loss, "relmse_tolerance": a.relmse_tolerance,
                                           "sweep": [{"key": k, "relmse": r, "ssim": s} for r, k, s in sweep]})
    write_header(a.model, header, data)
    print(f"wrote residue.exposure_key = {best[1]:g} into {a.model}")


if __name__ == "__main__":
    main()
