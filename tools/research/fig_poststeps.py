#!/usr/bin/python3
"""The figure of docs/MODELS.md's post-steps: for a clean scene (the variance blend) and a dark, very noisy
one (the energy correction), crops of the noisy input, the network's raw output, the output with the post-step
(through residue-cli, the variance written from the scene's two halves) and the reference, tonemapped alike.

  /usr/bin/python3 tools/research/fig_poststeps.py DATASET OUT.png [--model small]
"""
import argparse, os, subprocess, sys, tempfile
import numpy as np
import OpenImageIO as oiio
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "datagen"))
from exr_metrics import relmse  # noqa: E402  the metric, one definition

CLI = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "build", "release", "app", "residue-cli", "residue-cli")


def read_rgb(path, prefix=""):
    inp = oiio.ImageInput.open(path)
    spec = inp.spec()
    px = inp.read_image(0, 0, 0, spec.nchannels, "float")
    inp.close()
    names = list(spec.channelnames)
    idx = [names.index(prefix + c) for c in "RGB"] if prefix else [0, 1, 2]
    return px[..., idx]


def write_rgb(path, img):
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(img.shape[1], img.shape[0], 3, "float"))
    out.write_image(np.ascontiguousarray(img, dtype=np.float32))
    out.close()


def display_curve(x, exposure):
    """A brighter curve for the figure's panels only (Reinhard x 1.6, sRGB): not the metric's tonemap."""
    x = np.clip(x * exposure, 0, None)
    return np.clip(np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x / (1 + x) * 1.6, 1 / 2.4) - 0.055), 0, 1)


def denoise(scene_noisy, out, model, extra):
    subprocess.run([CLI, "denoise", scene_noisy, "-m", model, "-o", out, "--float", "-f"] + extra, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return read_rgb(out)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dataset")
    p.add_argument("png")
    p.add_argument("--model", default="small")
    p.add_argument("--blend-scene", default="s1077")
    p.add_argument("--energy-scene", default="s1000")
    a = p.parse_args()
    pre = "ViewLayer.Combined."
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        # The variance blend on a clean scene: the variance from the two halves, (a - b)^2 / 2, as an AOV.
        d = os.path.join(a.dataset, a.blend_scene)
        na, nb, ref = (read_rgb(os.path.join(d, f), pre) for f in ("noisy_a.exr", "noisy_b.exr", "reference.exr"))
        var = os.path.join(tmp, "var.exr")
        write_rgb(var, 0.5 * (na - nb) ** 2)
        common = ["--map", f"variance={var}:R,G,B", "--no-energy-correction"]
        raw = denoise(os.path.join(d, "noisy_a.exr"), os.path.join(tmp, "raw.exr"), a.model, common + ["--no-variance-blend"])
        post = denoise(os.path.join(d, "noisy_a.exr"), os.path.join(tmp, "post.exr"), a.model, common)
        rows.append((f"{a.blend_scene}: variance blend", na, raw, post, ref, 1.0))
        # The energy correction on a dark, very noisy scene.
        d = os.path.join(a.dataset, a.energy_scene)
        na, ref = (read_rgb(os.path.join(d, f), pre) for f in ("noisy_a.exr", "reference.exr"))
        raw = denoise(os.path.join(d, "noisy_a.exr"), os.path.join(tmp, "raw2.exr"), a.model, ["--no-energy-correction"])
        post = denoise(os.path.join(d, "noisy_a.exr"), os.path.join(tmp, "post2.exr"), a.model, [])
        rows.append((f"{a.energy_scene}: energy correction", na, raw, post, ref, 2.0))
    fig, axes = plt.subplots(len(rows), 4, figsize=(12, 3.2 * len(rows)))
    for r, (title, noisy, raw, post, ref, exposure) in enumerate(rows):
        for c, (name, img) in enumerate((("noisy", noisy), (f"{a.model}, raw", raw), ("with the post-step", post),
                                         ("reference", ref))):
            ax = axes[r][c]
            ax.imshow(display_curve(img, exposure))
            label = name if name == "reference" else f"{name}\nrelMSE {relmse(img, ref):.4f}, mean {img.mean() / ref.mean():.3f}"
            ax.set_title((title + "\n" if c == 0 else "\n") + label, fontsize=8)
            ax.axis("off")
    fig.tight_layout()
    fig.savefig(a.png, dpi=80)


if __name__ == "__main__":
    main()
