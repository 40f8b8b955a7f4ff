"""Renders Residue's bundled example: a small room lit through a window, noisy + reference.

Run with Debian's Blender (Cycles on the CPU, headless):
  blender -b --factory-startup -noaudio -t 2 --python tools/datagen/render_example.py -- \
      --out resources/examples/room --res 128 --spp 8 --ref-spp 1024

Writes OUT/noisy.exr (multilayer: Combined, Denoising Albedo/Normal/Depth, Depth, Normal; colour half, data
float, ZIP) and OUT/reference.exr (Combined only) rendered with a different sampling seed.
Adaptive sampling and denoising are off so the spp are exact (see ../shared/reference/NOTES.md).
"""
import argparse
import json
import math
import os
import sys

import bpy


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser()
    p.add_argument("--out", required=True)
    p.add_argument("--res", type=int, default=128)
    p.add_argument("--spp", type=int, default=8)
    p.add_argument("--ref-spp", type=int, default=1024)
    p.add_argument("--threads", type=int, default=2)
    return p.parse_args(argv)


def material(name, color, roughness=0.5, metallic=0.0, transmission=0.0, emission=None, strength=0.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Transmission"].default_value = transmission
    if emission is not None:
        bsdf.inputs["Emission"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
    return m


def add(obj_op, mat, **kw):
    obj_op(**kw)
    obj = bpy.context.active_object
    obj.data.materials.append(mat)
    return obj


def build_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    wall = material("wall", (0.75, 0.72, 0.66), roughness=0.9)
    floor = material("floor", (0.35, 0.22, 0.12), roughness=0.25)
    red = material("red", (0.7, 0.08, 0.05), roughness=0.6)
    metal = material("metal", (0.9, 0.85, 0.7), roughness=0.2, metallic=1.0)
    glass = material("glass", (1.0, 1.0, 1.0), roughness=0.0, transmission=1.0)
    lamp = material("lamp", (1.0, 1.0, 1.0), emission=(1.0, 0.8, 0.55), strength=25.0)

    # A 4 x 4 x 3 room, open towards the camera; a window cut in the left wall by leaving a gap.
    add(bpy.ops.mesh.primitive_plane_add, floor, size=4, location=(0, 0, 0))
    add(bpy.ops.mesh.primitive_plane_add, wall, size=4, location=(0, 0, 3))
    add(bpy.ops.mesh.primitive_plane_add, wall, size=4, location=(0, 2, 1.5), rotation=(math.pi / 2, 0, 0))
    add(bpy.ops.mesh.primitive_plane_add, wall, size=4, location=(2, 0, 1.5), rotation=(0, math.pi / 2, 0))
    left = add(bpy.ops.mesh.primitive_cube_add, wall, size=1, location=(-2, 0.8, 1.5))
    left.scale = (0.05, 1.2, 1.5)
    lower = add(bpy.ops.mesh.primitive_cube_add, wall, size=1, location=(-2, -1.2, 0.45))
    lower.scale = (0.05, 0.8, 0.45)
    upper = add(bpy.ops.mesh.primitive_cube_add, wall, size=1, location=(-2, -1.2, 2.55))
    upper.scale = (0.05, 0.8, 0.45)

    # Furniture and small objects.
    table = add(bpy.ops.mesh.primitive_cube_add, red, size=1, location=(0.4, 0.6, 0.4))
    table.scale = (0.6, 0.4, 0.4)
    bpy.ops.object.modifier_add(type="BEVEL")
    add(bpy.ops.mesh.primitive_uv_sphere_add, metal, radius=0.25, location=(0.3, 0.6, 1.05))
    add(bpy.ops.mesh.primitive_cylinder_add, glass, radius=0.15, depth=0.5, location=(0.8, 0.5, 1.05))
    add(bpy.ops.mesh.primitive_uv_sphere_add, lamp, radius=0.08, location=(1.3, 1.4, 2.2))
    bpy.ops.object.shade_smooth()

    # Sun through the window and a dim sky.
    bpy.ops.object.light_add(type="SUN", location=(-5, -1, 4), rotation=(0.2, -1.1, 0.3))
    bpy.context.active_object.data.energy = 4.0
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.5, 0.6, 0.8, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.6
    scene.world = world

    bpy.ops.object.camera_add(location=(0.2, -3.6, 1.4), rotation=(math.radians(85), 0, 0))
    scene.camera = bpy.context.active_object
    scene.camera.data.lens = 24
    return scene


def render(scene, path, spp, seed, args, data_passes):
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = spp
    scene.cycles.seed = seed
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.render.threads_mode = "FIXED"
    scene.render.threads = args.threads
    scene.render.resolution_x = scene.render.resolution_y = args.res
    scene.render.resolution_percentage = 100
    layer = scene.view_layers[0]
    layer.cycles.denoising_store_passes = data_passes
    layer.use_pass_z = data_passes
    layer.use_pass_normal = data_passes
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "16"
    settings.exr_codec = "ZIP"
    # The camera travels in the EXR's Note as JSON (Blender convention: row-major, p_cam = M p_world,
    # camera looking down -z); Residue reads it to turn world-space normals into view space.
    world_to_camera = [v for row in scene.camera.matrix_world.inverted() for v in row]
    scene.render.use_stamp_note = True
    scene.render.stamp_note_text = json.dumps({"worldToCamera": [round(v, 6) for v in world_to_camera],
                                               "spp": spp, "sampling_seed": seed})
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def main():
    args = parse_args()
    os.makedirs(args.out, exist_ok=True)
    scene = build_scene()
    render(scene, os.path.join(args.out, "noisy.exr"), args.spp, 11, args, True)
    render(scene, os.path.join(args.out, "reference.exr"), args.ref_spp, 77, args, False)


main()
