#!/usr/bin/python3
"""Writes resources/models/oidn/cards.json: what the viewer and `residue-cli models` show for Open Image Denoise's
networks beside Residue's models (the .tza files carry no metadata of ours). Validation: the mean relMSE/SSIM
over the same 36 scenes the shipped models' cards use (30 validation scenes of residue-v1 + the last 6 starter
scenes), from evaluate-set JSON; benchmark: seconds per megapixel from `residue-cli bench --json` output.

  /usr/bin/python3 tools/models/oidn_cards.py docs/research/models/eval_project_val_oidn.json docs/research/models/eval_starter_val_oidn.json \\
      --bench-json docs/benchmarks/2026-11-26-amd-epyc-f26m2/oidn_cards.json

--bench FAMILY=SOURCE:FP32:BF16:MACHINE records a measurement written down elsewhere (PERFORMANCE.md's tile-512
column, measured on the machine the shipped models were benchmarked on); --bench-json takes the best row per
precision for each family not given by --bench, naming the machine by the CPU the JSON records (--machine for older
JSON without it).
"""
import argparse, json, os, sys

def main():
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("evals", nargs="+")
    p.add_argument("--bench", action="append", default=[])
    p.add_argument("--bench-json")
    p.add_argument("--machine", help="the machine of a --bench-json that does not name its CPU")
    p.add_argument("--out", default=os.path.join(root, "resources/models/oidn/cards.json"))
    a = p.parse_args()
    scenes = []
    for path in a.evals:
        scenes += json.load(open(path))["scenes"]
    cards = {}
    for family in ("oidn", "oidn-cleanaux"):
        # An evaluation of one precision labels the column FAMILY; one of several, "FAMILY fp32" (the card's).
        picked = [(s["results"][c], s["results"]["noisy"]) for s in scenes
                  if (c := family if family in s["results"] else family + " fp32") in s["results"]]
        rows, noisy = [r for r, _ in picked], [n for _, n in picked]
        if not rows:
            continue
        cards[family] = {"validation": {
            "relmse": sum(r["relmse"] for r in rows) / len(rows),
            "ssim": sum(r["ssim"] for r in rows) / len(rows),
            "noisy_relmse": sum(r["relmse"] for r in noisy) / len(noisy),
            "scenes": len(rows),
            "sources": [os.path.relpath(e, root) for e in a.evals]}}
    for spec in a.bench:
        family, rest = spec.split("=", 1)
        source, fp32, bf16, machine = rest.split(":", 3)
        cards[family]["benchmark"] = {"fp32_s_per_mp": float(fp32), "bf16_s_per_mp": float(bf16),
                                      "machine": machine, "source": source}
    if a.bench_json:
        bench = json.load(open(a.bench_json))
        if a.machine:
            machine = a.machine
        elif "cpu" in bench:
            machine = f"{bench['cpu']}, {bench['threads']} cores"
        else:
            sys.exit(f"oidn_cards: {a.bench_json} does not name its CPU; pass --machine")
        for family in cards:
            if "benchmark" in cards[family]:
                continue
            best = {}
            for r in bench["rows"]:
                if r["model"] == family and (r["precision"] not in best or
                                             r["seconds_per_megapixel"] < best[r["precision"]]["seconds_per_megapixel"]):
                    best[r["precision"]] = r
            if "fp32" in best:
                cards[family]["benchmark"] = {
                    "fp32_s_per_mp": round(best["fp32"]["seconds_per_megapixel"], 4),
                    "bf16_s_per_mp": round(best["bf16"]["seconds_per_megapixel"], 4) if "bf16" in best else None,
                    "machine": f"{machine}, fp32 peak {bench['fp32_peak_gflops']:.0f} GFLOP/s",
                    "image": bench["image"], "source": os.path.relpath(a.bench_json, root)}
    with open(a.out + ".tmp", "w") as f:
        json.dump(cards, f, indent=1, sort_keys=True)
        f.write("\n")
    os.replace(a.out + ".tmp", a.out)
    print(json.dumps(cards, indent=1, sort_keys=True))

if __name__ == "__main__":
    sys.exit(main())
