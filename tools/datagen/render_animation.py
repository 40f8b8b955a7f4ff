#!/usr/bin/env python3
"""Short animations for measuring flicker: one scene, N frames, a noisy render per frame with its own sampling
seed, and references.

  static  the camera stands still: only the sampling noise changes from frame to frame. One reference (rendered
          once at --ref-spp) serves every frame (hard links), so the reference sequence has no flicker at all.
  move    the camera trucks sideways by --move-m metres and turns by --yaw-deg degrees over the shot (linearly);
          every frame has its own reference.

Layout (a frame sequence, as `residue-cli denoise` and `eval` take it):
  OUT/noisy.####.exr       --spp spp, every AOV (as the data set's noisy_a.exr), seed 10000 + frame
  OUT/reference.####.exr   --ref-spp spp, colour only
  OUT/reference_b.####.exr with --second-reference: a second, independent reference per frame (seed
                           30000 + frame; static: one for every frame, as the first), so that the error the
                           references' own noise adds to a metric can be measured (tools/research/flicker_study.py
                           subtracts it)
  OUT/animation.json       the scene, frames, camera moves, settings and timings
Resumable: frames whose files exist are not rendered again.

    /usr/bin/python3 tools/datagen/render_animation.py --out /work/datasets/anim/static --mode static --scene-seed 1302
    /usr/bin/python3 tools/datagen/render_animation.py --out /work/datasets/anim/move --mode move --scene-seed 1302
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--mode", choices=["static", "move"], required=True)
    ap.add_argument("--scene-seed", type=int, default=1302)
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--res", type=int, default=256)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--ref-spp", type=int, default=256)
    ap.add_argument("--move-m", type=float, default=0.4)
    ap.add_argument("--yaw-deg", type=float, default=4.0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--second-reference", action="store_true")
    ap.add_argument("--blender", default="/usr/bin/blender")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    info = {"scene_seed": args.scene_seed, "mode": args.mode, "frames": args.frames, "res": args.res, "spp": args.spp,
            "ref_spp": args.ref_spp, "move_m": args.move_m if args.mode == "move" else 0.0,
            "yaw_deg": args.yaw_deg if args.mode == "move" else 0.0, "frame_seconds": {}}
    for f in range(1, args.frames + 1):
        noisy = os.path.join(args.out, f"noisy.{f:04d}.exr")
        ref = os.path.join(args.out, f"reference.{f:04d}.exr")
        if os.path.exists(noisy) and os.path.exists(ref):
            continue
        t = (f - 1) / max(1, args.frames - 1)
        move = f"{t * args.move_m if args.mode == 'move' else 0.0},0,0,{t * args.yaw_deg if args.mode == 'move' else 0.0}"
        # The static shot renders its reference once (frame 1); later frames render a 1-spp stand-in, dropped.
        ref_spp = args.ref_spp if args.mode == "move" or f == 1 else 1
        tmp = os.path.join(args.out, f".tmp-{f:04d}")
        shutil.rmtree(tmp, ignore_errors=True)
        cmd = [args.blender, "-b", "--factory-startup", "-noaudio", "-t", str(args.threads), "--python",
               os.path.join(HERE, "make_scene.py"), "--", "--scene-seed", str(args.scene_seed),
               "--renders", f"{args.spp}:{10000 + f},{ref_spp}:{20000 + f}", "--names", "noisy,reference",
               "--outdir", tmp, "--res", str(args.res), "--threads", str(args.threads), "--camera-move", move]
        start = time.time()
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"frame {f} failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
        os.replace(os.path.join(tmp, "noisy.exr"), noisy)
        if ref_spp == args.ref_spp:
            os.replace(os.path.join(tmp, "reference.exr"), ref)
        else:
            os.link(os.path.join(args.out, "reference.0001.exr"), ref)
        if f == 1:
            shutil.copy(os.path.join(tmp, "scene.json"), os.path.join(args.out, "scene_0001.json"))
        shutil.rmtree(tmp, ignore_errors=True)
        info["frame_seconds"][f] = round(time.time() - start, 1)
        print(f"frame {f}/{args.frames} ({args.mode}) in {time.time() - start:.1f} s", flush=True)
    for f in range(1, args.frames + 1) if args.second_reference else []:
        ref_b = os.path.join(args.out, f"reference_b.{f:04d}.exr")
        if os.path.exists(ref_b):
            continue
        if args.mode == "static" and f > 1:  # one second reference serves every frame, as the first does
            os.link(os.path.join(args.out, "reference_b.0001.exr"), ref_b)
            continue
        t = (f - 1) / max(1, args.frames - 1)
        tmp = os.path.join(args.out, f".tmp-b-{f:04d}")
        shutil.rmtree(tmp, ignore_errors=True)
        cmd = [args.blender, "-b", "--factory-startup", "-noaudio", "-t", str(args.threads), "--python",
               os.path.join(HERE, "make_scene.py"), "--", "--scene-seed", str(args.scene_seed),
               "--renders", f"{args.ref_spp}:{30000 + f}", "--names", "reference",
               "--outdir", tmp, "--res", str(args.res), "--threads", str(args.threads),
               "--camera-move", f"{t * args.move_m},0,0,{t * args.yaw_deg}" if args.mode == "move" else "0,0,0,0"]
        start = time.time()
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"second reference of frame {f} failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
        os.replace(os.path.join(tmp, "reference.exr"), ref_b)
        shutil.rmtree(tmp, ignore_errors=True)
        info["frame_seconds"][f"b{f}"] = round(time.time() - start, 1)
        print(f"second reference {f}/{args.frames} in {time.time() - start:.1f} s", flush=True)
    with open(os.path.join(args.out, "animation.json"), "w") as fh:
        json.dump(info, fh, indent=1)


if __name__ == "__main__":
    main()
