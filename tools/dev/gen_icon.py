#!/usr/bin/python3
"""Draws Residue's application icon: resources/icons/residue.svg and the hicolor PNGs.

The design: a rounded square with a softly lit sphere on a teal ground, split along the diagonal. The upper-left
half is a noisy low-sample render (a grid of render "pixels" with random brightness and a few fireflies); the
lower-right half is the clean, denoised image.

There is no SVG rasteriser on the build machine, so this script holds the design once, as geometry, and emits both
the SVG and the PNGs from it: the PNGs are drawn analytically (the same shapes, gradients and cells, blended in
sRGB as SVG renderers do) with 8x8 supersampling for anti-aliasing. The noise comes from a fixed seed, so the
output is the same on every run.

Usage: /usr/bin/python3 tools/dev/gen_icon.py [OUTPUT_DIR]   (default: resources/icons beside this script's repo)
Needs numpy and OpenImageIO's Python bindings (Debian: python3-numpy, python3-openimageio).
"""

import math
import os
import sys

import numpy as np
import OpenImageIO as oiio

VIEW = 256                         # the SVG's view box is VIEW x VIEW units
SIZES = [16, 32, 48, 64, 128, 256]
SUPERSAMPLE = 8                    # samples per pixel along each axis

# Rounded square.
BOX = (16.0, 16.0, 240.0, 240.0)   # x0, y0, x1, y1
RADIUS = 44.0
# Ground: a linear gradient from the top-left corner to the bottom-right one.
GROUND = ((16.0, 16.0), (240.0, 240.0), [(0.0, "#3e8a93"), (1.0, "#17324a")])
# Sphere, lit from the upper left: a radial gradient centred on the highlight.
SPHERE_C, SPHERE_R = (128.0, 132.0), 70.0
SPHERE_LIGHT = ((104.0, 104.0), 104.0, [(0.0, "#fdf0d8"), (0.35, "#f2b77f"), (0.75, "#c96b4f"), (1.0, "#7a3a3f")])
# Noise: cells of CELL units over the half where x + y < VIEW. Icons smaller than VIEW / CELL pixels (16 px) would
# average such cells away, so they get a hinted variant with one-pixel cells (SMALL_CELL units) and fewer fireflies.
CELL = 8.0
SMALL_CELL, SMALL_FIREFLIES = 16.0, 5
SEED = 20190731
NOISE_SIGMA = 0.20                 # overlay opacity per unit of normal deviate
NOISE_MAX = 0.45
FIREFLIES = 14
FIREFLY_COLOUR, FIREFLY_OPACITY = "#fff6e6", 0.92
# The seam between the halves.
SEAM_WIDTH, SEAM_COLOUR, SEAM_OPACITY = 2.5, "#ffffff", 0.55


def hex_rgb(h):
    return np.array([int(h[i:i + 2], 16) / 255.0 for i in (1, 3, 5)])


def noise_cells(cell=CELL, fireflies=FIREFLIES):
    """[(x, y, colour, opacity)] for every cell (of `cell` units) in the noisy half, from the fixed seed."""
    rng = np.random.default_rng(SEED)
    n = int(VIEW / cell)
    cells = []
    for j in range(n):
        for i in range(n):
            x, y = i * cell, j * cell
            dev = float(rng.normal())
            inside_box = x + cell > BOX[0] and x < BOX[2] and y + cell > BOX[1] and y < BOX[3]
            if not inside_box or x + y >= VIEW:   # the cell's top-left corner must lie in the noisy half
                continue
            opacity = round(min(abs(dev) * NOISE_SIGMA, NOISE_MAX), 2)
            if opacity < 0.02:
                continue
            cells.append([x, y, "#ffffff" if dev > 0 else "#000000", opacity])
    # Fireflies: a few cells blown out to near white, chosen among the noisy ones.
    for k in rng.choice(len(cells), size=fireflies, replace=False):
        cells[k][2], cells[k][3] = FIREFLY_COLOUR, FIREFLY_OPACITY
    return [tuple(c) for c in cells]


def gradient(t, stops):
    t = np.clip(t, 0.0, 1.0)
    out = np.empty(t.shape + (3,))
    offs = [s[0] for s in stops]
    cols = [hex_rgb(s[1]) for s in stops]
    for c in range(3):
        out[..., c] = np.interp(t, offs, [col[c] for col in cols])
    return out


def blend(dst, mask, colour, opacity):
    a = (mask * opacity)[..., None]
    return dst * (1.0 - a) + np.asarray(colour) * a


def inside_rounded_box(x, y):
    x0, y0, x1, y1 = BOX
    cx = np.clip(x, x0 + RADIUS, x1 - RADIUS)
    cy = np.clip(y, y0 + RADIUS, y1 - RADIUS)
    return ((x - cx) ** 2 + (y - cy) ** 2 <= RADIUS ** 2) & (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)


def render(size, cells, cell=CELL):
    """RGBA float image (unassociated alpha) of size x size pixels; `cells` are noise cells of `cell` units."""
    n = size * SUPERSAMPLE
    coords = (np.arange(n) + 0.5) * (VIEW / n)
    x, y = np.meshgrid(coords, coords)

    (gx0, gy0), (gx1, gy1), stops = GROUND
    dx, dy = gx1 - gx0, gy1 - gy0
    col = gradient(((x - gx0) * dx + (y - gy0) * dy) / (dx * dx + dy * dy), stops)

    (lx, ly), lr, lstops = SPHERE_LIGHT
    in_sphere = (x - SPHERE_C[0]) ** 2 + (y - SPHERE_C[1]) ** 2 <= SPHERE_R ** 2
    col = np.where(in_sphere[..., None], gradient(np.hypot(x - lx, y - ly) / lr, lstops), col)

    # Each sample takes its cell's overlay (colour and opacity; none outside the listed cells).
    n_cells = int(VIEW / cell)
    over_col = np.zeros((n_cells, n_cells, 3))
    over_a = np.zeros((n_cells, n_cells))
    for cx, cy, colour, opacity in cells:
        i, j = int(cx / cell), int(cy / cell)
        over_col[j, i], over_a[j, i] = hex_rgb(colour), opacity
    ci = np.clip((x / cell).astype(int), 0, n_cells - 1)
    cj = np.clip((y / cell).astype(int), 0, n_cells - 1)
    a = (over_a[cj, ci] * (x + y < VIEW))[..., None]
    col = col * (1.0 - a) + over_col[cj, ci] * a

    seam = (np.abs(x + y - VIEW) / math.sqrt(2.0) <= SEAM_WIDTH / 2).astype(float)
    col = blend(col, seam, hex_rgb(SEAM_COLOUR), SEAM_OPACITY)

    alpha = inside_rounded_box(x, y).astype(float)
    premult = np.concatenate([col * alpha[..., None], alpha[..., None]], axis=-1)
    premult = premult.reshape(size, SUPERSAMPLE, size, SUPERSAMPLE, 4).mean(axis=(1, 3))
    a = premult[..., 3:4]
    rgb = np.where(a > 0, premult[..., :3] / np.maximum(a, 1e-12), 0.0)
    return np.concatenate([rgb, a], axis=-1)


def write_png(path, img):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    h, w = img.shape[:2]
    data = np.clip(np.rint(img * 255.0), 0, 255).astype(np.uint8)
    spec = oiio.ImageSpec(w, h, 4, "uint8")
    spec.attribute("oiio:UnassociatedAlpha", 1)   # the pixels are already straight (unassociated) alpha
    out = oiio.ImageOutput.create(path)
    if not out or not out.open(path, spec) or not out.write_image(data) or not out.close():
        sys.exit(f"gen_icon: cannot write {path}: {oiio.geterror()}")


def fmt(v):
    return f"{v:g}"


def svg(cells):
    x0, y0, x1, y1 = BOX
    (gx0, gy0), (gx1, gy1), gstops = GROUND
    (lx, ly), lr, lstops = SPHERE_LIGHT
    stop = lambda s: f'      <stop offset="{fmt(s[0])}" stop-color="{s[1]}"/>'
    box = (f'x="{fmt(x0)}" y="{fmt(y0)}" width="{fmt(x1 - x0)}" height="{fmt(y1 - y0)}" '
           f'rx="{fmt(RADIUS)}" ry="{fmt(RADIUS)}"')
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<!-- Residue application icon: a noisy render (upper left) and its denoised version (lower right).',
        '     Written by tools/dev/gen_icon.py, which draws the PNGs from the same geometry. -->',
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{VIEW}" height="{VIEW}" viewBox="0 0 {VIEW} {VIEW}">',
        '  <title>Residue</title>',
        '  <defs>',
        f'    <linearGradient id="ground" gradientUnits="userSpaceOnUse" x1="{fmt(gx0)}" y1="{fmt(gy0)}" '
        f'x2="{fmt(gx1)}" y2="{fmt(gy1)}">',
        *[stop(s) for s in gstops],
        '    </linearGradient>',
        f'    <radialGradient id="light" gradientUnits="userSpaceOnUse" cx="{fmt(lx)}" cy="{fmt(ly)}" r="{fmt(lr)}">',
        *[stop(s) for s in lstops],
        '    </radialGradient>',
        f'    <clipPath id="box"><rect {box}/></clipPath>',
        f'    <clipPath id="noisy"><path d="M0 0H{VIEW}L0 {VIEW}Z"/></clipPath>',
        '  </defs>',
        '  <g clip-path="url(#box)">',
        f'    <rect {box} fill="url(#ground)"/>',
        f'    <circle cx="{fmt(SPHERE_C[0])}" cy="{fmt(SPHERE_C[1])}" r="{fmt(SPHERE_R)}" fill="url(#light)"/>',
        '    <g clip-path="url(#noisy)">',
    ]
    for cx, cy, colour, opacity in cells:
        lines.append(f'      <rect x="{fmt(cx)}" y="{fmt(cy)}" width="{fmt(CELL)}" height="{fmt(CELL)}" '
                     f'fill="{colour}" fill-opacity="{fmt(opacity)}"/>')
    lines += [
        '    </g>',
        f'    <path d="M{VIEW} 0L0 {VIEW}" stroke="{SEAM_COLOUR}" stroke-opacity="{fmt(SEAM_OPACITY)}" '
        f'stroke-width="{fmt(SEAM_WIDTH)}"/>',
        '  </g>',
        '</svg>',
        '',
    ]
    return "\n".join(lines)


def main():
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(repo, "resources", "icons")
    cells = noise_cells()
    small_cells = noise_cells(SMALL_CELL, SMALL_FIREFLIES)
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, "residue.svg"), "w", encoding="utf-8") as f:
        f.write(svg(cells))
    for size in SIZES:
        img = render(size, cells) if size * CELL >= VIEW else render(size, small_cells, SMALL_CELL)
        write_png(os.path.join(out_dir, "hicolor", f"{size}x{size}", "apps", "residue.png"), img)
    print(f"gen_icon: wrote residue.svg and {len(SIZES)} PNGs under {out_dir}")


if __name__ == "__main__":
    main()
