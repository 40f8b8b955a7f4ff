#!/usr/bin/python3
"""The speed-versus-accuracy plot of an `evaluate-set --json` result: one point per model and precision,
seconds per megapixel against mean relMSE (left) and mean SSIM (right), the noisy input's values named above
the panels. This is the measured trade users pick from (docs/MODELS.md).

  /usr/bin/python3 tools/models/plot_tradeoff.py eval.json tradeoff.png [--title TEXT] [--models tiny,small,base]

--models keeps only those columns (the label without its precision): the feature-set variants serve renders
that lack AOVs, so they are not a choice on the same data and only crowd the plot. --speed cards takes each
model's seconds per megapixel from its card (`residue-cli models --json`: benchmarked warm on a 1024-px image, on
an idle machine) instead of the evaluation's own timing of small whole scenes, which a busy machine or a model's
first run skews; a model without a benchmark (the bilateral filter) keeps the evaluation's.
"""
import argparse, json, math, os, subprocess, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from safetensors_meta import metadata  # noqa: E402

def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("json")
    p.add_argument("png")
    p.add_argument("--title", default="")
    p.add_argument("--models", default="", help="comma-separated labels to plot (default: all)")
    p.add_argument("--speed", choices=["eval", "cards"], default="eval")
    p.add_argument("--cli", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "build", "release",
                                                 "app", "residue-cli", "residue-cli"))
    a = p.parse_args()
    d = json.load(open(a.json))
    rows = d["summary"]
    speed_note = "this machine, whole scenes"
    if a.speed == "cards":
        out = subprocess.run([a.cli, "models", "--json"], check=True, capture_output=True, text=True).stdout
        cards = {c["family"]: c.get("benchmark") or {} for c in json.loads(out[out.index("["):])}
        for r in rows:
            # A model given as a file (a variant has no card of its own): the benchmark its metadata records.
            bench = json.loads(metadata(r["model"]).get("benchmark", "{}")) if os.path.isfile(r["model"]) \
                else cards.get(r["model"], {})
            s = bench.get(f"{r['precision']}_s_per_mp")
            if s:
                r["seconds_per_megapixel"] = s
        speed_note = "benchmarked: the model cards"
    noisy = next(r for r in rows if r["label"] == "noisy")
    keep = set(filter(None, a.models.split(",")))
    points = [r for r in rows if r["label"] != "noisy"
              and (not keep or r["label"].rsplit(" ", 1)[0] in keep or r["label"] in keep)]
    # One colour per model, a filled circle for fp32 and a hollow triangle for bf16, named in one legend:
    # labels written beside the points collide where models are close (the base family).
    # Red is the bilateral baseline's; the networks take the other default colours in the order they appear.
    palette = iter(f"C{k}" for k in range(10) if k != 3)
    colour = {m: "C3" if m == "bilateral" else next(palette) for m in dict.fromkeys(r["model"] for r in points)}
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    for ax, key, name in ((axes[0], "mean_relmse", "mean relMSE (lower is better)"),
                          (axes[1], "mean_ssim", "mean SSIM (higher is better)")):
        for r in points:
            bf16 = r["precision"] == "bf16"
            c = colour[r["model"]]
            # Baselines that are not Residue's networks stand apart: squares for the bilateral filter, diamonds
            # for Open Image Denoise's networks.
            marker = "s" if r["model"] == "bilateral" else "D" if r["model"].startswith("oidn") else ("^" if bf16 else "o")
            ax.scatter(r["seconds_per_megapixel"], r[key], marker=marker, s=60, label=r["label"],
                       facecolors="none" if bf16 else c, edgecolors=c, linewidths=1.5)
        # The noisy input is far off the models' range (25x their relMSE): named, not drawn, so that the
        # differences between models stay visible.
        ax.set_title(f"noisy input: {noisy[key]:.3g}", fontsize=9, color="0.4")
        ax.margins(0.08)
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
        # Minor labels at 2 and 5 times a power of ten only: the times span two decades (0.5 to 26 s/MP).
        ax.xaxis.set_minor_formatter(matplotlib.ticker.FuncFormatter(
            lambda v, _: f"{v:g}" if round(v / 10 ** math.floor(math.log10(v))) in (2, 5) else ""))
        ax.tick_params(axis="both", which="both", labelsize=8)
        if key == "mean_relmse":
            ax.set_yscale("log")
            ax.yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
            ax.yaxis.set_minor_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
        ax.set_xlabel(f"seconds per megapixel ({speed_note})")
        ax.set_ylabel(name)
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 6), fontsize=8, frameon=False)
    n = len(d["scenes"])
    fig.suptitle(a.title or f"speed against accuracy, {n} scenes of {d['dataset'].rstrip('/').split('/')[-1]}",
                 fontsize=11)
    legend_rows = math.ceil(len(labels) / min(len(labels), 6))
    fig.tight_layout(rect=(0, 0.02 + 0.045 * legend_rows, 1, 1))
    fig.savefig(a.png, dpi=110)
    print(f"wrote {a.png}")

if __name__ == "__main__":
    main()
