#!/usr/bin/python3
"""Plots a residue-train CSV log: training loss and validation relMSE / SSIM against steps. tools/models/torch_train.py's
log has the same columns less the noisy relMSE and SSIM; those lines are drawn where present.

    /usr/bin/python3 tools/models/plot_training.py LOG.csv OUT.png [--title TITLE]

Needs Debian's python3-matplotlib (apt-get install python3-matplotlib).
"""
import argparse
import csv

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    p = argparse.ArgumentParser()
    p.add_argument("log")
    p.add_argument("out")
    p.add_argument("--title", default="")
    a = p.parse_args()
    rows = list(csv.DictReader(open(a.log)))
    steps = [int(r["step"]) for r in rows]
    loss = [float(r["loss"]) for r in rows]
    val = [r for r in rows if r["val_relmse"]]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6))
    for ax in (ax1, ax2):  # at most 6 step labels: five-digit step counts would run into each other
        ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(6, integer=True))
    ax1.plot(steps, loss, lw=1)
    ax1.set_yscale("log")
    ax1.set_xlabel("step")
    ax1.set_ylabel("training loss (the run's --loss)")
    ax1.grid(alpha=0.3)
    if val:
        vs = [int(r["step"]) for r in val]
        ax2.plot(vs, [float(r["val_relmse"]) for r in val], "o-", label="denoised relMSE")
        if val[-1].get("val_noisy_relmse"):
            ax2.axhline(float(val[-1]["val_noisy_relmse"]), color="grey", ls="--", label="noisy relMSE")
        ax2.set_yscale("log")
        ax2.set_xlabel("step")
        ax2.set_ylabel("validation relMSE")
        ax2.grid(alpha=0.3)
        handles, labels = ax2.get_legend_handles_labels()
        if val[-1].get("val_ssim"):
            ax3 = ax2.twinx()
            ax3.plot(vs, [float(r["val_ssim"]) for r in val], "s-", color="tab:green", label="SSIM")
            ax3.set_ylabel("validation SSIM")
            handles3, labels3 = ax3.get_legend_handles_labels()
            handles, labels = handles + handles3, labels + labels3
        ax2.legend(handles, labels, fontsize=8, loc="center right")
    fig.suptitle(a.title)
    fig.tight_layout()
    fig.savefig(a.out, dpi=100)


main()
