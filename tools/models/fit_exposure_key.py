#!/usr/bin/python3
"""Fits the exposure key a model runs at on a data set's validation scenes and writes it into the model file
("residue.autoexposure", "residue.exposure_key", read by core/nn/model_file.cpp). An autoexposed model scales each
render so that its log-average luminance lands on the key before the log (docs/research/MODELS_HISTORY.md, lever 3b). The key it was
trained at need not be the one it denoises best at (`multiscale`, trained at 1, measured 0.8 % lower relMSE at
1.4), and a model trained without autoexposure may denoise better with it (`base`: 3 % lower relMSE at 0.6, the
Cornell box 1.8x lower): lever 3d, issue 16, 2026-11-28. The candidate `off` is the model without autoexposure (the
default candidates include it for a model trained so). For every candidate this runs `residue-cli evaluate-set
--split validation` on a copy of the model so set, and keeps, among the candidates whose mean SSIM is within
--max-ssim-loss of the sweep's best and whose mean relMSE is within --relmse-tolerance of the lowest, the one with
the highest SSIM. Prints the whole sweep and records it (`exposure_key_fit`, with the setting the model was trained
at).

  /usr/bin/python3 tools/models/fit_exposure_key.py resources/models/multiscale.safetensors .cache/datasets/residue-v1 \\
      [--keys 0.7,1,1.2,1.4,1.6,2,2.5 (a model without autoexposure: off,0.3,0.45,0.6,0.8,1,1.4)]
      [--max-ssim-loss 0.0005] [--relmse-tolerance 0.001] [--dry-run]
"""
import argparse, copy, json, os, sys, tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from evaluate_mean import mean_scores, near_best  # noqa: E402
from safetensors_meta import read_header, write_header  # noqa: E402


def set_key(meta, key):
    """Model metadata set to run at key (None: without autoexposure)."""
    meta.pop("residue.exposure_key", None)
    meta["residue.autoexposure"] = "0" if key is None else "1"
    if key is not None:
        meta["residue.exposure_key"] = f"{key:g}"


def write_with_key(header, data, dst, key):
    """A model file (read_header's header and data) written to dst set to run at key; the header is left as it is."""
    header = copy.deepcopy(header)
    set_key(header.setdefault("__metadata__", {}), key)
    write_header(dst, header, data)


def parse_keys(text):
    keys = []
    for k in text.split(","):
        try:
            keys.append(None if k == "off" else float(k))
        except ValueError:
            sys.exit(f"fit_exposure_key: --keys: {k!r} is neither a positive number nor 'off'")
        if keys[-1] is not None and not keys[-1] > 0:
            sys.exit(f"fit_exposure_key: --keys: {k} is not a positive number")
    return keys


def name(key):
    return "off" if key is None else f"{key:g}"


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("model")
    p.add_argument("dataset")
    p.add_argument("--keys", help="comma-separated keys, 'off' for none (default: by the model's training, above)")
    p.add_argument("--cli", default=os.path.join(here, "..", "build", "release", "app", "residue-cli", "residue-cli"))
    p.add_argument("--max-ssim-loss", type=float, default=0.0005,
                   help="a key may cost at most this much mean SSIM against the sweep's best")
    p.add_argument("--relmse-tolerance", type=float, default=0.001,
                   help="relative: keys within this of the lowest mean relMSE count as equal; the highest SSIM wins")
    p.add_argument("--dry-run", action="store_true", help="print the sweep, leave the model file as it is")
    a = p.parse_args()

    header, data = read_header(a.model)
    meta = header.setdefault("__metadata__", {})
    # What the model was trained at: kept from an earlier fit, which changed the file's own setting.
    earlier = json.loads(meta.get("exposure_key_fit", "{}")).get("trained")
    trained = earlier or (name(float(meta.get("residue.exposure_key", "0.18")))
                          if meta.get("residue.autoexposure") == "1" else "off")
    keys = parse_keys(a.keys or ("off,0.3,0.45,0.6,0.8,1,1.4" if trained == "off" else "0.7,1,1.2,1.4,1.6,2,2.5"))
    sweep = []
    with tempfile.TemporaryDirectory() as tmp:
        for key in keys:
            candidate = os.path.join(tmp, "candidate.safetensors")
            write_with_key(header, data, candidate, key)
            relmse, ssim = mean_scores(a.cli, a.dataset, candidate)
            sweep.append((relmse, key, ssim))
            print(f"key {name(key):<6} mean relMSE {relmse:.6f}  SSIM {ssim:.5f}", flush=True)
    near, lowest, best_ssim = near_best(sweep, a.max_ssim_loss, a.relmse_tolerance)
    best = max(near, key=lambda r: r[2])
    print(f"best key {name(best[1])} (mean relMSE {best[0]:.6f}, SSIM {best[2]:.5f}; the highest SSIM among the keys "
          f"within {a.relmse_tolerance:g} of the lowest relMSE, {lowest:.6f}, and {a.max_ssim_loss:g} of the best "
          f"SSIM, {best_ssim:.5f})")
    if a.dry_run:
        return
    set_key(meta, best[1])
    meta["exposure_key_fit"] = json.dumps({"dataset": os.path.abspath(a.dataset), "split": "validation",
                                           "trained": trained, "chosen": name(best[1]),
                                           "max_ssim_loss": a.max_ssim_loss, "relmse_tolerance": a.relmse_tolerance,
                                           "sweep": [{"key": name(k), "relmse": r, "ssim": s} for r, k, s in sweep]})
    write_header(a.model, header, data)
    print(f"wrote exposure key {name(best[1])} into {a.model} (trained at {trained})")


if __name__ == "__main__":
    main()
