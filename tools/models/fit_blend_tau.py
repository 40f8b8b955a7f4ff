#!/usr/bin/python3
"""Fits a model's variance-blend tau on a data set's validation scenes and writes it into the model file
("residue.blend_tau", read by core/denoise/variance_blend). tau stands for the network's own relative error:
a better model should keep more of its output, so each model gets its own. For every candidate tau this runs
`residue-cli evaluate-set --split validation --blend-tau TAU` (the scenes' variance comes from their two
halves) and keeps, among the taus whose mean SSIM is within --max-ssim-loss of the sweep's best, the smallest
whose mean relMSE is within --relmse-tolerance of the lowest: a larger tau keeps more of the noisy input, so
relMSE can fall while visible noise comes back (SSIM sees it), and a tau that buys no clear gain on these scenes
only risks it on others. tau 0 is no blend at all (a model better than its input everywhere: the blend can
only add noise back), the smallest candidate. Prints the whole sweep.

  /usr/bin/python3 tools/models/fit_blend_tau.py resources/models/base.safetensors /work/datasets/residue-v1 \\
      [--taus 0,0.0001,0.0003,0.001,0.003,0.01] [--last N (a data set without index.json: its last N scenes)] [--max-ssim-loss 0.005] [--relmse-tolerance 0.005] [--cli build/release/app/residue-cli/residue-cli] [--dry-run]
"""
import argparse, json, os, sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from evaluate_mean import mean_scores, near_best  # noqa: E402
from safetensors_meta import read_header, write_header  # noqa: E402


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("model")
    p.add_argument("dataset")
    p.add_argument("--taus", default="0,0.0001,0.0003,0.001,0.003,0.01")
    p.add_argument("--last", type=int, default=0, help="score the last N scenes (a data set without index.json)")
    p.add_argument("--cli", default=os.path.join(here, "..", "build", "release", "app", "residue-cli", "residue-cli"))
    p.add_argument("--max-ssim-loss", type=float, default=0.005,
                   help="a tau may cost at most this much mean SSIM against the sweep's best")
    p.add_argument("--relmse-tolerance", type=float, default=0.005,
                   help="relative: a smaller tau is kept when its mean relMSE is within this of the lowest")
    p.add_argument("--dry-run", action="store_true", help="print the sweep, leave the model file as it is")
    a = p.parse_args()

    sweep = []
    scenes = ["--last", str(a.last)] if a.last > 0 else ["--split", "validation"]
    for tau in [float(t) for t in a.taus.split(",")]:
        blend = ["--blend-tau", str(tau)] if tau > 0 else ["--variance-blend", "off"]
        relmse, ssim = mean_scores(a.cli, a.dataset, a.model, scenes, blend)
        sweep.append((relmse, tau, ssim))
        print(f"tau {tau:<8g} mean relMSE {relmse:.5f}  SSIM {ssim:.4f}", flush=True)
    near, lowest, best_ssim = near_best(sweep, a.max_ssim_loss, a.relmse_tolerance)
    best = min(near, key=lambda r: r[1])
    print(f"best tau {best[1]:g} (mean relMSE {best[0]:.5f}, SSIM {best[2]:.4f}; the smallest tau within "
          f"{a.relmse_tolerance:g} of the lowest relMSE, {lowest:.5f}, among those within {a.max_ssim_loss:g} "
          f"of the best SSIM, {best_ssim:.4f})")
    if a.dry_run:
        return
    header, data = read_header(a.model)
    meta = header.setdefault("__metadata__", {})
    meta["residue.blend_tau"] = f"{best[1]:g}"
    meta["blend_tau_fit"] = json.dumps({"dataset": os.path.abspath(a.dataset),
                                        "split": f"last {a.last}" if a.last > 0 else "validation",
                                        "max_ssim_loss": a.max_ssim_loss, "relmse_tolerance": a.relmse_tolerance,
                                        "sweep": [{"tau": t, "relmse": r, "ssim": s} for r, t, s in sweep]})
    write_header(a.model, header, data)
    print(f"wrote residue.blend_tau = {best[1]:g} into {a.model}")


if __name__ == "__main__":
    main()
