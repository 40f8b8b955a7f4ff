# The add-on tests' scene (test_addon.py, test_addon_modal.py): a floor, an orange sphere, an area light and a dim
# sky, 96 x 64 at 8 spp with Cycles on the CPU, nothing else that could vary between machines.
import math

import bpy


def build(width=96, height=64, samples=8):
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.seed = 3
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = width, height, 100
    scene.render.threads_mode, scene.render.threads = "FIXED", 2
    bpy.ops.mesh.primitive_plane_add(size=20)
    bpy.ops.mesh.primitive_uv_sphere_add(location=(0, 0, 1))
    material = bpy.data.materials.new("orange")
    material.use_nodes = True
    material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.8, 0.3, 0.1, 1)
    bpy.context.object.data.materials.append(material)
    bpy.ops.object.light_add(type="AREA", location=(2, -2, 4))
    bpy.context.object.data.energy = 400
    bpy.ops.object.camera_add(location=(0, -6, 2.5), rotation=(math.radians(72), 0, 0))
    scene.camera = bpy.context.object
    scene.world = bpy.data.worlds.new("sky")
    scene.world.color = (0.05, 0.06, 0.08)
    return scene
