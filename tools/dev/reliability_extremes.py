#!/usr/bin/env python3
"""Numerical extremes, every model: the bundled room scaled by 1e-30 .. 1e30, to the half and float maxima and
to denormals, and black with one lit pixel, denoised by each model (and OIDN's networks, the bilateral filter,
the self-ensembles) with the automatic tiling and with --tile 32. For each case and model it records whether the
run succeeded (or its exit code), whether the output is finite, how far output / scale is from the unscaled
output (relative to that output's peak), and whether the two tilings agree bit for bit. Prints a Markdown table
(docs/RELIABILITY.md, "Extremes") and writes the numbers as JSON.

    /usr/bin/python3 tools/dev/reliability_extremes.py build/release/app/residue-cli/residue-cli --json OUT.json
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
import OpenImageIO as oiio

HERE = os.path.dirname(os.path.abspath(__file__))
ROOM = os.path.join(HERE, "..", "..", "resources", "examples", "room", "noisy.exr")
FLT_MAX = float(np.finfo(np.float32).max)
MODELS = [("tiny", []), ("small", []), ("multiscale", []), ("multiscale x2", ["-m", "multiscale", "--ensemble", "2"]),
          ("best", []), ("base", []), ("paper", []), ("oidn", []), ("oidn-cleanaux", []), ("bilateral", [])]


def read(path):
    i = oiio.ImageInput.open(path)
    spec = i.spec()
    a = i.read_image(oiio.FLOAT)
    i.close()
    return spec, a


def write(path, spec, pixels):
    s = oiio.ImageSpec(spec.width, spec.height, spec.nchannels, oiio.FLOAT)
    s.channelnames = list(spec.channelnames)
    for attr in spec.extra_attribs:
        try:
            s.attribute(attr.name, attr.type, attr.value)
        except Exception:
            pass
    o = oiio.ImageOutput.create(path)
    o.open(path, s)
    o.write_image(pixels.astype(np.float32))
    o.close()


def cases(pixels):
    """(name, scale or None, image): scale is what the output should be divided by to match the room's."""
    rgb = pixels[:, :, 0:3].astype(np.float64)
    peak = rgb.max()
    out = []
    for k in (1e-30, 1e-10, 1e10, 1e30):
        out.append((f"x {k:g}", k, k))
    out.append(("peak at half max (65504)", 65504.0 / peak, 65504.0 / peak))
    out.append(("peak at float max", FLT_MAX / peak, FLT_MAX / peak))
    out.append(("denormals (peak 1e-40)", 1e-40 / peak, None))  # float denormals lose digits: no scale check
    out.append(("black, one pixel of 1e-12", "one", None))
    out.append(("black", "black", None))
    return out


def make(pixels, how):
    a = pixels.copy()
    if how == "one":
        a[:, :, 0:3] = 0
        a[50, 50, 0:3] = 1e-12
    elif how == "black":
        a[:, :, 0:3] = 0
    else:
        a[:, :, 0:3] = (a[:, :, 0:3].astype(np.float64) * how).astype(np.float32)
    return a


def denoise(cli, src, out, name, extra, tile):
    args = extra if extra else ["-m", name]
    cmd = [cli, "denoise", src, "-o", out, "--float", "--force"] + args + (["--tile", str(tile)] if tile else [])
    r = subprocess.run(cmd, capture_output=True, text=True)
    return r.returncode, (r.stderr.strip().splitlines() or [""])[-1]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("cli")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    spec, pixels = read(ROOM)
    work = tempfile.mkdtemp(prefix="residue-extremes-")
    results = []
    base = {}
    for name, extra in MODELS:
        out = os.path.join(work, "base.exr")
        rc, msg = denoise(args.cli, ROOM, out, name, extra, 0)
        if rc != 0:
            sys.exit(f"{name} fails on the room itself: {msg}")
        base[name] = read(out)[1][:, :, 0:3].astype(np.float64)
    for case, how, scale in cases(pixels):
        src = os.path.join(work, "in.exr")
        write(src, spec, make(pixels, how))
        for name, extra in MODELS:
            row = {"case": case, "model": name}
            outs = []
            for tile in (0, 32):
                out = os.path.join(work, f"out{tile}.exr")
                rc, msg = denoise(args.cli, src, out, name, extra, tile)
                row[f"exit_tile{tile}"] = rc
                if rc != 0:
                    row["message"] = msg
                    break
                outs.append(read(out)[1][:, :, 0:3].astype(np.float64))
            if len(outs) == 2:
                o = outs[0]
                row["finite"] = bool(np.isfinite(o).all())
                row["max"] = float(np.nanmax(o))
                row["tiles_identical"] = bool(np.array_equal(outs[0], outs[1]))
                if scale is not None:
                    row["scale_deviation"] = float(np.abs(o / scale - base[name]).max() / base[name].max())
            results.append(row)
            print(f"{case:28s} {name:14s} {row}", file=sys.stderr, flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)
    # The table: a row per case, a column per model.
    names = [n for n, _ in MODELS]
    print("| case | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(names))
    for case, _, scale in cases(pixels):
        cells = []
        for name in names:
            r = next(x for x in results if x["case"] == case and x["model"] == name)
            if r.get("exit_tile0", 0) != 0 or r.get("exit_tile32", 0) != 0:
                cells.append(f"exit {r.get('exit_tile32', r['exit_tile0'])}")
                continue
            cell = "finite" if r["finite"] else "**NOT FINITE**"
            if "scale_deviation" in r:
                cell = f"{r['scale_deviation']:.0e}"
            elif case.startswith("black"):
                cell = f"max {r['max']:.1g}"
            if not r["tiles_identical"]:
                cell += " (tiles differ)"
            cells.append(cell)
        print(f"| {case} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
