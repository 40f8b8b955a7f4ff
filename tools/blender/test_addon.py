# The Blender add-on, tested headless inside Blender (run by tools/blender/run_addon_test.sh, ctest blender_addon):
# installs and enables the zip, renders a tiny scene with the passes the add-on enables, and runs every operator:
# the denoised render is finite and closer than the noisy one to a 512-spp render of the same scene (scored by
# residue-cli eval), the animation's frames are denoised into 'denoised/', a render sent to the viewer arrives as
# tev's 'open image' packet naming an EXR with the passes, and a missing input fails naming it.
# Writes RESIDUE_TEST_DIR/PASSED when every check holds.
import json
import os
import socket
import struct
import subprocess
import sys
import threading

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import test_scene  # noqa: E402

work = os.environ["RESIDUE_TEST_DIR"]
cli = os.environ["RESIDUE_CLI"]


def check(condition, what):
    if not condition:
        print("FAILED: " + what)
        sys.exit(1)
    print("ok: " + what)


bpy.ops.wm.read_factory_settings(use_empty=True)  # first: it would disable the add-on again
bpy.ops.preferences.addon_install(filepath=os.environ["RESIDUE_ADDON_ZIP"], overwrite=True)
bpy.ops.preferences.addon_enable(module="residue_blender")
import residue_blender  # noqa: E402  (installed just above)

check(hasattr(bpy.types.Scene, "residue"), "the add-on registers its settings")

scene = test_scene.build()

check(bpy.ops.residue.enable_passes() == {"FINISHED"}, "enable_passes runs")
check(bpy.context.view_layer.cycles.denoising_store_passes, "Denoising Data is on")

bpy.ops.render.render()
noisy = os.path.join(work, "noisy.exr")
residue_blender.save_render_result(scene, noisy)
scene.residue.model = "tiny"
check(bpy.ops.residue.denoise() == {"FINISHED"}, "denoise runs")
image = bpy.data.images.get("Residue tiny")
check(image is not None and os.path.isfile(bpy.path.abspath(image.filepath)), "the result is loaded as an image")

scene.cycles.samples = 512
bpy.ops.render.render()
reference = os.path.join(work, "reference.exr")
residue_blender.save_render_result(scene, reference)
scene.cycles.samples = 8

report = json.loads(subprocess.run([cli, "eval", noisy, "-r", reference, "--denoised", bpy.path.abspath(image.filepath),
                                    "--json"], check=True, capture_output=True, text=True).stdout)
print(json.dumps(report)[:600])
rows = {r["name"]: r for r in report["rows"]}
check("noisy" in rows and "denoised" in rows, "residue-cli eval scores both")
check(rows["denoised"]["excluded_test"] == 0, "the denoised render is finite")
check(rows["denoised"]["relmse"] < rows["noisy"]["relmse"],
      "denoised relMSE %.4g < noisy %.4g" % (rows["denoised"]["relmse"], rows["noisy"]["relmse"]))

# Send to the viewer: a listener stands in for `residue` and reads the packet.
server = socket.socket()
server.bind(("127.0.0.1", 0))
server.listen(1)
received = []


def accept():
    connection, _ = server.accept()
    data = b""
    while True:
        chunk = connection.recv(65536)
        if not chunk:
            break
        data += chunk
    received.append(data)


listener = threading.Thread(target=accept)
listener.start()
scene.residue.viewer_port = server.getsockname()[1]
check(bpy.ops.residue.send_to_viewer() == {"FINISHED"}, "send_to_viewer runs")
listener.join(10)
packet = received[0] if received else b""
length, kind, grab = struct.unpack("<IBB", packet[:6]) if len(packet) >= 6 else (0, 0, 0)
path = packet[6:].split(b"\0")[0].decode() if packet else ""
check(length == len(packet) and kind == 7 and grab == 1, "tev's open image v2 packet (type 7, grab focus)")
info = subprocess.run([cli, "info", path], capture_output=True, text=True).stdout
check("Blender Cycles" in info and "Denoising Albedo" in info, "the file sent holds the render with its passes")

# The animation: two frames rendered as multilayer EXRs, then denoised beside them.
scene.frame_start, scene.frame_end = 1, 2
scene.render.filepath = os.path.join(work, "frames", "shot_")
scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
scene.render.image_settings.color_depth = "32"
bpy.ops.render.render(animation=True)
check(bpy.ops.residue.denoise_animation() == {"FINISHED"}, "denoise_animation runs")
for f in (1, 2):
    out = os.path.join(work, "frames", "denoised", "shot_%04d.exr" % f)
    check(os.path.isfile(out), "frame %d denoised: %s" % (f, out))

# A missing input fails, saying which file.
scene.residue.input_file = os.path.join(work, "missing.exr")
try:
    bpy.ops.residue.denoise()  # an operator's error report is an exception in a script
    refused = ""
except RuntimeError as e:
    refused = str(e)
check("missing.exr" in refused and "does not exist" in refused, "a missing input is refused, naming it: " + refused)
check("missing.exr" in scene.residue.status, "the panel's status says it too: " + scene.residue.status)

open(os.path.join(work, "PASSED"), "w").close()
print("PASSED")
