#!/usr/bin/python3
"""Issue 16, lever 3 (inputs from any renderer), measured without training: the same Cycles renders denoised as
Cycles wrote them and re-saved in Tungsten's conventions (one file per buffer; world-space normals and no camera,
so they cannot be made view-space; albedo with emission, as Cycles' denoising albedo already is; ray-length
depth), for each model. A model that reads renderers' conventions well loses little between the two.

  /usr/bin/python3 tools/conventions_study.py [--data ../shared/datasets/cycles-starter] [--scenes s158,...]
      [--models bilateral,small,base,paper,oidn] [--cli build/release/app/residue-cli/residue-cli] --out DIR

Writes DIR/<scene>/tungsten/{color,albedo,normal,depth,reference}.exr and prints a Markdown table (mean relMSE
and SSIM per model and convention, and the relative change); --json FILE keeps the per-scene numbers.
"""
import argparse, json, os, re, subprocess, sys

def oiiotool(*args):
    subprocess.run(["oiiotool", *args], check=True, capture_output=True)

def to_tungsten(noisy, reference, out):
    os.makedirs(out, exist_ok=True)
    L = "ViewLayer."
    pick = {
        "color": [("R", L + "Combined.R"), ("G", L + "Combined.G"), ("B", L + "Combined.B")],
        "albedo": [("R", L + "Denoising Albedo.R"), ("G", L + "Denoising Albedo.G"), ("B", L + "Denoising Albedo.B")],
        "normal": [("R", L + "Normal.X"), ("G", L + "Normal.Y"), ("B", L + "Normal.Z")],  # world space
        "depth": [("Y", L + "Denoising Depth.Z")],  # distance along the camera ray
    }
    for name, channels in pick.items():
        spec = ",".join(f"{new}={old}" for new, old in channels)
        oiiotool(noisy, "--ch", spec, "-d", "half", "--compression", "piz", "-o", os.path.join(out, name + ".exr"))
    oiiotool(reference, "--ch", f"R={L}Combined.R,G={L}Combined.G,B={L}Combined.B", "-d", "half",
             "--compression", "piz", "-o", os.path.join(out, "reference.exr"))

def scores(cli, inputs, model, out, reference=None):
    args = [cli, "denoise", *inputs, "-m", model, "-o", out, "--force"]
    if reference:
        args += ["-r", reference]
    text = subprocess.run(args, check=True, capture_output=True, text=True).stdout
    row = re.search(r"^denoised\s+(\S+)\s+\S+\s+\S+\s+(\S+)", text, re.M)
    return float(row.group(1)), float(row.group(2))

def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", default=os.path.join(root, "..", "shared", "datasets", "cycles-starter"))
    p.add_argument("--scenes", default="s158,s159,s160,s161,s162,s163")
    p.add_argument("--models", default="bilateral,small,base,paper,oidn")
    p.add_argument("--cli", default=os.path.join(root, "build/release/app/residue-cli/residue-cli"))
    p.add_argument("--out", required=True)
    p.add_argument("--json")
    a = p.parse_args()
    results = {}
    for scene in a.scenes.split(","):
        src = os.path.join(a.data, scene)
        tdir = os.path.join(a.out, scene, "tungsten")
        to_tungsten(os.path.join(src, "noisy_a.exr"), os.path.join(src, "reference.exr"), tdir)
        for model in a.models.split(","):
            c = scores(a.cli, [os.path.join(src, "noisy_a.exr")], model, os.path.join(a.out, scene, f"cycles_{model}.exr"),
                       os.path.join(src, "reference.exr"))
            t = scores(a.cli, [tdir], model, os.path.join(a.out, scene, f"tungsten_{model}.exr"))
            results.setdefault(model, []).append({"scene": scene, "cycles": c, "tungsten": t})
            print(f"{scene} {model}: cycles {c[0]:.5f} / {c[1]:.4f}, tungsten {t[0]:.5f} / {t[1]:.4f}", file=sys.stderr)
    print("| model | relMSE, Cycles conventions | relMSE, Tungsten conventions | change | SSIM, Cycles | SSIM, Tungsten |")
    print("|---|---|---|---|---|---|")
    for model, rows in results.items():
        n = len(rows)
        cr = sum(r["cycles"][0] for r in rows) / n
        tr = sum(r["tungsten"][0] for r in rows) / n
        cs = sum(r["cycles"][1] for r in rows) / n
        ts = sum(r["tungsten"][1] for r in rows) / n
        print(f"| `{model}` | {cr:.5f} | {tr:.5f} | {100 * (tr / cr - 1):+.1f} % | {cs:.4f} | {ts:.4f} |")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(results, f, indent=1)

if __name__ == "__main__":
    sys.exit(main())
