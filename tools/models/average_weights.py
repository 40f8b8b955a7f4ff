#!/usr/bin/python3
"""Averages the weights of model files of one network shape (a "model soup"): fine-tunes of one network that
trade one metric for another (e.g. with and without --relmse-weight) lie in one basin, and a weighted mean of their
parameters often keeps most of each one's gain. Float32 tensors are averaged, batch-norm statistics included (a
close approximation when the models are close; residue-train --precise-bn is the exact way); other tensors must be
equal and are copied. The first file's metadata is kept, with "averaged_from" added.

  /usr/bin/python3 tools/models/average_weights.py OUT A.safetensors[:WEIGHT] B.safetensors[:WEIGHT] ... [--force]
"""
import argparse, json, os, sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from safetensors_meta import read_tensors, write_tensors  # noqa: E402


def parse_input(text):
    path, sep, weight = text.rpartition(":")
    if sep and path.endswith(".safetensors"):
        try:
            return path, float(weight)
        except ValueError:
            sys.exit(f"average_weights: {text}: the weight after ':' must be a number, not '{weight}'")
    return text, 1.0


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("out")
    p.add_argument("inputs", nargs="+", metavar="MODEL[:WEIGHT]")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    a = p.parse_args()
    if os.path.exists(a.out) and not a.force:
        p.error(f"{a.out} exists (--force replaces it)")
    inputs = [parse_input(t) for t in a.inputs]
    for path, _ in inputs:
        if not os.path.isfile(path):
            sys.exit(f"average_weights: {path}: no such model file")
    if any(w < 0 for _, w in inputs) or sum(w for _, w in inputs) <= 0:
        p.error("weights must be non-negative, and not all zero")
    total = sum(w for _, w in inputs)
    loaded = [read_tensors(path) for path, _ in inputs]
    meta, first = loaded[0]
    for (path, _), (_, other) in zip(inputs[1:], loaded[1:]):
        if other.keys() != first.keys():
            sys.exit(f"average_weights: {path} holds other tensors than {inputs[0][0]}: not one network shape")
        for name, (dtype, shape, _) in first.items():
            if other[name][:2] != (dtype, shape):
                sys.exit(f"average_weights: {path}: tensor '{name}' is {other[name][0]} {list(other[name][1])}, "
                         f"expected {dtype} {list(shape)}")

    averaged = {}
    for name, (dtype, shape, raw) in first.items():
        if dtype == "F32":
            acc = np.zeros(shape, np.float64)
            for (_, w), (_, t) in zip(inputs, loaded):
                acc += (w / total) * np.frombuffer(t[name][2], "<f4").reshape(shape)
            if not np.isfinite(acc).all():
                sys.exit(f"average_weights: tensor '{name}' is not finite")
            raw = acc.astype("<f4").tobytes()
        elif any(t[name][2] != raw for _, t in loaded[1:]):
            sys.exit(f"average_weights: tensor '{name}' ({dtype}) differs between the inputs and cannot be averaged")
        averaged[name] = (dtype, shape, raw)
    meta = dict(meta)
    meta["averaged_from"] = json.dumps([{"file": os.path.basename(path), "weight": w / total} for path, w in inputs])
    write_tensors(a.out, meta, averaged)
    print(f"wrote {a.out}: {len(first)} tensors, the mean of {len(inputs)} models")


if __name__ == "__main__":
    main()
