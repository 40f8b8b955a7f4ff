# Residue for Blender: denoise the render result (or a multilayer EXR, or the rendered frame range) with
# residue-cli, send a render to the Residue viewer over tev's protocol, and enable the passes Residue reads.
#
# The denoise runs in its own process (residue-cli), so Blender's UI stays responsive: the operators are modal,
# poll the process on a timer, show its tile progress and stop it on Esc (SIGINT: residue-cli writes nothing then).
# Run from a script or in the background (blender -b), the same operators run to the end before returning.
# Install: Edit > Preferences > Add-ons > Install..., the zip made by tools/blender/make_zip.py.

bl_info = {
    "name": "Residue denoiser",
    "author": "Residue",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > Residue; Image Editor > Sidebar > Residue",
    "description": "Denoise renders with Residue's direct residual networks and compare them in its viewer",
    "category": "Render",
}

import os
import re
import shutil
import signal
import socket
import struct
import subprocess
import tempfile

import bpy

MODELS = [
    ("multiscale", "multiscale", "The default: the best speed/accuracy trade measured"),
    ("best", "best", "multiscale with an 8-fold self-ensemble: the lowest error, 8x the time"),
    ("small", "small", "A small flat ResNet"),
    ("tiny", "tiny", "The fastest network"),
    ("base", "base", "The flat ResNet of the paper's size class"),
    ("paper", "paper", "The paper's network (Wong & Wong 2019): the slowest"),
    ("oidn", "oidn", "Open Image Denoise's network (Intel's weights), for comparison"),
    ("oidn-cleanaux", "oidn-cleanaux", "Open Image Denoise's final-frame mode (albedo and normal denoised first)"),
    ("bilateral", "bilateral", "The cross-bilateral filter (no network)"),
]
PRECISIONS = [("fp32", "fp32", "32-bit floats"), ("bf16", "bf16", "bfloat16 (CPUs with AVX512_BF16)")]
ENSEMBLES = [("0", "model's", "The model's own self-ensemble"), ("1", "1", ""), ("2", "2", ""), ("4", "4", ""),
             ("8", "8", "")]
TILE_PROGRESS = re.compile(r"(\d+)/(\d+) tiles")
FRAME_DONE = re.compile(r"^frame -?\d+  ", re.MULTILINE)  # a sequence's line per frame: denoised, skipped or failed


def cli_path(context):
    """residue-cli: the add-on's preference, else $RESIDUE_CLI, else the one on PATH."""
    prefs = context.preferences.addons[__package__].preferences if __package__ in context.preferences.addons else None
    for candidate in (prefs.cli if prefs else "", os.environ.get("RESIDUE_CLI", ""), shutil.which("residue-cli") or ""):
        if candidate and os.path.isfile(bpy.path.abspath(candidate)) and os.access(bpy.path.abspath(candidate), os.X_OK):
            return bpy.path.abspath(candidate)
    return None


def model_arguments(settings):
    args = ["-m", settings.model, "--precision", settings.precision]
    if settings.strength < 1.0:
        args += ["--strength", "%.4g" % settings.strength]
    if settings.ensemble != "0" and settings.model != "bilateral":
        args += ["--ensemble", settings.ensemble]
    return args


def enable_passes(view_layer, vector=False):
    """The passes Residue reads: Denoising Data (albedo, normal, depth), and Vector for sequences."""
    view_layer.cycles.denoising_store_passes = True
    if vector:
        view_layer.use_pass_vector = True


def save_render_result(scene, path):
    """The Render Result as a multilayer EXR with every pass (float), whatever the scene's output format."""
    image = bpy.data.images.get("Render Result")
    if image is None:
        raise RuntimeError("there is no render result: render first (F12)")
    settings = scene.render.image_settings
    kept = (settings.file_format, settings.color_depth, settings.exr_codec)
    try:
        settings.file_format = "OPEN_EXR_MULTILAYER"
        settings.color_depth = "32"
        settings.exr_codec = "ZIP"
        image.save_render(filepath=path, scene=scene)
    finally:
        settings.file_format, settings.color_depth, settings.exr_codec = kept


def tev_open_packet(path, grab_focus=True):
    """tev's 'open image v2' packet: u32 length, u8 type 7, flag grab_focus, path, channel selector (NUL-ended)."""
    body = struct.pack("<BB", 7, 1 if grab_focus else 0) + path.encode() + b"\0" + b"\0"
    return struct.pack("<I", 4 + len(body)) + body


def show_image(context, image):
    screen = context.screen if context.screen else None
    for area in (screen.areas if screen else []):
        if area.type == "IMAGE_EDITOR":
            area.spaces.active.image = image
            return


class ResidueSettings(bpy.types.PropertyGroup):
    model: bpy.props.EnumProperty(name="Model", items=MODELS, default="multiscale")
    precision: bpy.props.EnumProperty(name="Precision", items=PRECISIONS, default="fp32")
    strength: bpy.props.FloatProperty(name="Strength", min=0.0, max=1.0, default=1.0, subtype="FACTOR",
                                      description="1 the denoised image, 0 the noisy one; between, a blend")
    ensemble: bpy.props.EnumProperty(name="Ensemble", items=ENSEMBLES, default="0",
                                     description="Flips and transposes averaged: lower error for that many times the time")
    input_file: bpy.props.StringProperty(name="EXR", subtype="FILE_PATH",
                                         description="A multilayer EXR to denoise instead of the render result")
    temporal: bpy.props.BoolProperty(name="Temporal", default=False,
                                     description="Denoise each frame with its neighbours (needs the Vector pass)")
    viewer_port: bpy.props.IntProperty(name="Port", min=1, max=65535, default=14158,
                                       description="The port the Residue viewer listens on (tev's, 14158)")
    status: bpy.props.StringProperty(name="Status", default="")  # what the last run did, in the panel
    progress: bpy.props.FloatProperty(name="Progress", min=0.0, max=1.0, default=0.0, subtype="FACTOR")
    running: bpy.props.BoolProperty(name="Running", default=False)


class ResiduePreferences(bpy.types.AddonPreferences):
    bl_idname = __package__
    cli: bpy.props.StringProperty(name="residue-cli", subtype="FILE_PATH",
                                  description="The residue-cli program (empty: $RESIDUE_CLI or the one on PATH)")

    def draw(self, context):
        self.layout.prop(self, "cli")


class ResidueRun:
    """What the denoise operators share: one residue-cli process, polled on a timer, stopped on Esc."""

    process = None
    timer = None
    frames = 0  # a sequence's frame count (0: a still)

    def start(self, context, args):
        cli = cli_path(context)
        if cli is None:
            self.report({"ERROR"}, "residue-cli not found: set it in the add-on's preferences, or $RESIDUE_CLI")
            return False
        self.log_file = tempfile.TemporaryFile(mode="w+")
        # Its stdout line by line (a sequence's frame lines), where coreutils' stdbuf is there.
        line_buffered = ["stdbuf", "-oL"] if shutil.which("stdbuf") else []
        self.process = subprocess.Popen(line_buffered + [cli] + args, stdout=self.log_file, stderr=subprocess.STDOUT,
                                        text=True)
        context.scene.residue.status = "denoising frames" if self.frames else "denoising"
        context.scene.residue.running = True
        context.scene.residue.progress = 0.0
        return True

    def poll_progress(self, context):
        self.log_file.seek(0)
        log = self.log_file.read()
        tiles = TILE_PROGRESS.findall(log)
        tile_fraction = 0.0
        if tiles:
            done, total = (int(x) for x in tiles[-1])
            tile_fraction = done / max(1, total)
        if self.frames:
            finished = len(FRAME_DONE.findall(log))
            context.scene.residue.progress = min(1.0, (finished + (tile_fraction if finished < self.frames else 0)) / self.frames)
        else:
            context.scene.residue.progress = tile_fraction
        return log

    def finish(self, context):
        log = self.poll_progress(context)
        code = self.process.returncode
        self.process = None
        context.scene.residue.running = False
        if code != 0:
            lines = [l for l in log.splitlines() if "error" in l] or log.splitlines()[-1:]
            context.scene.residue.status = "failed: " + (lines[-1] if lines else "exit %d" % code)
            self.report({"ERROR"}, context.scene.residue.status)
            return False
        context.scene.residue.progress = 1.0
        return True

    def run_to_end(self, context):
        self.process.wait()
        return self.finish(context)

    def modal(self, context, event):
        if event.type == "ESC":
            self.process.send_signal(signal.SIGINT)  # residue-cli stops and writes nothing
            self.process.wait()
            self.process = None
            context.window_manager.event_timer_remove(self.timer)
            context.scene.residue.running = False
            context.scene.residue.status = "cancelled"
            self.report({"WARNING"}, "Residue: cancelled")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        self.poll_progress(context)
        for area in context.screen.areas if context.screen else []:
            area.tag_redraw()
        if self.process.poll() is None:
            return {"RUNNING_MODAL"}
        context.window_manager.event_timer_remove(self.timer)
        return {"FINISHED"} if self.finish(context) and self.done(context) else {"CANCELLED"}

    def invoke(self, context, event):
        if not self.begin(context):
            return {"CANCELLED"}
        self.timer = context.window_manager.event_timer_add(0.25, window=context.window)
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):  # scripts and blender -b: to the end, then return
        if not self.begin(context):
            return {"CANCELLED"}
        return {"FINISHED"} if self.run_to_end(context) and self.done(context) else {"CANCELLED"}


class RESIDUE_OT_enable_passes(bpy.types.Operator):
    """Enable the passes Residue reads: Denoising Data (and Vector, for temporal denoising)"""

    bl_idname = "residue.enable_passes"
    bl_label = "Enable Residue's Passes"
    bl_options = {"REGISTER", "UNDO"}
    vector: bpy.props.BoolProperty(name="Vector", default=False)

    def execute(self, context):
        enable_passes(context.view_layer, self.vector or context.scene.residue.temporal)
        context.scene.render.engine = "CYCLES"
        return {"FINISHED"}


class RESIDUE_OT_denoise(ResidueRun, bpy.types.Operator):
    """Denoise the render result (or the chosen multilayer EXR) with Residue and show it as an image"""

    bl_idname = "residue.denoise"
    bl_label = "Denoise with Residue"

    def begin(self, context):
        settings = context.scene.residue
        self.folder = tempfile.mkdtemp(prefix="residue-blender-")
        source = bpy.path.abspath(settings.input_file) if settings.input_file else ""
        if not source:
            source = os.path.join(self.folder, "render.exr")
            try:
                save_render_result(context.scene, source)
            except RuntimeError as e:
                self.report({"ERROR"}, str(e))
                return False
        self.output = os.path.join(self.folder, "denoised_%s.exr" % settings.model)
        return self.start(context, ["denoise", source, "-o", self.output, "--force"] + model_arguments(settings))

    def done(self, context):
        name = "Residue %s" % context.scene.residue.model
        old = bpy.data.images.get(name)
        if old is not None:
            bpy.data.images.remove(old)
        image = bpy.data.images.load(self.output, check_existing=False)
        image.name = name
        show_image(context, image)
        context.scene.residue.status = "denoised: " + name
        return True


class RESIDUE_OT_denoise_animation(ResidueRun, bpy.types.Operator):
    """Denoise the rendered frame range (multilayer EXRs at the output path) into a 'denoised' folder beside them"""

    bl_idname = "residue.denoise_animation"
    bl_label = "Denoise Animation"

    def begin(self, context):
        scene = context.scene
        first, second = (bpy.path.abspath(scene.render.frame_path(frame=f)) for f in (scene.frame_start, scene.frame_start + 1))
        # The frame number: the file name's last run of digits, which differs between two frames; made a #### pattern.
        folder, name = os.path.split(first)
        digits = list(re.finditer(r"\d+", name))
        if not digits or first == second:
            self.report({"ERROR"}, "the output path %s has no frame number" % first)
            return False
        start, end = digits[-1].span()
        pattern = os.path.join(folder, name[:start] + "#" * (end - start) + name[end:])
        self.frames = scene.frame_end - scene.frame_start + 1
        out_dir = os.path.join(os.path.dirname(pattern), "denoised")
        os.makedirs(out_dir, exist_ok=True)
        self.output = os.path.join(out_dir, os.path.basename(pattern))
        args = ["denoise", pattern, "--frames", "%d-%d" % (scene.frame_start, scene.frame_end), "-o", self.output,
                "--skip-existing"] + model_arguments(scene.residue)
        if scene.residue.temporal:
            args.append("--temporal")
        return self.start(context, args)

    def done(self, context):
        context.scene.residue.status = "denoised frames: " + self.output
        return True


class RESIDUE_OT_send_to_viewer(bpy.types.Operator):
    """Send the render result, with its passes, to a running Residue viewer (tev's protocol: it opens the file)"""

    bl_idname = "residue.send_to_viewer"
    bl_label = "Send to the Residue Viewer"

    def execute(self, context):
        settings = context.scene.residue
        path = os.path.join(tempfile.mkdtemp(prefix="residue-blender-"), "render.exr")
        try:
            save_render_result(context.scene, path)
            with socket.create_connection(("127.0.0.1", settings.viewer_port), timeout=2.0) as s:
                s.sendall(tev_open_packet(path))
        except (RuntimeError, OSError) as e:
            self.report({"ERROR"}, "Residue viewer: %s (is `residue` running, listening on port %d?)" %
                        (e, settings.viewer_port))
            return {"CANCELLED"}
        settings.status = "sent to the viewer: " + path
        return {"FINISHED"}


def draw_settings(layout, context):
    """One control a row, so that the sidebar's narrow width cuts no label."""
    settings = context.scene.residue
    col = layout.column()
    col.use_property_split = True
    col.use_property_decorate = False
    col.prop(settings, "model")
    col.prop(settings, "precision")
    col.prop(settings, "ensemble")
    col.prop(settings, "strength")
    col.prop(settings, "input_file")
    col = layout.column(align=True)
    col.operator(RESIDUE_OT_enable_passes.bl_idname, icon="RENDERLAYERS")
    col.operator(RESIDUE_OT_denoise.bl_idname, icon="SHADERFX")
    col.operator(RESIDUE_OT_denoise_animation.bl_idname, icon="RENDER_ANIMATION")
    col.prop(settings, "temporal")
    col = layout.column(align=True)
    col.operator(RESIDUE_OT_send_to_viewer.bl_idname, icon="IMAGE")
    col.prop(settings, "viewer_port")
    if settings.status:  # the whole text in the tooltip-less label may be cut: the operators report it too
        layout.label(text=settings.status + (" (%d %%, Esc stops)" % round(100 * settings.progress) if settings.running else ""),
                     icon="TIME" if settings.running else "INFO")


class ResiduePanel:
    """The one panel, shown in two places."""

    bl_label = "Residue"

    def draw(self, context):
        draw_settings(self.layout, context)


class RENDER_PT_residue(ResiduePanel, bpy.types.Panel):
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"


class IMAGE_PT_residue(ResiduePanel, bpy.types.Panel):
    bl_space_type = "IMAGE_EDITOR"
    bl_region_type = "UI"
    bl_category = "Residue"


CLASSES = (ResidueSettings, ResiduePreferences, RESIDUE_OT_enable_passes, RESIDUE_OT_denoise,
           RESIDUE_OT_denoise_animation, RESIDUE_OT_send_to_viewer, RENDER_PT_residue, IMAGE_PT_residue)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.residue = bpy.props.PointerProperty(type=ResidueSettings)


def unregister():
    del bpy.types.Scene.residue
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
