# The add-on's modal path, in a real Blender window (run by tools/blender/run_addon_test.sh under Xvfb, with
# --enable-event-simulate): "Denoise with Residue" invoked as a user invokes it runs modal and ends with the result
# loaded; a long run does not block Blender (this script's timer is called while it runs) and, stopped with Esc,
# ends cancelled with nothing loaded. Writes RESIDUE_TEST_DIR/MODAL_PASSED when every check holds.
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import test_scene  # noqa: E402

work = os.environ["RESIDUE_TEST_DIR"]
failures = []


def check(condition, what):
    print(("ok: " if condition else "FAILED: ") + what)
    if not condition:
        failures.append(what)


def finish():
    if not failures:
        open(os.path.join(work, "MODAL_PASSED"), "w").close()
    bpy.ops.wm.quit_blender()


def override():
    window = bpy.context.window_manager.windows[0]
    area = next(a for a in window.screen.areas if a.type == "VIEW_3D")
    return bpy.context.temp_override(window=window, area=area)


state = {"step": "start", "ticks": 0}


def tick():
    scene = bpy.context.scene
    settings = scene.residue
    state["ticks"] += 1
    if state["ticks"] > 2400:  # 8 minutes of ticks: something hangs
        check(False, "the modal runs end (stuck at step %s, status %s)" % (state["step"], settings.status))
        finish()
        return None
    if state["step"] == "start":
        with override():
            bpy.ops.object.select_all(action="SELECT")
            bpy.ops.object.delete()
        scene = test_scene.build()
        with override():
            bpy.ops.residue.enable_passes()
            bpy.ops.render.render()
            scene.residue.model = "tiny"
            check(bpy.ops.residue.denoise("INVOKE_DEFAULT") == {"RUNNING_MODAL"}, "denoise invoked runs modal")
        state["step"], state["ticks_at_start"] = "denoising", state["ticks"]
    elif state["step"] == "denoising":
        if settings.running:
            return 0.05
        check(settings.status.startswith("denoised"), "the run ends denoised: " + settings.status)
        check(bpy.data.images.get("Residue tiny") is not None, "the result is loaded")
        # A long run (paper with an 8-fold ensemble on a larger render), then Esc.
        scene.render.resolution_x, scene.render.resolution_y = 640, 426
        scene.cycles.samples = 2
        with override():
            bpy.ops.render.render()
            settings.model, settings.ensemble = "paper", "8"
            check(bpy.ops.residue.denoise("INVOKE_DEFAULT") == {"RUNNING_MODAL"}, "a long denoise invoked")
        state["step"] = "long"
    elif state["step"] == "long":
        if settings.running:  # this timer runs while residue-cli does: Blender is not blocked
            check(True, "Blender's timers run while residue-cli runs")
            window = bpy.context.window_manager.windows[0]
            window.event_simulate(type="ESC", value="PRESS")
            window.event_simulate(type="ESC", value="RELEASE")
            state["step"] = "escaped"
    elif state["step"] == "escaped":
        if settings.running:
            return 0.05
        check(settings.status == "cancelled", "Esc cancels: " + settings.status)
        check(bpy.data.images.get("Residue paper") is None, "nothing is loaded for the cancelled run")
        finish()
        return None
    return 0.05


def guarded_tick():
    try:
        return tick()
    except Exception as e:  # a timer that raises is dropped: end the test instead of waiting forever
        check(False, "no exception at step %s: %r" % (state["step"], e))
        finish()
        return None


bpy.ops.preferences.addon_install(filepath=os.environ["RESIDUE_ADDON_ZIP"], overwrite=True)
bpy.ops.preferences.addon_enable(module="residue_blender")
bpy.app.timers.register(guarded_tick, first_interval=1.0)
