#!/usr/bin/python3
"""A second, independent reference for every frame of a shot data set's validation shots (issue 51: the
references' own noise is a floor under every per-frame and temporal score; with a second reference it is measured,
relMSE(r_b, r) = 2 s2 and temporal(r_b, r) = 4 s2, and subtracted; tools/research/sequence_eval.py does).

  /usr/bin/python3 tools/datagen/second_references.py /work/datasets/residue-shots-v1 --threads 1

Each shot's frames are rendered again by make_scene.py as the shot's own reference is (the same scene, move and
exposure, read from its shot.json; the same spp), with sampling seed 30000 + frame, into OUT/.tmp-refb-s<seed>/,
then moved into the shot's folder as reference_b.####.exr, one file at a time (atomic renames). A rerun renders only
the frames still missing; the shot's shot.json gets "second_reference" once all are there. Exit 0 when every
validation shot has them.
"""
import argparse
import datetime
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import shots  # noqa: E402
from blender_process import run_logged  # noqa: E402

MAKE_SCENE = os.path.join(HERE, "make_scene.py")
SEED_BASE = 30000
NAME = "reference_b"


def read_json(path):
    with open(path) as f:
        return json.load(f)


def write_json(path, doc):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(doc, f, indent=1)
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shots", help="a shot data set (render_shots.py's OUT)")
    ap.add_argument("--split", default="validation", choices=("validation", "train"))
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--blender", default="/usr/bin/blender")
    ap.add_argument("--timeout", type=int, default=3600, help="seconds a frame may take")
    a = ap.parse_args()
    index = read_json(os.path.join(a.shots, "index.json"))
    os.makedirs(os.path.join(a.shots, "logs"), exist_ok=True)
    missing_any = False
    for entry in [s for s in index["shots"] if s["split"] == a.split]:
        folder = os.path.join(a.shots, entry["folder"])
        doc = read_json(os.path.join(folder, "shot.json"))
        frames = doc["frames"]
        todo = [f for f in range(1, frames + 1) if not os.path.isfile(os.path.join(folder, shots.frame_file(NAME, f)))]
        if todo:
            spp = doc["files"]["reference"]["spp"]
            tmp = os.path.join(a.shots, f".tmp-refb-{entry['folder']}")
            os.makedirs(tmp, exist_ok=True)
            cmd = [a.blender, "-b", "--factory-startup", "-noaudio", "-t", str(a.threads), "--python", MAKE_SCENE, "--",
                   "--scene-seed", str(doc["scene_seed"]), "--shot", doc["shot"]["requested"], "--frames", str(frames),
                   "--frame-renders", f"{spp}:{SEED_BASE}", "--names", NAME,
                   "--render-frames", ",".join(str(f) for f in todo), "--outdir", tmp,
                   "--res", str(doc["resolution"][0]), "--threads", str(a.threads),
                   "--light-scale-log2", str(doc["scene"]["exposure"]["light_scale_log2"])]
            started = datetime.datetime.now()
            rc = run_logged(cmd, os.path.join(a.shots, "logs", f"{entry['folder']}_refb.log"), a.timeout * len(todo) + 300,
                            f"\n== {started.isoformat(timespec='seconds')} " + " ".join(cmd) + "\n\n")
            for f in todo:
                src = os.path.join(tmp, shots.frame_file(NAME, f))
                if os.path.isfile(src):
                    os.replace(src, os.path.join(folder, shots.frame_file(NAME, f)))
            seconds = (datetime.datetime.now() - started).total_seconds()
            print(f"{entry['folder']}: frames {todo[0]}-{todo[-1]} at {spp} spp, blender exit {rc}, {seconds:.0f} s", flush=True)
        have = all(os.path.isfile(os.path.join(folder, shots.frame_file(NAME, f))) for f in range(1, frames + 1))
        if have and "second_reference" not in doc:
            doc["second_reference"] = {"pattern": f"{NAME}.####.exr", "spp": doc["files"]["reference"]["spp"],
                                       "sampling_seed": f"{SEED_BASE} + frame",
                                       "generator": "tools/datagen/second_references.py"}
            write_json(os.path.join(folder, "shot.json"), doc)
        missing_any = missing_any or not have
    sys.exit(1 if missing_any else 0)


if __name__ == "__main__":
    main()
