#!/usr/bin/python3
"""Regenerates the small EXR seeds of tests/fuzz/corpus/fuzz_exr_loader from the bundled example
(resources/examples/room) with OpenImageIO's Python bindings: crops of the real Cycles render and its reference,
and small files in the other conventions (multipart, plain layers, RenderMan, Arnold, odd data windows, other
compressions). Run from the repository root; the seeds are committed, so this is only needed to change them."""
import os
import numpy as np
import OpenImageIO as oiio

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
OUT = os.path.join(ROOT, "tests", "fuzz", "corpus", "fuzz_exr_loader")
ROOM = os.path.join(ROOT, "resources", "examples", "room")


def crop(src, dst, x, y, w, h, compression="zip"):
    buf = oiio.ImageBuf(os.path.join(ROOM, src))
    out = oiio.ImageBufAlgo.cut(buf, oiio.ROI(x, x + w, y, y + h))  # cut: the crop's data window starts at 0
    out.specmod().attribute("compression", compression)
    assert out.write(os.path.join(OUT, dst)), out.geterror()


def write(dst, parts, compression="zip"):
    """parts: list of (channel names, array HxWxC, pixel type, (x, y) data-window origin, (full w, full h))."""
    out = oiio.ImageOutput.create(os.path.join(OUT, dst))
    specs = []
    for i, (names, arr, fmt, origin, full) in enumerate(parts):
        h, w, c = arr.shape
        s = oiio.ImageSpec(w, h, c, fmt)
        s.channelnames = tuple(names)
        s.x, s.y = origin
        s.full_x, s.full_y, s.full_width, s.full_height = 0, 0, full[0], full[1]
        s.attribute("compression", compression)
        if len(parts) > 1:
            s.attribute("name", f"part{i}")
        specs.append(s)
    assert out.open(os.path.join(OUT, dst), tuple(specs)) if len(specs) > 1 else out.open(os.path.join(OUT, dst), specs[0]), out.geterror()
    for i, (names, arr, fmt, origin, full) in enumerate(parts):
        if i:
            assert out.open(os.path.join(OUT, dst), specs[i], "AppendSubimage"), out.geterror()
        assert out.write_image(arr.astype(np.float32)), out.geterror()
    out.close()


rng = np.random.default_rng(18)
def img(h, w, c):
    return rng.random((h, w, c), dtype=np.float32)


crop("noisy.exr", "cycles_room_24x24.exr", 84, 84, 24, 24)
crop("reference.exr", "room_reference_16x16_piz.exr", 90, 60, 16, 16, "piz")
rgb, xyz = ["R", "G", "B"], ["X", "Y", "Z"]
# plain: root RGB with albedo/normal/depth/variance layers, a data window offset inside a larger display window
write("plain_layers_offset_window.exr",
      [(rgb + ["albedo." + c for c in rgb] + ["normal." + c for c in xyz] + ["depth.Z"] + ["variance." + c for c in rgb],
        img(8, 10, 13), oiio.HALF, (3, 5), (16, 16))])
# multipart: colour, albedo and normal in three parts (unqualified channels), the parts' windows differing
write("multipart_three_parts.exr",
      [(rgb + ["A"], img(8, 8, 4), oiio.HALF, (0, 0), (8, 8)),
       (rgb, img(8, 8, 3), oiio.HALF, (0, 0), (8, 8)),
       (xyz, img(6, 8, 3), oiio.FLOAT, (0, 2), (8, 8))])
# RenderMan-style names, float, RLE
write("renderman_ci.exr", [(["Ci.r", "Ci.g", "Ci.b", "albedo.r", "albedo.g", "albedo.b", "normal.x", "normal.y",
                             "normal.z", "z", "mse.r", "mse.g", "mse.b"], img(6, 6, 13), oiio.FLOAT, (0, 0), (6, 6))],
      "rle")
# Arnold-style: RGBA, N, Z, denoise_albedo; negative data window origin (outside the display window)
write("arnold_negative_origin.exr", [(rgb + ["A", "N.X", "N.Y", "N.Z", "Z", "denoise_albedo.R", "denoise_albedo.G",
                                             "denoise_albedo.B"], img(7, 5, 11), oiio.HALF, (-2, -3), (4, 4))], "zips")
# V-Ray-style names with a leading dot, and a reference layer
write("vray_dots_reference.exr", [([".R", ".G", ".B", "diffuse.red", "diffuse.green", "diffuse.blue", "bump_normals.X",
                                    "bump_normals.Y", "bump_normals.Z", "reference.R", "reference.G", "reference.B"],
                                   img(4, 6, 12), oiio.HALF, (0, 0), (6, 4))], "none")
# colour only, one pixel; and a file with no recognisable colour
write("colour_only_1x1.exr", [(rgb, img(1, 1, 3), oiio.FLOAT, (0, 0), (1, 1))], "none")
write("no_colour_channels.exr", [(["foo", "bar.baz"], img(3, 3, 2), oiio.HALF, (0, 0), (3, 3))], "b44")
# two Cycles view layers
write("cycles_two_view_layers.exr",
      [([f"{l}.Combined.{c}" for l in ("ViewLayer", "Other") for c in rgb + ["A"]] +
        [f"Other.Denoising Albedo.{c}" for c in rgb] + [f"Other.Denoising Normal.{c}" for c in xyz] +
        ["Other.Denoising Depth.Z"], img(4, 4, 15), oiio.HALF, (0, 0), (4, 4))], "dwaa")
