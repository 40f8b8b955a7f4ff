#!/usr/bin/python3
"""The quality goal (issue 16, with HDR-FLIP from issue 52), checked for one model: are its mean relMSE, SSIM and
HDR-FLIP at least as good as `oidn`'s on the project's validation scenes and on Tungsten's Cornell box, and is its
SSIM above the bilateral filter's on every scene? Runs `residue-cli evaluate-set --split validation` on the data set,
and `residue-cli denoise` then `residue-cli eval --json` on the Cornell box, prints one table and a verdict, and
writes everything as JSON.

  /usr/bin/python3 tools/research/goal_check.py MODEL [--ensemble N] [--dataset .cache/datasets/residue-v1]
      [--cornell ../shared/datasets/tungsten-example/cornell-box] [--json out.json] [--cli PATH]

MODEL is a model name or file, as `-m` takes it; --ensemble runs it (only it: `oidn` is scored as users run it)
with that many flips and transposes. Exit status 0 when the goal holds, 1 when it does not.
"""
import argparse, json, os, re, subprocess, sys, tempfile


def denoised_scores(cli_output):
    """relMSE and SSIM from the "denoised" row of `residue-cli denoise --reference`'s metrics table (relMSE, MSE,
    PSNR, SSIM, pixels, excluded)."""
    row = next(line for line in cli_output.splitlines() if line.startswith("denoised"))
    fields = re.split(r"\s+", row.strip())
    return {"relmse": float(fields[1]), "ssim": float(fields[4])}


def cornell_scores(cli, folder, model, ensemble, tmp):
    """relMSE, SSIM and HDR-FLIP of `model` on the Cornell box, as `residue-cli eval` scores its output."""
    out = os.path.join(tmp, "cornell.exr")
    cmd = [cli, "denoise", folder, "-m", model, "-o", out, "--force"]
    if ensemble:
        cmd += ["--ensemble", str(ensemble)]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    ev = json.loads(subprocess.run([cli, "eval", "--json", folder, "--denoised", out], check=True, capture_output=True,
                                   text=True).stdout)
    row = ev["rows"][1]
    return {"relmse": row["relmse"], "ssim": row["ssim"], "hdr_flip": row["hdr_flip"]}


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("model")
    p.add_argument("--ensemble", type=int, choices=[1, 2, 4, 8])
    p.add_argument("--dataset", default=os.path.join(here, "..", ".cache", "datasets", "residue-v1"))
    p.add_argument("--cornell", default=os.path.join(here, "..", "..", "shared", "datasets", "tungsten-example", "cornell-box"))
    p.add_argument("--cli", default=os.path.join(here, "..", "build", "release", "app", "residue-cli", "residue-cli"))
    p.add_argument("--json")
    a = p.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        # The model's column (with its ensemble) and oidn's and the bilateral filter's (as users run them).
        runs = {}
        for label, models, ens in (("model", a.model, a.ensemble), ("baselines", "oidn,bilateral", None)):
            path = os.path.join(tmp, f"{label}.json")
            cmd = [a.cli, "evaluate-set", a.dataset, "--split", "validation", "--models", models, "--json", path, "--force"]
            if ens:
                cmd += ["--ensembles", str(ens)]
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            runs[label] = json.load(open(path))
        model_label = next(s["label"] for s in runs["model"]["summary"] if s["label"] != "noisy")
        scenes = []
        for m, b in zip(runs["model"]["scenes"], runs["baselines"]["scenes"]):
            assert m["scene"] == b["scene"]
            scenes.append({"scene": m["scene"], "model": m["results"][model_label], "oidn": b["results"]["oidn"],
                           "bilateral": b["results"]["bilateral"]})
        cornell = {"model": cornell_scores(a.cli, a.cornell, a.model, a.ensemble, tmp),
                   "oidn": cornell_scores(a.cli, a.cornell, "oidn", None, tmp)}

    def mean(who, key):
        return sum(s[who][key] for s in scenes) / len(scenes)

    below = [s["scene"] for s in scenes if s["model"]["ssim"] < s["bilateral"]["ssim"]]
    checks = {
        "validation relMSE <= oidn": mean("model", "relmse") <= mean("oidn", "relmse"),
        "validation SSIM >= oidn": mean("model", "ssim") >= mean("oidn", "ssim"),
        "validation HDR-FLIP <= oidn": mean("model", "hdr_flip") <= mean("oidn", "hdr_flip"),
        "Cornell relMSE <= oidn": cornell["model"]["relmse"] <= cornell["oidn"]["relmse"],
        "Cornell SSIM >= oidn": cornell["model"]["ssim"] >= cornell["oidn"]["ssim"],
        "Cornell HDR-FLIP <= oidn": cornell["model"]["hdr_flip"] <= cornell["oidn"]["hdr_flip"],
        "no scene's SSIM below the bilateral filter's": not below,
    }
    name = a.model + (f" x{a.ensemble}" if a.ensemble else "")
    print(f"{'':34} {name[:24]:>24} {'oidn':>10}")
    print(f"{len(scenes)} validation scenes, mean relMSE   {mean('model', 'relmse'):>24.6f} {mean('oidn', 'relmse'):>10.6f}")
    print(f"{len(scenes)} validation scenes, mean SSIM     {mean('model', 'ssim'):>24.4f} {mean('oidn', 'ssim'):>10.4f}")
    print(f"{len(scenes)} validation scenes, mean HDR-FLIP {mean('model', 'hdr_flip'):>24.4f} {mean('oidn', 'hdr_flip'):>10.4f}")
    print(f"Cornell box relMSE                 {cornell['model']['relmse']:>24.6f} {cornell['oidn']['relmse']:>10.6f}")
    print(f"Cornell box SSIM                   {cornell['model']['ssim']:>24.4f} {cornell['oidn']['ssim']:>10.4f}")
    print(f"Cornell box HDR-FLIP               {cornell['model']['hdr_flip']:>24.4f} {cornell['oidn']['hdr_flip']:>10.4f}")
    print(f"scenes with SSIM below the bilateral filter's: {', '.join(below) if below else 'none'}")
    for what, ok in checks.items():
        print(f"  {'yes' if ok else 'NO ':3}  {what}")
    reached = all(checks.values())
    print("goal reached" if reached else "goal not reached")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"model": a.model, "ensemble": a.ensemble, "dataset": os.path.abspath(a.dataset),
                       "scenes": scenes, "cornell": cornell, "checks": checks, "reached": reached}, f, indent=1)
    return 0 if reached else 1


if __name__ == "__main__":
    sys.exit(main())
