#!/usr/bin/python3
"""A temporal model file to start training from (issue 51), made from a still model: the same network with the
head reading 4 more planes per neighbour (each neighbour's log colour and its validity, core/features/features.h).

  tools/models/temporal_init.py resources/models/multiscale.safetensors OUT.safetensors --radius 1 --share average

--share zero:    the neighbours' weights are 0: the model denoises exactly as the still one (and must learn them).
--share average: the colour's weights are split evenly over the frame and its 2k neighbours, so that from the
                 first step the network sees the mean of the log colours of the frames that show the pixel's
                 surface (where a neighbour is not valid it reads as the frame's own colour: the mean of fewer).
The validity planes start at 0 either way. residue-train --init-from OUT then trains it (its planes match by name).
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from safetensors_meta import read_tensors, write_tensors  # noqa: E402

COLOR = 3  # the colour planes come first in every feature set


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("still")
    ap.add_argument("out")
    ap.add_argument("--radius", type=int, default=1, choices=(1, 2))
    ap.add_argument("--share", choices=("zero", "average"), default="average")
    ap.add_argument("--name", default=None)
    ap.add_argument("--force", action="store_true")
    a = ap.parse_args()
    if os.path.exists(a.out) and not a.force:
        sys.exit(f"temporal_init: {a.out} exists; pass --force to replace it")
    meta, tensors = read_tensors(a.still)
    if meta.get("residue.features", "full") != "full" or "residue.prior" in meta or meta.get("residue.demodulate") == "1":
        sys.exit(f"temporal_init: {a.still}: a temporal model starts from a 'full' model without a prior or demodulation")
    if "residue.temporal" in meta:
        sys.exit(f"temporal_init: {a.still} is temporal already")
    dtype, shape, raw = tensors["head.conv.weight"]
    if dtype != "F32":
        sys.exit(f"temporal_init: {a.still}: head.conv.weight is {dtype}; expected F32")
    w = np.frombuffer(raw, "<f4").reshape(shape)
    neighbours = 2 * a.radius
    out = np.zeros((shape[0], shape[1] + 4 * neighbours) + tuple(shape[2:]), np.float32)
    out[:, :shape[1]] = w
    if a.share == "average":
        share = w[:, :COLOR] / (neighbours + 1)
        out[:, :COLOR] = share
        for n in range(neighbours):
            first = shape[1] + 4 * n
            out[:, first:first + COLOR] = share
    tensors["head.conv.weight"] = ("F32", out.shape, np.ascontiguousarray(out, "<f4").tobytes())
    meta = {k: v for k, v in meta.items() if k.startswith("residue.") and k not in ("residue.blend_tau",)}
    meta["residue.temporal"] = str(a.radius)
    meta["name"] = a.name or os.path.splitext(os.path.basename(a.out))[0]
    meta["training"] = json.dumps({"init": f"{os.path.basename(a.still)} made temporal (radius {a.radius}, "
                                           f"neighbour weights: {a.share}) by tools/models/temporal_init.py"})
    write_tensors(a.out, meta, tensors)
    print(f"wrote {a.out}: head {tuple(shape)} -> {out.shape}, neighbours' colour weights {a.share}")


if __name__ == "__main__":
    main()
