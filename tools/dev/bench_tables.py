#!/usr/bin/python3
"""Prints the Markdown tables of docs/PERFORMANCE.md from one tools/dev/bench_all.sh folder, so that the figures in
the document are the measured ones, not copied by hand.

  /usr/bin/python3 tools/dev/bench_tables.py docs/benchmarks/2026-11-26-amd-epyc-f26m2
"""
import json, os, re, statistics, sys


def load(folder, name):
    path = os.path.join(folder, name + ".json")
    return json.load(open(path)) if os.path.exists(path) else None


def header(j):
    return (f"{j['cpu']}, {j['threads']} threads, fp32 ceiling {j['fp32_peak_gflops']:.0f} GFLOP/s "
            f"({j['peak_isa']} FMA loop), image {j['image']}^2")


def by_model(j):
    """Rows as a table per model: one line per backend x precision, one column pair per tile."""
    out = []
    tiles = sorted({r["tile"] for r in j["rows"]})
    models = list(dict.fromkeys(r["model"] for r in j["rows"]))
    cols = " | ".join(f"tile {t}: warm s/MP (% of ceiling), first run" for t in tiles)
    out.append(f"| model | backend | precision | {cols} |")
    out.append("|---|---|---|" + "---|" * len(tiles))
    for m in models:
        configs = list(dict.fromkeys((r["backend"], r["precision"]) for r in j["rows"] if r["model"] == m))
        for b, p in configs:
            cells = []
            for t in tiles:
                r = next((r for r in j["rows"] if (r["model"], r["backend"], r["precision"], r["tile"]) == (m, b, p, t)),
                         None)
                cells.append("" if r is None else
                             f"{r['seconds_per_megapixel']:.3f} ({r['percent_of_fp32_peak']:.0f} %), "
                             f"{r['first_run_seconds_per_megapixel']:.3f}")
            out.append(f"| {m} | {b} | {p} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def end_to_end(folder):
    path = os.path.join(folder, "end_to_end.txt")
    if not os.path.exists(path):
        return None
    runs, key = {}, None
    for line in open(path):
        if line.startswith("=="):
            _, model, precision, _, _ = line.split()
            key = (model, precision)
            runs.setdefault(key, []).append({})
        elif line.startswith("backend"):
            runs[key][-1]["backend"] = line.split()[1]
        elif line.startswith("time"):
            runs[key][-1]["denoise"] = float(re.search(r"time\s+([\d.]+) s", line).group(1))
        elif line.startswith("files"):
            m = re.search(r"read ([\d.]+) s, written ([\d.]+) s", line)
            runs[key][-1]["read"], runs[key][-1]["write"] = float(m.group(1)), float(m.group(2))
        elif line.startswith("wall"):
            runs[key][-1]["wall"] = float(re.search(r"wall ([\d.]+) s", line).group(1))
    out = ["| model | precision | backend | `denoise()` | read | write | wall (whole process) | wall / denoise - 1 (median) |",
           "|---|---|---|---|---|---|---|---|"]
    for (model, precision), rs in runs.items():
        over = [r["wall"] / r["denoise"] - 1 for r in rs]
        fmt = lambda k: " / ".join(f"{r[k]:.2f}" for r in rs)
        backend = rs[0].get("backend", "onednn")  # runs before 2026-11-26 named no backend: all were onednn
        out.append(f"| {model} | {precision} | {backend} | {fmt('denoise')} s | {fmt('read')} s | {fmt('write')} s | "
                   f"{fmt('wall')} s | +{100 * statistics.median(over):.0f} % |")
    return "\n".join(out)


def main():
    folder = sys.argv[1]
    for name in ("narrow", "paper", "oidn_2k", "oidn_cards"):
        j = load(folder, name)
        if j:
            print(f"### {name}: {header(j)}\n\n{by_model(j)}\n")
    e = end_to_end(folder)
    if e:
        print(f"### end to end (2048^2, default backend)\n\n{e}\n")


if __name__ == "__main__":
    main()
