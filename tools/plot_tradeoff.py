#!/usr/bin/python3
"""The speed-versus-accuracy plot of an `evaluate-set --json` result: one point per model and precision,
seconds per megapixel against mean relMSE (left) and mean SSIM (right), the noisy input as a line. This is the
measured trade users pick from (docs/MODELS.md).

  /usr/bin/python3 tools/plot_tradeoff.py eval.json tradeoff.png [--title TEXT] [--models tiny,small,base]

--models keeps only those columns (the label without its precision): the feature-set variants serve renders
that lack AOVs, so they are not a choice on the same data and only crowd the plot.
"""
import argparse, json
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("json")
    p.add_argument("png")
    p.add_argument("--title", default="")
    p.add_argument("--models", default="", help="comma-separated labels to plot (default: all)")
    a = p.parse_args()
    d = json.load(open(a.json))
    rows = d["summary"]
    noisy = next(r for r in rows if r["label"] == "noisy")
    keep = set(filter(None, a.models.split(",")))
    points = [r for r in rows if r["label"] != "noisy"
              and (not keep or r["label"].rsplit(" ", 1)[0] in keep or r["label"] in keep)]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, key, name in ((axes[0], "mean_relmse", "mean relMSE (lower is better)"),
                          (axes[1], "mean_ssim", "mean SSIM (higher is better)")):
        for r in points:
            bf16 = r["precision"] == "bf16"
            marker = "s" if r["model"] == "bilateral" else ("^" if bf16 else "o")
            ax.scatter(r["seconds_per_megapixel"], r[key], marker=marker, s=60,
                       facecolors="none" if bf16 else None, edgecolors="C0" if bf16 else None,
                       color=None if bf16 else ("C3" if r["model"] == "bilateral" else "C0"))
            ax.annotate(r["label"], (r["seconds_per_megapixel"], r[key]), textcoords="offset points",
                        xytext=(6, 4), fontsize=8)
        ax.axhline(noisy[key], color="0.5", linestyle="--", linewidth=1)
        ax.text(0.02, noisy[key], f"noisy input {noisy[key]:.3g}", transform=ax.get_yaxis_transform(),
                fontsize=8, color="0.4", va="bottom")
        ax.set_xscale("log")
        if key == "mean_relmse":
            ax.set_yscale("log")
        ax.set_xlabel("seconds per megapixel (this machine, whole scenes)")
        ax.set_ylabel(name)
        ax.grid(True, which="both", alpha=0.3)
    n = len(d["scenes"])
    fig.suptitle(a.title or f"speed against accuracy, {n} scenes of {d['dataset'].rstrip('/').split('/')[-1]}",
                 fontsize=11)
    fig.tight_layout()
    fig.savefig(a.png, dpi=110)
    print(f"wrote {a.png}")

if __name__ == "__main__":
    main()
