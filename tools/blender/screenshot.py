# A screenshot of the add-on's panel in a real Blender window (docs/images/blender_addon.png), made under Xvfb:
#   /usr/bin/python3 tools/blender/make_zip.py /tmp/rb.zip
#   blender -b --factory-startup --python-expr "import bpy; bpy.ops.wm.save_as_mainfile(filepath='/tmp/start.blend')"
#   residue-cli denoise ../shared/datasets/cycles-starter/s120/noisy_a.exr -m tiny -o /tmp/shot_den.exr
#   ZIP=/tmp/rb.zip IMG=/tmp/shot_den.exr OUT=docs/images/blender_addon.png BLENDER_USER_SCRIPTS=$(mktemp -d) \
#     xvfb-run -a -s "-screen 0 1280x720x24" blender --factory-startup /tmp/start.blend --python tools/blender/screenshot.py
# The Image Editor's sidebar shows the panel on its first tab here (the add-on's own tab is "Residue", which a
# script cannot select in Blender 3.4), with an image loaded and a run's status.
import bpy, os
bpy.ops.preferences.addon_install(filepath=os.environ["ZIP"], overwrite=True)
bpy.ops.preferences.addon_enable(module="residue_blender")
import residue_blender
class IMAGE_PT_residue_shot(bpy.types.Panel):  # the same panel on the sidebar's first tab, for the screenshot
    bl_label = "Residue"
    bl_space_type = "IMAGE_EDITOR"
    bl_region_type = "UI"
    bl_category = "Tool"
    def draw(self, context):
        residue_blender.draw_settings(self.layout, context)
bpy.utils.register_class(IMAGE_PT_residue_shot)
def arrange():
    screen = bpy.context.window.screen
    for area in screen.areas:
        if area.type == "PROPERTIES":
            area.spaces.active.context = "RENDER"
        if area.type == "VIEW_3D":
            area.type = "IMAGE_EDITOR"
            area.spaces.active.show_region_ui = True
    s = bpy.context.scene
    s.render.engine = "CYCLES"
    s.residue.status = "denoising"
    s.residue.running = True
    img = bpy.data.images.load(os.environ["IMG"])
    for area in screen.areas:
        if area.type == "IMAGE_EDITOR":
            area.spaces.active.image = img
    s.residue.progress = 0.4
    return None
def shoot():
    bpy.ops.screen.screenshot(filepath=os.environ["OUT"])
    bpy.ops.wm.quit_blender()
bpy.app.timers.register(arrange, first_interval=2.0)
bpy.app.timers.register(shoot, first_interval=4.0)
