#!/usr/bin/python3
"""Checks the convention of Cycles' Vector pass (the motion vectors in the shots' noisy.####.exr) on a known motion.

  /usr/bin/python3 tools/datagen/vector_convention_check.py [--blender /usr/bin/blender] [--keep DIR] [-v]

Renders, at 48x48 and 4 spp with one thread (a few seconds in all), two tiny three-frame shots: a bright square that
moves right and up with a speed that changes between frames (2 then 4 px right, 1 then 3 px up, relative to the
camera), a grey square that stands still, and a camera that moves (orthographic camera: trucks right 1 then 2 px;
perspective camera: pans about world up). Where each square is in frames 1, 2 and 3 is measured from the rendered
colour (centroids), so the truth comes from the images themselves; then frame 2's Vector channels inside each
square must equal, to 0.05 px:

  ViewLayer.Vector.X =   col(f-1) - col(f)     ViewLayer.Vector.Y = -(row(f-1) - row(f))
  ViewLayer.Vector.Z =   col(f)   - col(f+1)   ViewLayer.Vector.W = -(row(f)   - row(f+1))

i.e. X, Y point from the pixel to where its surface was in the previous frame, Z, W from where it will be in the
next frame back to the pixel (so the next position is the pixel minus (Z, W)); pixels of the render's resolution;
x to the right, y up (rows of the EXR as OpenImageIO reads them run downwards, so a row index goes with -Y). Both
pairs are motion over one whole frame (f-1 and f+1), not over a shutter. Also: the four channels are float32 with
the colour depth 16 that make_scene.py uses (half colour, float data). tools/datagen/README.md, "Shots and motion
vectors", has the numbers.

Exit status: 0 when the convention holds, 1 when it does not, 77 when Blender (or OpenImageIO) is missing (a
skipped test for ctest). The same file is the Blender script (run with `blender --python` it renders).
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile

RES = 48
CHANNELS = [f"ViewLayer.Vector.{c}" for c in "XYZW"]
TOL = 0.05
BACKGROUND, WHITE, GREY = 0.02, 1.0, 0.4  # the emitters' brightness

# Per frame (1, 2, 3): the moving square's offset in metres (x right, z up; 0.1 m = 1 px with the orthographic
# camera) and the camera's move (truck in metres, or pan in degrees).
SQUARE = {1: (0.0, 0.0), 2: (0.3, 0.1), 3: (0.9, 0.4)}
TRUCK = {1: 0.0, 2: 0.1, 3: 0.3}
PAN_DEG = {1: 0.0, 2: -1.0, 3: -3.0}


def render(outdir):
    """Inside Blender: renders ortho.{1,2,3}.exr and persp.{1,2,3}.exr into outdir."""
    import bmesh
    import bpy
    for camera_kind in ("ortho", "persp"):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        sc = bpy.context.scene

        def emitter(name, grey):
            m = bpy.data.materials.new(name)
            m.use_nodes = True
            nt = m.node_tree
            nt.nodes.clear()
            e = nt.nodes.new("ShaderNodeEmission")
            e.inputs["Color"].default_value = (grey, grey, grey, 1.0)
            o = nt.nodes.new("ShaderNodeOutputMaterial")
            nt.links.new(e.outputs[0], o.inputs[0])
            return m

        def square(name, size, mat, loc):
            me = bpy.data.meshes.new(name)
            bm = bmesh.new()
            bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=size / 2)
            bm.to_mesh(me)
            bm.free()
            me.materials.append(mat)
            ob = bpy.data.objects.new(name, me)
            sc.collection.objects.link(ob)
            ob.location = loc
            ob.rotation_euler = (1.5707963267948966, 0.0, 0.0)  # facing -Y, towards the camera
            return ob

        square("background", 60.0, emitter("dark", BACKGROUND), (0.0, 6.0, 0.0))
        moving = square("moving", 1.2, emitter("white", WHITE), (0.0, 0.0, 0.0))
        square("static", 0.8, emitter("grey", GREY), (-1.4, 0.0, -1.4))
        cd = bpy.data.cameras.new("camera")
        if camera_kind == "ortho":
            cd.type = "ORTHO"
            cd.ortho_scale = RES * 0.1  # 0.1 m per pixel
        else:
            cd.lens, cd.sensor_width = 50.0, 36.0
        cam = bpy.data.objects.new("camera", cd)
        sc.collection.objects.link(cam)
        cam.location = (0.0, -10.0, 0.0)
        cam.rotation_euler = (1.5707963267948966, 0.0, 0.0)  # looking along +Y, up = +Z
        sc.camera = cam
        for f in (1, 2, 3):
            moving.location.x, moving.location.z = SQUARE[f]
            moving.keyframe_insert("location", frame=f)
            if camera_kind == "ortho":
                cam.location.x = TRUCK[f]
                cam.keyframe_insert("location", frame=f)
            else:
                cam.rotation_euler.z = PAN_DEG[f] * 3.141592653589793 / 180.0
                cam.keyframe_insert("rotation_euler", frame=f)
        for ob in (moving, cam):
            for fc in ob.animation_data.action.fcurves:
                for k in fc.keyframe_points:
                    k.interpolation = "LINEAR"
        sc.render.engine = "CYCLES"
        sc.cycles.device = "CPU"
        sc.cycles.samples = 64  # coverage of the squares' edge pixels, for their centroids
        sc.cycles.use_denoising = False
        sc.cycles.pixel_filter_type = "BOX"  # every sample inside its pixel: centroids without the filter's blur
        sc.cycles.filter_width = 1.0
        sc.render.use_motion_blur = False  # the Vector pass exists only without motion blur
        sc.render.resolution_x = sc.render.resolution_y = RES
        sc.render.resolution_percentage = 100
        sc.render.threads_mode = "FIXED"
        sc.render.threads = 1
        s = sc.render.image_settings
        s.file_format = "OPEN_EXR_MULTILAYER"
        s.color_depth = "16"  # as make_scene.py: half colour passes, float data passes
        s.exr_codec = "ZIP"
        sc.view_layers[0].use_pass_vector = True
        for f in (1, 2, 3):
            sc.frame_set(f)
            sc.render.filepath = os.path.join(outdir, f"{camera_kind}.{f}.exr")
            bpy.ops.render.render(write_still=True)


def read(path):
    import numpy as np
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise IOError(f"cannot open {path}: {oiio.geterror()}")
    spec = inp.spec()
    px = np.asarray(inp.read_image(0, 0, 0, spec.nchannels, "float")).reshape(spec.height, spec.width,
                                                                               spec.nchannels)
    names = list(spec.channelnames)
    types = {n: str(spec.channelformat(i)) for i, n in enumerate(names)}
    inp.close()
    return px, names, types


def dilate(mask, n):
    import numpy as np
    for _ in range(n):
        mask = mask | np.roll(mask, 1, 0) | np.roll(mask, -1, 0) | np.roll(mask, 1, 1) | np.roll(mask, -1, 1)
    return mask


def centroid(lum, lo, hi, grey):
    """The (col, row) centroid of a square of brightness GREY on the dark background, its edge pixels weighted by
    their coverage, within 2 px of the pixels with lo < lum < hi (the white square's edge pixels left out of the
    grey one's); and those pixels' mask."""
    import numpy as np
    mask = (lum > lo) & (lum < hi)
    if grey < WHITE:
        mask &= ~dilate(lum > 0.7, 2)
    near = dilate(mask, 2)
    w = np.where(near, np.clip((lum - BACKGROUND) / (grey - BACKGROUND), 0.0, 1.0), 0.0)
    rows, cols = np.indices(lum.shape)
    return (float((w * cols).sum() / w.sum()), float((w * rows).sum() / w.sum())), mask


def check(outdir, verbose):
    import numpy as np
    failures, lines = [], []
    for camera_kind in ("ortho", "persp"):
        frames = {f: read(os.path.join(outdir, f"{camera_kind}.{f}.exr")) for f in (1, 2, 3)}
        px, names, types = frames[2]
        missing = [c for c in CHANNELS if c not in names]
        if missing:
            return [f"{camera_kind}: no {missing} in frame 2 (channels: {names})"], lines
        for c in CHANNELS:
            if types[c] != "float":
                failures.append(f"{camera_kind}: {c} is {types[c]}, not float")
        vec = np.stack([px[..., names.index(c)] for c in CHANNELS], axis=-1)
        lum = {f: frames[f][0][..., names.index("ViewLayer.Combined.G")] for f in (1, 2, 3)}
        for what, lo, hi, grey in (("moving square", 0.7, 2.0, WHITE), ("static square", 0.3, 0.5, GREY)):
            cen = {f: centroid(lum[f], lo, hi, grey)[0] for f in (1, 2, 3)}
            _, mask = centroid(lum[2], lo, hi, grey)
            # The square's inner pixels only (the vectors of edge pixels mix in the background's).
            inner = mask & np.roll(mask, 1, 0) & np.roll(mask, -1, 0) & np.roll(mask, 1, 1) & np.roll(mask, -1, 1)
            v = vec[inner]
            measured = v.astype(np.float64).mean(axis=0)
            spread = float(np.abs(v - measured).max()) if len(v) else float("nan")
            (c1, r1), (c2, r2), (c3, r3) = cen[1], cen[2], cen[3]
            expected = np.array([c1 - c2, -(r1 - r2), c2 - c3, -(r2 - r3)])
            lines.append(f"{camera_kind:5s} {what}: centroid (col, row) f1 ({c1:.2f}, {r1:.2f}) f2 ({c2:.2f}, "
                         f"{r2:.2f}) f3 ({c3:.2f}, {r3:.2f}); frame 2 Vector XYZW over {len(v)} px = "
                         f"{np.round(measured, 3).tolist()} (spread {spread:.3f}), expected "
                         f"{np.round(expected, 3).tolist()}")
            if len(v) < 4 or not np.all(np.abs(measured - expected) <= TOL) or spread > TOL:
                failures.append(lines[-1])
            if np.abs(expected[:2] - expected[2:]).max() < 0.5:
                failures.append(f"{camera_kind} {what}: the test motion does not tell previous from next")
    return failures, lines


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--blender", default="/usr/bin/blender")
    p.add_argument("--keep", default=None, help="render into DIR and keep it (default: a temporary folder)")
    p.add_argument("-v", "--verbose", action="store_true")
    args = p.parse_args()
    if not (os.path.isfile(args.blender) and os.access(args.blender, os.X_OK)):
        print(f"vector_convention_check: SKIP, no Blender at {args.blender}")
        return 77
    try:
        import numpy  # noqa: F401
        import OpenImageIO  # noqa: F401
    except ImportError as e:
        print(f"vector_convention_check: SKIP, {e} (apt-get install python3-numpy python3-openimageio)")
        return 77
    outdir = os.path.abspath(args.keep) if args.keep else tempfile.mkdtemp(prefix="residue-vector-check-")
    os.makedirs(outdir, exist_ok=True)
    try:
        cmd = [args.blender, "-b", "--factory-startup", "-noaudio", "-t", "1", "--python", os.path.abspath(__file__),
               "--", "--render", outdir]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        if r.returncode != 0 or not os.path.isfile(os.path.join(outdir, "persp.3.exr")):
            print(f"vector_convention_check: FAIL, Blender exit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
            return 1
        failures, lines = check(outdir, args.verbose)
    finally:
        if not args.keep:
            shutil.rmtree(outdir, ignore_errors=True)
    if args.verbose or failures:
        print("\n".join(lines))
    if failures:
        print("vector_convention_check: FAIL\n  " + "\n  ".join(failures))
        return 1
    print("vector_convention_check: OK (Vector.XY = previous position - pixel, Vector.ZW = pixel - next position; "
          "pixels, x right, y up)")
    return 0


def _in_blender():
    try:
        import bpy  # noqa: F401
        return True
    except ImportError:
        return False


if _in_blender():  # run by Blender (--python): render, and make Blender exit non-zero on an error
    try:
        argv = sys.argv[sys.argv.index("--") + 1:]
        render(argv[argv.index("--render") + 1])
    except Exception:  # noqa: BLE001
        import traceback
        traceback.print_exc()
        sys.stdout.flush()
        os._exit(1)
elif __name__ == "__main__":
    sys.exit(main())
