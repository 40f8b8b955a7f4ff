#!/usr/bin/python3
"""Measures each shipped model's speed with `residue-cli bench` and writes it into the model file's metadata
("benchmark": seconds per megapixel for fp32 and bf16, the machine, the command), where the viewer's
speed-versus-accuracy table reads it.

  /usr/bin/python3 tools/models/stamp_benchmark.py [--cli build/release/app/residue-cli/residue-cli] [MODEL.safetensors ...]

Only the JSON header changes (the tensors are copied byte for byte); the file is replaced atomically.
Run it on an idle machine: the numbers are what users compare models by. The figure is the warm speed (bench's
fastest run after the cold first one), as in a viewer's runs and every tile after a CLI run's first.
"""
import argparse, glob, json, os, subprocess, sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from safetensors_meta import read_header, write_header  # noqa: E402

def main():
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cli", default=os.path.join(root, "build/release/app/residue-cli/residue-cli"))
    p.add_argument("--size", type=int, default=1024)
    p.add_argument("models", nargs="*")
    a = p.parse_args()
    models = a.models or sorted(glob.glob(os.path.join(root, "resources/models/*.safetensors")))
    # The file itself, not its BLOCKS/WIDTH: a multi-scale network has no such size, and the file's own settings
    # (autoexposure, prefilters) are part of what it costs.
    bench = lambda model: ["bench", "--models", model, "--precisions", "fp32,bf16", "--size", str(a.size),
                           "--repeat", "2", "--json"]
    for path in models:
        header, data = read_header(path)
        meta = header.setdefault("__metadata__", {})
        result = json.loads(subprocess.run([a.cli] + bench(os.path.abspath(path)), check=True, capture_output=True,
                                           text=True).stdout)
        best = {}
        for r in result["rows"]:
            s = r["seconds_per_megapixel"]
            if r["precision"] not in best or s < best[r["precision"]]["seconds_per_megapixel"]:
                best[r["precision"]] = r
        meta["benchmark"] = json.dumps({
            "fp32_s_per_mp": round(best["fp32"]["seconds_per_megapixel"], 4),
            "bf16_s_per_mp": round(best["bf16"]["seconds_per_megapixel"], 4) if "bf16" in best else None,
            "fp32_implementation": best["fp32"]["implementation"],
            "bf16_implementation": best["bf16"]["implementation"] if "bf16" in best else None,
            "machine": f"{result['cpu']}, {os.cpu_count()} cores",  # the CPU as bench names it
            "image": a.size,
            "command": " ".join(["residue-cli"] + bench(os.path.basename(path))),
        }, separators=(",", ":"))
        write_header(path, header, data)
        print(f"{os.path.basename(path)}: fp32 {best['fp32']['seconds_per_megapixel']:.3f} s/MP"
              + (f", bf16 {best['bf16']['seconds_per_megapixel']:.3f} s/MP" if "bf16" in best else ""))

if __name__ == "__main__":
    sys.exit(main())
