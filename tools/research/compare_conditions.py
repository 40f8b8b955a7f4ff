#!/usr/bin/python3
"""The same scenes rendered two ways (e.g. residue-v1's validation scenes as the generator renders them and as an
unclamped path tracer leaves them, fireflies and caustics kept), each scored by `residue-cli evaluate-set --json`:
per model, the mean relMSE and SSIM under each condition over the scenes both hold, each model's relMSE against a
yardstick's (default `oidn`) and its SSIM less the yardstick's under each, so that a model that copes worse with the
second condition shows as a ratio that grows or a difference that falls.

A reference at R spp is itself noisy, and more so with fireflies: against it every model's expected relMSE carries
the reference's own error, about the noisy input's relMSE x n / (n + R) for an n-spp input (independent samples of
one integrand: the variances add and scale as 1 / spp). That floor is the same for every model, so it compresses
their ratios towards 1; the table also gives each mean with the floor taken off (an estimate: heavy-tailed noise
makes a scene's own variance estimate rough).

  /usr/bin/python3 tools/research/compare_conditions.py FIRST.json FIRST_DATASET SECOND.json SECOND_DATASET \\
      [--models multiscale,best,oidn,bilateral] [--yardstick oidn] [--names clamped,unclamped] [--md OUT.md]

A model is a column label of both files, with or without the precision (`multiscale` matches `multiscale fp32`).
"""
import argparse, json, os, sys


def load(path, dataset):
    """{scene: {label: (relmse, ssim)}} of an evaluate-set JSON and {scene: (spp, reference spp)} of its data set."""
    doc = json.load(open(path))
    scores = {s["scene"]: {k: (v["relmse"], v["ssim"]) for k, v in s["results"].items()} for s in doc["scenes"]}
    index = json.load(open(os.path.join(dataset, "index.json")))
    spp = {s["folder"]: (s["spp"], s["ref_spp"]) for s in index["scenes"]}
    return scores, spp


def column(results, model):
    for label in (model, model + " fp32"):
        if label in results:
            return results[label]
    sys.exit(f"compare_conditions: no column {model!r} (columns: {', '.join(sorted(results))})")


def summary(scores, spp, scenes, model):
    """Mean relMSE, mean SSIM and mean relMSE less the reference's floor over the scenes."""
    rel = ssim = floor = 0.0
    for s in scenes:
        r, q = column(scores[s], model)
        n, ref = spp[s]
        rel += r
        ssim += q
        floor += scores[s]["noisy"][0] * n / (n + ref)
    k = len(scenes)
    return rel / k, ssim / k, (rel - floor) / k


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("first")
    p.add_argument("first_dataset")
    p.add_argument("second")
    p.add_argument("second_dataset")
    p.add_argument("--models", default="multiscale,best,oidn,bilateral")
    p.add_argument("--yardstick", default="oidn")
    p.add_argument("--names", default="first,second", help="the two conditions' names, comma-separated")
    p.add_argument("--md", help="also write the table here")
    a = p.parse_args()
    names = a.names.split(",")
    (s1, spp1), (s2, spp2) = load(a.first, a.first_dataset), load(a.second, a.second_dataset)
    scenes = sorted(set(s1) & set(s2))
    if not scenes:
        sys.exit("compare_conditions: the two files share no scene")
    models = ["noisy"] + [m for m in a.models.split(",") if m != "noisy"]
    if a.yardstick not in models:
        models.append(a.yardstick)
    rows = {m: (summary(s1, spp1, scenes, m), summary(s2, spp2, scenes, m)) for m in models}
    y1, y2 = rows[a.yardstick]
    lines = [f"{len(scenes)} scenes: {', '.join(scenes)}", "",
             f"| model | {names[0]} relMSE / SSIM | {names[1]} relMSE / SSIM | relMSE x {a.yardstick}'s, {names[0]} "
             f"| {names[1]} | the same less the reference's floor, {names[0]} | {names[1]} "
             f"| SSIM - {a.yardstick}'s, {names[0]} | {names[1]} |",
             "|---|---|---|---|---|---|---|---|---|"]
    for m in models:
        (r1, q1, c1), (r2, q2, c2) = rows[m]
        ratios = (f"{r1 / y1[0]:.3f} | {r2 / y2[0]:.3f} | {c1 / y1[2]:.3f} | {c2 / y2[2]:.3f} "
                  f"| {q1 - y1[1]:+.4f} | {q2 - y2[1]:+.4f}" if m != "noisy" else "| | | | |")
        lines.append(f"| `{m}` | {r1:.6f} / {q1:.4f} | {r2:.6f} / {q2:.4f} | {ratios} |")
    floor1 = rows["noisy"][0][0] - rows["noisy"][0][2]
    floor2 = rows["noisy"][1][0] - rows["noisy"][1][2]
    lines += ["", f"The references' floor (mean noisy relMSE x n / (n + R)): {names[0]} {floor1:.6f}, "
                  f"{names[1]} {floor2:.6f}."]
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if a.md:
        with open(a.md, "w") as f:
            f.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
