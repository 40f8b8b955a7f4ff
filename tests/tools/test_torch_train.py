#!/usr/bin/python3
"""`residue-train --export-training-set` and tools/models/torch_train.py (issue 16, lever 7: training on a lent GPU).

On three real starter scenes: the export holds each half's feature planes and target exactly (the target checked
against log(1 + reference) read here with OpenImageIO, the patch weights against the noise measure recomputed here
in float64 from both halves and the reference); it refuses to replace a file; `pack` keeps the values at fp16.
Where PyTorch is installed (not in CI: Debian's python3-torch is not part of the set-up), the port's network run on
the exported planes equals residue-cli's output, for a flat and a multi-scale model file.

  test_torch_train.py REPO RESIDUE_TRAIN RESIDUE_CLI
"""
import json, os, subprocess, sys, tempfile

import numpy as np
import OpenImageIO as oiio

repo, trainer, cli = sys.argv[1], sys.argv[2], sys.argv[3]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(repo, "tools", "models"))
from checks import check, finish  # noqa: E402
import fit_exposure_key  # noqa: E402
import safetensors_meta  # noqa: E402
import torch_train  # noqa: E402

starter = os.path.join(repo, "..", "shared", "datasets", "cycles-starter")
if not os.path.isdir(starter):
    starter = os.environ.get("RESIDUE_SHARED_DIR", "") + "/datasets/cycles-starter"
scenes = sorted(d for d in os.listdir(starter) if d.startswith("s"))[:3]


def rgb(path):
    image = oiio.ImageBuf(path)
    spec = image.spec()
    names = spec.channelnames
    pick = [names.index(c) for c in ("R", "G", "B")] if "R" in names else \
        [i for i, n in enumerate(names) if n.endswith((".R", ".r"))][:1]
    if len(pick) == 1:  # multilayer: the combined pass's R, G, B
        base = names[pick[0]][:-1]
        pick = [names.index(base + c) for c in "RGB"]
    return image.get_pixels(oiio.FLOAT)[:, :, pick].astype(np.float64)


with tempfile.TemporaryDirectory() as tmp:
    data = os.path.join(tmp, "data")
    os.mkdir(data)
    for s in scenes:
        os.symlink(os.path.join(starter, s), os.path.join(data, s))
    export = os.path.join(tmp, "export.safetensors")
    args = [trainer, "--data", data, "--val", "1", "--arch", "4/32", "--features", "full", "--patch", "64",
            "--threads", "2", "--export-training-set", export]
    r = subprocess.run(args, capture_output=True, text=True)
    check(r.returncode == 0, f"the export runs: {r.stdout} {r.stderr}")
    tensors, meta = torch_train.read_safetensors(export)
    check(json.loads(meta["train.scenes"]) == scenes[:2] and json.loads(meta["val.scenes"]) == scenes[2:],
          f"two training scenes and one validation scene, named: {meta.get('train.scenes')} {meta.get('val.scenes')}")
    planes = json.loads(meta["feature_planes"])
    check(len(planes) == 9 and tensors["train/0/input0"].shape == (256, 256, 9), f"9 feature planes: {planes}")

    # Targets: log(1 + reference) for both halves (no autoexposure in 4/32).
    scene = os.path.join(starter, scenes[0])
    reference = rgb(os.path.join(scene, "reference.exr"))
    expected = np.log1p(np.maximum(reference, 0))
    for h in (0, 1):
        err = np.max(np.abs(tensors[f"train/0/target{h}"] - expected))
        check(err < 1e-5, f"half {h}'s target is log(1 + reference) (largest difference {err})")
    # The colour planes: log(1 + each half's colour).
    for h, name in ((0, "noisy_a.exr"), (1, "noisy_b.exr")):
        color = np.log1p(np.maximum(rgb(os.path.join(scene, name)), 0))
        at = planes.index("color.r")
        err = np.max(np.abs(tensors[f"train/0/input{h}"][:, :, at:at + 3] - color))
        check(err < 1e-5, f"half {h}'s colour planes are log(1 + {name}) (largest difference {err})")

    # Patch weights: the mean of min(sum_c (a - b)^2 / (r^2 + 0.01), 100) over each 64-px patch, plus a floor of a
    # quarter of their mean, recomputed in float64.
    a, b = rgb(os.path.join(scene, "noisy_a.exr")), rgb(os.path.join(scene, "noisy_b.exr"))
    noise = np.minimum(((a - b) ** 2 / (reference ** 2 + 0.01)).sum(axis=2), 100)
    corners = tensors["train/0/corners"].astype(int)
    raw = np.array([noise[y:y + 64, x:x + 64].mean() for x, y in corners])
    want = raw + 0.25 * raw.mean() + 1e-6
    err = np.max(np.abs(tensors["train/0/weights"] - want) / want)
    check(len(corners) == 25 * 25 and err < 1e-3, f"{len(corners)} corners, weights as recomputed (relative {err})")

    # Nothing is replaced without --force.
    before = os.path.getmtime(export)
    r = subprocess.run(args, capture_output=True, text=True)
    check(r.returncode == 4 and "exists" in r.stderr and os.path.getmtime(export) == before,
          f"an existing export is refused (exit 4) and kept: {r.returncode} {r.stderr}")

    # pack: both halves of the training scenes, the validation scene's first, at fp16.
    packed = os.path.join(tmp, "data.npz")
    r = subprocess.run([sys.executable, os.path.join(repo, "tools", "models", "torch_train.py"), "pack", export, packed],
                       capture_output=True, text=True)
    check(r.returncode == 0, f"pack runs: {r.stderr}")
    z = np.load(packed)
    check(z["train_inputs"].shape == (4, 256, 256, 9) and z["val_inputs"].shape == (1, 256, 256, 9),
          f"4 training images, 1 validation image: {z['train_inputs'].shape} {z['val_inputs'].shape}")
    err = np.max(np.abs(z["train_inputs"][1].astype(np.float32) - tensors["train/0/input1"]) /
                 (np.abs(tensors["train/0/input1"]) + 1e-3))
    check(err < 1e-3, f"the packed planes are the export's at fp16 (relative {err})")

    # --part K/N keeps every N-th training scene from K (the data cut for N device calls).
    part = os.path.join(tmp, "part.npz")
    r = subprocess.run([sys.executable, os.path.join(repo, "tools", "models", "torch_train.py"), "pack", export, part,
                        "--part", "1/2", "--half", "1", "--no-val"], capture_output=True, text=True)
    zp = np.load(part) if r.returncode == 0 else {}
    check(r.returncode == 0 and zp["train_inputs"].shape[0] == 1 and "val_inputs" not in zp and
          np.array_equal(zp["train_inputs"][0], z["train_inputs"][3]), f"part 1/2, half 1: scene 1's half 1 alone")

    # With autoexposure (at the shipped multiscale's key), each half's colour planes and target are scaled by its
    # exposure, which the export records.
    multiscale = os.path.join(repo, "resources", "models", "multiscale.safetensors")
    ms_key = torch_train.read_safetensors(multiscale)[1]["residue.exposure_key"]
    export_ae = os.path.join(tmp, "export_ae.safetensors")
    r = subprocess.run([trainer, "--data", data, "--val", "1", "--arch", "2,2,2,2/24,40,56,80", "--patch", "128",
                        "--autoexposure", "--exposure-key", ms_key, "--threads", "2", "--export-training-set",
                        export_ae], capture_output=True, text=True)
    check(r.returncode == 0, f"the export with autoexposure runs: {r.stderr}")
    tae, mae = torch_train.read_safetensors(export_ae)
    e = float(tae["train/0/exposure0"][0])
    err = np.max(np.abs(tae["train/0/target0"] - np.log1p(np.maximum(reference, 0) * e)))
    check(mae.get("autoexposure") == "1" and mae.get("exposure_key") == ms_key and e != 1.0 and err < 1e-4,
          f"the target is log(1 + reference x exposure {e}) (largest difference {err}); key {mae.get('exposure_key')}")

    # `tiny` as trained, without autoexposure (the shipped file runs autoexposed since lever 3d, 2026-11-28).
    tiny_raw = os.path.join(tmp, "tiny_raw.safetensors")
    fit_exposure_key.write_with_key(*safetensors_meta.read_header(os.path.join(repo, "resources", "models",
                                                                               "tiny.safetensors")), tiny_raw, None)

    # forward refuses a model that would read the planes at another exposure: without autoexposure, or at another key.
    other_key = os.path.join(tmp, "other_key.safetensors")
    fit_exposure_key.write_with_key(*safetensors_meta.read_header(multiscale), other_key, 2.5 if ms_key != "2.5" else 1)
    for model in (tiny_raw, other_key):
        r = subprocess.run([sys.executable, os.path.join(repo, "tools", "models", "torch_train.py"), "forward", "--data",
                            export_ae, "--model", model, "--out", os.path.join(tmp, "never.npy")],
                           capture_output=True, text=True)
        check(r.returncode != 0 and "--exposure-key" in r.stderr and "key " + ms_key in r.stderr and
              not os.path.exists(os.path.join(tmp, "never.npy")),
              f"forward refuses {os.path.basename(model)} on data at key {ms_key}: {r.returncode} {r.stderr}")

    # The port's network equals core's, where PyTorch is installed.
    try:
        import torch  # noqa: F401
    except ImportError:
        print("note: PyTorch is not installed; the network parity check did not run")
    else:
        # The sampler: each patch is its source under core's Dihedral (core/image/dihedral.h: output (u, v) reads
        # the source at (v, u) when transposing, then mirrored), the normals turned as Dihedral::turn_normal turns them.
        data = torch_train.Data(torch, [packed], torch.device("cpu"))
        err = float(((data.weights[0] - torch.from_numpy(tensors["train/0/weights"].copy())).abs() /
                     torch.from_numpy(tensors["train/0/weights"].copy())).max())
        check(data.corners.tolist() == corners.tolist() and err < 1e-3,
              f"the port's patch weights are the trainer's (relative {err})")
        data.set_patch(128)
        check(data.corners.shape == (17 * 17, 2), f"17 x 17 corners for 128-px patches: {tuple(data.corners.shape)}")
        data.set_patch(64)
        gen = torch.Generator()
        gen.manual_seed(3)
        x, y, (s, xy, t) = data.sample(64, gen, details=True)
        images, targets = z["train_inputs"].astype(np.float32), z["train_targets"].astype(np.float32)
        n = planes.index("normal.x")
        check(planes[n + 1] == "normal.y" and data.normal_plane == n, f"the port finds the normal planes: {planes}")
        uu, vv = np.meshgrid(np.arange(64), np.arange(64))
        worst = 0.0
        for b in range(64):
            fx, fy, tr = int(t[b]) & 1, int(t[b]) & 2, int(t[b]) & 4
            sx, sy = (vv, uu) if tr else (uu, vv)
            sx, sy = (63 - sx if fx else sx), (63 - sy if fy else sy)
            x0, y0 = (int(v) for v in xy[b])
            want = images[int(s[b])][y0 + sy, x0 + sx].copy()
            nu, nv = want[..., n], -want[..., n + 1]
            nu, nv = (-nu if fx else nu), (-nv if fy else nv)
            nu, nv = (nv, nu) if tr else (nu, nv)
            want[..., n], want[..., n + 1] = nu, -nv
            worst = max(worst, float(np.abs(x[b].permute(1, 2, 0).numpy() - want).max()),
                        float(np.abs(y[b].permute(1, 2, 0).numpy() - targets[int(s[b])][y0 + sy, x0 + sx]).max()))
        check(len(set(t.tolist())) == 8 and worst == 0.0,
              f"64 patches under {len(set(t.tolist()))} of the 8 transforms are core's (largest difference {worst})")

        # The SSIM term's SSIM is the metric's: on a noisy half against its reference, as residue-cli eval scores it.
        r = subprocess.run([cli, "eval", os.path.join(scene, "noisy_a.exr"), "--reference",
                            os.path.join(scene, "reference.exr"), "--json"], capture_output=True, text=True)
        metric = json.loads(r.stdout)["rows"][0]["ssim"] if r.returncode == 0 else float("nan")
        as_planes = lambda im: torch.from_numpy(im).permute(2, 0, 1)[None]  # noqa: E731
        ours = float(torch_train.ssim_map(torch, torch_train.tonemap_filmic_srgb(torch, as_planes(a)),
                                          torch_train.tonemap_filmic_srgb(torch, as_planes(reference))).mean())
        check(abs(ours - metric) < 1e-6, f"the loss's SSIM {ours} is the metric's {metric}")
        loss = float(torch_train.training_loss(torch, "l1-log+ssim", as_planes(np.log1p(np.maximum(a, 0))),
                                               as_planes(np.log1p(np.maximum(reference, 0))), 1.0))
        check(loss > float(torch_train.training_loss(torch, "l1-log", as_planes(np.log1p(np.maximum(a, 0))),
                                                     as_planes(np.log1p(np.maximum(reference, 0))), 1.0)) + 0.1,
              f"l1-log+ssim adds the SSIM term ({loss})")

        # A short run exports a model file residue-cli loads, which computes what the port computes (from `tiny` at a
        # low rate, so that the output stays within core's overshoot guard, which an untrained network trips).
        trained = os.path.join(tmp, "trained.safetensors")
        r = subprocess.run([sys.executable, os.path.join(repo, "tools", "models", "torch_train.py"), "train", "--data", packed,
                            "--init-from", tiny_raw,
                            "--steps", "30", "--batch", "2", "--lr", "1e-4", "--val-every", "10",
                            "--precise-bn", "4", "--device", "cpu", "--out", trained], capture_output=True, text=True)
        check(r.returncode == 0 and "val relMSE" in r.stdout, f"a 30-step run on the CPU: {r.stdout} {r.stderr}")
        meta = torch_train.read_safetensors(trained)[1] if os.path.exists(trained) else {}
        check(json.loads(meta.get("training", "{}")).get("steps") == 30, "the file records its 30 steps")
        before = os.path.getmtime(trained)
        r = subprocess.run([sys.executable, os.path.join(repo, "tools", "models", "torch_train.py"), "train", "--data", packed,
                            "--steps", "1", "--device", "cpu", "--out", trained], capture_output=True, text=True)
        check(r.returncode != 0 and "exists" in r.stderr and os.path.getmtime(trained) == before,
              f"an existing model file is not replaced: {r.returncode} {r.stderr}")

        # A model trained without autoexposure is refused on data made with it, naming both.
        ae_packed = os.path.join(tmp, "ae.npz")
        subprocess.run([sys.executable, os.path.join(repo, "tools", "models", "torch_train.py"), "pack", export_ae, ae_packed],
                       capture_output=True)
        r = subprocess.run([sys.executable, os.path.join(repo, "tools", "models", "torch_train.py"), "train", "--data",
                            ae_packed, "--init-from", tiny_raw,
                            "--steps", "1", "--device", "cpu", "--out", os.path.join(tmp, "never.safetensors")],
                           capture_output=True, text=True)
        never = os.path.join(tmp, "never.safetensors")
        check(r.returncode != 0 and "autoexposure" in r.stderr and not os.path.exists(never),
              f"a model without autoexposure on data with it is refused: {r.returncode} {r.stderr}")

        val = os.path.join(starter, scenes[2])
        for model, planes_file in ((tiny_raw, export),
                                   (os.path.join(repo, "docs", "research", "models", "weights",
                                                 "study_ms_wide_p128_20k.safetensors"), export),
                                   (trained, export),
                                   (multiscale, export_ae)):
            ours = os.path.join(tmp, "port.npy")
            r = subprocess.run([sys.executable, os.path.join(repo, "tools", "models", "torch_train.py"), "forward", "--data",
                                planes_file, "--model", model, "--out", ours], capture_output=True, text=True)
            check(r.returncode == 0, f"forward runs with {model}: {r.stderr}")
            core = os.path.join(tmp, "core.exr")
            r = subprocess.run([cli, "denoise", os.path.join(val, "noisy_a.exr"), "-m", model, "-o", core, "--float",
                                "--no-energy-correction", "--no-variance-blend", "--no-skip", "-f"],
                               capture_output=True, text=True)
            check(r.returncode == 0, f"residue-cli denoise with {model}: {r.stderr}")
            if r.returncode == 0 and os.path.exists(ours):
                port, theirs = np.load(ours), rgb(core)
                err = np.max(np.abs(port - theirs) / (np.abs(theirs) + 0.01))
                check(err < 2e-3, f"{os.path.basename(model)}: the port's output is core's (relative {err})")
                print(f"{os.path.basename(model)}: the port against core: largest relative difference {err:.2e}")
finish()
