#!/usr/bin/python3
"""Renders shots for a temporal denoiser (issue 51, "Shots, not frames"): one Blender process per shot
(tools/datagen/make_scene.py --shot), resumable frame by frame.

  /usr/bin/python3 tools/datagen/render_shots.py --out /work/datasets/residue-shots-v1 --seeds 8000-8047 --threads 1
  /usr/bin/python3 tools/datagen/render_shots.py --out DIR --seeds 8004,8015 --frames 16 --res 256 \\
      --spp 4,8,16,32 --ref-spp 256 --val-ref-spp 512 --shot auto --threads 2

Each shot is the scene its seed builds (even seeds interiors, odd ones open-air, as make_scene.py does), animated
by a move drawn from the seed's shot stream (--shot auto; or one kind for all: dolly, pan, orbit, truck, objects,
light, mixed), and goes to OUT/s<seed>/:
  noisy.####.exr      frames 1..N, SPP spp, sampling seed 10000 + frame: every AOV of the data set's noisy_a.exr
                      plus ViewLayer.Vector.XYZW (motion to the previous and from the next frame, pixels; the
                      convention is in shot.json and tools/datagen/README.md)
  reference.####.exr  --ref-spp spp (training) or --val-ref-spp (validation), sampling seed 20000 + frame,
                      ViewLayer.Combined RGBA only
  shot.json           the scene (as scene.json's "scene"), the shot (kind, moves, profile, predicted motion),
                      settings, the camera of every frame, per-frame timings, rendered motion statistics and relMSE
The noisy spp cycles over --spp by seed pair (spp[(seed // 2) % len]: an interior and an open-air shot per level).
Split: seed % 11 == 10 is validation (never trained on), the rest training (as render_dataset.py); validation
shots are rendered first. A shot is rendered in OUT/.tmp-s<seed>/shot/ and renamed to OUT/s<seed> when its last
frame is done; inside, every frame is written to a temporary and renamed (the reference last), so a partial frame
never looks complete, and a rerun of the same command renders only the missing frames (with the exposure of the
shot's first run). OUT/index.json lists every complete shot, rewritten after each; one line per shot goes to
OUT/render_log.txt, Blender's output to OUT/logs/s<seed>.log.
One driver per OUT (OUT/.render_shots.lock): a second one exits with status 3, or with --wait waits and resumes.
Exit status: 0 when every requested shot is complete at the end, 1 otherwise.
"""
import argparse
import datetime
import fcntl
import json
import os
import shutil
import signal
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import shots  # noqa: E402
from blender_process import run_logged  # noqa: E402

MAKE_SCENE = os.path.join(HERE, "make_scene.py")
SEED_BASE = {"noisy": 10000, "reference": 20000}
NAMES = ["noisy", "reference"]


def split_of(seed):
    return "validation" if seed % 11 == 10 else "train"


def spp_of(args, seed):
    return args.spp_list[(seed // 2) % len(args.spp_list)]


def ref_spp_of(args, seed):
    return args.val_ref_spp if split_of(seed) == "validation" else args.ref_spp


def frame_renders(args, seed):
    return f"{spp_of(args, seed)}:{SEED_BASE['noisy']},{ref_spp_of(args, seed)}:{SEED_BASE['reference']}"


def ranges(frames):
    """[1, 2, 3, 7] -> "1-3,7"."""
    out, start, prev = [], None, None
    for f in sorted(frames):
        if start is None:
            start = prev = f
        elif f == prev + 1:
            prev = f
        else:
            out.append(f"{start}-{prev}" if prev > start else str(start))
            start = prev = f
    if start is not None:
        out.append(f"{start}-{prev}" if prev > start else str(start))
    return ",".join(out)


def write_json(path, doc):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(doc, f, indent=1)
    os.replace(tmp, path)


def read_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def log(out, line):
    text = f"{datetime.datetime.now().strftime('%Y-%m-%d %H:%M:%S')} {line}"
    print(text, flush=True)
    with open(os.path.join(out, "render_log.txt"), "a") as f:
        f.write(text + "\n")


def done_frames(folder, frames):
    """Frames whose files are all in FOLDER and recorded in its shot.json."""
    doc = read_json(os.path.join(folder, "shot.json")) or {}
    recs = doc.get("frame_records", {})
    return [f for f in range(1, frames + 1) if str(f) in recs and
            all(os.path.isfile(os.path.join(folder, shots.frame_file(n, f))) for n in NAMES)]


def complete(out, seed):
    doc = read_json(os.path.join(out, f"s{seed}", "shot.json"))
    return bool(doc and doc.get("complete"))


def summary(doc):
    recs = list(doc.get("frame_records", {}).values())

    def mean(vals):
        vals = [v for v in vals if v is not None]
        return round(sum(vals) / len(vals), 4) if vals else None
    return {
        "seconds_per_frame": mean([r.get("frame_wall_s") for r in recs]),
        "relmse_noisy_mean": mean([r.get("relmse", {}).get("noisy") for r in recs]),
        "motion_p90_px_mean": mean([r.get("motion", {}).get("to_previous", {}).get("p90") for r in recs]),
        "motion_max_px": max([r.get("motion", {}).get("to_previous", {}).get("max", 0.0) for r in recs] or [0.0]),
        "moving_share_mean": mean([r.get("motion", {}).get("to_previous", {}).get("moving_share") for r in recs]),
        "all_finite": all(r.get("all_finite", False) for r in recs),
    }


def write_index(out):
    entries = []
    for name in sorted(os.listdir(out)):
        if not (name.startswith("s") and name[1:].isdigit()):
            continue
        doc = read_json(os.path.join(out, name, "shot.json"))
        if not doc or not doc.get("complete"):
            continue
        seed = int(name[1:])
        entries.append(dict({
            "seed": seed, "folder": name, "split": split_of(seed), "kind": doc.get("kind"),
            "shot": doc.get("shot", {}).get("kind"), "frames": doc.get("frames"), "resolution": doc.get("resolution"),
            "spp": doc.get("files", {}).get("noisy", {}).get("spp"),
            "ref_spp": doc.get("files", {}).get("reference", {}).get("spp"),
            "movers": [m.get("what") for m in doc.get("shot", {}).get("movers", [])],
        }, **summary(doc)))
    entries.sort(key=lambda e: e["seed"])
    counts = {}
    for e in entries:
        counts[e["split"]] = counts.get(e["split"], 0) + 1
    write_json(os.path.join(out, "index.json"), {
        "generator": "tools/datagen/render_shots.py + make_scene.py --shot",
        "updated": datetime.datetime.now().isoformat(timespec="seconds"),
        "split_rule": "seed % 11 == 10 -> validation, else train",
        "files": ["noisy.####.exr", "reference.####.exr", "shot.json"],
        "vector_convention": shots.VECTOR_CONVENTION,
        "counts": counts,
        "shots": entries,
    })


def run_blender(args, seed, todo, outdir):
    """make_scene.py --shot for frames TODO of shot SEED into OUTDIR; Blender's exit status (None: timed out)."""
    cmd = [args.blender, "-b", "--factory-startup", "-noaudio", "-t", str(args.threads), "--python", MAKE_SCENE, "--",
           "--scene-seed", str(seed), "--shot", args.shot, "--frames", str(args.frames),
           "--frame-renders", frame_renders(args, seed), "--names", ",".join(NAMES), "--render-frames", ranges(todo),
           "--outdir", outdir, "--res", str(args.res), "--threads", str(args.threads)]
    header = f"\n== {datetime.datetime.now().isoformat(timespec='seconds')} " + " ".join(cmd) + "\n\n"
    return run_logged(cmd, os.path.join(args.out, "logs", f"s{seed}.log"), args.timeout * len(todo) + 300, header)


def render_shot(args, seed):
    """Renders the missing frames of shot SEED and moves it to OUT/s<seed> when complete: (ok, message)."""
    tmp_root = os.path.join(args.out, f".tmp-s{seed}")
    tmp = os.path.join(tmp_root, "shot")
    os.makedirs(tmp, exist_ok=True)
    have = done_frames(tmp, args.frames)
    todo = [f for f in range(1, args.frames + 1) if f not in have]
    if todo:
        rc = run_blender(args, seed, todo, tmp)
        if rc is None:
            return False, f"timed out (frames {ranges(todo)}; the finished ones are kept in {tmp})"
        if rc != 0:
            return False, f"blender exit {rc} (see logs/s{seed}.log; the finished frames are kept)"
    have = done_frames(tmp, args.frames)
    doc = read_json(os.path.join(tmp, "shot.json"))
    if len(have) != args.frames or not doc or not doc.get("complete"):
        return False, f"frames {ranges([f for f in range(1, args.frames + 1) if f not in have])} missing"
    doc["split"] = split_of(seed)
    doc["driver"] = {"generator": "tools/datagen/render_shots.py",
                     "command": " ".join([os.path.relpath(sys.argv[0], os.path.dirname(os.path.dirname(HERE)))]
                                         + sys.argv[1:]),
                     "seed_bases": SEED_BASE, "finished": datetime.datetime.now().isoformat(timespec="seconds")}
    doc["summary"] = summary(doc)
    write_json(os.path.join(tmp, "shot.json"), doc)
    for f in os.listdir(tmp):  # nothing but the frames and shot.json in a shot folder
        if not (f == "shot.json" or any(f.startswith(n + ".") and f.endswith(".exr") for n in NAMES)):
            p = os.path.join(tmp, f)
            shutil.rmtree(p) if os.path.isdir(p) else os.remove(p)
    final = os.path.join(args.out, f"s{seed}")
    shutil.rmtree(final, ignore_errors=True)
    os.replace(tmp, final)
    shutil.rmtree(tmp_root, ignore_errors=True)
    return True, ""


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True)
    p.add_argument("--seeds", required=True, help="A-B and/or comma-separated scene seeds, e.g. 8000-8047")
    p.add_argument("--frames", type=int, default=16)
    p.add_argument("--res", type=int, default=256)
    p.add_argument("--spp", default="4,8,16,32", help="noisy spp, cycled by seed pair (spp[(seed // 2) %% len])")
    p.add_argument("--ref-spp", type=int, default=256, help="reference spp of training shots")
    p.add_argument("--val-ref-spp", type=int, default=512, help="reference spp of validation shots")
    p.add_argument("--shot", default="auto", choices=["auto"] + shots.KINDS,
                   help="the move (auto: drawn per seed from its shot stream)")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--timeout", type=float, default=1800.0, help="seconds per frame before giving up on a shot")
    p.add_argument("--blender", default="/usr/bin/blender")
    p.add_argument("--no-validation-first", action="store_true",
                   help="render in the order given (default: validation shots first)")
    p.add_argument("--wait", action="store_true",
                   help="when another render_shots.py renders into OUT, wait for it to end and then resume "
                        "(default: exit with status 3)")
    args = p.parse_args()
    args.out = os.path.abspath(args.out)
    args.spp_list = [int(s) for s in args.spp.split(",")]
    seeds = shots.parse_int_list(args.seeds)
    if not args.no_validation_first:
        seeds = [s for s in seeds if split_of(s) == "validation"] + [s for s in seeds if split_of(s) != "validation"]
    if not os.path.isfile(args.blender):
        sys.exit(f"render_shots: no Blender at {args.blender} (apt-get install blender)")
    os.makedirs(args.out, exist_ok=True)
    lock = open(os.path.join(args.out, ".render_shots.lock"), "a+")  # one driver per OUT (held until exit)
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.seek(0)
        holder = lock.read().strip() or "?"
        if not args.wait:
            print(f"render_shots: another render_shots.py (pid {holder}) renders into {args.out}; --wait to wait "
                  "for it", file=sys.stderr)
            return 3
        print(f"render_shots: waiting for render_shots.py pid {holder} to finish with {args.out}", flush=True)
        fcntl.flock(lock, fcntl.LOCK_EX)
    lock.seek(0)
    lock.truncate()
    lock.write(f"{os.getpid()}\n")
    lock.flush()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # the running Blender is killed on the way out

    todo = [s for s in seeds if not complete(args.out, s)]
    log(args.out, f"render_shots: {len(seeds)} shots requested, {len(seeds) - len(todo)} already complete, "
                  f"{len(todo)} to render ({args.frames} frames at {args.res}x{args.res}, noisy spp {args.spp_list}, "
                  f"reference {args.ref_spp} spp (validation {args.val_ref_spp}), shot {args.shot}, "
                  f"{args.threads} threads) -> {args.out}")
    failed, times = [], []
    t_all = time.time()
    for i, seed in enumerate(todo):
        t = time.time()
        ok, msg = render_shot(args, seed)
        dt = time.time() - t
        kind = "interior" if seed % 2 == 0 else "exterior"
        if ok:
            times.append(dt)
            doc = read_json(os.path.join(args.out, f"s{seed}", "shot.json"))
            sm = doc["summary"]
            left = (len(todo) - i - 1) * sum(times) / len(times)
            log(args.out, f"[{i + 1}/{len(todo)}] s{seed} {kind:8s} {split_of(seed):10s} {doc['shot']['kind']:7s} "
                          f"{spp_of(args, seed):3d}/{ref_spp_of(args, seed)} spp  {dt:7.1f} s "
                          f"({sm['seconds_per_frame']} s a frame)  motion p90 {sm['motion_p90_px_mean']} px "
                          f"max {sm['motion_max_px']}  relMSE {sm['relmse_noisy_mean']}  finite {sm['all_finite']}"
                          f"  ~{left / 3600:.1f} h left")
            write_index(args.out)
        else:
            failed.append(seed)
            log(args.out, f"[{i + 1}/{len(todo)}] s{seed} {kind:8s} FAILED after {dt:.1f} s: {msg}")
    write_index(args.out)
    done = [s for s in seeds if complete(args.out, s)]
    log(args.out, f"render_shots: {len(done)}/{len(seeds)} requested shots complete, {len(failed)} failed this run"
                  f"{' ' + str(failed) if failed else ''}, {time.time() - t_all:.0f} s")
    return 0 if len(done) == len(seeds) else 1


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        sys.exit(130)
