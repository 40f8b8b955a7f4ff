#!/usr/bin/python3
"""A model card (Markdown) from what the model file and an `evaluate-set --json` result record: architecture,
data, steps, training time, schedule, the training curve, per-scene validation relMSE/SSIM against the noisy
input and the cross-bilateral baseline (and, with --compare, other columns of the evaluation such as `oidn`), the
brightness ratio, seconds per megapixel, and the release checks (lowers the noisy relMSE; the reduction at 4-16 spp;
beats the bilateral filter; against each compared column, its means and on how many scenes it is better).

  /usr/bin/python3 tools/models/model_card.py resources/models/base.safetensors --eval eval.json \\
      --label base --dataset /work/datasets/residue-v1 --curve models/base_training.png [--compare oidn,best] > card.md
"""
import argparse, json, os, subprocess, sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from safetensors_meta import metadata  # noqa: E402


def spp_of(dataset, scene):
    try:
        with open(os.path.join(dataset, scene, "scene.json")) as f:
            return json.load(f)["spp"]["noisy_a"]
    except (OSError, KeyError, ValueError):
        return None


def hours(s):
    return f"{s / 3600:.1f} h" if s >= 3600 else f"{s / 60:.0f} min"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("model")
    p.add_argument("--eval", required=True, help="evaluate-set --json output that has a column for this model")
    p.add_argument("--label", help="the model's column in the evaluation (default: the file's stem)")
    p.add_argument("--dataset", help="data set folder, for each scene's samples per pixel")
    p.add_argument("--curve", help="training curve PNG, as linked from the card")
    p.add_argument("--compare", default="",
                   help="other columns of the evaluation to show per scene, comma-separated (e.g. oidn,best; "
                        "with or without the precision: `oidn` matches `oidn fp32`)")
    p.add_argument("--cli", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "build", "release",
                                                 "app", "residue-cli", "residue-cli"))
    a = p.parse_args()

    md = metadata(a.model)
    label = a.label or os.path.splitext(os.path.basename(a.model))[0]
    training = json.loads(md.get("training", "{}"))
    bench = json.loads(md.get("benchmark", "{}"))
    ev = json.load(open(a.eval))
    # The receptive field as core's graph computes it (`residue-cli models --json`), for flat and multi-scale alike.
    cards = subprocess.run([a.cli, "models", "--json"], check=True, capture_output=True, text=True).stdout
    cards = json.loads(cards[cards.index("["):])
    card = [c for c in cards if c["file"] == os.path.abspath(a.model)] or \
        [c for c in cards if md.get("name", "").startswith(c["family"] + "-")]  # a variant: its family's reach
    receptive = card[0]["reach_px"] if card else "?"
    if "residue.levels" in md:
        arch = f"{md['residue.levels']}/{md['residue.widths']}"
        shape = (f"{len(md['residue.levels'].split(','))} levels of {md['residue.levels']} ResBlocks, widths "
                 f"{md['residue.widths']}" + (", autoexposed" if md.get("residue.autoexposure") == "1" else ""))
    else:
        arch = f"{md['residue.blocks']}/{md['residue.width']}"
        dil = f", dilations {md['residue.dilations']}" if "residue.dilations" in md else ""
        shape = f"{md['residue.blocks']} ResBlocks of width {md['residue.width']}{dil}"

    out = [f"## {md.get('name', label)}", ""]
    out.append(f"- **Network**: {arch} ({shape}), features `{md['residue.features']}`, receptive field {receptive} px "
               "each side.")
    if training:
        data = ", ".join(f"`{os.path.normpath(d)}`" for d in training.get("data", []))
        wall = training.get("wall_s", training.get("wall_s_this_run", 0))
        out.append(f"- **Training**: {training.get('steps')} steps of {training.get('batch')} patches of "
                   f"{training.get('patch')}x{training.get('patch')}, {training.get('loss')}, "
                   f"{training.get('optimizer')}, lr {training.get('lr')} ({training.get('schedule')}), "
                   f"{training.get('precision', 'fp32')}, {training.get('threads')} threads, seed {training.get('seed')}; "
                   f"{hours(wall)} of training on a 2-core machine"
                   + (f"; fine-tuned from `{training['init_from']}`." if training.get("init_from") else "."))
        out.append(f"- **Data**: {training.get('train_scenes')} training scenes from {data}.")
    if a.curve:
        out.append(f"- **Curve**: ![{label} training]({a.curve})")
    if bench:
        speeds = ", ".join(f"{k[:-len('_s_per_mp')]} {v:.3g} s/MP" for k, v in bench.items() if k.endswith("_s_per_mp"))
        machine = f" on {bench['machine']}" if bench.get("machine") else ""
        out.append(f"- **Speed** (`tools/models/stamp_benchmark.py`, warm runs): {speeds}{machine}.")

    scenes = ev["scenes"]
    if not scenes or label not in scenes[0]["results"]:
        raise SystemExit(f"model_card: no column '{label}' in {a.eval}")
    have_bilateral = "bilateral" in scenes[0]["results"]
    compared = []  # (name, column label)
    for name in filter(None, a.compare.split(",")):
        found = [c for c in (name, name + " fp32") if c in scenes[0]["results"]]
        if not found:
            raise SystemExit(f"model_card: no column '{name}' in {a.eval}")
        compared.append((name, found[0]))
    out += ["", f"Validation ({len(scenes)} scenes of `{ev.get('dataset', '')}`, split {ev.get('split', 'all')}):", ""]
    head = "| scene | spp | noisy relMSE | relMSE | reduction | SSIM | brightness |"
    rule = "|---|---|---|---|---|---|---|"
    if have_bilateral:
        head += " bilateral relMSE | bilateral SSIM |"
        rule += "---|---|"
    for name, _ in compared:
        head += f" {name} relMSE | {name} SSIM |"
        rule += "---|---|"
    out += [head, rule]
    rows = []
    for s in scenes:
        r, n = s["results"][label], s["results"]["noisy"]
        b = s["results"].get("bilateral")
        spp = spp_of(a.dataset, s["scene"]) if a.dataset else None
        rows.append((s["scene"], spp, n["relmse"], r, b))
        line = (f"| {s['scene']} | {spp if spp else ''} | {n['relmse']:.4g} | {r['relmse']:.4g} | "
                f"{n['relmse'] / r['relmse']:.1f}x | {r['ssim']:.4f} | {r['mean_ratio']:.3f} |")
        if b:
            line += f" {b['relmse']:.4g} | {b['ssim']:.4f} |"
        for _, column in compared:
            c = s["results"][column]
            line += f" {c['relmse']:.4g} | {c['ssim']:.4f} |"
        out.append(line)
    k = len(rows)
    mean = lambda xs: sum(xs) / max(1, len(xs))
    m_noisy, m_model = mean([x[2] for x in rows]), mean([x[3]["relmse"] for x in rows])
    m_ssim = mean([x[3]["ssim"] for x in rows])
    line = (f"| **mean** | | {m_noisy:.4g} | **{m_model:.4g}** | {m_noisy / m_model:.1f}x | "
            f"**{m_ssim:.4f}** | {mean([x[3]['mean_ratio'] for x in rows]):.3f} |")
    if have_bilateral:
        line += f" {mean([x[4]['relmse'] for x in rows]):.4g} | {mean([x[4]['ssim'] for x in rows]):.4f} |"
    # Each compared column's scores per scene and their means: (name, scores, mean relMSE, mean SSIM).
    theirs = [(name, [s["results"][column] for s in scenes]) for name, column in compared]
    theirs = [(name, t, mean([x["relmse"] for x in t]), mean([x["ssim"] for x in t])) for name, t in theirs]
    for _, _, t_rel, t_ssim in theirs:
        line += f" {t_rel:.4g} | {t_ssim:.4f} |"
    out.append(line)

    # The release checks.
    lowered = sum(1 for x in rows if x[3]["relmse"] < x[2])
    checks = [f"lowers the noisy relMSE on {lowered} of {k} scenes (mean {m_noisy / m_model:.1f}x)"]
    mid = [x for x in rows if x[1] is not None and 4 <= x[1] <= 16]
    if mid:
        ratio_of_means = mean([x[2] for x in mid]) / mean([x[3]["relmse"] for x in mid])
        mean_of_ratios = mean([x[2] / x[3]["relmse"] for x in mid])
        checks.append(f"at 4-16 spp ({len(mid)} scenes): {ratio_of_means:.1f}x lower mean relMSE "
                      f"(mean of per-scene reductions {mean_of_ratios:.1f}x)")
    if have_bilateral:
        beats = sum(1 for x in rows if x[3]["relmse"] < x[4]["relmse"])
        m_bil = mean([x[4]["relmse"] for x in rows])
        checks.append(f"{'beats' if m_model < m_bil else 'does not beat'} the bilateral filter on mean relMSE "
                      f"({m_model:.4g} vs {m_bil:.4g}; better on {beats} of {k} scenes)")
    for name, scores, t_rel, t_ssim in theirs:
        lower = sum(1 for x, t in zip(rows, scores) if x[3]["relmse"] < t["relmse"])
        higher = sum(1 for x, t in zip(rows, scores) if x[3]["ssim"] > t["ssim"])
        checks.append(f"against `{name}`: mean relMSE {m_model:.4g} vs {t_rel:.4g} ({m_model / t_rel - 1:+.1%}; "
                      f"lower on {lower} of {k} scenes), mean SSIM {m_ssim:.4f} vs {t_ssim:.4f} "
                      f"(higher on {higher} of {k})")
    out += ["", "Checks: " + "; ".join(checks) + "."]
    print("\n".join(out))


if __name__ == "__main__":
    main()
