"""One seeded procedural scene for Residue's training data, rendered by Debian's Blender (Cycles, CPU).

  blender -b --factory-startup -noaudio -t 2 --python tools/datagen/make_scene.py -- \
      --scene-seed 1000 --renders 8:1001,8:1002,1024:1007 --outdir DIR --res 256 --threads 2

The same --scene-seed always builds the same scene (geometry, materials, lights, camera). Even seeds are
interiors (a room lit through one or two windows and/or by lamps), odd seeds open-air scenes. Every entry of
--renders is SPP:SAMPLING_SEED; they are rendered in this one process (the scene is built once) and named by
--names (default noisy_a,noisy_b,reference for three renders). Noisy renders carry the full AOV set of the
cycles-starter data set (21 channels); the last render (the reference) only ViewLayer.Combined. Writes
DIR/<name>.exr for each render and DIR/scene.json (same format as /work/shared/datasets/cycles-starter).

Brightness: before the real renders a small probe render measures the log-average luminance, and every light
(lamps, emitters, sky) is scaled so that it lands at 0.18 * 2^ev, ev drawn per scene in [-1.5, 1.5]. Lights,
not the film, are scaled, so the indirect clamp (10) means the same thing in every scene.
See tools/datagen/README.md.
"""
import argparse
import json
import math
import os
import random
import resource
import shutil
import subprocess
import sys
import time

import bpy
import bmesh
from mathutils import Matrix, Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import exr_metrics  # noqa: E402  (numpy + OpenImageIO; Blender's Python on Debian is the system Python)
import shots  # noqa: E402  (shot kinds and their random stream, shared with render_shots.py)

T0 = time.time()
NOISY_PASSES = "Combined, Denoising Albedo/Depth/Normal, Depth, DiffCol, GlossCol, Normal"
CLAMP_INDIRECT = 10.0  # Blender's default indirect clamp: every data set so far (a scene's command names another)


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="make_scene.py")
    p.add_argument("--scene-seed", type=int, required=True)
    p.add_argument("--renders", default="8:1001,8:1002,1024:1007", help="SPP:SEED,... (last = reference)")
    p.add_argument("--names", default=None, help="file names without .exr, one per render")
    p.add_argument("--outdir", required=True)
    p.add_argument("--res", type=int, default=256)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--max-bounces", type=int, default=8)
    p.add_argument("--adaptive-threshold", type=float, default=0.0,
                   help="Cycles' adaptive sampling for the noisy renders (not the reference), with this noise "
                        "threshold: the spp given is then the most a pixel gets (0: off, every pixel gets it)")
    p.add_argument("--clamp-indirect", type=float, default=CLAMP_INDIRECT, help="Cycles' indirect clamp (0: none)")
    p.add_argument("--caustics", action="store_true",
                   help="keep caustics and sharp glossy reflections (no glossy filter): the fireflies other "
                        "renderers leave in, which the default settings remove from noisy and reference alike")
    p.add_argument("--probe-res", type=int, default=48, help="auto-exposure probe resolution (0 = no probe)")
    p.add_argument("--probe-spp", type=int, default=16)
    p.add_argument("--save-blend", action="store_true", help="also save DIR/scene.blend (debugging)")
    p.add_argument("--photos", default=None,
                   help="folder of photographs and artwork (searched recursively for .jpg/.png): a share of the "
                        "scene's opaque materials take one as their colour (box-projected, 0.4-3 m per image); "
                        "issue 16's lever 5. Drawn from their own random stream, so the scene is otherwise the "
                        "same as without")
    p.add_argument("--photo-share", type=float, default=0.5, help="share of materials given a photograph")
    p.add_argument("--hdris", default=None,
                   help="folder of .exr/.hdr environment maps: the world (sky, and the view through windows) is one "
                        "of them in 60 %% of scenes, rotated at random")
    p.add_argument("--camera-move", default=None,
                   help="DX,DY,DZ,YAW: move the camera by (DX,DY,DZ) in its own axes (metres) and turn it by YAW "
                        "degrees about the world's up axis, after the scene and its exposure are set (animations: "
                        "tools/datagen/render_animation.py)")
    p.add_argument("--shot", default=None, choices=["auto"] + shots.KINDS,
                   help="render a shot instead of stills: the scene animated over --frames frames (auto: the kind "
                        "drawn from the seed's shot stream); see tools/datagen/README.md, 'Shots and motion vectors'")
    p.add_argument("--frames", type=int, default=16, help="with --shot: the shot's length")
    p.add_argument("--frame-renders", default=None,
                   help="with --shot: SPP:SEEDBASE,... rendered at every frame with sampling seed SEEDBASE + frame "
                        "(last = reference, colour only; the others carry every AOV and the Vector pass), written "
                        "as <name>.####.exr")
    p.add_argument("--render-frames", default=None,
                   help="with --shot: only these frames (e.g. 5-16); the animation is the whole shot's either way")
    p.add_argument("--light-scale-log2", type=float, default=None,
                   help="with --shot: the exposure (log2 of the light scale) instead of the probe's (a resumed "
                        "shot keeps its first run's, which is also read from DIR/shot.json)")
    a = p.parse_args(argv)
    if a.shot:
        if not a.frame_renders:
            p.error("--shot needs --frame-renders SPP:SEEDBASE,...")
        a.frame_render_list = [tuple(int(v) for v in item.split(":")) for item in a.frame_renders.split(",")]
        n = len(a.frame_render_list)
        a.name_list = (a.names.split(",") if a.names else
                       {1: ["reference"], 2: ["noisy", "reference"], 3: ["noisy_a", "noisy_b", "reference"]}.get(
                           n, [f"render_{i}" for i in range(n - 1)] + ["reference"]))
        if len(a.name_list) != n:
            p.error("--names must have one entry per --frame-renders entry")
        a.frame_list = shots.parse_int_list(a.render_frames) if a.render_frames else list(range(1, a.frames + 1))
        if a.frames < 1 or any(f < 1 or f > a.frames for f in a.frame_list):
            p.error(f"--render-frames must lie in 1-{a.frames}")
        return a
    a.render_list = []
    for item in a.renders.split(","):
        spp, seed = item.split(":")
        a.render_list.append((int(spp), int(seed)))
    if a.names:
        a.name_list = a.names.split(",")
    elif len(a.render_list) == 3:
        a.name_list = ["noisy_a", "noisy_b", "reference"]
    elif len(a.render_list) == 2:
        a.name_list = ["noisy_a", "reference"]
    else:
        a.name_list = [f"render_{i}" for i in range(len(a.render_list) - 1)] + ["reference"]
    if len(a.name_list) != len(a.render_list):
        p.error("--names must have one entry per --renders entry")
    return a


def r3(v):
    return [round(float(x), 3) for x in v]


# ----------------------------------------------------------------------------------------------------------
# Scene context: the random stream, the description written into scene.json, and the light sources that the
# auto-exposure scales.
class Ctx:
    def __init__(self, seed):
        self.seed = seed
        self.rng = random.Random(seed * 7919 + 17)
        self.desc = {"scene_seed": seed, "objects": [], "lights": [], "features": []}
        self.light_scalers = []  # (get, set) pairs
        self.collection = bpy.context.scene.collection
        self.protos = {}
        self.mat_count = 0

    def u(self, a, b):
        return self.rng.uniform(a, b)

    def chance(self, p):
        return self.rng.random() < p

    def choice(self, seq):
        return self.rng.choice(seq)

    def feature(self, name):
        if name not in self.desc["features"]:
            self.desc["features"].append(name)

    def scalable(self, owner, attr, index=None):
        if index is None:
            self.light_scalers.append((lambda: getattr(owner, attr), lambda v: setattr(owner, attr, v)))
        else:
            self.light_scalers.append((lambda: owner.default_value, lambda v: setattr(owner, "default_value", v)))

    def scale_lights(self, k):
        for get, put in self.light_scalers:
            put(get() * k)


# ----------------------------------------------------------------------------------------------------------
# Materials. Each returns (material, kind). Texture coordinates are Object coordinates (metres on the boxes,
# which are built at their real size; unit-prototype props get them in their local frame).
def _principled(ctx, name):
    ctx.mat_count += 1
    m = bpy.data.materials.new(f"{name}.{ctx.mat_count}")
    m.use_nodes = True
    nt = m.node_tree
    return m, nt, nt.nodes["Principled BSDF"]


def _coords(nt, scale, rotation=(0.0, 0.0, 0.0)):
    tc = nt.nodes.new("ShaderNodeTexCoord")
    mp = nt.nodes.new("ShaderNodeMapping")
    mp.inputs["Scale"].default_value = scale
    mp.inputs["Rotation"].default_value = rotation
    nt.links.new(tc.outputs["Object"], mp.inputs["Vector"])
    return mp.outputs["Vector"]


def _bump(nt, bsdf, height_socket, strength, distance=0.02):
    b = nt.nodes.new("ShaderNodeBump")
    b.inputs["Strength"].default_value = strength
    b.inputs["Distance"].default_value = distance
    nt.links.new(height_socket, b.inputs["Height"])
    nt.links.new(b.outputs["Normal"], bsdf.inputs["Normal"])


def _ramp(nt, fac_socket, c0, c1):
    r = nt.nodes.new("ShaderNodeValToRGB")
    r.color_ramp.elements[0].color = (*c0, 1.0)
    r.color_ramp.elements[1].color = (*c1, 1.0)
    nt.links.new(fac_socket, r.inputs["Fac"])
    return r.outputs["Color"]


def _hsv(ctx, h=None, s=(0.3, 0.9), v=(0.2, 0.9)):
    import colorsys
    hh = ctx.u(0, 1) if h is None else h
    return colorsys.hsv_to_rgb(hh, ctx.u(*s), ctx.u(*v))


def _scale(c, k):
    return tuple(min(1.0, x * k) for x in c)


def mat_diffuse(ctx, color=None):
    m, nt, b = _principled(ctx, "diffuse")
    b.inputs["Base Color"].default_value = (*(color or _hsv(ctx, s=(0.0, 0.7), v=(0.15, 0.85))), 1)
    b.inputs["Roughness"].default_value = ctx.u(0.7, 1.0)
    b.inputs["Specular"].default_value = 0.3
    return m, "diffuse"


def mat_plastic(ctx):
    m, nt, b = _principled(ctx, "plastic")
    b.inputs["Base Color"].default_value = (*_hsv(ctx, s=(0.4, 1.0), v=(0.1, 0.85)), 1)
    b.inputs["Roughness"].default_value = ctx.u(0.08, 0.5)
    if ctx.chance(0.3):
        b.inputs["Clearcoat"].default_value = 1.0
        b.inputs["Clearcoat Roughness"].default_value = ctx.u(0.0, 0.1)
    return m, "plastic"


def mat_metal(ctx, rough=None):
    m, nt, b = _principled(ctx, "metal")
    tint = ctx.choice([(0.91, 0.92, 0.92), (0.95, 0.64, 0.54), (1.0, 0.78, 0.34), (0.56, 0.57, 0.58),
                       (0.97, 0.96, 0.91), (0.3, 0.5, 0.8)])
    b.inputs["Base Color"].default_value = (*tint, 1)
    b.inputs["Metallic"].default_value = 1.0
    rough = ctx.choice([ctx.u(0.0, 0.08), ctx.u(0.1, 0.45)]) if rough is None else rough
    b.inputs["Roughness"].default_value = rough
    if ctx.chance(0.25):
        b.inputs["Anisotropic"].default_value = ctx.u(0.5, 0.9)
    ctx.feature("metal")
    return m, "metal" if rough < 0.1 else "rough_metal"


def mat_glass(ctx, rough=None):
    m, nt, b = _principled(ctx, "glass")
    tint = ctx.choice([(1, 1, 1), (1, 1, 1), (0.8, 0.95, 0.85), (0.95, 0.85, 0.7), (0.75, 0.85, 1.0)])
    b.inputs["Base Color"].default_value = (*tint, 1)
    b.inputs["Transmission"].default_value = 1.0
    b.inputs["IOR"].default_value = ctx.u(1.4, 1.6)
    rough = ctx.choice([0.0, 0.0, ctx.u(0.05, 0.3)]) if rough is None else rough
    b.inputs["Roughness"].default_value = rough
    ctx.feature("glass")
    return m, "glass" if rough == 0.0 else "rough_glass"


def mat_emission(ctx, strength=None, color=None):
    ctx.mat_count += 1
    m = bpy.data.materials.new(f"emission.{ctx.mat_count}")
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    e = nt.nodes.new("ShaderNodeEmission")
    col = color or ctx.choice([(1.0, 0.85, 0.6), (1.0, 0.75, 0.45), (1.0, 0.95, 0.9), (0.7, 0.85, 1.0),
                               _hsv(ctx, s=(0.5, 1.0), v=(1.0, 1.0))])
    e.inputs["Color"].default_value = (*col, 1)
    e.inputs["Strength"].default_value = strength if strength is not None else ctx.u(3.0, 25.0)
    nt.links.new(e.outputs["Emission"], nt.nodes["Material Output"].inputs["Surface"])
    ctx.scalable(e.inputs["Strength"], "default_value", index=0)
    ctx.feature("emissive")
    return m, "emission"


def mat_wood(ctx, gloss=True):
    """Planks (an elongated Brick texture: per-plank colour, grooves) with Wave/Noise grain."""
    m, nt, b = _principled(ctx, "wood")
    v = _coords(nt, (1.0, 1.0, 1.0), (0.0, 0.0, ctx.choice([0.0, math.pi / 2])))
    base = _hsv(ctx, h=ctx.u(0.04, 0.1), s=(0.45, 0.8), v=(0.15, 0.6))
    brick = nt.nodes.new("ShaderNodeTexBrick")
    brick.inputs["Color1"].default_value = (*base, 1)
    brick.inputs["Color2"].default_value = (*_scale(base, ctx.u(0.6, 0.85)), 1)
    brick.inputs["Mortar"].default_value = (*_scale(base, 0.3), 1)
    brick.inputs["Scale"].default_value = 1.0
    brick.inputs["Mortar Size"].default_value = 0.004
    brick.inputs["Brick Width"].default_value = ctx.u(0.8, 2.0)
    brick.inputs["Row Height"].default_value = ctx.u(0.1, 0.25)
    brick.offset = ctx.u(0.3, 0.7)
    nt.links.new(v, brick.inputs["Vector"])
    wave = nt.nodes.new("ShaderNodeTexWave")
    wave.wave_type = "BANDS"
    wave.bands_direction = "X"
    wave.inputs["Scale"].default_value = ctx.u(2.0, 6.0)
    wave.inputs["Distortion"].default_value = ctx.u(3.0, 10.0)
    wave.inputs["Detail"].default_value = 3.0
    wave.inputs["Detail Scale"].default_value = ctx.u(1.0, 3.0)
    mp = nt.nodes.new("ShaderNodeMapping")
    mp.inputs["Scale"].default_value = (0.25, 4.0, 1.0)
    nt.links.new(v, mp.inputs["Vector"])
    nt.links.new(mp.outputs["Vector"], wave.inputs["Vector"])
    grain = _ramp(nt, wave.outputs["Fac"], (0.55, 0.55, 0.55), (1.0, 1.0, 1.0))
    mix = nt.nodes.new("ShaderNodeMixRGB")
    mix.blend_type = "MULTIPLY"
    mix.inputs["Fac"].default_value = 1.0
    nt.links.new(brick.outputs["Color"], mix.inputs["Color1"])
    nt.links.new(grain, mix.inputs["Color2"])
    nt.links.new(mix.outputs["Color"], b.inputs["Base Color"])
    _bump(nt, b, brick.outputs["Fac"], 0.3, 0.005)
    b.inputs["Roughness"].default_value = ctx.u(0.08, 0.3) if gloss else ctx.u(0.4, 0.7)
    if gloss and ctx.chance(0.5):
        b.inputs["Clearcoat"].default_value = ctx.u(0.3, 1.0)
    return m, "wood"


def mat_plaster(ctx, color=None):
    """Painted plaster: Musgrave colour variation, Noise bump."""
    m, nt, b = _principled(ctx, "plaster")
    v = _coords(nt, (1.0, 1.0, 1.0))
    c = color or ctx.choice([(0.8, 0.78, 0.72), (0.85, 0.85, 0.85), (0.75, 0.7, 0.62)] +
                            [_hsv(ctx, s=(0.1, 0.45), v=(0.45, 0.85))] * 2)
    mus = nt.nodes.new("ShaderNodeTexMusgrave")
    mus.inputs["Scale"].default_value = ctx.u(1.0, 4.0)
    nt.links.new(v, mus.inputs["Vector"])
    col = _ramp(nt, mus.outputs["Fac"], _scale(c, ctx.u(0.8, 0.95)), c)
    nt.links.new(col, b.inputs["Base Color"])
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = ctx.u(20.0, 80.0)
    noise.inputs["Detail"].default_value = 3.0
    nt.links.new(v, noise.inputs["Vector"])
    if ctx.chance(0.6):  # the bump costs ~30 % of an interior's render time: not on every wall
        _bump(nt, b, noise.outputs["Fac"], ctx.u(0.05, 0.25), 0.01)
    b.inputs["Roughness"].default_value = ctx.u(0.75, 0.95)
    b.inputs["Specular"].default_value = 0.3
    return m, "plaster"


def mat_tiles(ctx, size=None):
    """Glazed tiles: Brick texture with no offset, mortar grooves as bump."""
    m, nt, b = _principled(ctx, "tiles")
    v = _coords(nt, (1.0, 1.0, 1.0))
    s = size or ctx.u(0.1, 0.4)
    c = _hsv(ctx, s=(0.0, 0.6), v=(0.2, 0.9))
    brick = nt.nodes.new("ShaderNodeTexBrick")
    brick.offset = ctx.choice([0.0, 0.0, 0.5])
    brick.inputs["Color1"].default_value = (*c, 1)
    brick.inputs["Color2"].default_value = (*_scale(c, ctx.u(0.75, 1.0)), 1)
    brick.inputs["Mortar"].default_value = (*ctx.choice([(0.6, 0.6, 0.58), (0.1, 0.1, 0.1), (0.85, 0.85, 0.8)]), 1)
    brick.inputs["Scale"].default_value = 1.0
    brick.inputs["Mortar Size"].default_value = s * ctx.u(0.03, 0.06)
    brick.inputs["Brick Width"].default_value = s * ctx.choice([1.0, 1.0, 2.0])
    brick.inputs["Row Height"].default_value = s
    nt.links.new(v, brick.inputs["Vector"])
    nt.links.new(brick.outputs["Color"], b.inputs["Base Color"])
    _bump(nt, b, brick.outputs["Fac"], -0.6, 0.004)
    b.inputs["Roughness"].default_value = ctx.u(0.03, 0.25)
    return m, "tiles"


def mat_fabric(ctx):
    """Cloth: Checker (gingham) or Voronoi colour, sheen, fine Wave bump for the weave."""
    m, nt, b = _principled(ctx, "fabric")
    v = _coords(nt, (1.0, 1.0, 1.0))
    c0 = _hsv(ctx, s=(0.3, 0.9), v=(0.1, 0.7))
    c1 = _scale(c0, ctx.u(0.3, 0.7)) if ctx.chance(0.5) else _hsv(ctx, s=(0.0, 0.5), v=(0.5, 0.9))
    if ctx.chance(0.5):
        t = nt.nodes.new("ShaderNodeTexChecker")
        t.inputs["Scale"].default_value = ctx.u(4.0, 30.0)
        t.inputs["Color1"].default_value = (*c0, 1)
        t.inputs["Color2"].default_value = (*c1, 1)
        nt.links.new(v, t.inputs["Vector"])
        nt.links.new(t.outputs["Color"], b.inputs["Base Color"])
    else:
        t = nt.nodes.new("ShaderNodeTexVoronoi")
        t.inputs["Scale"].default_value = ctx.u(5.0, 40.0)
        nt.links.new(v, t.inputs["Vector"])
        nt.links.new(_ramp(nt, t.outputs["Distance"], c0, c1), b.inputs["Base Color"])
    wv = nt.nodes.new("ShaderNodeTexWave")
    wv.inputs["Scale"].default_value = ctx.u(80.0, 200.0)
    nt.links.new(v, wv.inputs["Vector"])
    _bump(nt, b, wv.outputs["Fac"], 0.2, 0.002)
    b.inputs["Roughness"].default_value = 1.0
    b.inputs["Sheen"].default_value = ctx.u(0.3, 1.0)
    b.inputs["Specular"].default_value = 0.2
    return m, "fabric"


def mat_marble(ctx):
    m, nt, b = _principled(ctx, "marble")
    v = _coords(nt, (1.0, 1.0, 1.0))
    n = nt.nodes.new("ShaderNodeTexNoise")
    n.inputs["Scale"].default_value = ctx.u(1.0, 5.0)
    n.inputs["Detail"].default_value = 10.0
    n.inputs["Distortion"].default_value = ctx.u(2.0, 8.0)
    nt.links.new(v, n.inputs["Vector"])
    c = ctx.choice([(0.9, 0.9, 0.88), (0.1, 0.1, 0.1), (0.6, 0.5, 0.4), (0.3, 0.45, 0.35)])
    nt.links.new(_ramp(nt, n.outputs["Fac"], _scale(c, 0.4), c), b.inputs["Base Color"])
    b.inputs["Roughness"].default_value = ctx.u(0.05, 0.25)
    return m, "marble"


def mat_checker(ctx):
    m, nt, b = _principled(ctx, "checker")
    v = _coords(nt, (1.0, 1.0, 1.0))
    t = nt.nodes.new("ShaderNodeTexChecker")
    t.inputs["Scale"].default_value = ctx.u(0.5, 4.0)
    t.inputs["Color1"].default_value = (*_hsv(ctx, s=(0.0, 0.6), v=(0.5, 0.9)), 1)
    t.inputs["Color2"].default_value = (*_hsv(ctx, s=(0.0, 0.6), v=(0.03, 0.3)), 1)
    nt.links.new(v, t.inputs["Vector"])
    nt.links.new(t.outputs["Color"], b.inputs["Base Color"])
    b.inputs["Roughness"].default_value = ctx.u(0.2, 0.9)
    return m, "checker"


def mat_noise_color(ctx):
    m, nt, b = _principled(ctx, "noise")
    v = _coords(nt, (1.0, 1.0, 1.0))
    n = nt.nodes.new("ShaderNodeTexNoise")
    n.inputs["Scale"].default_value = ctx.u(2.0, 20.0)
    n.inputs["Detail"].default_value = 6.0
    nt.links.new(v, n.inputs["Vector"])
    nt.links.new(_ramp(nt, n.outputs["Fac"], _hsv(ctx, v=(0.05, 0.5)), _hsv(ctx, v=(0.4, 0.9))),
                 b.inputs["Base Color"])
    b.inputs["Roughness"].default_value = ctx.u(0.3, 0.9)
    return m, "noise"


def mat_prop(ctx):
    """A material for a small object: anything but the room's own surfaces."""
    f = ctx.choice([mat_plastic, mat_plastic, mat_diffuse, mat_metal, mat_metal, mat_glass, mat_glass,
                    mat_marble, mat_fabric, mat_checker, mat_noise_color, mat_wood])
    if ctx.chance(0.04):
        return mat_emission(ctx)
    return f(ctx)


# ----------------------------------------------------------------------------------------------------------
# Geometry. Props share unit prototype meshes (size 1, centred, base at z = -0.5) with object-linked
# materials; boxes are built at their real size so bevels and textures are in metres.
def _finish_mesh(me, smooth=True, angle=35.0):
    for poly in me.polygons:
        poly.use_smooth = smooth
    me.use_auto_smooth = True
    me.auto_smooth_angle = math.radians(angle)


def _bm_to_mesh(bm, name, smooth=True):
    me = bpy.data.meshes.new(name)
    bm.to_mesh(me)
    bm.free()
    _finish_mesh(me, smooth)
    return me


def proto(ctx, kind):
    if kind in ctx.protos:
        return ctx.protos[kind]
    bm = bmesh.new()
    if kind == "cube":
        bmesh.ops.create_cube(bm, size=1.0)
    elif kind == "cylinder":
        bmesh.ops.create_cone(bm, cap_ends=True, segments=32, radius1=0.5, radius2=0.5, depth=1.0)
    elif kind == "cone":
        bmesh.ops.create_cone(bm, cap_ends=True, segments=32, radius1=0.5, radius2=0.0, depth=1.0)
    elif kind == "shade":  # an open lamp shade (no caps), base at z = -0.5
        bmesh.ops.create_cone(bm, cap_ends=False, segments=32, radius1=0.5, radius2=0.3, depth=1.0)
    elif kind == "sphere":
        bmesh.ops.create_uvsphere(bm, u_segments=48, v_segments=24, radius=0.5)
    elif kind == "icosphere":
        bmesh.ops.create_icosphere(bm, subdivisions=2, radius=0.5)
    elif kind == "monkey":
        bmesh.ops.create_monkey(bm)
        bmesh.ops.scale(bm, vec=(0.37, 0.37, 0.37), verts=bm.verts)
        bmesh.ops.translate(bm, vec=(0.0, 0.0, -0.5 - min(v.co.z for v in bm.verts)), verts=bm.verts)
    elif kind == "torus":
        big, small, nu, nv = 0.35, 0.15, 48, 16
        grid = []
        for i in range(nu):
            a = 2 * math.pi * i / nu
            row = []
            for j in range(nv):
                c = 2 * math.pi * j / nv
                row.append(bm.verts.new(((big + small * math.cos(c)) * math.cos(a),
                                         (big + small * math.cos(c)) * math.sin(a), small * math.sin(c))))
            grid.append(row)
        for i in range(nu):
            for j in range(nv):
                bm.faces.new((grid[i][j], grid[(i + 1) % nu][j], grid[(i + 1) % nu][(j + 1) % nv],
                              grid[i][(j + 1) % nv]))
    else:
        raise ValueError(kind)
    me = _bm_to_mesh(bm, f"proto_{kind}", smooth=kind != "cube")
    me.materials.append(None)
    ctx.protos[kind] = me
    return me


def link(ctx, obj):
    ctx.collection.objects.link(obj)
    return obj


def prop(ctx, kind, mat, loc, size, rot=(0.0, 0.0, 0.0), record=True):
    """A prototype object of the given overall size (scalar or xyz), resting with its base at loc.z."""
    me = proto(ctx, kind)
    obj = link(ctx, bpy.data.objects.new(kind, me))
    sx, sy, sz = (size, size, size) if isinstance(size, (int, float)) else size
    obj.scale = (sx, sy, sz)
    obj.location = (loc[0], loc[1], loc[2] + (0.5 * sz if kind not in ("torus",) else 0.15 * sz))
    obj.rotation_euler = rot
    obj.material_slots[0].link = "OBJECT"
    obj.material_slots[0].material = mat[0]
    if kind == "monkey":
        mod = obj.modifiers.new("subsurf", "SUBSURF")
        mod.levels = mod.render_levels = 2
    if record:
        ctx.desc["objects"].append({"type": kind, "material": mat[1], "loc": r3(loc), "size": r3(obj.scale)})
    return obj


def box(ctx, mat, lo, hi, bevel=0.0, name="box", record=True, rot_z=0.0):
    """An axis-aligned box from corner lo to corner hi (rotated by rot_z about its centre), optionally bevelled."""
    lo, hi = Vector(lo), Vector(hi)
    size = hi - lo
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    bmesh.ops.scale(bm, vec=size, verts=bm.verts)
    me = _bm_to_mesh(bm, name, smooth=bevel > 0)
    me.materials.append(mat[0])
    obj = link(ctx, bpy.data.objects.new(name, me))
    obj.location = (lo + hi) * 0.5
    obj.rotation_euler = (0.0, 0.0, rot_z)
    if bevel > 0:
        mod = obj.modifiers.new("bevel", "BEVEL")
        mod.width = min(bevel, 0.45 * min(size))
        mod.segments = 3
        mod.limit_method = "ANGLE"
    if record:
        ctx.desc["objects"].append({"type": name, "material": mat[1], "loc": r3(obj.location), "size": r3(size)})
    return obj


def curves(ctx, mat, polylines, radius, name="wires", record=True):
    """Many thin tubes (one curve object, one spline per polyline)."""
    cu = bpy.data.curves.new(name, "CURVE")
    cu.dimensions = "3D"
    cu.bevel_depth = radius
    cu.bevel_resolution = 1
    cu.fill_mode = "FULL"
    cu.use_fill_caps = True
    for pts in polylines:
        sp = cu.splines.new("POLY")
        sp.points.add(len(pts) - 1)
        for p, q in zip(sp.points, pts):
            p.co = (q[0], q[1], q[2], 1.0)
    cu.materials.append(mat[0])
    obj = link(ctx, bpy.data.objects.new(name, cu))
    if record:
        ctx.desc["objects"].append({"type": name, "material": mat[1], "count": len(polylines),
                                    "radius": round(radius, 4)})
    ctx.feature("thin_geometry")
    return obj


def look_at(obj, target):
    d = Vector(target) - obj.location
    obj.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()


def add_light(ctx, kind, loc, energy, size=0.5, target=None, color=(1.0, 1.0, 1.0), rot=None, angle=None):
    ld = bpy.data.lights.new(kind.lower(), kind)
    ld.energy = energy
    ld.color = color
    if kind == "AREA":
        ld.shape = "DISK" if ctx.chance(0.5) else "RECTANGLE"
        ld.size = size
        ld.size_y = size * ctx.u(0.5, 1.5)
    elif kind in ("POINT", "SPOT"):
        ld.shadow_soft_size = size
    elif kind == "SUN":
        ld.angle = angle if angle is not None else math.radians(ctx.u(0.5, 3.0))
    obj = link(ctx, bpy.data.objects.new(kind.lower(), ld))
    obj.location = loc
    if target is not None:
        look_at(obj, target)
    elif rot is not None:
        obj.rotation_euler = rot
    ctx.scalable(ld, "energy")
    ctx.desc["lights"].append({"type": kind, "loc": r3(loc), "energy": round(energy, 3), "size": round(size, 3),
                               "color": r3(color)})
    return obj


def sun_towards(ctx, direction, strength, angle_deg=None):
    """A sun lamp whose light travels along `direction`."""
    d = Vector(direction).normalized()
    ld = bpy.data.lights.new("sun", "SUN")
    ld.energy = strength
    ld.angle = math.radians(angle_deg if angle_deg is not None else ctx.u(0.5, 4.0))
    ld.color = ctx.choice([(1.0, 0.95, 0.85), (1.0, 0.85, 0.65), (1.0, 1.0, 1.0)])
    obj = link(ctx, bpy.data.objects.new("sun", ld))
    obj.location = -d * 20
    obj.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()
    ctx.scalable(ld, "energy")
    ctx.desc["lights"].append({"type": "SUN", "direction": r3(d), "strength": round(strength, 3),
                               "angle_deg": round(math.degrees(ld.angle), 2)})
    return obj


def world(ctx, kind, strength, sun_dir=None):
    """kind: nishita (physical sky, no sun disc), hosek, gradient, constant."""
    w = bpy.data.worlds.new("world")
    w.use_nodes = True
    nt = w.node_tree
    bg = nt.nodes["Background"]
    bg.inputs["Strength"].default_value = strength
    info = {"type": kind, "strength": round(strength, 4)}
    if kind in ("nishita", "hosek"):
        sky = nt.nodes.new("ShaderNodeTexSky")
        d = Vector(sun_dir or (0.3, 0.4, -0.6)).normalized()
        elev = math.asin(max(0.02, -d.z))
        rot = math.atan2(-d.x, -d.y)  # sky's sun azimuth: 0 = +Y, anticlockwise... close enough for a sky
        if kind == "nishita":
            sky.sky_type = "NISHITA"
            sky.sun_disc = False
            sky.sun_elevation = elev
            sky.sun_rotation = rot
            sky.air_density = ctx.u(0.5, 2.0)
            sky.dust_density = ctx.u(0.0, 3.0)
        else:
            sky.sky_type = "HOSEK_WILKIE"
            sky.sun_direction = -d
            sky.turbidity = ctx.u(2.0, 6.0)
            sky.ground_albedo = 0.3
        nt.links.new(sky.outputs["Color"], bg.inputs["Color"])
        info["sun_elevation_deg"] = round(math.degrees(elev), 1)
    elif kind == "gradient":
        tc = nt.nodes.new("ShaderNodeTexCoord")
        sep = nt.nodes.new("ShaderNodeSeparateXYZ")
        nt.links.new(tc.outputs["Generated"], sep.inputs["Vector"])
        top = ctx.choice([(0.35, 0.5, 0.9), (0.8, 0.85, 0.9), (0.1, 0.12, 0.3), (0.9, 0.6, 0.4)])
        bottom = ctx.choice([(0.9, 0.85, 0.75), (0.3, 0.3, 0.3), (0.6, 0.7, 0.8), (1.0, 0.8, 0.6)])
        ramp = _ramp(nt, sep.outputs["Z"], bottom, top)  # Generated = the view direction in the world
        ramp.node.color_ramp.elements[0].position = 0.0
        ramp.node.color_ramp.elements[1].position = ctx.u(0.3, 0.8)
        nt.links.new(ramp, bg.inputs["Color"])
        info["top"], info["bottom"] = r3(top), r3(bottom)
    else:
        c = _hsv(ctx, s=(0.0, 0.4), v=(0.5, 1.0))
        bg.inputs["Color"].default_value = (*c, 1)
        info["color"] = r3(c)
    ctx.scalable(bg.inputs["Strength"], "default_value", index=0)
    bpy.context.scene.world = w
    ctx.desc["world"] = info
    return w


# ----------------------------------------------------------------------------------------------------------
# Photographs (issue 16, lever 5): real image statistics on the surfaces and in the sky. Applied after the scene
# is built, from a random stream of their own, so that --scene-seed builds the same geometry, lights and camera
# with or without them.
PHOTO_SKIP = ("emission", "glass", "grass_hair")  # light sources, transmission, hair: their colour stays


def image_files(folder, exts):
    out = []
    for root, _dirs, files in os.walk(folder):
        out += [os.path.join(root, f) for f in files if f.lower().endswith(exts) and not f.startswith("screenshot")]
    return sorted(out)


def image_licence(path):
    """The licence recorded beside an image: a KDE wallpaper's metadata.json (../../ from contents/images), or a
    license.txt in its folder (Blender's studio lights: CC0)."""
    meta = os.path.join(os.path.dirname(path), "..", "..", "metadata.json")
    if os.path.isfile(meta):
        with open(meta) as f:
            k = json.load(f).get("KPlugin", {})
        authors = ", ".join(a.get("Name", "") for a in k.get("Authors", []))
        return f"{k.get('License', 'see the package copyright')} ({authors})" if authors else k.get("License", "")
    lic = os.path.join(os.path.dirname(path), "license.txt")
    if os.path.isfile(lic):
        with open(lic) as f:
            return " ".join(f.read().split())[:200]
    return "see the package copyright"


def photo_material(rng, m, path):
    """Replace the Principled BSDF's base colour by the photograph, box-projected in object space."""
    nt = m.node_tree
    bsdf = next((n for n in nt.nodes if n.type == "BSDF_PRINCIPLED"), None)
    if bsdf is None:
        return None
    size = rng.uniform(0.4, 3.0)
    tc = nt.nodes.new("ShaderNodeTexCoord")
    mp = nt.nodes.new("ShaderNodeMapping")
    mp.inputs["Scale"].default_value = (1.0 / size,) * 3
    mp.inputs["Location"].default_value = (rng.uniform(0, 1), rng.uniform(0, 1), rng.uniform(0, 1))
    mp.inputs["Rotation"].default_value = (0.0, 0.0, rng.choice([0.0, math.pi / 2]))
    nt.links.new(tc.outputs["Object"], mp.inputs["Vector"])
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(path, check_existing=True)
    tex.projection = "BOX"
    tex.projection_blend = 0.2
    tex.extension = "REPEAT"
    nt.links.new(mp.outputs["Vector"], tex.inputs["Vector"])
    gain = rng.uniform(0.5, 1.0)  # photographs are bright; albedos of real surfaces mostly are not
    mix = nt.nodes.new("ShaderNodeMixRGB")
    mix.blend_type = "MULTIPLY"
    mix.inputs["Fac"].default_value = 1.0
    mix.inputs["Color2"].default_value = (gain, gain, gain, 1.0)
    nt.links.new(tex.outputs["Color"], mix.inputs["Color1"])
    for link in list(bsdf.inputs["Base Color"].links):
        nt.links.remove(link)
    nt.links.new(mix.outputs["Color"], bsdf.inputs["Base Color"])
    return {"material": m.name, "image": path, "licence": image_licence(path), "size_m": round(size, 3),
            "gain": round(gain, 3)}


def hdri_world(rng, path):
    """The world's background colour from an environment map (its strength, scaled by the exposure, is kept)."""
    w = bpy.context.scene.world
    nt = w.node_tree
    bg = nt.nodes["Background"]
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(path, check_existing=True)
    tc = nt.nodes.new("ShaderNodeTexCoord")
    mp = nt.nodes.new("ShaderNodeMapping")
    mp.inputs["Rotation"].default_value = (0.0, 0.0, rng.uniform(0, 2 * math.pi))
    nt.links.new(tc.outputs["Generated"], mp.inputs["Vector"])
    nt.links.new(mp.outputs["Vector"], env.inputs["Vector"])
    for link in list(bg.inputs["Color"].links):
        nt.links.remove(link)
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    return {"image": path, "licence": image_licence(path), "rotation_deg": round(math.degrees(mp.inputs["Rotation"].default_value[2]), 1)}


def apply_photos(ctx, args):
    rng = random.Random(ctx.seed * 104729 + 3)
    if args.photos:
        photos = image_files(args.photos, (".jpg", ".jpeg", ".png"))
        if not photos:
            raise SystemExit(f"make_scene: no .jpg/.png images under --photos {args.photos}")
        used = []
        for m in sorted(bpy.data.materials, key=lambda m: m.name):
            if not m.use_nodes or m.name.startswith(PHOTO_SKIP) or rng.random() >= args.photo_share:
                continue
            info = photo_material(rng, m, rng.choice(photos))
            if info:
                used.append(info)
        ctx.desc["photos"] = used
        ctx.feature("photographs")
    if args.hdris and bpy.context.scene.world is not None and rng.random() < 0.6:
        maps = image_files(args.hdris, (".exr", ".hdr"))
        if not maps:
            raise SystemExit(f"make_scene: no .exr/.hdr maps under --hdris {args.hdris}")
        ctx.desc["world"]["hdri"] = hdri_world(rng, rng.choice(maps))
        ctx.feature("hdri")


def camera(ctx, loc, target, lens, dof_focus=None, fstop=None):
    cd = bpy.data.cameras.new("camera")
    cd.lens = lens
    cd.sensor_width = 36.0
    cd.clip_start = 0.01
    cd.clip_end = 1000.0
    obj = link(ctx, bpy.data.objects.new("camera", cd))
    obj.location = loc
    look_at(obj, target)
    if dof_focus is not None:
        cd.dof.use_dof = True
        cd.dof.focus_distance = dof_focus
        cd.dof.aperture_fstop = fstop
        cd.dof.aperture_blades = ctx.choice([0, 0, 5, 6])
        ctx.feature("depth_of_field")
    bpy.context.scene.camera = obj
    ctx.desc["camera"] = {"lens_mm": round(lens, 2), "loc": r3(loc), "target": r3(target),
                          "dof": dof_focus is not None,
                          "fstop": round(fstop, 2) if fstop else None,
                          "focus": round(dof_focus, 3) if dof_focus else None}
    return obj


# ----------------------------------------------------------------------------------------------------------
# Interiors: a closed room (floor, ceiling and walls are boxes that overlap at the corners, so nothing leaks)
# with one or two windows left as gaps between wall boxes; furniture along the walls and in the middle, shelves
# of small objects, lamps; sun and/or sky through the windows, or lamps only at night.
class WallFrame:
    """Coordinates along a wall: a along it, b from its inner face into the room, z up."""

    def __init__(self, side, x0, x1, y0, y1):
        self.side, self.x0, self.x1, self.y0, self.y1 = side, x0, x1, y0, y1
        self.amin, self.amax = (x0, x1) if side in ("far", "back") else (y0, y1)
        self.normal = Vector({"far": (0, -1, 0), "back": (0, 1, 0), "left": (1, 0, 0), "right": (-1, 0, 0)}[side])
        self.tangent = Vector({"far": (1, 0, 0), "back": (1, 0, 0), "left": (0, 1, 0), "right": (0, 1, 0)}[side])
        self.yaw = {"far": 0.0, "back": math.pi, "left": math.pi / 2, "right": -math.pi / 2}[side]
        self.used = []  # (a0, a1, height) of what stands against this wall

    def world(self, a, b, z):
        return Vector({"far": (a, self.y1 - b, z), "back": (a, self.y0 + b, z),
                       "left": (self.x0 + b, a, z), "right": (self.x1 - b, a, z)}[self.side])

    def box(self, ctx, mat, a0, a1, b0, b1, z0, z1, **kw):
        p, q = self.world(a0, b0, z0), self.world(a1, b1, z1)
        return box(ctx, mat, [min(u, v) for u, v in zip(p, q)], [max(u, v) for u, v in zip(p, q)], **kw)

    def free_span(self, ctx, width, height, windows, margin=0.15):
        """A centre a where [a - width/2, a + width/2] is free (and clear of windows when taller than a sill)."""
        lo, hi = self.amin + margin + width / 2, self.amax - margin - width / 2
        if hi <= lo:
            return None
        for _ in range(20):
            a = ctx.u(lo, hi)
            spans = [(u0, u1) for u0, u1, _h in self.used]
            spans += [(w["a"] - w["w"] / 2, w["a"] + w["w"] / 2) for w in windows if height > w["sill"] - 0.05]
            if all(a + width / 2 + 0.05 < u0 or a - width / 2 - 0.05 > u1 for u0, u1 in spans):
                self.used.append((a - width / 2, a + width / 2, height))
                return a
        return None


class Palette:
    """A few materials shared by the small objects of a scene (and a new one now and then)."""

    def __init__(self, ctx, n=8):
        self.ctx = ctx
        self.mats = [mat_prop(ctx) for _ in range(n)]
        self.books = [ctx.choice([mat_diffuse, mat_fabric, mat_plastic])(ctx) for _ in range(5)]

    def pick(self):
        return mat_prop(self.ctx) if self.ctx.chance(0.15) else self.ctx.choice(self.mats)


SMALL_KINDS = ["cube", "cylinder", "cylinder", "sphere", "sphere", "monkey", "torus", "cone", "icosphere"]


def small_object(ctx, pal, at, max_size, yaw=0.0):
    kind = ctx.choice(SMALL_KINDS)
    s = ctx.u(0.4, 1.0) * max_size
    if kind == "cylinder":
        size = (s * ctx.u(0.4, 0.9), ) * 2 + (s,)
    elif kind == "sphere" and ctx.chance(0.3):  # a bowl-ish flattened sphere
        size = (s, s, s * 0.45)
    else:
        size = s
    rot = (0.0, 0.0, yaw + ctx.u(-0.6, 0.6))
    if kind == "torus" and ctx.chance(0.5):
        rot = (math.pi / 2, 0.0, yaw + ctx.u(-0.6, 0.6))
        obj = prop(ctx, kind, pal.pick(), at, s, rot)
        obj.location.z = at[2] + 0.5 * s
        return obj
    return prop(ctx, kind, pal.pick(), at, size, rot)


def block(ctx, lo, hi):
    ctx.blocks.append((Vector(lo), Vector(hi)))


def shelf(ctx, wf, pal, windows, H):
    w, d, h = ctx.u(0.6, 1.6), ctx.u(0.25, 0.4), ctx.u(1.0, min(2.3, H - 0.2))
    a = wf.free_span(ctx, w, h, windows)
    if a is None:
        return
    mat = ctx.choice([mat_wood(ctx, gloss=False), mat_diffuse(ctx), mat_metal(ctx, rough=0.3)])
    th = 0.025
    a0, a1 = a - w / 2, a + w / 2
    wf.box(ctx, mat, a0, a0 + th, 0, d, 0, h, bevel=0.004, name="shelf_side")
    wf.box(ctx, mat, a1 - th, a1, 0, d, 0, h, bevel=0.004, name="shelf_side", record=False)
    wf.box(ctx, mat, a0, a1, 0, 0.012, 0, h, name="shelf_back", record=False)
    n = ctx.rng.randint(3, 5)
    levels = [0.06 + i * (h - 0.06 - th) / (n - 1) for i in range(n)]
    for i, z in enumerate(levels):
        wf.box(ctx, mat, a0 + th, a1 - th, 0.012, d, z, z + th, bevel=0.003, name="shelf_board", record=False)
        if i == len(levels) - 1:
            gap = 0.3
        else:
            gap = levels[i + 1] - z - th
        ztop = z + th
        cur = a0 + th + 0.02
        while cur < a1 - th - 0.06:
            if ctx.chance(0.3):  # a row of books
                for _ in range(ctx.rng.randint(3, 10)):
                    bw = ctx.u(0.015, 0.05)
                    if cur + bw > a1 - th - 0.01:
                        break
                    bh = min(gap - 0.01, ctx.u(0.15, 0.3))
                    bd = min(d - 0.03, ctx.u(0.12, 0.24))
                    wf.box(ctx, ctx.choice(pal.books), cur, cur + bw, 0.02, 0.02 + bd, ztop, ztop + bh,
                           bevel=0.002, name="book")
                    cur += bw + ctx.u(0.0, 0.004)
                cur += ctx.u(0.02, 0.08)
            else:
                s = min(gap * 0.85, d * 0.8, ctx.u(0.05, 0.2))
                if cur + s > a1 - th - 0.01:
                    break
                small_object(ctx, pal, wf.world(cur + s / 2, d * ctx.u(0.4, 0.6), ztop), s, wf.yaw)
                cur += s + ctx.u(0.01, 0.1)
        if ctx.chance(0.12) and i > 0:  # an LED strip under the board
            wf.box(ctx, mat_emission(ctx, ctx.u(5, 20)), a0 + th, a1 - th, d - 0.02, d - 0.01, z - 0.006, z,
                   name="led_strip")
    ctx.spots.append(wf.world(a, d * 0.5, levels[len(levels) // 2] + 0.1))
    block(ctx, wf.world(a0, 0, 0), wf.world(a1, d, h))


def cabinet(ctx, wf, pal, windows):
    w, d, h = ctx.u(0.5, 1.6), ctx.u(0.35, 0.6), ctx.u(0.45, 1.0)
    a = wf.free_span(ctx, w, h, windows)
    if a is None:
        return
    mat = ctx.choice([mat_wood(ctx, gloss=True), mat_plastic(ctx), mat_diffuse(ctx)])
    wf.box(ctx, mat, a - w / 2, a + w / 2, 0, d, 0.08, h, bevel=0.015, name="cabinet")
    for s in (-1, 1):
        prop(ctx, "cylinder", ctx.choice(pal.mats), wf.world(a + s * (w / 2 - 0.05), d - 0.05, 0), (0.03, 0.03, 0.08),
             record=False)
        prop(ctx, "cylinder", ctx.choice(pal.mats), wf.world(a + s * (w / 2 - 0.05), 0.05, 0), (0.03, 0.03, 0.08),
             record=False)
    if ctx.chance(0.5):  # handles / drawer lines
        hm = mat_metal(ctx, rough=0.2)
        for k in range(ctx.rng.randint(1, 3)):
            z = 0.08 + (h - 0.08) * (k + 0.5) / 3
            wf.box(ctx, hm, a - 0.08, a + 0.08, d, d + 0.015, z - 0.008, z + 0.008, bevel=0.004, name="handle",
                   record=False)
    n = ctx.rng.randint(1, 4)
    for _ in range(n):
        small_object(ctx, pal, wf.world(a + ctx.u(-w / 2 + 0.1, w / 2 - 0.1), d * ctx.u(0.3, 0.7), h),
                     ctx.u(0.08, 0.3), wf.yaw)
    if ctx.chance(0.35):
        table_lamp(ctx, wf.world(a + ctx.u(-w / 3, w / 3), d * 0.5, h))
    ctx.spots.append(wf.world(a, d * 0.5, h + 0.1))
    block(ctx, wf.world(a - w / 2, 0, 0), wf.world(a + w / 2, d, h))


def sofa(ctx, wf, windows):
    w = ctx.u(1.4, 2.4)
    a = wf.free_span(ctx, w, 0.9, windows)
    if a is None:
        return
    fab = mat_fabric(ctx)
    a0, a1 = a - w / 2, a + w / 2
    wf.box(ctx, fab, a0 + 0.15, a1 - 0.15, 0.2, 0.9, 0.12, 0.42, bevel=0.06, name="sofa_seat")
    wf.box(ctx, fab, a0, a1, 0.0, 0.25, 0.12, 0.85, bevel=0.07, name="sofa_back", record=False)
    wf.box(ctx, fab, a0, a0 + 0.18, 0.0, 0.9, 0.12, 0.62, bevel=0.06, name="sofa_arm", record=False)
    wf.box(ctx, fab, a1 - 0.18, a1, 0.0, 0.9, 0.12, 0.62, bevel=0.06, name="sofa_arm", record=False)
    leg = mat_metal(ctx, rough=0.25) if ctx.chance(0.5) else mat_wood(ctx)
    for s in (a0 + 0.08, a1 - 0.08):
        for b in (0.08, 0.82):
            prop(ctx, "cylinder", leg, wf.world(s, b, 0), (0.04, 0.04, 0.12), record=False)
    for _ in range(ctx.rng.randint(0, 3)):
        c = ctx.u(a0 + 0.4, a1 - 0.4)
        cm = mat_fabric(ctx)
        obj = wf.box(ctx, cm, c - 0.2, c + 0.2, 0.22, 0.36, 0.42, 0.8, bevel=0.06, name="cushion")
        obj.rotation_euler = (0.0, 0.0, ctx.u(-0.2, 0.2))
    block(ctx, wf.world(a0, 0, 0), wf.world(a1, 0.9, 0.85))


def picture(ctx, wf, windows, H):
    w, h = ctx.u(0.3, 1.2), ctx.u(0.3, 0.9)
    z0 = ctx.u(1.2, max(1.25, H - h - 0.3))
    a = wf.free_span(ctx, w, 9.0, windows, margin=0.3)
    if a is None:
        return
    wf.used.pop()  # pictures hang above furniture
    frame = ctx.choice([mat_wood(ctx), mat_metal(ctx, rough=0.3), mat_diffuse(ctx)])
    wf.box(ctx, frame, a - w / 2, a + w / 2, 0, 0.03, z0, z0 + h, bevel=0.005, name="picture_frame")
    canvas = ctx.choice([mat_noise_color, mat_marble, mat_checker, mat_fabric, mat_plastic])(ctx)
    if ctx.chance(0.1):
        canvas = mat_emission(ctx, ctx.u(1.0, 5.0))  # a screen
    wf.box(ctx, canvas, a - w / 2 + 0.03, a + w / 2 - 0.03, 0.03, 0.034, z0 + 0.03, z0 + h - 0.03,
           name="picture")


def plant(ctx, at, h):
    """A pot with thin curved stems (tubes) ending in leaves (flattened spheres)."""
    pot_r = ctx.u(0.12, 0.25)
    prop(ctx, "cylinder",
         ctx.choice([mat_plastic(ctx), mat_diffuse(ctx), mat_marble(ctx)]), at, (2 * pot_r, 2 * pot_r, pot_r * 1.6),
         record=False)
    leaf = mat_diffuse(ctx, _hsv(ctx, h=ctx.u(0.22, 0.38), s=(0.5, 0.9), v=(0.1, 0.45)))
    leaf[0].node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = ctx.u(0.3, 0.6)
    stems = []
    top = Vector(at) + Vector((0, 0, pot_r * 1.6))
    for _ in range(ctx.rng.randint(5, 14)):
        ang, lean = ctx.u(0, 2 * math.pi), ctx.u(0.1, 0.7)
        length = h * ctx.u(0.5, 1.0)
        pts = []
        for k in range(6):
            f = k / 5
            r = math.sin(lean * f * 1.5) * length * 0.5
            pts.append(top + Vector((math.cos(ang) * r, math.sin(ang) * r, length * f * math.cos(lean * f))))
        stems.append(pts)
        end = pts[-1]
        ls = ctx.u(0.06, 0.16)
        prop(ctx, "sphere", leaf, (end.x, end.y, end.z - ls * 0.1), (ls, ls * 0.5, ls * 0.2),
             rot=(ctx.u(-0.6, 0.6), ctx.u(-0.6, 0.6), ang), record=False)
    curves(ctx, mat_diffuse(ctx, (0.1, 0.25, 0.05)), stems, ctx.u(0.003, 0.008), name="plant_stems")
    block(ctx, Vector(at) - Vector((0.4, 0.4, 0)), Vector(at) + Vector((0.4, 0.4, h)))
    ctx.spots.append(top + Vector((0, 0, h * 0.5)))


def table_lamp(ctx, at):
    base = mat_metal(ctx, rough=0.2) if ctx.chance(0.5) else mat_plastic(ctx)
    h = ctx.u(0.25, 0.5)
    prop(ctx, "cylinder", base, at, (0.14, 0.14, 0.02), record=False)
    prop(ctx, "cylinder", base, at, (0.015, 0.015, h), record=False)
    bulb_at = (at[0], at[1], at[2] + h)
    prop(ctx, "sphere", mat_emission(ctx, ctx.u(5, 30)), (bulb_at[0], bulb_at[1], bulb_at[2] - 0.05), 0.1)
    shade = None
    if ctx.chance(0.5):
        shade = prop(ctx, "shade", ctx.choice([mat_fabric(ctx), mat_metal(ctx, rough=0.3), mat_diffuse(ctx)]),
                     (bulb_at[0], bulb_at[1], bulb_at[2] - 0.08), (0.3, 0.3, 0.18), record=False)
    ctx.desc["lights"].append({"type": "table_lamp", "loc": r3(bulb_at)})
    return shade


def floor_lamp(ctx, x, y, H):
    h = ctx.u(1.3, min(1.9, H - 0.4))
    m = mat_metal(ctx, rough=ctx.u(0.1, 0.4))
    prop(ctx, "cylinder", m, (x, y, 0), (0.3, 0.3, 0.025), record=False)
    prop(ctx, "cylinder", m, (x, y, 0), (0.025, 0.025, h), record=False)
    up = ctx.chance(0.15)
    prop(ctx, "sphere", mat_emission(ctx, ctx.u(5, 25)), (x, y, h - 0.06), 0.12)
    shade = prop(ctx, "shade", ctx.choice([mat_fabric(ctx), m, mat_diffuse(ctx)]),
                 (x, y, h - 0.12 if not up else h - 0.05), (0.45, 0.45, 0.3), record=False)
    if not up and ctx.chance(0.4):
        shade.hide_render = True  # a bare bulb
    if up:
        shade.rotation_euler = (math.pi, 0.0, 0.0)
        shade.location.z = h + 0.1
    block(ctx, (x - 0.2, y - 0.2, 0), (x + 0.2, y + 0.2, h + 0.2))
    ctx.desc["lights"].append({"type": "floor_lamp", "loc": r3((x, y, h)), "uplight": up})


def ceiling_lights(ctx, x0, x1, y0, y1, H, allow_none=True):
    kind = ctx.choice(["pendant", "spots", "area", "area"] + (["none"] if allow_none else []))
    if kind == "pendant":
        for _ in range(ctx.rng.randint(1, 2)):
            x, y = ctx.u(x0 + 0.8, x1 - 0.8), ctx.u(y0 + 0.8, y1 - 0.8)
            drop = ctx.u(0.4, min(1.2, H - 1.9))
            prop(ctx, "cylinder", mat_diffuse(ctx, (0.05, 0.05, 0.05)), (x, y, H - drop), (0.008, 0.008, drop),
                 record=False)
            prop(ctx, "sphere", mat_emission(ctx, ctx.u(8, 30)), (x, y, H - drop - 0.13), 0.12)
            if ctx.chance(0.4):
                prop(ctx, "shade", ctx.choice([mat_metal(ctx), mat_plastic(ctx), mat_fabric(ctx)]),
                     (x, y, H - drop - 0.25), (0.45, 0.45, 0.25), record=False)
            ctx.desc["lights"].append({"type": "pendant", "loc": r3((x, y, H - drop))})
    elif kind == "spots":
        n = ctx.rng.randint(2, 6)
        em = mat_emission(ctx, ctx.u(10, 40))
        for _ in range(n):
            x, y = ctx.u(x0 + 0.4, x1 - 0.4), ctx.u(y0 + 0.4, y1 - 0.4)
            prop(ctx, "cylinder", em, (x, y, H - 0.01), (0.15, 0.15, 0.012))
        ctx.desc["lights"].append({"type": "ceiling_spots", "count": n})
    elif kind == "area":
        x, y = ctx.u(x0 + 1, x1 - 1), ctx.u(y0 + 1, y1 - 1)
        add_light(ctx, "AREA", (x, y, H - 0.05), ctx.u(50, 250), size=ctx.u(0.3, 1.2), rot=(0.0, 0.0, 0.0))


def table(ctx, pal, x0, x1, y0, y1):
    w, d, h = ctx.u(0.8, 1.8), ctx.u(0.6, 1.0), ctx.u(0.45, 0.8)
    cx, cy = ctx.u(x0 + w / 2 + 0.5, x1 - w / 2 - 0.5), ctx.u(y0 + d / 2 + 0.5, y1 - d / 2 - 0.5)
    if x1 - x0 < w + 1.0 or y1 - y0 < d + 1.0:
        return
    top = ctx.choice([mat_wood(ctx), mat_marble(ctx), mat_glass(ctx, rough=0.0), mat_plastic(ctx)])
    th = 0.04
    if ctx.chance(0.3):  # round
        prop(ctx, "cylinder", top, (cx, cy, h - th), (w, w, th))
        d = w
    else:
        box(ctx, top, (cx - w / 2, cy - d / 2, h - th), (cx + w / 2, cy + d / 2, h), bevel=0.01, name="table_top")
    leg = ctx.choice([mat_wood(ctx), mat_metal(ctx, rough=0.2), mat_diffuse(ctx)])
    for sx in (-1, 1):
        for sy in (-1, 1):
            px, py = cx + sx * (w / 2 - 0.08) * (0.7 if d == w else 1), cy + sy * (d / 2 - 0.08) * (0.7 if d == w else 1)
            if ctx.chance(0.5):
                box(ctx, leg, (px - 0.025, py - 0.025, 0), (px + 0.025, py + 0.025, h - th), bevel=0.005,
                    name="table_leg", record=False)
            else:
                prop(ctx, "cylinder", leg, (px, py, 0), (0.04, 0.04, h - th), record=False)
    for _ in range(ctx.rng.randint(1, 6)):
        small_object(ctx, pal, (cx + ctx.u(-w / 2 + 0.12, w / 2 - 0.12), cy + ctx.u(-d / 2 + 0.12, d / 2 - 0.12), h),
                     ctx.u(0.06, 0.25), ctx.u(0, 6.3))
    if ctx.chance(0.2):
        table_lamp(ctx, (cx + ctx.u(-w / 3, w / 3), cy, h))
    if ctx.chance(0.5):  # a rug
        rx, ry = w / 2 + ctx.u(0.4, 1.0), d / 2 + ctx.u(0.4, 1.0)
        box(ctx, mat_fabric(ctx), (max(x0 + 0.05, cx - rx), max(y0 + 0.05, cy - ry), 0),
            (min(x1 - 0.05, cx + rx), min(y1 - 0.05, cy + ry), 0.012), bevel=0.004, name="rug")
    chair_mat = ctx.choice([mat_wood(ctx), mat_plastic(ctx), mat_fabric(ctx)])
    for k in range(ctx.rng.randint(0, 4)):
        ang = k * math.pi / 2 + ctx.u(-0.2, 0.2)
        dist = (w if k % 2 == 0 else d) / 2 + 0.25
        px, py = cx + math.cos(ang) * dist, cy + math.sin(ang) * dist
        sh = h - 0.28
        seat = box(ctx, chair_mat, (px - 0.22, py - 0.22, sh - 0.04), (px + 0.22, py + 0.22, sh), bevel=0.01,
                   name="chair")
        back = box(ctx, chair_mat, (px - 0.22, py - 0.22, sh), (px + 0.22, py - 0.19, sh + 0.45), bevel=0.01,
                   name="chair_back", record=False)
        # turn the back away from the table
        back.rotation_euler.z = 0.0
        back.location = (px + math.cos(ang) * 0.205, py + math.sin(ang) * 0.205, sh + 0.225)
        back.rotation_euler.z = ang - math.pi / 2
        seat.rotation_euler.z = ang
        for sx in (-1, 1):
            for sy in (-1, 1):
                prop(ctx, "cylinder", leg, (px + sx * 0.18, py + sy * 0.18, 0), (0.03, 0.03, sh - 0.04),
                     record=False)
        block(ctx, (px - 0.3, py - 0.3, 0), (px + 0.3, py + 0.3, sh + 0.5))
    ctx.spots.append(Vector((cx, cy, h + 0.1)))
    block(ctx, (cx - w / 2, cy - d / 2, 0), (cx + w / 2, cy + d / 2, h + 0.3))


def patch_of_sun(wc, d, x0, x1, y0, y1, H):
    """Where the sun ray through the window centre wc (direction d) first meets the room's inner surfaces."""
    best = None
    for axis, planes in ((2, (0.0, H)), (0, (x0, x1)), (1, (y0, y1))):
        for p in planes:
            if abs(d[axis]) < 1e-6:
                continue
            s = (p - wc[axis]) / d[axis]
            if s > 1e-3 and (best is None or s < best):
                best = s
    return wc + d * (best or 0.0)


def in_view(cam_obj, p, margin=0.95):
    pc = cam_obj.matrix_world.inverted() @ Vector(p)
    if pc.z >= -1e-3:
        return False
    t = math.tan(cam_obj.data.angle_x / 2) * margin
    return abs(pc.x / -pc.z) < t and abs(pc.y / -pc.z) < t


def build_interior(ctx):
    ctx.blocks, ctx.spots = [], []
    W, D, H = ctx.u(3.5, 7.0), ctx.u(4.0, 8.0), ctx.u(2.5, 3.4)
    x0, x1, y0, y1, t = -W / 2, W / 2, -D / 2, D / 2, 0.15
    ctx.desc["room"] = {"size": r3((W, D, H))}
    floor_mat = ctx.choice([mat_wood, mat_wood, mat_wood, mat_tiles, mat_marble, mat_checker])(ctx)
    wall_mat = mat_plaster(ctx)
    box(ctx, floor_mat, (x0 - t, y0 - t, -0.1), (x1 + t, y1 + t, 0), name="floor")
    box(ctx, mat_plaster(ctx, color=(0.85, 0.85, 0.83)), (x0 - t, y0 - t, H), (x1 + t, y1 + t, H + 0.1),
        name="ceiling")
    walls = {s: WallFrame(s, x0, x1, y0, y1) for s in ("far", "back", "left", "right")}

    # Windows: one or two, on different walls.
    windows = []
    sides = ctx.rng.sample(["far", "left", "right", "back"], 2 if ctx.chance(0.4) else 1)
    for side in sides:
        wf = walls[side]
        length = wf.amax - wf.amin
        ww = ctx.u(1.0, min(3.0, length - 1.0))
        sill = 0.0 if ctx.chance(0.15) else ctx.u(0.3, 1.0)
        top = ctx.u(max(sill + 0.9, 1.8), H - 0.15)
        a = ctx.u(wf.amin + 0.5 + ww / 2, wf.amax - 0.5 - ww / 2)
        windows.append({"side": side, "a": a, "w": ww, "sill": sill, "top": top})
    ctx.desc["windows"] = [{k: (round(v, 3) if isinstance(v, float) else v) for k, v in w.items()} for w in windows]
    for side, wf in walls.items():
        mine = [w for w in windows if w["side"] == side]
        cur = wf.amin - t
        for w in sorted(mine, key=lambda w: w["a"]):
            wa0, wa1 = w["a"] - w["w"] / 2, w["a"] + w["w"] / 2
            wf.box(ctx, wall_mat, cur, wa0, -t, 0, -0.1, H + 0.1, name="wall", record=False)
            if w["sill"] > 0:
                wf.box(ctx, wall_mat, wa0, wa1, -t, 0, -0.1, w["sill"], name="wall", record=False)
                if w["sill"] > 0.2 and ctx.chance(0.6):
                    wf.box(ctx, ctx.choice([mat_marble(ctx), mat_diffuse(ctx, (0.8, 0.8, 0.8))]),
                           wa0 - 0.05, wa1 + 0.05, -t, 0.08, w["sill"] - 0.03, w["sill"], name="window_sill")
            wf.box(ctx, wall_mat, wa0, wa1, -t, 0, w["top"], H + 0.1, name="wall", record=False)
            if ctx.chance(0.6):  # mullions
                fm = ctx.choice([mat_diffuse(ctx, (0.85, 0.85, 0.85)), mat_metal(ctx, rough=0.3),
                                 mat_diffuse(ctx, (0.05, 0.05, 0.05))])
                nv = ctx.rng.randint(1, 3)
                for k in range(1, nv + 1):
                    a = wa0 + k * w["w"] / (nv + 1)
                    wf.box(ctx, fm, a - 0.02, a + 0.02, -t * 0.6, -t * 0.3, w["sill"], w["top"], name="mullion",
                           record=False)
                zm = w["sill"] + (w["top"] - w["sill"]) * ctx.u(0.5, 0.7)
                wf.box(ctx, fm, wa0, wa1, -t * 0.6, -t * 0.3, zm - 0.02, zm + 0.02, name="mullion", record=False)
                ctx.feature("window_frames")
            cur = wa1
        wf.box(ctx, wall_mat, cur, wf.amax + t, -t, 0, -0.1, H + 0.1, name="wall", record=False)
    ctx.desc["objects"].append({"type": "room", "material": f"{floor_mat[1]} floor, plaster walls"})
    # Light portals in the window openings: Cycles then samples the sky through the windows rather than over
    # the whole sphere (an interior's sky light is otherwise mostly occluded samples, i.e. noise).
    portals = []
    for w in windows:
        wf = walls[w["side"]]
        ld = bpy.data.lights.new("portal", "AREA")
        ld.shape = "RECTANGLE"
        ld.size, ld.size_y = w["w"], w["top"] - w["sill"]
        ld.cycles.is_portal = True
        obj = link(ctx, bpy.data.objects.new("portal", ld))
        obj.location = wf.world(w["a"], -t - 0.005, (w["sill"] + w["top"]) / 2)
        obj.rotation_euler = wf.normal.to_track_quat("-Z", "Y").to_euler()
        portals.append(obj)

    # Tiles on part of a wall (a kitchen/bathroom splash back).
    if ctx.chance(0.3):
        wf = walls[ctx.choice(["far", "left", "right"])]
        a0 = ctx.u(wf.amin, wf.amax - 1.0)
        a1 = min(wf.amax, a0 + ctx.u(1.0, 3.0))
        wf.box(ctx, mat_tiles(ctx), a0, a1, 0, 0.012, 0, ctx.u(0.9, 2.0), name="wall_tiles")

    # Furniture.
    pal = Palette(ctx)
    for side in ("far", "left", "right"):
        wf = walls[side]
        for _ in range(ctx.rng.randint(2, 4)):
            f = ctx.choice(["shelf", "shelf", "cabinet", "cabinet", "sofa", "picture", "picture"])
            if f == "shelf":
                shelf(ctx, wf, pal, windows, H)
            elif f == "cabinet":
                cabinet(ctx, wf, pal, windows)
            elif f == "sofa":
                sofa(ctx, wf, windows)
            else:
                picture(ctx, wf, windows, H)
    if ctx.chance(0.9):
        table(ctx, pal, x0, x1, y0, y1)
    for _ in range(ctx.rng.randint(0, 3)):
        side = ctx.choice(["far", "left", "right"])
        a = walls[side].free_span(ctx, 0.5, 0.5, windows)
        if a is not None:
            plant(ctx, walls[side].world(a, ctx.u(0.25, 0.5), 0.0), ctx.u(0.6, 1.6))
    outside = []
    if ctx.chance(0.7):  # ground outside the windows, and sometimes other buildings
        g = ctx.choice([mat_noise_color, mat_checker, mat_tiles, mat_diffuse])(ctx)
        box(ctx, g, (-100, -100, -0.3), (100, 100, -0.15), name="ground_outside")
        for _ in range(ctx.rng.randint(0, 4)) if ctx.chance(0.5) else []:
            ang, dist = ctx.u(0, 2 * math.pi), ctx.u(8, 25)
            cx, cy = math.cos(ang) * dist, math.sin(ang) * dist
            bw, bh = ctx.u(3, 10), ctx.u(4, 20)
            outside.append(box(ctx, mat_plaster(ctx), (cx - bw / 2, cy - bw / 2, -0.2), (cx + bw / 2, cy + bw / 2, bh),
                               name="building"))

    # Lighting.
    mode = ctx.rng.choices(["day", "overcast", "dusk", "night"], [0.35, 0.3, 0.1, 0.25])[0]
    ctx.desc["lighting"] = mode
    lamps = {"night": 1.0, "dusk": 0.8, "overcast": 0.6, "day": 0.5}[mode]
    if ctx.chance(lamps) or mode == "night":
        ceiling_lights(ctx, x0, x1, y0, y1, H, allow_none=mode != "night")
        if ctx.chance(0.5):
            floor_lamp(ctx, ctx.u(x0 + 0.4, x1 - 0.4), ctx.u(y0 + 0.4, y1 - 0.4), H)
    if mode == "night" and ctx.chance(0.6):
        add_light(ctx, "AREA", (ctx.u(x0 + 1, x1 - 1), ctx.u(y0 + 1, y1 - 1), H - 0.05), ctx.u(50, 250),
                  size=ctx.u(0.5, 1.5), rot=(0.0, 0.0, 0.0))
    if mode == "night" and not any(l["type"] not in ("SUN",) for l in ctx.desc["lights"]):
        floor_lamp(ctx, ctx.u(x0 + 0.4, x1 - 0.4), ctx.u(y0 + 0.4, y1 - 0.4), H)
    sun_patch = None
    if mode in ("day", "dusk"):
        w = windows[0]
        wf = walls[w["side"]]
        e = math.radians(ctx.u(15, 60) if mode == "day" else ctx.u(4, 14))
        az = math.radians(ctx.u(-55, 55))
        d = (wf.normal * math.cos(az) + wf.tangent * math.sin(az)) * math.cos(e) + Vector((0, 0, -math.sin(e)))
        strength = ctx.u(1.5, 4.0) if mode == "day" else ctx.u(1.0, 3.0)
        sun = sun_towards(ctx, d, strength)
        if mode == "dusk":
            sun.data.color = (1.0, ctx.u(0.5, 0.7), ctx.u(0.25, 0.4))
        sky = ctx.choice(["nishita", "hosek"])
        world(ctx, sky, ctx.u(0.2, 0.6) if sky == "nishita" else ctx.u(2.0, 5.0), d)
        wc = wf.world(w["a"], 0, (w["sill"] + w["top"]) / 2)
        sun_patch = patch_of_sun(wc, d, x0, x1, y0, y1, H)
    elif mode == "overcast":
        world(ctx, ctx.choice(["gradient", "constant"]), ctx.u(0.8, 3.0))
    else:
        for obj in portals:  # they cost ~25 % of the render time, for a sky that is too dark to matter
            bpy.data.objects.remove(obj)
        world(ctx, "constant", ctx.u(0.003, 0.03))
        bpy.context.scene.world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.1, 0.15, 0.35, 1)
        ctx.desc["world"]["color"] = [0.1, 0.15, 0.35]

    # Camera: a wide view across the room, or a close-up of a table/shelf (sometimes with depth of field);
    # with the sun in, sometimes insist that the sunlit patch is out of view (indirect light only: noisy).
    want_patch = None
    if sun_patch is not None:
        want_patch = ctx.choice([None, True, True, False])
    closeup = ctx.spots and ctx.chance(0.3)
    cam = camera(ctx, (0, y0 + 0.5, 1.5), (0, 0, 1.0), 20.0)
    best = None
    for attempt in range(60):
        if closeup:
            spot = ctx.choice(ctx.spots)
            ang = ctx.u(0, 2 * math.pi)
            dist = ctx.u(0.5, 1.6)
            loc = spot + Vector((math.cos(ang) * dist, math.sin(ang) * dist, ctx.u(0.05, 0.6)))
            target = spot + Vector((ctx.u(-0.1, 0.1), ctx.u(-0.1, 0.1), ctx.u(-0.1, 0.05)))
            lens = ctx.u(28, 60)
        else:
            loc = Vector((ctx.u(x0 + 0.3, x1 - 0.3), ctx.u(y0 + 0.3, y1 - 0.3), ctx.u(0.8, min(1.9, H - 0.3))))
            if ctx.spots and ctx.chance(0.6):  # look at some furniture
                target = ctx.choice(ctx.spots) + Vector((ctx.u(-0.3, 0.3), ctx.u(-0.3, 0.3), ctx.u(-0.3, 0.2)))
            else:
                target = Vector((ctx.u(x0 + 0.3, x1 - 0.3), ctx.u(y0 + 0.3, y1 - 0.3), ctx.u(0.3, 1.6)))
            if (target - loc).length < 2.0:
                continue
            lens = ctx.u(14, 30)
        if not (x0 + 0.2 < loc.x < x1 - 0.2 and y0 + 0.2 < loc.y < y1 - 0.2 and 0.2 < loc.z < H - 0.2):
            continue
        if any(all(lo[i] - 0.08 < loc[i] < hi[i] + 0.08 for i in range(3)) for lo, hi in ctx.blocks):
            continue
        cam.location = loc
        look_at(cam, target)
        cam.data.lens = lens
        bpy.context.view_layer.update()
        ok = want_patch is None or in_view(cam, sun_patch) == want_patch
        best = (loc.copy(), target.copy(), lens)
        if ok:
            break
    if best:
        loc, target, lens = best
        cam.location = loc
        look_at(cam, target)
        cam.data.lens = lens
        bpy.context.view_layer.update()
    dof = closeup and ctx.chance(0.4)
    if dof:
        cam.data.dof.use_dof = True
        cam.data.dof.focus_distance = (target - cam.location).length
        cam.data.dof.aperture_fstop = ctx.u(1.2, 4.0)
        ctx.feature("depth_of_field")
    ctx.desc["camera"] = {"lens_mm": round(cam.data.lens, 2), "loc": r3(cam.location), "target": r3(target),
                          "closeup": bool(closeup), "dof": bool(dof),
                          "fstop": round(cam.data.dof.aperture_fstop, 2) if dof else None,
                          "focus": round(cam.data.dof.focus_distance, 3) if dof else None}
    if sun_patch is not None:
        vis = in_view(cam, sun_patch)
        ctx.desc["sun_patch"] = {"loc": r3(sun_patch), "in_view": vis}
        if not vis:
            ctx.feature("sun_patch_out_of_view")


# ----------------------------------------------------------------------------------------------------------
# Open-air scenes: a textured ground, a cluster of primitives, thin high-frequency geometry (grass from particle
# hair, fences, grilles, wires, wireframes, sticks), sun and sky or dusk with lamps. Built at garden scale and
# then scaled as a whole (a parent empty): macro (x0.03-0.15), garden (x1) or monoliths (x4-12).
def mat_grass_ground(ctx):
    m, nt, b = _principled(ctx, "grass_ground")
    v = _coords(nt, (1.0, 1.0, 1.0))
    n = nt.nodes.new("ShaderNodeTexNoise")
    n.inputs["Scale"].default_value = ctx.u(0.5, 3.0)
    n.inputs["Detail"].default_value = 6.0
    nt.links.new(v, n.inputs["Vector"])
    green = _hsv(ctx, h=ctx.u(0.18, 0.33), s=(0.4, 0.8), v=(0.05, 0.3))
    soil = _hsv(ctx, h=ctx.u(0.05, 0.1), s=(0.3, 0.6), v=(0.05, 0.25))
    nt.links.new(_ramp(nt, n.outputs["Fac"], soil, green), b.inputs["Base Color"])
    fine = nt.nodes.new("ShaderNodeTexNoise")
    fine.inputs["Scale"].default_value = ctx.u(30.0, 120.0)
    nt.links.new(v, fine.inputs["Vector"])
    _bump(nt, b, fine.outputs["Fac"], 0.4, 0.01)
    b.inputs["Roughness"].default_value = ctx.u(0.7, 1.0)
    return m, "grass_ground"


def mat_sand(ctx):
    m, nt, b = _principled(ctx, "sand")
    v = _coords(nt, (1.0, 1.0, 1.0))
    mus = nt.nodes.new("ShaderNodeTexMusgrave")
    mus.inputs["Scale"].default_value = ctx.u(0.3, 2.0)
    nt.links.new(v, mus.inputs["Vector"])
    c = _hsv(ctx, h=ctx.u(0.07, 0.12), s=(0.2, 0.5), v=(0.3, 0.75))
    b.inputs["Base Color"].default_value = (*c, 1)
    _bump(nt, b, mus.outputs["Fac"], ctx.u(0.2, 0.6), 0.05)
    b.inputs["Roughness"].default_value = 0.95
    return m, "sand"


def mat_asphalt(ctx):
    """Dark, sometimes wet: noise-driven roughness between puddles and rough tarmac."""
    m, nt, b = _principled(ctx, "asphalt")
    v = _coords(nt, (1.0, 1.0, 1.0))
    n = nt.nodes.new("ShaderNodeTexNoise")
    n.inputs["Scale"].default_value = ctx.u(0.3, 1.5)
    nt.links.new(v, n.inputs["Vector"])
    wet = ctx.chance(0.5)
    rough = _ramp(nt, n.outputs["Fac"], (0.03, 0.03, 0.03) if wet else (0.5, 0.5, 0.5), (0.8, 0.8, 0.8))
    nt.links.new(rough, b.inputs["Roughness"])
    g = nt.nodes.new("ShaderNodeTexNoise")
    g.inputs["Scale"].default_value = ctx.u(80.0, 200.0)
    nt.links.new(v, g.inputs["Vector"])
    nt.links.new(_ramp(nt, g.outputs["Fac"], (0.02, 0.02, 0.02), (0.12, 0.12, 0.11)), b.inputs["Base Color"])
    return m, "wet_asphalt" if wet else "asphalt"


def grass(ctx, center, radius, length, scale):
    """Particle hair on a disc: thousands of thin strands. Built directly at the scene's final scale (not
    parented to the scaled root), so that hair lengths and radii need no assumption about parent scaling."""
    bm = bmesh.new()
    bmesh.ops.create_circle(bm, cap_ends=True, segments=32, radius=radius * scale)
    me = _bm_to_mesh(bm, "grass_patch", smooth=False)
    obj = link(ctx, bpy.data.objects.new("grass", me))
    obj.location = (center[0] * scale, center[1] * scale, 0.002 * scale)
    obj["residue_unscaled"] = True
    me.materials.append(mat_diffuse(ctx)[0])
    hm = bpy.data.materials.new("grass_hair")
    hm.use_nodes = True
    nt = hm.node_tree
    b = nt.nodes["Principled BSDF"]
    hi = nt.nodes.new("ShaderNodeHairInfo")
    h0 = ctx.u(0.12, 0.3)
    nt.links.new(_ramp(nt, hi.outputs["Random"], _hsv(ctx, h=h0, s=(0.5, 0.9), v=(0.05, 0.2)),
                       _hsv(ctx, h=h0 + ctx.u(-0.05, 0.05), s=(0.4, 0.9), v=(0.25, 0.6))), b.inputs["Base Color"])
    b.inputs["Roughness"].default_value = ctx.u(0.3, 0.6)
    me.materials.append(hm)
    mod = obj.modifiers.new("grass", "PARTICLE_SYSTEM")
    ps = obj.particle_systems[0]
    ps.seed = ctx.rng.randint(0, 10000)
    st = ps.settings
    st.type = "HAIR"
    area = math.pi * radius * radius
    st.count = int(min(20000, max(2000, area * ctx.u(300, 1500))))
    st.use_advanced_hair = True
    # Blender's hair_length is 4 x normal_factor (the emission velocity); the random velocity is in the same
    # units, so both scale with the length.
    st.normal_factor = length * scale / 4.0
    st.factor_random = st.normal_factor * ctx.u(0.3, 0.8)
    st.hair_step = 4
    st.render_step = 3
    st.material = 2
    obj.show_instancer_for_render = False
    st.child_type = "SIMPLE" if ctx.chance(0.5) else "NONE"
    st.rendered_child_count = 4
    st.child_radius = 0.05
    st.radius_scale = ctx.u(0.002, 0.006) * scale
    st.root_radius = 1.0
    st.tip_radius = ctx.u(0.0, 0.3)
    ctx.desc["objects"].append({"type": "grass_hair", "material": "hair", "count": st.count,
                                "children": st.child_type, "length": round(length, 3), "radius": round(radius, 2)})
    ctx.feature("hair")
    ctx.feature("thin_geometry")
    return obj


def fence(ctx, p0, p1, height, spacing, r, mat):
    p0, p1 = Vector(p0), Vector(p1)
    n = max(2, int((p1 - p0).length / spacing))
    bars = [[p0.lerp(p1, i / n), p0.lerp(p1, i / n) + Vector((0, 0, height))] for i in range(n + 1)]
    rails = [[p0 + Vector((0, 0, z)), p1 + Vector((0, 0, z))] for z in (height * 0.15, height * 0.9)]
    return curves(ctx, mat, bars + rails, r, name="fence")


def grille(ctx, center, yaw, w, h, spacing, r, mat):
    t = Vector((math.cos(yaw), math.sin(yaw), 0))
    c = Vector(center)
    lines = []
    n = int(w / spacing)
    for i in range(n + 1):
        a = -w / 2 + i * spacing
        lines.append([c + t * a, c + t * a + Vector((0, 0, h))])
    for j in range(int(h / spacing) + 1):
        z = j * spacing
        lines.append([c - t * (w / 2) + Vector((0, 0, z)), c + t * (w / 2) + Vector((0, 0, z))])
    return curves(ctx, mat, lines, r, name="grille")


def wires(ctx, center, yaw, span, height, count, r, mat):
    t = Vector((math.cos(yaw), math.sin(yaw), 0))
    c = Vector(center)
    pole = mat_wood(ctx, gloss=False) if ctx.chance(0.5) else mat_metal(ctx, rough=0.4)
    for s in (-1, 1):
        q = c + t * (s * span / 2)
        prop(ctx, "cylinder", pole, (q.x, q.y, 0), (0.12, 0.12, height + 0.3), record=False)
    lines = []
    for k in range(count):
        z = height - k * ctx.u(0.1, 0.3)
        off = Vector((-t.y, t.x, 0)) * ctx.u(-0.3, 0.3)
        sag = ctx.u(0.1, 0.6)
        pts = []
        for i in range(17):
            f = i / 16
            p = c + t * (span * (f - 0.5)) + off
            pts.append(p + Vector((0, 0, z - sag * 4 * f * (1 - f))))
        lines.append(pts)
    return curves(ctx, mat, lines, r, name="wires")


def sticks(ctx, center, spread, count, length, r, mat):
    c = Vector(center)
    lines = []
    for _ in range(count):
        p = c + Vector((ctx.u(-spread, spread), ctx.u(-spread, spread), 0))
        ang, tilt = ctx.u(0, 2 * math.pi), ctx.u(0.0, 1.2)
        d = Vector((math.cos(ang) * math.sin(tilt), math.sin(ang) * math.sin(tilt), math.cos(tilt)))
        lines.append([p, p + d * length * ctx.u(0.5, 1.0)])
    return curves(ctx, mat, lines, r, name="sticks")


def wireframe_object(ctx, at, size, mat):
    kind = ctx.choice(["icosphere", "cube", "sphere", "torus"])
    obj = prop(ctx, kind, mat, at, size, record=False)
    mod = obj.modifiers.new("wire", "WIREFRAME")
    mod.thickness = ctx.u(0.01, 0.04)
    mod.use_replace = True
    ctx.desc["objects"].append({"type": f"wireframe_{kind}", "material": mat[1], "loc": r3(at),
                                "size": round(size, 3)})
    ctx.feature("thin_geometry")
    return obj


def build_exterior(ctx):
    ctx.blocks, ctx.spots = [], []
    variant = ctx.rng.choices(["garden", "macro", "monoliths"], [0.55, 0.25, 0.2])[0]
    scale = {"garden": 1.0, "macro": ctx.u(0.03, 0.15), "monoliths": ctx.u(4.0, 12.0)}[variant]
    ctx.desc["variant"], ctx.desc["scale"] = variant, round(scale, 4)
    root = link(ctx, bpy.data.objects.new("root", None))

    gm = ctx.choice([mat_grass_ground, mat_grass_ground, mat_checker, mat_tiles, mat_sand, mat_asphalt,
                     mat_noise_color, mat_wood, mat_marble])
    gmat = mat_tiles(ctx, ctx.u(0.3, 0.8)) if gm is mat_tiles else gm(ctx)
    box(ctx, gmat, (-300, -300, -0.2), (300, 300, 0), name="ground")

    # A cluster of primitives around the origin.
    pal = Palette(ctx, 6)
    n = ctx.rng.randint(4, 12)
    spread = ctx.u(1.5, 4.0)
    kinds = ["cube", "sphere", "sphere", "cylinder", "cone", "torus", "monkey", "icosphere", "bevel_box",
             "pillar", "bevel_box"]
    for _ in range(n):
        kind = ctx.choice(kinds)
        x, y = ctx.u(-spread, spread), ctx.u(-spread, spread)
        s = ctx.u(0.2, 1.6)
        mat = pal.pick()
        if kind == "bevel_box":
            sx, sy, sz = s * ctx.u(0.5, 1.5), s * ctx.u(0.5, 1.5), s * ctx.u(0.3, 1.5)
            obj = box(ctx, mat, (x - sx / 2, y - sy / 2, 0), (x + sx / 2, y + sy / 2, sz), bevel=ctx.u(0.01, 0.1),
                      name="bevel_box")
            obj.rotation_euler.z = ctx.u(0, math.pi)
            top = sz
        elif kind == "pillar":
            r = s * ctx.u(0.1, 0.25)
            prop(ctx, "cylinder", mat, (x, y, 0), (2 * r, 2 * r, s * ctx.u(1.5, 3.0)))
            top = None
        else:
            rot = (0.0, 0.0, ctx.u(0, 2 * math.pi))
            if kind == "torus" and ctx.chance(0.5):
                rot = (math.pi / 2, 0.0, rot[2])
                obj = prop(ctx, kind, mat, (x, y, 0), s, rot)
                obj.location.z = 0.5 * s
            else:
                prop(ctx, kind, mat, (x, y, 0), s, rot)
            top = s if kind in ("cube", "cylinder") else None
        ctx.spots.append(Vector((x, y, s * 0.5)))
        if top is not None and ctx.chance(0.35):  # something on top
            small_object(ctx, pal, (x, y, top), s * ctx.u(0.3, 0.6))
    if ctx.chance(0.3):  # a glowing thing
        x, y = ctx.u(-spread, spread), ctx.u(-spread, spread)
        s = ctx.u(0.1, 0.5)
        prop(ctx, ctx.choice(["sphere", "cube", "cylinder"]), mat_emission(ctx, ctx.u(2, 20)), (x, y, 0), s)

    # Thin, high-frequency geometry.
    thin = ctx.rng.sample(["grass", "fence", "grille", "wires", "wireframe", "sticks"],
                          ctx.rng.choices([0, 1, 2, 3], [0.2, 0.4, 0.3, 0.1])[0])
    for t in thin:
        if t == "grass":
            grass(ctx, (ctx.u(-1, 1), ctx.u(-1, 1)), ctx.u(2.0, 6.0), ctx.u(0.05, 0.35), scale)
        elif t == "fence":
            yaw = ctx.u(0, math.pi)
            d = Vector((math.cos(yaw), math.sin(yaw), 0)) * ctx.u(2, 6)
            off = Vector((ctx.u(-3, 3), ctx.u(-3, 3), 0))
            fence(ctx, off - d, off + d, ctx.u(0.5, 1.8), ctx.u(0.05, 0.2), ctx.u(0.004, 0.02),
                  ctx.choice([mat_metal(ctx), mat_diffuse(ctx), mat_wood(ctx, gloss=False)]))
        elif t == "grille":
            grille(ctx, (ctx.u(-2, 2), ctx.u(-2, 2), 0), ctx.u(0, math.pi), ctx.u(1, 4), ctx.u(0.8, 2.5),
                   ctx.u(0.02, 0.1), ctx.u(0.002, 0.008), ctx.choice([mat_metal(ctx), mat_diffuse(ctx)]))
        elif t == "wires":
            wires(ctx, (ctx.u(-2, 2), ctx.u(-2, 2), 0), ctx.u(0, math.pi), ctx.u(6, 15), ctx.u(2, 5),
                  ctx.rng.randint(2, 8), ctx.u(0.004, 0.015), mat_diffuse(ctx, (0.03, 0.03, 0.03)))
        elif t == "wireframe":
            wireframe_object(ctx, (ctx.u(-2, 2), ctx.u(-2, 2), 0), ctx.u(0.5, 2.0),
                             ctx.choice([mat_metal(ctx), mat_plastic(ctx), mat_emission(ctx, ctx.u(2, 10))]))
        else:
            sticks(ctx, (ctx.u(-2, 2), ctx.u(-2, 2), 0), ctx.u(0.5, 2.0), ctx.rng.randint(30, 200),
                   ctx.u(0.3, 1.2), ctx.u(0.003, 0.015), ctx.choice([mat_wood(ctx, gloss=False), mat_plastic(ctx)]))

    # Light.
    mode = ctx.rng.choices(["sun", "overcast", "dusk", "studio"], [0.45, 0.2, 0.2, 0.15])[0]
    ctx.desc["lighting"] = mode
    if mode == "sun":
        e, az = math.radians(ctx.u(8, 70)), ctx.u(0, 2 * math.pi)
        d = Vector((math.cos(az) * math.cos(e), math.sin(az) * math.cos(e), -math.sin(e)))
        sun_towards(ctx, d, ctx.u(2.0, 5.0))
        sky = ctx.choice(["nishita", "hosek"])
        world(ctx, sky, ctx.u(0.2, 0.6) if sky == "nishita" else ctx.u(2.0, 5.0), d)
    elif mode == "overcast":
        world(ctx, ctx.choice(["gradient", "constant"]), ctx.u(0.5, 2.0))
    elif mode == "dusk":
        if ctx.chance(0.5):
            e, az = math.radians(ctx.u(-2, 4)), ctx.u(0, 2 * math.pi)
            world(ctx, "nishita", ctx.u(0.2, 0.6), (math.cos(az), math.sin(az), -math.sin(e)))
        else:
            world(ctx, "constant", ctx.u(0.01, 0.05))
            bpy.context.scene.world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.1, 0.15, 0.4, 1)
        for _ in range(ctx.rng.randint(1, 3)):
            ang, dist = ctx.u(0, 2 * math.pi), ctx.u(2, 6)
            add_light(ctx, ctx.choice(["AREA", "POINT", "SPOT"]),
                      (math.cos(ang) * dist, math.sin(ang) * dist, ctx.u(1.5, 5)), ctx.u(100, 1500),
                      size=ctx.u(0.1, 1.5), target=(ctx.u(-1, 1), ctx.u(-1, 1), 0),
                      color=ctx.choice([(1, 0.8, 0.6), (1, 1, 1), (0.7, 0.8, 1.0), (1, 0.6, 0.4)]))
        for _ in range(ctx.rng.randint(0, 3)):  # lamp posts
            x, y = ctx.u(-spread - 1, spread + 1), ctx.u(-spread - 1, spread + 1)
            h = ctx.u(1.5, 3.5)
            prop(ctx, "cylinder", mat_metal(ctx, rough=0.4), (x, y, 0), (0.08, 0.08, h), record=False)
            prop(ctx, "sphere", mat_emission(ctx, ctx.u(5, 30)), (x, y, h), 0.25)
    else:  # studio: the starter set's look
        world(ctx, "constant", ctx.u(0.05, 0.6))
        add_light(ctx, "AREA", (ctx.u(-4, 4), ctx.u(-4, 4), ctx.u(4, 8)), ctx.u(300, 1500), size=ctx.u(0.5, 3),
                  target=(0, 0, 0))

    # Camera: orbit the cluster, look at one of its objects, with a clear line of sight to it (no object
    # right in front of the lens, camera not inside anything); depth of field on ~40 %.
    bpy.context.view_layer.update()
    deps = bpy.context.evaluated_depsgraph_get()
    for attempt in range(16):
        ang = ctx.u(0, 2 * math.pi)
        dist = ctx.u(3.0, 12.0)
        loc = Vector((math.cos(ang) * dist, math.sin(ang) * dist, ctx.u(0.25, 3.0)))
        target = ctx.choice(ctx.spots) if ctx.spots else Vector((0, 0, 0.5))
        ray = target - loc
        hit, where, *_ = bpy.context.scene.ray_cast(deps, loc, ray.normalized(), distance=ray.length)
        if not hit or (where - loc).length > 0.75 * ray.length:
            break
    ctx.desc["camera_attempts"] = attempt + 1
    lens = ctx.u(24, 85) if dist > 5 else ctx.u(20, 50)
    dof = ctx.chance(0.4)
    fstop = ctx.u(1.2, 5.6) if variant != "macro" else ctx.u(2.8, 16.0)
    cam = camera(ctx, loc, target, lens, (target - loc).length if dof else None, fstop if dof else None)
    # Slightly off-centre framing.
    cam.rotation_euler.z += ctx.u(-0.12, 0.12)
    cam.rotation_euler.x += ctx.u(-0.08, 0.08)

    # Scale the whole scene: geometry is parented to the root (textures, bevels, hair and curves follow);
    # lamps and the camera are moved instead (no scale in their matrices), lamp power goes with the area.
    for obj in list(bpy.context.scene.objects):
        if obj is root or obj.parent is not None or obj.get("residue_unscaled"):
            continue
        if obj.type in ("LIGHT", "CAMERA"):
            obj.location = obj.location * scale
        else:
            obj.parent = root
    root.scale = (scale, scale, scale)
    for obj in bpy.context.scene.objects:
        if obj.type == "LIGHT" and obj.data.type != "SUN":
            obj.data.energy *= scale * scale
            obj.data.shadow_soft_size *= scale
            if obj.data.type == "AREA":
                obj.data.size *= scale
                obj.data.size_y *= scale
    cam.data.clip_start = 0.01 * scale
    cam.data.clip_end = 2000.0 * scale
    if dof:
        cam.data.dof.focus_distance *= scale
        ctx.desc["camera"]["focus"] = round(cam.data.dof.focus_distance, 4)
    bpy.context.view_layer.update()


def build_test(ctx):
    """A minimal scene for checking the machinery."""
    box(ctx, mat_wood(ctx), (-3, -3, -0.1), (3, 3, 0), name="floor")
    prop(ctx, "monkey", mat_metal(ctx), (0, 0, 0), 0.8)
    prop(ctx, "sphere", mat_glass(ctx), (0.8, 0.3, 0), 0.5)
    sun_towards(ctx, (0.3, 0.5, -0.7), 3.0)
    world(ctx, "nishita", 0.2, (0.3, 0.5, -0.7))
    camera(ctx, (0, -4, 1.5), (0, 0, 0.4), 40)


# ----------------------------------------------------------------------------------------------------------
# Rendering and scene.json
def configure(scene, args):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.sampling_pattern = "PROGRESSIVE_MULTI_JITTER"
    c.max_bounces = args.max_bounces
    c.diffuse_bounces = 4
    c.glossy_bounces = 4
    c.transmission_bounces = args.max_bounces
    c.transparent_max_bounces = args.max_bounces
    c.volume_bounces = 0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = args.clamp_indirect
    # By default no caustics (diffuse -> specular -> light paths) and glossy filtering: they are what turns small
    # lamps and sun patches into fireflies that no 1024-spp reference resolves. Same for noisy and reference.
    # --caustics keeps them (with --clamp-indirect 0: a render as an unclamped path tracer leaves it).
    scene.cycles_curves.shape = "THICK"
    c.caustics_reflective = args.caustics
    c.caustics_refractive = args.caustics
    c.blur_glossy = 0.0 if args.caustics else 1.0
    scene.render.film_transparent = False
    scene.render.threads_mode = "FIXED"
    scene.render.threads = args.threads
    scene.render.resolution_x = scene.render.resolution_y = args.res
    scene.render.resolution_percentage = 100
    scene.render.use_persistent_data = False
    s = scene.render.image_settings
    s.file_format = "OPEN_EXR_MULTILAYER"
    s.color_depth = "16"
    s.exr_codec = "ZIP"
    scene.view_settings.view_transform = "Standard"


def set_passes(scene, full, vector=False):
    layer = scene.view_layers[0]
    layer.cycles.denoising_store_passes = full
    layer.use_pass_z = full
    layer.use_pass_normal = full
    layer.use_pass_diffuse_color = full
    layer.use_pass_glossy_color = full
    layer.use_pass_vector = vector  # shots only (motion blur off): ViewLayer.Vector.XYZW


def render_one(scene, path, spp, seed, full, vector=False, note=None):
    scene.cycles.samples = spp
    scene.cycles.seed = seed
    set_passes(scene, full, vector)
    w2c = scene.camera.matrix_world.inverted()
    scene.render.use_stamp_note = True
    scene.render.stamp_note_text = json.dumps({"worldToCamera": [round(v, 6) for row in w2c for v in row],
                                               "spp": spp, "sampling_seed": seed, **(note or {})})
    scene.render.filepath = path
    t = time.time()
    bpy.ops.render.render(write_still=True)
    return time.time() - t


def probe_exposure(ctx, scene, args):
    """Scales every light so the probe's log-average luminance lands at 0.18 * 2^ev."""
    ev = round(ctx.u(-1.0, 1.5), 2)
    info = {"target_ev": ev}
    if args.probe_res <= 0:
        ctx.desc["exposure"] = info
        return
    res = scene.render.resolution_x
    scene.render.resolution_x = scene.render.resolution_y = args.probe_res
    path = os.path.join(args.outdir, ".probe.exr")
    t = time.time()
    render_one(scene, path, args.probe_spp, 99991, False)
    img = exr_metrics.read_exr(path)
    os.remove(path)
    scene.render.resolution_x = scene.render.resolution_y = res
    rgb = exr_metrics.layer_rgb(img)
    lav = exr_metrics.log_average_luminance(rgb)
    mean = float(exr_metrics.luminance(rgb).mean())
    target = 0.18 * 2.0 ** ev
    # The log-average sets the key; a mean luminance cap keeps a view dominated by a bright window or sky
    # from being blown out (the log-average of a dark room with a bright window is low, its mean high).
    k = min(target / max(lav, 1e-6), 2.0 * 2.0 ** ev / max(mean, 1e-6))
    k = min(2.0 ** 8, max(2.0 ** -6, k))
    k = 2.0 ** round(math.log2(k), 1)  # quantised: re-runs build the same lights despite probe noise
    ctx.scale_lights(k)
    info.update({"probe_log_average_lum": round(lav, 5), "probe_mean_lum": round(mean, 5), "light_scale": round(k, 5),
                 "probe_s": round(time.time() - t, 2), "probe_res": args.probe_res, "probe_spp": args.probe_spp})
    ctx.desc["exposure"] = info


def parse_time(s):
    try:
        parts = [float(x) for x in str(s).split(":")]
    except ValueError:
        return None
    v = 0.0
    for x in parts:
        v = v * 60 + x
    return round(v, 3)


def camera_json(scene, res):
    cam = scene.camera
    c2w = cam.matrix_world.copy()
    w2c = c2w.inverted()
    deps = bpy.context.evaluated_depsgraph_get()
    proj = cam.calc_matrix_camera(deps, x=res, y=res)
    flip = Matrix.Diagonal((1.0, 1.0, -1.0, 1.0))
    exr_w2c = (flip @ w2c).transposed()
    d = cam.data
    return {
        "cameraToWorld": [list(map(float, row)) for row in c2w],
        "worldToCamera": [list(map(float, row)) for row in w2c],
        "projection": [list(map(float, row)) for row in proj],
        "lens_mm": float(d.lens),
        "sensor_mm": float(d.sensor_width),
        "fov_x_rad": float(d.angle_x),
        "fov_y_rad": float(d.angle_y),
        "fov_x_deg": math.degrees(d.angle_x),
        "dof": bool(d.dof.use_dof),
        "focus_distance": float(d.dof.focus_distance) if d.dof.use_dof else None,
        "fstop": float(d.dof.aperture_fstop) if d.dof.use_dof else None,
        "convention": "Blender: world Z-up right-handed; matrices row-major, column-vector (p_cam = "
                      "worldToCamera @ [x,y,z,1]); camera looks down -Z, +Y up; projection = Blender/OpenGL "
                      "clip matrix for this resolution",
        "openexr_worldToCamera": [list(map(float, row)) for row in exr_w2c],
        "openexr_convention": "OpenEXR standard attribute layout (Imath row-vector, p' = [x,y,z,1] @ M), "
                              "left-handed camera (+z = view dir); not written into the EXRs",
    }


def scene_flags(args):
    """The command-line flags that change what a seed builds or how it is lit and rendered (for the record)."""
    return ((f" --photos {args.photos} --photo-share {args.photo_share}" if args.photos else "") +
            (f" --hdris {args.hdris}" if args.hdris else "") +
            (f" --clamp-indirect {args.clamp_indirect:g}" if args.clamp_indirect != CLAMP_INDIRECT else "") +
            (" --caustics" if args.caustics else ""))


def render_settings(scene, args, command):
    return {
        "blender": blender_version(),
        "engine": "CYCLES",
        "device": "CPU",
        "threads": args.threads,
        "sampling_pattern": scene.cycles.sampling_pattern,
        "adaptive_sampling": {"threshold": args.adaptive_threshold, "for": "noisy renders"} if args.adaptive_threshold > 0 else False,
        "denoising": False,
        "max_bounces": scene.cycles.max_bounces,
        "diffuse_bounces": scene.cycles.diffuse_bounces,
        "glossy_bounces": scene.cycles.glossy_bounces,
        "transmission_bounces": scene.cycles.transmission_bounces,
        "clamp_direct": scene.cycles.sample_clamp_direct,
        "clamp_indirect": scene.cycles.sample_clamp_indirect,
        "caustics": scene.cycles.caustics_reflective,
        "blur_glossy": scene.cycles.blur_glossy,
        "film_transparent": False,
        "aovs": "minimal (noisy: " + NOISY_PASSES + "; reference: Combined)",
        "exr": "OPEN_EXR_MULTILAYER, color_depth 16 (half colour passes, float data passes), ZIP",
        "generator": "tools/datagen/make_scene.py",
        "command": command,
    }


def blender_version():
    v = bpy.app.version_string
    try:
        deb = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "blender"], capture_output=True, text=True,
                             timeout=10).stdout.strip()
        if deb:
            v += f" (Debian {deb})"
    except Exception:  # noqa: BLE001 - informative only
        pass
    return v


def process_wall():
    try:
        with open("/proc/self/stat") as f:
            start_ticks = float(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            up = float(f.read().split()[0])
        return round(up - start_ticks / os.sysconf("SC_CLK_TCK"), 3)
    except Exception:  # noqa: BLE001
        return round(time.time() - T0, 3)


# ----------------------------------------------------------------------------------------------------------
# Shots (issue 51, "Shots, not frames"): the scene the seed builds, animated over --frames frames. The scene, its
# exposure (probed once, before anything moves) and the render settings are the stills' own; the moves are drawn
# from a random stream of their own (shots.shot_rng), so the scene is the one the seed makes anyway. Every
# animated property has a keyframe at every frame from 0 to N+1 (linear in between), so that Cycles' Vector pass
# (motion to frames f-1 and f+1) is a real motion at the first and last frame too. The moves are centred on the
# middle of the shot (the framing the generator chose is frame (N+1)/2's) and their speed is set from the motion it
# makes on the screen: a few to ~15 pixels per frame at 256x256 (scaled with --res), measured on points of the
# scene projected through the camera of each frame, before anything is rendered.
MOVABLE_KINDS = ("cube", "cylinder", "cone", "sphere", "icosphere", "monkey", "torus", "bevel_box")


def _base_name(obj):
    return obj.name.split(".")[0]


def _material_name(obj):
    slot = obj.material_slots[0] if obj.material_slots else None
    return slot.material.name.split(".")[0] if slot and slot.material else ""


def _about_up(point, angle):
    """A turn by `angle` about the world's up axis through `point` (4x4)."""
    point = Vector(point)
    return Matrix.Translation(point) @ Matrix.Rotation(angle, 4, "Z") @ Matrix.Translation(-point)


def _m4(m):
    return [[round(float(v), 6) for v in row] for row in m]


class Profile:
    """The shot's timing: s(f), in frames, 0 at the middle of the shot. linear: constant speed (ds/df = 1);
    smooth: a speed that swings smoothly between 1 - a and 1 + a over the shot (never stops)."""

    def __init__(self, kind, frames, a, phase):
        self.kind, self.n, self.a, self.phase = kind, frames, a, phase
        self.mid = (frames + 1) / 2.0

    def __call__(self, f):
        x = f - self.mid
        if self.kind == "linear":
            return x
        w = 2.0 * math.pi / (self.n + 1)
        return x + self.a / w * (math.sin(w * x + self.phase) - math.sin(self.phase))

    def json(self):
        return {"kind": self.kind, "amplitude": round(self.a, 3) if self.kind == "smooth" else 0.0,
                "phase": round(self.phase, 3) if self.kind == "smooth" else 0.0, "centre_frame": self.mid}


class Mover:
    """Something that moves: its world matrix at frame f for a speed lam (metres or radians per frame)."""

    def __init__(self, obj, what, profile):
        self.obj, self.what, self.profile = obj, what, profile
        self.m0 = obj.matrix_world.copy()
        self.lam = 0.0
        self.info = {"object": obj.name, "what": what}

    def matrix(self, f, lam=None):
        raise NotImplementedError

    def keyframe(self, frames):
        obj = self.obj
        parent = (obj.parent.matrix_world @ obj.matrix_parent_inverse) if obj.parent else Matrix.Identity(4)
        pinv = parent.inverted()
        scale = obj.scale.copy()
        prev = obj.rotation_euler.copy()
        for f in frames:
            loc, rot, _ = (pinv @ self.matrix(f)).decompose()
            eul = rot.to_euler(obj.rotation_mode, prev)
            prev = eul
            obj.location, obj.rotation_euler = loc, eul
            obj.keyframe_insert("location", frame=f)
            obj.keyframe_insert("rotation_euler", frame=f)
        obj.scale = scale
        for fc in obj.animation_data.action.fcurves:
            for k in fc.keyframe_points:
                k.interpolation = "LINEAR"


class CameraMove(Mover):
    def __init__(self, cam, kind, profile, sign, pivot=None):
        super().__init__(cam, kind, profile)
        self.kind, self.sign = kind, sign
        self.pivot = Vector(pivot) if pivot is not None else cam.matrix_world.translation.copy()
        self.forward = -(self.m0.to_3x3() @ Vector((0.0, 0.0, 1.0))).normalized()
        self.right = (self.m0.to_3x3() @ Vector((1.0, 0.0, 0.0))).normalized()

    def matrix(self, f, lam=None):
        t = (self.lam if lam is None else lam) * self.profile(f) * self.sign
        if self.kind == "dolly":
            return Matrix.Translation(self.forward * t) @ self.m0
        if self.kind == "truck":
            return Matrix.Translation(self.right * t) @ self.m0
        if self.kind == "pan":
            return _about_up(self.m0.translation, t) @ self.m0
        return _about_up(self.pivot, t) @ self.m0  # orbit

    def json(self):
        unit = "rad" if self.kind in ("pan", "orbit") else "m"
        d = {"what": self.kind, "speed_per_frame": round(self.lam, 6), "unit": unit, "sign": self.sign}
        if self.kind == "orbit":
            d["pivot"] = r3(self.pivot)
        if self.kind in ("pan", "orbit"):
            d["deg_per_frame"] = round(math.degrees(self.lam), 4)
        return d


class ObjectMove(Mover):
    """A prop (with what belongs to it or stands on it: the group's first object is the prop) that slides along a
    horizontal direction (metres per frame: lam) and spins about its vertical axis (spin: radians per frame)."""

    def __init__(self, group, profile, direction, spin, what="prop"):
        super().__init__(group[0], what, profile)
        self.group = list(group)
        self.m0s = [o.matrix_world.copy() for o in self.group]
        self.direction, self.spin = Vector(direction).normalized(), spin
        self.centre = self.m0.translation.copy()

    def delta(self, f, lam=None):
        s = self.profile(f)
        t = (self.lam if lam is None else lam) * s
        return Matrix.Translation(self.direction * t) @ _about_up(self.centre, self.spin * s)

    def matrix(self, f, lam=None):
        return self.delta(f, lam) @ self.m0

    def corners(self, f, lam=None):
        d = self.delta(f, lam)
        return [d @ (m0 @ Vector(c)) for o, m0 in zip(self.group, self.m0s) for c in o.bound_box]

    def keyframe(self, frames):
        for o, m0 in zip(self.group, self.m0s):
            one = Mover(o, self.what, self.profile)
            one.matrix = lambda f, lam=None, m0=m0: self.delta(f) @ m0
            one.keyframe(frames)

    def json(self):
        return {"what": self.what, "object": self.obj.name, "type": _base_name(self.obj),
                "material": _material_name(self.obj), "with": [o.name for o in self.group[1:]],
                "direction": r3(self.direction), "speed_per_frame_m": round(self.lam, 6),
                "spin_deg_per_frame": round(math.degrees(self.spin), 4)}


class SunMove(Mover):
    """The sun (and the sky's sun with it) turning about the world's up axis (radians per frame)."""

    def __init__(self, sun, profile, sign):
        super().__init__(sun, "sun", profile)
        self.sign = sign

    def angle(self, f):
        return self.lam * self.profile(f) * self.sign

    def matrix(self, f, lam=None):
        t = (self.lam if lam is None else lam) * self.profile(f) * self.sign
        return _about_up(self.m0.translation, t) @ self.m0

    def keyframe(self, frames):
        super().keyframe(frames)
        world = bpy.context.scene.world
        sky = next((n for n in world.node_tree.nodes if n.type == "TEX_SKY"), None) if world else None
        if sky is None:
            return
        d0 = -(self.m0.to_3x3() @ Vector((0.0, 0.0, 1.0))).normalized()  # the direction the light travels
        prev = None
        for f in frames:
            d = Matrix.Rotation(self.angle(f), 3, "Z") @ d0
            if sky.sky_type == "NISHITA":
                rot = math.atan2(-d.x, -d.y)  # as world() sets it
                if prev is not None:
                    rot += 2.0 * math.pi * round((prev - rot) / (2.0 * math.pi))
                prev = rot
                sky.sun_rotation = rot
                sky.keyframe_insert("sun_rotation", frame=f)
            else:
                sky.sun_direction = -d
                sky.keyframe_insert("sun_direction", frame=f)
        for fc in world.node_tree.animation_data.action.fcurves:
            for k in fc.keyframe_points:
                k.interpolation = "LINEAR"

    def json(self):
        return {"what": "sun", "object": self.obj.name, "deg_per_frame": round(math.degrees(self.lam), 4),
                "sign": self.sign, "sky_follows": True}


class LampMove(Mover):
    """A lamp sliding along a horizontal direction (metres per frame)."""

    def __init__(self, obj, profile, direction):
        super().__init__(obj, "lamp", profile)
        self.direction = Vector(direction).normalized()

    def matrix(self, f, lam=None):
        t = (self.lam if lam is None else lam) * self.profile(f)
        return Matrix.Translation(self.direction * t) @ self.m0

    def json(self):
        return {"what": "lamp", "object": self.obj.name, "type": self.obj.data.type if self.obj.type == "LIGHT"
                else _base_name(self.obj), "direction": r3(self.direction), "speed_per_frame_m": round(self.lam, 6)}


class Screen:
    """Projects world points through the scene camera as it is at some frame (pinhole, square image, the sensor
    fitted to the width: Blender's AUTO fit), in pixels of the render: (col, row), rows downwards."""

    def __init__(self, cam, res):
        self.res = res
        self.f_px = res * cam.data.lens / cam.data.sensor_width

    def __call__(self, cam_matrix, points):
        inv = cam_matrix.inverted()
        out = []
        for p in points:
            q = inv @ p
            if q.z > -1e-6:
                out.append(None)
                continue
            out.append((self.res / 2 + self.f_px * q.x / -q.z, self.res / 2 - self.f_px * q.y / -q.z))
        return out

    def ray(self, cam_matrix, col, row):
        d = Vector(((col - self.res / 2) / self.f_px, -(row - self.res / 2) / self.f_px, -1.0))
        return (cam_matrix.to_3x3() @ d).normalized()


def _percentile(values, q):
    v = sorted(values)
    if not v:
        return 0.0
    return v[min(len(v) - 1, int(round(q * (len(v) - 1))))]


def screen_motion(screen, cam_at, points_at, frames):
    """Per pair of consecutive frames, the 90th percentile and the maximum over the points of their motion on the
    screen (pixels); returns the largest of each over the shot. cam_at(f): the camera's matrix; points_at(f): the
    points (the same ones, in order)."""
    p90, pmax = 0.0, 0.0
    prev = screen(cam_at(frames[0]), points_at(frames[0]))
    for f in frames[1:]:
        cur = screen(cam_at(f), points_at(f))
        d = [math.hypot(a[0] - b[0], a[1] - b[1]) for a, b in zip(prev, cur) if a is not None and b is not None]
        if d:
            p90, pmax = max(p90, _percentile(d, 0.9)), max(pmax, max(d))
        prev = cur
    return p90, pmax


def calibrate(measure, target, cap, lam=1.0):
    """The speed whose largest 90th-percentile motion per frame is `target` px (its largest motion at most
    `cap` px): measure(lam) -> (p90, max), close to linear in lam."""
    for _ in range(4):
        p90, pmax = measure(lam)
        if p90 <= 1e-9 and pmax <= 1e-9:
            return lam
        k = target / p90 if p90 > 1e-9 else cap / pmax
        if pmax * k > cap:
            k = cap / pmax
        lam *= k
        if abs(k - 1.0) < 0.02:
            break
    return lam


def scene_points(scene, cam, screen, far, n=12):
    """Points of the scene seen through an n x n grid of pixels (the sky: points at distance `far`)."""
    deps = bpy.context.evaluated_depsgraph_get()
    m = cam.matrix_world
    origin = m.translation.copy()
    pts = []
    for i in range(n):
        for j in range(n):
            d = screen.ray(m, (i + 0.5) * screen.res / n, (j + 0.5) * screen.res / n)
            hit, where, *_ = scene.ray_cast(deps, origin, d, distance=far)
            pts.append(where.copy() if hit else origin + d * far)
    return pts


def path_clear(scene, positions, margin, ignore=()):
    """No surface on the path through `positions` (nor within `margin` beyond each step); surfaces of the
    objects named in `ignore` (the thing that moves) do not count."""
    deps = bpy.context.evaluated_depsgraph_get()
    for a, b in zip(positions, positions[1:]):
        d = b - a
        if d.length < 1e-9:
            continue
        u, left, origin = d.normalized(), d.length + margin, a
        while left > 0:
            hit, where, _n, _i, obj, _m = scene.ray_cast(deps, origin, u, distance=left)
            if not hit:
                break
            if obj is None or obj.original.name not in ignore:
                return False
            step = (where - origin).length + 1e-4
            origin, left = origin + u * step, left - step
    return True


def _world_box(obj):
    corners = [obj.matrix_world @ Vector(c) for c in obj.bound_box]
    return (Vector([min(c[i] for c in corners) for i in range(3)]),
            Vector([max(c[i] for c in corners) for i in range(3)]))


def prop_groups(scene):
    """What may move, each with what goes with it: primitives (not emitters, not thin parts such as stems and
    discs) and chairs (seat, back and legs), each with whatever stands on it."""
    meshes = [o for o in scene.objects if o.type == "MESH" and not o.hide_render]
    boxes = {o.name: _world_box(o) for o in meshes}
    groups = []
    for o in meshes:
        base = _base_name(o)
        if _material_name(o) == "emission":
            continue
        lo, hi = boxes[o.name]
        ext = hi - lo
        if base == "chair":
            members = [o] + [m for m in meshes if _base_name(m) in ("chair_back", "cylinder") and
                             all(lo[i] <= (boxes[m.name][0][i] + boxes[m.name][1][i]) / 2 <= hi[i] for i in (0, 1))
                             and boxes[m.name][1].z <= hi.z + 0.6]
        elif base in MOVABLE_KINDS and min(ext) >= 0.15 * max(ext):
            members = [o]
        else:
            continue
        size = max(ext)
        for m in meshes:  # things standing on it
            mlo, mhi = boxes[m.name]
            c = (mlo + mhi) / 2
            if (m not in members and abs(mlo.z - hi.z) < 0.03 * size and lo.x <= c.x <= hi.x and lo.y <= c.y <= hi.y
                    and max(mhi - mlo) < size):
                members.append(m)
        groups.append(members)
    return groups


def visible_props(scene, cam, screen):
    """prop_groups() whose prop is in view and not hidden behind something else, largest on the screen first:
    [(area of the group's screen bounding box in px, group)]."""
    deps = bpy.context.evaluated_depsgraph_get()
    origin = cam.matrix_world.translation
    out = []
    for group in prop_groups(scene):
        names = {o.name for o in group}
        lo, hi = _world_box(group[0])
        centre = (lo + hi) / 2
        sc = screen(cam.matrix_world, [centre])[0]
        if sc is None or not (0 <= sc[0] < screen.res and 0 <= sc[1] < screen.res):
            continue
        d = centre - origin
        hit, where, _n, _i, hobj, _m = scene.ray_cast(deps, origin, d.normalized(), distance=d.length)
        if hit and hobj is not None and hobj.original.name not in names:
            continue
        corners = [o.matrix_world @ Vector(c) for o in group for c in o.bound_box]
        pc = screen(cam.matrix_world, corners)
        if any(p is None for p in pc):
            continue
        cols, rows = [p[0] for p in pc], [p[1] for p in pc]
        area = (min(screen.res, max(cols)) - max(0, min(cols))) * (min(screen.res, max(rows)) - max(0, min(rows)))
        if area > 0:
            out.append((area, group))
    out.sort(key=lambda t: -t[0])
    return out


def plan_shot(args, scene, ctx):
    """Draws the shot from the seed's shot stream and keyframes it; returns its description."""
    rng = shots.shot_rng(args.scene_seed)
    drawn = shots.draw_kind(rng)
    kind = drawn if args.shot == "auto" else args.shot
    n = args.frames
    frames = list(range(0, n + 2))  # keyframes: one frame before and after the shot, for the Vector pass
    px = args.res / 256.0  # the speeds are set in pixels at 256x256
    profile_kind = rng.choice(["linear", "smooth"])
    scale = ctx.desc.get("scale", 1.0)  # open-air scenes are built at garden scale, then scaled
    cam = scene.camera
    screen = Screen(cam, args.res)
    bpy.context.view_layer.update()
    far = 500.0 * scale
    desc = {"kind": kind, "kind_drawn": drawn, "frames": n, "keyframes": [frames[0], frames[-1]],
            "interpolation": "a keyframe at every frame, linear in between", "notes": []}

    def new_profile():
        return Profile(profile_kind, n, rng.uniform(0.3, 0.8), rng.uniform(0.0, 2.0 * math.pi))

    movers = []
    cam_kind = kind if kind in shots.CAMERA_KINDS else rng.choice(shots.CAMERA_KINDS)  # drawn either way
    cam_target = rng.uniform(3.0, 10.0) * px if kind != "mixed" else rng.uniform(2.0, 7.0) * px
    obj_target = rng.uniform(3.0, 12.0) * px
    sign = rng.choice([-1, 1])
    cam_profile = new_profile()

    def camera_move(what):
        pivot = None
        if what == "orbit":  # about the point the generator aimed the camera at (else what the centre sees)
            m = cam.matrix_world
            pivot = Vector(ctx.desc["camera"]["target"]) * scale
            if not 0.3 * scale < (pivot - m.translation).length < 50.0 * scale:
                deps = bpy.context.evaluated_depsgraph_get()
                d = screen.ray(m, args.res / 2, args.res / 2)
                hit, where, *_ = scene.ray_cast(deps, m.translation, d, distance=far)
                pivot = where if hit else m.translation + d * min(far, 5.0 * scale)
        mv = CameraMove(cam, what, cam_profile, sign, pivot)
        pts = scene_points(scene, cam, screen, far)
        measure = lambda lam: screen_motion(screen, lambda f: mv.matrix(f, lam), lambda f: pts, frames)  # noqa: E731
        lam = calibrate(measure, cam_target, 16.0 * px, 0.01 * scale if what in ("dolly", "truck") else 0.005)
        if what in ("dolly", "truck", "orbit"):
            full = lam
            while lam > 0.3 * full and not path_clear(scene, [mv.matrix(f, lam).translation for f in frames],
                                                      0.15 * scale):
                lam *= 0.8
            if not path_clear(scene, [mv.matrix(f, lam).translation for f in frames], 0.15 * scale):
                desc["notes"].append(f"{what}: the camera's path ran into the scene; a pan instead")
                return camera_move("pan")
            if lam < full:
                desc["notes"].append(f"{what}: slowed to {lam / full:.2f} of the aimed speed to stay clear")
        mv.lam = lam
        return mv

    def object_moves(count_range, target):
        # Props of some size on the screen (at least ~13 x 13 px at 256x256; else ~6 x 6): a speck would need metres
        # per frame.
        cands = visible_props(scene, cam, screen)
        pool = [g for a, g in cands if a >= (0.05 * args.res) ** 2][:5] or \
            [g for a, g in cands if a >= (0.025 * args.res) ** 2][:3]
        k = rng.randint(*count_range)
        chosen = rng.sample(pool, min(k, len(pool))) if pool else []
        out = []
        right = (cam.matrix_world.to_3x3() @ Vector((1.0, 0.0, 0.0)))
        right.z = 0.0
        right = right.normalized() if right.length > 1e-6 else Vector((1.0, 0.0, 0.0))
        taken = set()
        for group in chosen:
            ang = rng.uniform(-0.8, 0.8) + (math.pi if rng.random() < 0.5 else 0.0)
            direction = Matrix.Rotation(ang, 3, "Z") @ right
            mv = ObjectMove(group, new_profile(), direction, math.radians(rng.uniform(-6.0, 6.0)))
            if taken & {o.name for o in group}:  # shares a thing with a group already moving
                continue
            taken |= {o.name for o in group}
            measure = lambda lam, mv=mv: screen_motion(  # noqa: E731
                screen, lambda f: cam.matrix_world, lambda f: mv.corners(f, lam), frames)
            aim = target * rng.uniform(0.7, 1.3)
            spin_only = measure(0.0)[0]
            if spin_only > 0.6 * aim:  # a large prop close by: its spin alone would be most of the motion
                mv.spin *= 0.6 * aim / spin_only
            mv.lam = calibrate(measure, aim, 16.0 * px, 0.01 * scale)
            out.append(mv)
        return out

    if kind in shots.CAMERA_KINDS or kind == "mixed":
        movers.append(camera_move(cam_kind))
    if kind in ("objects", "mixed"):
        props = object_moves((1, 3) if ctx.desc["kind"] == "interior" else (1, 4), obj_target)
        if not props:
            desc["notes"].append("no prop in view to move" + ("; a truck instead" if kind == "objects" else ""))
            if kind == "objects":
                movers.append(camera_move("truck"))
        movers += props
    if kind == "light":
        suns = [o for o in scene.objects if o.type == "LIGHT" and o.data.type == "SUN"]
        lamps = [o for o in scene.objects if o.type == "LIGHT" and o.data.type != "SUN" and not o.data.cycles.is_portal]
        glowing = [o for o in scene.objects if o.type == "MESH" and not o.hide_render
                   and _base_name(o) in MOVABLE_KINDS and _material_name(o) == "emission"]
        pick_sun = suns and (not (lamps or glowing) or rng.random() < (0.5 if lamps else 0.7))
        lamp_pool = lamps or glowing  # a lamp, else something that glows (a ceiling spot, a bulb)
        if pick_sun:
            mv = SunMove(suns[0], new_profile(), rng.choice([-1, 1]))
            mv.lam = math.radians(rng.uniform(0.4, 1.2))
            movers.append(mv)
        elif lamp_pool:
            obj = lamp_pool[rng.randrange(len(lamp_pool))]
            direction = Matrix.Rotation(rng.uniform(0.0, 2.0 * math.pi), 3, "Z") @ Vector((1.0, 0.0, 0.0))
            mv = LampMove(obj, new_profile(), direction)
            d = obj.matrix_world.translation - cam.matrix_world.translation
            lam = rng.uniform(0.01, 0.025) * max(d.length, 1.0 * scale)
            while lam > 1e-4 and not path_clear(scene, [mv.matrix(f, lam).translation for f in frames], 0.05 * scale,
                                                {obj.name}):
                lam *= 0.7
            mv.lam = lam
            movers.append(mv)
        else:
            desc["notes"].append("no sun or lamp to move; props instead")
            movers += object_moves((1, 3), obj_target)
    for mv in movers:
        mv.keyframe(frames)
    scene.frame_start, scene.frame_end = 1, n
    bpy.context.view_layer.update()
    desc["profile"] = profile_kind
    desc["movers"] = [dict(mv.json(), profile=mv.profile.json()) for mv in movers]
    # What the moves do on the screen (pixels per frame, before rendering; the rendered Vector pass is in each
    # frame's record): the camera over the scene's points, each prop over its bounding box.
    cam_mv = next((mv for mv in movers if isinstance(mv, CameraMove)), None)
    pts = scene_points(scene, cam, screen, far) if cam_mv else []
    pred = {}
    if cam_mv:
        pred["camera_p90_px"], pred["camera_max_px"] = (round(v, 2) for v in screen_motion(
            screen, cam_mv.matrix, lambda f: pts, frames))
    for mv in movers:
        if isinstance(mv, ObjectMove):
            pred.setdefault("props_max_px", []).append(round(screen_motion(
                screen, lambda f: cam.matrix_world if cam_mv is None else cam_mv.matrix(f),
                mv.corners, frames)[1], 2))
    desc["predicted_motion"] = pred
    desc["aimed_px_per_frame"] = {"camera": round(cam_target, 2), "props": round(obj_target, 2)}
    return desc


def vector_stats(img):
    """The rendered motion (Vector pass) of a frame: magnitudes of both pairs, pixels."""
    import numpy as np
    ch = img["channels"]
    v = img["pixels"][:, :, [ch.index(f"ViewLayer.Vector.{c}") for c in "XYZW"]].astype(np.float64)
    out = {}
    for name, pair in (("to_previous", v[..., 0:2]), ("from_next", v[..., 2:4])):
        m = np.hypot(pair[..., 0], pair[..., 1]).ravel()
        out[name] = {"mean": round(float(m.mean()), 3), "p50": round(float(np.percentile(m, 50)), 3),
                     "p90": round(float(np.percentile(m, 90)), 3), "p99": round(float(np.percentile(m, 99)), 3),
                     "max": round(float(m.max()), 3), "moving_share": round(float((m > 0.5).mean()), 4)}
    return out


def shot_main(args, scene, ctx, kind, build_s):
    """--shot: exposure, the shot's moves, then every requested frame: scene.frame_set(f) and each render of
    --frame-renders with sampling seed base + f, into DIR/.partial/ and renamed (the reference last, so that a
    frame whose reference exists is complete); DIR/shot.json is rewritten after every frame."""
    import numpy as np
    shot_path = os.path.join(args.outdir, "shot.json")
    old = None
    if os.path.isfile(shot_path):
        with open(shot_path) as f:
            old = json.load(f)
        same = (old.get("scene_seed") == args.scene_seed and old.get("shot", {}).get("requested") == args.shot
                and old.get("frames") == args.frames and old.get("resolution") == [args.res, args.res]
                and old.get("frame_renders") == args.frame_renders and old.get("names") == args.name_list)
        if not same:
            raise SystemExit(f"make_scene: {shot_path} is another shot's (seed, kind, frames, resolution or renders "
                             "differ): render into another folder")
    k_log2 = args.light_scale_log2
    if k_log2 is None and old is not None:
        k_log2 = old.get("scene", {}).get("exposure", {}).get("light_scale_log2")
    if k_log2 is None:
        probe_exposure(ctx, scene, args)
        k = ctx.desc["exposure"].get("light_scale", 1.0)
        ctx.desc["exposure"]["light_scale_log2"] = round(math.log2(k), 1) if args.probe_res > 0 else 0.0
    else:  # the shot's first run probed it: every frame of a shot has the same exposure
        ev = round(ctx.u(-1.0, 1.5), 2)  # drawn as the probe draws it
        ctx.scale_lights(2.0 ** k_log2)
        if args.light_scale_log2 is None:  # the first run's record, probe and all
            ctx.desc["exposure"] = dict(old["scene"]["exposure"], reused_from="shot.json")
        else:
            ctx.desc["exposure"] = {"target_ev": ev, "light_scale": round(2.0 ** k_log2, 5),
                                    "light_scale_log2": k_log2, "from": "--light-scale-log2"}
    scene.render.use_motion_blur = False  # Cycles writes the Vector pass only without motion blur
    t = time.time()
    shot = plan_shot(args, scene, ctx)
    shot["requested"] = args.shot
    plan_s = time.time() - t
    if args.save_blend:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(args.outdir, "scene.blend"))
    names = args.name_list
    partial = os.path.join(args.outdir, ".partial")
    os.makedirs(partial, exist_ok=True)
    records = {}
    if old is not None:  # frames of an earlier run whose files are all there
        for key, rec in old.get("frame_records", {}).items():
            if all(os.path.isfile(os.path.join(args.outdir, shots.frame_file(nm, int(key)))) for nm in names):
                records[key] = rec
    flags = scene_flags(args)
    doc = {
        "scene_seed": args.scene_seed,
        "kind": kind,
        "shot": shot,
        "frames": args.frames,
        "resolution": [args.res, args.res],
        "frame_renders": args.frame_renders,
        "names": names,
        "files": {nm: {"pattern": f"{nm}.####.exr", "spp": spp, "sampling_seed": f"{base} + frame",
                       "passes": (NOISY_PASSES + ", Vector") if i < len(names) - 1 else "Combined (RGBA) only"}
                  for i, (nm, (spp, base)) in enumerate(zip(names, args.frame_render_list))},
        "vector_convention": shots.VECTOR_CONVENTION,
        "render_settings": dict(render_settings(
            scene, args, f"blender -b --factory-startup -noaudio -t {args.threads} --python "
                         f"tools/datagen/make_scene.py -- --scene-seed {args.scene_seed} --shot {args.shot} "
                         f"--frames {args.frames} --frame-renders {args.frame_renders} --names {','.join(names)} "
                         f"--outdir <dir> --res {args.res} --threads {args.threads}{flags}"),
            vector_pass="noisy renders (ViewLayer.Vector.XYZW, float)", motion_blur=False),
        "camera": None,
        "scene": ctx.desc,
        "timing": {},
        "frame_records": records,
    }

    def write_doc():
        ru = resource.getrusage(resource.RUSAGE_SELF)
        doc["frames_done"] = sorted(int(k) for k in records)
        doc["complete"] = len(records) == args.frames
        doc["timing"] = {"process_wall_s": process_wall(), "process_user_cpu_s": round(ru.ru_utime, 2),
                         "process_max_rss_kb": ru.ru_maxrss, "build_scene_s": round(build_s, 3),
                         "probe_s": ctx.desc.get("exposure", {}).get("probe_s"), "plan_shot_s": round(plan_s, 3),
                         "frame_wall_s_mean": round(sum(r["frame_wall_s"] for r in records.values()) /
                                                    max(1, len(records)), 2)}
        doc["frame_records"] = {k: records[k] for k in sorted(records, key=int)}
        tmp = shot_path + ".tmp"
        with open(tmp, "w") as f:
            json.dump(doc, f, indent=1)
        os.replace(tmp, shot_path)

    for fr in args.frame_list:
        t_frame = time.time()
        scene.frame_set(fr)
        if doc["camera"] is None:
            doc["camera"] = camera_json(scene, args.res)
            doc["camera"]["note"] = "at frame %d; every frame's cameraToWorld is in frame_records" % fr
        rec = {"frame": fr, "cameraToWorld": _m4(scene.camera.matrix_world),
               "worldToCamera": _m4(scene.camera.matrix_world.inverted()), "files": {}}
        paths = []
        for i, (nm, (spp, base)) in enumerate(zip(names, args.frame_render_list)):
            ref = i == len(names) - 1
            path = os.path.join(partial, shots.frame_file(nm, fr))
            wall = render_one(scene, path, spp, base + fr, not ref, vector=not ref, note={"frame": fr})
            img = exr_metrics.read_exr(path)
            a = img["attrs"]
            rec["files"][shots.frame_file(nm, fr)] = {
                "spp": spp, "sampling_seed": base + fr, "bytes": os.path.getsize(path), "render_wall_s": round(wall, 2),
                "cycles_render_time_s": parse_time(a.get("cycles.ViewLayer.render_time")),
                "cycles_sync_time_s": parse_time(a.get("cycles.ViewLayer.synchronization_time")),
                "channels": len(img["channels"])}
            if not ref and "motion" not in rec:
                rec["motion"] = vector_stats(img)
            paths.append((path, img))
            print(f"make_scene: seed {args.scene_seed} shot frame {fr} {nm} {spp} spp in {wall:.2f} s", flush=True)
        ref_rgb = exr_metrics.layer_rgb(paths[-1][1])
        rec["relmse"] = {names[i]: round(exr_metrics.relmse(exr_metrics.layer_rgb(img), ref_rgb), 6)
                         for i, (_p, img) in enumerate(paths[:-1])}
        rec["all_finite"] = bool(all(np.isfinite(img["pixels"]).all() for _p, img in paths))
        for path, _img in paths:  # the reference last: a frame is complete when its reference is there
            os.replace(path, os.path.join(args.outdir, os.path.basename(path)))
        rec["frame_wall_s"] = round(time.time() - t_frame, 2)
        records[str(fr)] = rec
        write_doc()
    if doc["camera"] is None:
        scene.frame_set(1)
        doc["camera"] = camera_json(scene, args.res)
    write_doc()
    shutil.rmtree(partial, ignore_errors=True)
    print(f"make_scene: seed {args.scene_seed} ({kind}) shot {shot['kind']} frames {args.frame_list[0]}-"
          f"{args.frame_list[-1]} done in {process_wall():.1f} s", flush=True)


def main():
    args = parse_args()
    args.outdir = os.path.abspath(args.outdir)
    os.makedirs(args.outdir, exist_ok=True)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    ctx = Ctx(args.scene_seed)
    t = time.time()
    kind = os.environ.get("RESIDUE_DATAGEN_KIND") or ("interior" if args.scene_seed % 2 == 0 else "exterior")
    ctx.desc["kind"] = kind
    {"interior": build_interior, "exterior": build_exterior, "test": build_test}[kind](ctx)
    apply_photos(ctx, args)
    configure(scene, args)
    build_s = time.time() - t
    if args.shot:
        return shot_main(args, scene, ctx, kind, build_s)
    probe_exposure(ctx, scene, args)
    if args.camera_move:  # after the exposure probe, so every frame of an animation has the same exposure
        dx, dy, dz, yaw = (float(v) for v in args.camera_move.split(","))
        cam = scene.camera
        cam.location = cam.location + cam.matrix_world.to_3x3() @ Vector((dx, dy, dz))
        cam.rotation_euler.z += math.radians(yaw)
        bpy.context.view_layer.update()
        ctx.desc["camera_move"] = {"local_offset_m": [dx, dy, dz], "yaw_deg": yaw}
    if args.save_blend:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(args.outdir, "scene.blend"))

    files, walls, spp_of, seed_of = {}, {}, {}, {}
    for i, ((spp, seed), name) in enumerate(zip(args.render_list, args.name_list)):
        ref = i == len(args.render_list) - 1
        path = os.path.join(args.outdir, name + ".exr")
        scene.cycles.use_adaptive_sampling = args.adaptive_threshold > 0 and not ref
        scene.cycles.adaptive_threshold = args.adaptive_threshold
        walls[name] = round(render_one(scene, path, spp, seed, not ref), 2)
        spp_of[name], seed_of[name] = spp, seed
        print(f"make_scene: seed {args.scene_seed} {name} {spp} spp in {walls[name]:.2f} s", flush=True)

    t = time.time()
    images = {}
    for name in args.name_list:
        path = os.path.join(args.outdir, name + ".exr")
        img = exr_metrics.read_exr(path)
        images[name] = img
        a = img["attrs"]
        entry = {"spp": spp_of[name], "sampling_seed": seed_of[name], "bytes": os.path.getsize(path),
                 "render_wall_s": walls[name],
                 "cycles_render_time_s": parse_time(a.get("cycles.ViewLayer.render_time")),
                 "cycles_sync_time_s": parse_time(a.get("cycles.ViewLayer.synchronization_time")),
                 "cycles_samples_header": a.get("cycles.ViewLayer.samples"),
                 "channels": img["channels"], "channel_types": img["types"]}
        if name == args.name_list[-1]:
            entry["note"] = f"ViewLayer.Combined RGBA only, {spp_of[name]} spp, its own sampling seed"
        else:
            entry["passes"] = NOISY_PASSES
        files[name + ".exr"] = entry
    ref_name = args.name_list[-1]
    a_name = args.name_list[0]
    b_name = args.name_list[1] if len(args.name_list) > 2 else None
    metrics = exr_metrics.scene_metrics(images[a_name], images[b_name] if b_name else None, images[ref_name])

    ru = resource.getrusage(resource.RUSAGE_SELF)
    doc = {
        "scene_seed": args.scene_seed,
        "kind": kind,
        "resolution": [args.res, args.res],
        "spp": spp_of,
        "sampling_seeds": seed_of,
        "files": files,
        "render_settings": render_settings(
            scene, args, "blender -b --factory-startup -noaudio -t {t} --python tools/datagen/make_scene.py -- "
                         "--scene-seed {s} --renders {r} --outdir <dir> --res {res} --threads {t}{ph}".format(
                             t=args.threads, s=args.scene_seed, r=args.renders, res=args.res, ph=scene_flags(args))),
        "timing": {
            "process_wall_s": process_wall(),
            "process_user_cpu_s": round(ru.ru_utime, 2),
            "process_sys_cpu_s": round(ru.ru_stime, 2),
            "process_max_rss_kb": ru.ru_maxrss,
            "build_scene_s": round(build_s, 3),
            "probe_s": ctx.desc.get("exposure", {}).get("probe_s"),
            "render_wall_s": walls,
            "loadavg_at_postproc": list(os.getloadavg()),
            "postproc_s": round(time.time() - t, 3),
        },
        "camera": camera_json(scene, args.res),
        "camera_identical_across_renders": True,
        "scene": ctx.desc,
        "metrics": metrics,
    }
    tmp = os.path.join(args.outdir, "scene.json.tmp")
    with open(tmp, "w") as f:
        json.dump(doc, f, indent=1)
    os.replace(tmp, os.path.join(args.outdir, "scene.json"))
    print(f"make_scene: seed {args.scene_seed} ({kind}) done in {process_wall():.1f} s, relMSE noisy_a "
          f"{metrics['relmse_noisy_a']:.4f}, finite {metrics['all_finite']}", flush=True)


try:
    main()
except Exception:  # noqa: BLE001 - make Blender exit non-zero instead of staying at the prompt
    import traceback
    traceback.print_exc()
    sys.stdout.flush()
    os._exit(1)
