#!/usr/bin/python3
"""Renders a Residue training data set: one Blender process per scene (tools/datagen/make_scene.py), resumable.

  /usr/bin/python3 tools/datagen/render_dataset.py --out /work/datasets/residue-v1 --seeds 1000-1329
  /usr/bin/python3 tools/datagen/render_dataset.py --out DIR --seeds 1000-1005,1010 --res 256 \
      --spp 4,8,16,32 --ref-spp 512 --val-ref-spp 1024 --threads 2

Each scene goes to OUT/s<seed>/ (noisy_a.exr, noisy_b.exr, reference.exr, scene.json; the layout of
/work/shared/datasets/cycles-starter). It is rendered into OUT/.tmp-s<seed>/scene/ and renamed when complete, so an
interrupted run leaves no half scene behind; scenes whose scene.json exists are skipped, so re-running the same
command resumes. The noisy spp cycles over --spp by seed pairs (spp[(seed // 2) % len]: an interior and an
open-air scene per level, as even seeds are interiors and odd ones open-air); sampling seeds are 1001 and 1002
for the two noisy renders and 1007 for the reference. Training scenes get --ref-spp references (a noisy target
only adds zero-mean noise to the loss), validation scenes --val-ref-spp (the reference's own error is a floor
under every relMSE we report, so it is kept lower where we measure). With --pseudo-ref MODEL, training
scenes (interiors, by default) get a pseudo-reference instead: a --pseudo-ref-spp render (sampling seed 1009,
full AOVs) denoised by MODEL as a self-ensemble, its --pseudo-ref-low-band box means taken from the render
itself, recorded in scene.json's "reference"; an interior then costs a
third of what a 512-spp reference does, and tools/datagen/pseudo_reference_check.py measures how far such
references are from the truth. One line per scene is printed and appended to
OUT/render_log.txt; Blender's own output goes to OUT/logs/s<seed>.log. OUT/index.json lists every complete
scene of OUT with its split (seed % 11 == 10: validation, else train), rewritten after each scene.
Exit status: 0 when every requested scene exists at the end, 1 otherwise.
"""
import argparse
import datetime
import hashlib
import json
import os
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
MAKE_SCENE = os.path.join(HERE, "make_scene.py")
sys.path.insert(0, HERE)
from blender_process import run_logged  # noqa: E402
SEEDS = {"noisy_a": 1001, "noisy_b": 1002, "reference": 1007, "pseudo": 1009}
REPO = os.path.dirname(os.path.dirname(HERE))
DEFAULT_CLI = os.path.join(REPO, "build", "release", "app", "residue-cli", "residue-cli")
CLAMP_INDIRECT = 10.0  # make_scene.py's default (Blender's): left out of its command line


def parse_seeds(text):
    seeds = []
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        lo, sep, hi = part.partition("-")
        seeds.extend(range(int(lo), int(hi) + 1) if sep else [int(lo)])
    return list(dict.fromkeys(seeds))


def split_of(seed):
    return "validation" if seed % 11 == 10 else "train"


def write_json(path, doc):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(doc, f, indent=1)
    os.replace(tmp, path)


def write_index(out, args):
    scenes = []
    for name in sorted(os.listdir(out)):
        if not (name.startswith("s") and name[1:].isdigit()):
            continue
        path = os.path.join(out, name, "scene.json")
        if not os.path.isfile(path):
            continue
        try:
            with open(path) as f:
                doc = json.load(f)
        except (OSError, ValueError):
            continue
        seed = int(name[1:])
        m = doc.get("metrics", {})
        scenes.append({
            "seed": seed,
            "folder": name,
            "split": split_of(seed),
            "kind": doc.get("kind"),
            "spp": doc.get("spp", {}).get("noisy_a"),
            "ref_spp": doc.get("spp", {}).get("reference"),
            "ref_kind": doc.get("reference", {}).get("kind", "render"),
            "resolution": doc.get("resolution"),
            "relmse_noisy_a": m.get("relmse_noisy_a"),
            "all_finite": m.get("all_finite"),
            "process_wall_s": doc.get("timing", {}).get("process_wall_s"),
        })
    scenes.sort(key=lambda s: s["seed"])
    counts = {}
    for s in scenes:
        counts[s["split"]] = counts.get(s["split"], 0) + 1
    write_json(os.path.join(out, "index.json"), {
        "generator": "tools/datagen/render_dataset.py + make_scene.py",
        "updated": datetime.datetime.now().isoformat(timespec="seconds"),
        "split_rule": "seed % 11 == 10 -> validation, else train",
        "files": ["noisy_a.exr", "noisy_b.exr", "reference.exr", "scene.json"],
        "counts": counts,
        "scenes": scenes,
    })


def log(out, line):
    stamp = datetime.datetime.now().strftime("%Y-%m-%d %H:%M:%S")
    text = f"{stamp} {line}"
    print(text, flush=True)
    with open(os.path.join(out, "render_log.txt"), "a") as f:
        f.write(text + "\n")


def ref_spp_of(args, seed):
    return args.val_ref_spp if split_of(seed) == "validation" else args.ref_spp


def pseudo_of(args, seed):
    """Whether this scene's reference is a denoised moderate-spp render (training scenes under --pseudo-ref,
    interiors only unless --pseudo-ref-for all)."""
    interior = seed % 2 == 0  # the generator's rule
    return bool(args.pseudo_ref) and split_of(seed) == "train" and (args.pseudo_ref_for == "all" or interior)


def restore_low_band(pseudo, raw, width, eps=None):
    """The pseudo-reference with its W x W box-mean band taken from the raw render it was denoised from.

    The denoiser's output is far closer to the truth than its input in fine detail but carries its own blotches
    at 16-48 px, which a network trained on it learns (docs/research/models/GOAL_JOURNAL.md, 2026-11-27); the raw render's box
    means there are nearly noise-free (128 spp over a 16 x 16 box is about 32000 spp) and unbiased. The
    difference is taken relative to the pseudo-reference, (raw - pseudo) / sqrt(pseudo^2 + eps), before the box
    mean, so a bright light's noise does not spill into dark neighbours; a constant relative offset comes back
    exactly, zero-mean noise finer than the box not at all."""
    if eps is None:
        from exr_metrics import EPS as eps  # noqa: N811 - the metric's eps
    from exr_metrics import box_mean
    import numpy as np
    scale = np.sqrt(pseudo * pseudo + eps)
    return pseudo + box_mean((raw - pseudo) / scale, width) * scale


def make_pseudo_reference(args, tmp, logpath):
    """Denoises DIR/pseudo_input.exr with --pseudo-ref (a self-ensemble) into DIR/reference.exr (the data set's
    layout: ViewLayer.Combined RGBA, half) and rewrites scene.json's metrics and reference record against it."""
    sys.path.insert(0, HERE)
    import exr_metrics  # noqa: E402 - OpenImageIO and numpy, needed only here
    import numpy as np
    import OpenImageIO as oiio
    denoised = os.path.join(tmp, "pseudo_denoised.exr")
    cmd = [args.cli, "denoise", os.path.join(tmp, "pseudo_input.exr"), "-m", args.pseudo_ref, "--ensemble",
           str(args.pseudo_ref_ensemble), "--float", "--force",
           "--threads", str(args.threads), "-o", denoised]
    with open(logpath, "a") as logf:
        logf.write("\n" + " ".join(cmd) + "\n")
        logf.flush()
        rc = subprocess.call(cmd, stdout=logf, stderr=subprocess.STDOUT)
    if rc != 0 or not os.path.isfile(denoised):
        return False, f"the pseudo-reference denoise failed (exit {rc}; see {logpath})"
    color = exr_metrics.layer_rgb(exr_metrics.read_exr(denoised), None)
    if args.pseudo_ref_low_band > 0:
        raw = exr_metrics.layer_rgb(exr_metrics.read_exr(os.path.join(tmp, "pseudo_input.exr")))
        color = restore_low_band(color, raw, args.pseudo_ref_low_band)
    pixels = np.ascontiguousarray(np.concatenate(
        [color.astype(np.float32), np.ones(color.shape[:2] + (1,), np.float32)], axis=2))
    if not np.isfinite(pixels).all():
        return False, "the pseudo-reference is not finite"
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], 4, "half")
    spec.channelnames = tuple(f"{exr_metrics.COMBINED}.{c}" for c in "RGBA")
    spec.attribute("compression", "zip")
    written = os.path.join(tmp, "pseudo_reference.exr")  # renamed over the placeholder once complete
    out = oiio.ImageOutput.create(written)
    if not out or not out.open(written, spec) or not out.write_image(pixels):
        return False, f"cannot write the pseudo-reference: {out.geterror() if out else oiio.geterror()}"
    out.close()
    os.replace(written, os.path.join(tmp, "reference.exr"))
    path = os.path.join(tmp, "scene.json")
    with open(path) as f:
        doc = json.load(f)
    images = {n: exr_metrics.read_exr(os.path.join(tmp, n + ".exr")) for n in ("noisy_a", "noisy_b", "reference")}
    doc["metrics"] = exr_metrics.scene_metrics(images["noisy_a"], images["noisy_b"], images["reference"])
    doc["metrics"]["relmse_pseudo_input"] = exr_metrics.relmse(
        exr_metrics.layer_rgb(exr_metrics.read_exr(os.path.join(tmp, "pseudo_input.exr"))),
        exr_metrics.layer_rgb(images["reference"]))
    doc.setdefault("spp", {})["reference"] = args.pseudo_ref_spp
    doc["reference"] = {
        "kind": "pseudo",
        "what": f"a {args.pseudo_ref_spp}-spp render (sampling seed {SEEDS['pseudo']}, full AOVs) denoised by "
                f"{args.pseudo_ref} as a self-ensemble x{args.pseudo_ref_ensemble}"
                + (f", its {args.pseudo_ref_low_band}-px box-mean band taken from the render itself"
                   if args.pseudo_ref_low_band > 0 else "") + ", written as half RGBA",
        "low_band_from_raw_px": args.pseudo_ref_low_band,
        "model": args.pseudo_ref,
        "model_sha256": sha256_of(model_path(args.pseudo_ref)),
        "command": " ".join(os.path.relpath(c, REPO) if c.startswith(REPO) else c.replace(tmp, "<scene>")
                            for c in cmd),
    }
    write_json(path, doc)
    os.remove(denoised)
    os.remove(os.path.join(tmp, "pseudo_input.exr"))
    return True, ""


def model_path(name):
    """A model name of resources/models or a file path (for the record in scene.json)."""
    return name if os.path.isfile(name) else os.path.join(REPO, "resources", "models", name + ".safetensors")


def sha256_of(path):
    if not os.path.isfile(path):
        return None
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def make_scene_command(blender, threads, seed, renders, outdir, res, extra=()):
    """The Blender command line that renders one scene with make_scene.py (renders: "SPP:SEED,...")."""
    return [blender, "-b", "--factory-startup", "-noaudio", "-t", str(threads), "--python", MAKE_SCENE, "--",
            "--scene-seed", str(seed), "--renders", renders, "--outdir", outdir, "--res", str(res),
            "--threads", str(threads)] + list(extra)


def scene_flags(doc):
    """make_scene.py's --photos/--photo-share/--hdris/--clamp-indirect/--caustics flags, as the scene was rendered
    (from its scene.json)."""
    cmd = doc["render_settings"]["command"].split()
    flags = []
    for name in ("--photos", "--photo-share", "--hdris", "--clamp-indirect"):
        if name in cmd:
            flags += [name, cmd[cmd.index(name) + 1]]
    return flags + (["--caustics"] if "--caustics" in cmd else [])


def render_flags(args):
    """make_scene.py's flags for a new scene, from this command's options."""
    flags = ["--photos", args.photos, "--photo-share", str(args.photo_share)] if args.photos else []
    flags += ["--hdris", args.hdris] if args.hdris else []
    flags += ["--clamp-indirect", f"{args.clamp_indirect:g}"] if args.clamp_indirect != CLAMP_INDIRECT else []
    return flags + (["--caustics"] if args.caustics else [])


def run_blender(args, seed, renders, outdir, names, log_mode="w", scene=None):
    """Renders scene SEED with make_scene.py into OUTDIR, logging to OUT/logs/s<seed>.log; Blender's exit status,
    or None when it ran past --timeout (killed). The resolution and make_scene.py's flags are this command's
    (--res, --photos, --hdris, --clamp-indirect, --caustics), or those recorded in SCENE (a scene.json) for a scene
    that exists."""
    if scene is None:
        res, flags = args.res, render_flags(args)
    else:
        res, flags = scene["resolution"][0], scene_flags(scene)
    cmd = make_scene_command(args.blender, args.threads, seed, renders, outdir, res, names + flags)
    return run_logged(cmd, os.path.join(args.out, "logs", f"s{seed}.log"), args.timeout, " ".join(cmd) + "\n\n", log_mode)


def restore_scene_low_band(args, seed):
    """--restore-low-band: gives OUT/s<seed>'s pseudo-reference, made before --pseudo-ref-low-band, its low band
    from its raw render. That render was not kept, so it is rendered again (the same scene, sampling seed 1009,
    full AOVs) and denoised again as before; the old reference.exr is kept as
    OUT/pseudo-references-without-low-band/s<seed>.exr. Returns (ok, message); ok is None when there is nothing
    to do (not a pseudo-reference, or one that has its low band)."""
    final = os.path.join(args.out, f"s{seed}")
    with open(os.path.join(final, "scene.json")) as f:
        doc = json.load(f)
    record = doc.get("reference", {})
    if record.get("kind") != "pseudo" or record.get("low_band_from_raw_px", 0) > 0:
        return None, "nothing to do"
    if record.get("model_sha256") != sha256_of(model_path(args.pseudo_ref)):
        return False, f"its pseudo-reference came from another model than {args.pseudo_ref} (sha256 differs)"
    if doc.get("spp", {}).get("pseudo_input") != args.pseudo_ref_spp:
        return False, (f"its pseudo-reference input had {doc.get('spp', {}).get('pseudo_input')} spp, not "
                       f"--pseudo-ref-spp {args.pseudo_ref_spp}")
    tmp_root = os.path.join(args.out, f".tmp-s{seed}")
    tmp, raw_dir = os.path.join(tmp_root, "scene"), os.path.join(tmp_root, "raw")
    shutil.rmtree(tmp_root, ignore_errors=True)
    os.makedirs(tmp)
    for name in ("noisy_a.exr", "noisy_b.exr", "scene.json"):
        shutil.copy2(os.path.join(final, name), tmp)
    # make_scene's last render is the reference (Combined only): a 1-spp placeholder, unused.
    rc = run_blender(args, seed, f"{args.pseudo_ref_spp}:{SEEDS['pseudo']},1:{SEEDS['reference']}", raw_dir,
                     ["--names", "pseudo_input,placeholder"], log_mode="a", scene=doc)
    if rc != 0 or not os.path.isfile(os.path.join(raw_dir, "pseudo_input.exr")):
        return False, f"blender exit {rc} (see logs/s{seed}.log)"
    os.replace(os.path.join(raw_dir, "pseudo_input.exr"), os.path.join(tmp, "pseudo_input.exr"))
    ok, msg = make_pseudo_reference(args, tmp, os.path.join(args.out, "logs", f"s{seed}.log"))
    if not ok:
        return False, msg
    keep = os.path.join(args.out, "pseudo-references-without-low-band")
    os.makedirs(keep, exist_ok=True)
    if not os.path.isfile(os.path.join(keep, f"s{seed}.exr")):  # the first one, should a rerun redo the scene
        shutil.copy2(os.path.join(final, "reference.exr"), os.path.join(keep, f"s{seed}.exr"))
    os.replace(os.path.join(tmp, "reference.exr"), os.path.join(final, "reference.exr"))
    os.replace(os.path.join(tmp, "scene.json"), os.path.join(final, "scene.json"))  # last: marks it done
    shutil.rmtree(tmp_root, ignore_errors=True)
    return True, ""


def render_scene(args, seed, spp):
    """Renders one scene into OUT/.tmp-s<seed> and renames it; returns (ok, message)."""
    final = os.path.join(args.out, f"s{seed}")
    # The files go one level down, OUT/.tmp-s<seed>/scene/: a data set scanner that takes any folder of OUT
    # holding noisy_a.exr and reference.exr (core's list_dataset_scenes) never sees a scene being written.
    tmp_root = os.path.join(args.out, f".tmp-s{seed}")
    tmp = os.path.join(tmp_root, "scene")
    shutil.rmtree(tmp_root, ignore_errors=True)
    os.makedirs(tmp)
    halves = f"{spp}:{SEEDS['noisy_a']},{spp}:{SEEDS['noisy_b']}"
    if pseudo_of(args, seed):
        # make_scene's last render is the reference (Combined only): a 1-spp placeholder that the denoised
        # pseudo-reference input (full AOVs, its own sampling seed) replaces below.
        renders = f"{halves},{args.pseudo_ref_spp}:{SEEDS['pseudo']},1:{SEEDS['reference']}"
        names = ["--names", "noisy_a,noisy_b,pseudo_input,reference"]
    else:
        renders = f"{halves},{ref_spp_of(args, seed)}:{SEEDS['reference']}"
        names = []
    rc = run_blender(args, seed, renders, tmp, names)
    if rc is None:
        return False, f"timed out after {args.timeout} s"
    expected = ["noisy_a.exr", "noisy_b.exr", "reference.exr", "scene.json"]
    missing = [f for f in expected + (["pseudo_input.exr"] if pseudo_of(args, seed) else [])
               if not os.path.isfile(os.path.join(tmp, f))]
    if rc != 0 or missing:
        return False, f"blender exit {rc}, missing {missing} (see logs/s{seed}.log)"
    if pseudo_of(args, seed):
        ok, msg = make_pseudo_reference(args, tmp, os.path.join(args.out, "logs", f"s{seed}.log"))
        if not ok:
            return False, msg
    for f in os.listdir(tmp):  # nothing but the four files in a scene folder
        if f not in expected:
            os.remove(os.path.join(tmp, f))
    shutil.rmtree(final, ignore_errors=True)
    os.replace(tmp, final)
    shutil.rmtree(tmp_root, ignore_errors=True)
    return True, ""


def restore_low_bands(args, seeds):
    """--restore-low-band over the --seeds scenes present in OUT; 0 when none failed."""
    present = [s for s in seeds if os.path.isfile(os.path.join(args.out, f"s{s}", "scene.json"))]
    log(args.out, f"render_dataset: restoring the low band of the pseudo-references among {len(present)} scenes "
                  f"({args.pseudo_ref_spp}-spp raw renders, {args.pseudo_ref_low_band}-px box) -> {args.out}")
    failed = []
    for i, seed in enumerate(present):
        t = time.time()
        ok, msg = restore_scene_low_band(args, seed)
        if ok is None:
            continue
        if not ok:
            failed.append(seed)
        log(args.out, f"[{i + 1}/{len(present)}] s{seed} " + (f"low band restored in {time.time() - t:.1f} s"
                                                             if ok else f"FAILED: {msg}"))
    write_index(args.out, args)
    return 1 if failed else 0


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True)
    p.add_argument("--seeds", required=True, help="A-B and/or comma-separated seeds, e.g. 1000-1329")
    p.add_argument("--res", type=int, default=256)
    p.add_argument("--spp", default="4,8,16,32", help="noisy spp, cycled by seed pair (spp[(seed // 2) %% len])")
    p.add_argument("--ref-spp", type=int, default=512, help="reference spp of training scenes")
    p.add_argument("--val-ref-spp", type=int, default=1024, help="reference spp of validation scenes")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--blender", default="/usr/bin/blender")
    p.add_argument("--timeout", type=float, default=3600.0, help="seconds per scene before giving up on it")
    p.add_argument("--photos", default=None, help="photographs for the surfaces (make_scene.py --photos), e.g. "
                   "/usr/share/wallpapers (Debian's plasma-workspace-wallpapers)")
    p.add_argument("--photo-share", type=float, default=0.5)
    p.add_argument("--hdris", default=None, help="environment maps for the world (make_scene.py --hdris), e.g. "
                   "/usr/share/blender/datafiles/studiolights/world (Blender's CC0 HDRIs)")
    p.add_argument("--clamp-indirect", type=float, default=CLAMP_INDIRECT,
                   help="Cycles' indirect clamp (make_scene.py --clamp-indirect; 0: none)")
    p.add_argument("--caustics", action="store_true",
                   help="keep caustics and sharp glossy reflections (make_scene.py --caustics): fireflies as an "
                        "unclamped path tracer leaves them, with --clamp-indirect 0")
    p.add_argument("--pseudo-ref", default=None, metavar="MODEL",
                   help="training scenes get a pseudo-reference: a --pseudo-ref-spp render denoised by MODEL (a "
                        "residue-cli model name or file) as a self-ensemble, instead of a --ref-spp render "
                        "(validation scenes keep true references)")
    p.add_argument("--pseudo-ref-spp", type=int, default=128)
    p.add_argument("--pseudo-ref-for", choices=["interiors", "all"], default="interiors",
                   help="which training scenes get one: measured (pseudo_reference_check.py, docs/research/models/"
                        "pseudo_reference_check_*.md), a 128-spp pseudo-reference is 1.2-6.5x closer to the truth "
                        "than a 512-spp render in all 6 interiors, farther in 5 of 6 open-air scenes (where a "
                        "512-spp render is also cheaper)")
    p.add_argument("--pseudo-ref-ensemble", type=int, default=8, choices=[1, 2, 4, 8])
    p.add_argument("--pseudo-ref-low-band", type=int, default=16, metavar="PX",
                   help="the pseudo-reference's PX x PX box-mean band comes from the raw render instead (0: off); "
                        "measured closer to the truth in total and 2-5x in the 48-px band (docs/research/MODELS_HISTORY.md, lever 5)")
    p.add_argument("--restore-low-band", action="store_true",
                   help="render nothing new: give the --seeds scenes' pseudo-references made without "
                        "--pseudo-ref-low-band their low band (each one's raw input rendered again)")
    p.add_argument("--cli", default=DEFAULT_CLI,
                   help="residue-cli, for --pseudo-ref")
    args = p.parse_args()
    if args.restore_low_band and (not args.pseudo_ref or args.pseudo_ref_low_band <= 0):
        sys.exit("render_dataset: --restore-low-band needs --pseudo-ref MODEL (the one that made them) and "
                 "--pseudo-ref-low-band > 0")
    if args.pseudo_ref and not os.path.isfile(args.cli):
        sys.exit(f"render_dataset: --pseudo-ref needs residue-cli, not found at {args.cli} (build it, or --cli)")
    args.out = os.path.abspath(args.out)
    spp_list = [int(s) for s in args.spp.split(",")]
    seeds = parse_seeds(args.seeds)
    if not os.path.isfile(args.blender):
        sys.exit(f"render_dataset: no Blender at {args.blender} (apt-get install blender)")
    os.makedirs(args.out, exist_ok=True)
    if args.restore_low_band:
        return restore_low_bands(args, seeds)

    todo = [s for s in seeds if not os.path.isfile(os.path.join(args.out, f"s{s}", "scene.json"))]
    log(args.out, f"render_dataset: {len(seeds)} scenes requested, {len(seeds) - len(todo)} already done, "
                  f"{len(todo)} to render at {args.res}x{args.res}, spp {spp_list}, reference {args.ref_spp} spp "
                  f"(validation {args.val_ref_spp}), "
                  + (f"training {args.pseudo_ref_for}' references pseudo ({args.pseudo_ref_spp} spp denoised by "
                     f"{args.pseudo_ref} x{args.pseudo_ref_ensemble}), " if args.pseudo_ref else "")
                  + (f"indirect clamp {args.clamp_indirect:g}, " if args.clamp_indirect != CLAMP_INDIRECT else "")
                  + ("caustics and sharp glossy kept, " if args.caustics else "") +
                  f"{args.threads} threads -> {args.out}")
    failed, times = [], []
    t_all = time.time()
    for i, seed in enumerate(todo):
        spp = spp_list[(seed // 2) % len(spp_list)]
        t = time.time()
        ok, msg = render_scene(args, seed, spp)
        dt = time.time() - t
        kind = "interior" if seed % 2 == 0 else "exterior"
        if ok:
            times.append(dt)
            with open(os.path.join(args.out, f"s{seed}", "scene.json")) as f:
                doc = json.load(f)
            m = doc["metrics"]
            rt = doc["timing"]["render_wall_s"]
            left = (len(todo) - i - 1) * sum(times) / len(times)
            log(args.out, f"[{i + 1}/{len(todo)}] s{seed} {kind:8s} {split_of(seed):10s} {spp:3d} spp  "
                          f"{dt:6.1f} s (reference {rt['reference']:.1f} s)  relMSE a {m['relmse_noisy_a']:.4f} "
                          f"b {m['relmse_noisy_b']:.4f}  finite {m['all_finite']}  ~{left / 60:.0f} min left")
            write_index(args.out, args)
        else:
            failed.append(seed)
            log(args.out, f"[{i + 1}/{len(todo)}] s{seed} {kind:8s} FAILED after {dt:.1f} s: {msg}")
    write_index(args.out, args)
    done = [s for s in seeds if os.path.isfile(os.path.join(args.out, f"s{s}", "scene.json"))]
    log(args.out, f"render_dataset: {len(done)}/{len(seeds)} requested scenes present, {len(failed)} failed "
                  f"this run{' ' + str(failed) if failed else ''}, {time.time() - t_all:.0f} s")
    return 0 if len(done) == len(seeds) else 1


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        sys.exit(130)
