#!/usr/bin/env python3
"""residue-train's network, loss and patch sampler in PyTorch, to train where a GPU is lent (docs/research/MODELS_HISTORY.md, lever 7).

residue-train is libtorch C++ against Debian's CPU build; the lent GPU machines have Python's PyTorch with CUDA and
no Debian libraries. So the data travel as exactly what residue-train trains on (`residue-train
--export-training-set`: feature planes, targets, patch weights, made by core's own loader and feature code), and
this file holds only what a trainer adds: the network (module and tensor names are the model file's, so the state
dict exports as a model file core loads), L1 on log(1 + c), Adam with grad clipping at 1 and residue-train's cosine
schedule, patches drawn by the same noise weights under the same 8 flips (normals turned), precise BN.

  torch_train.py pack EXPORT.safetensors OUT.npz [--half 0|1] [--part K/N] [--no-val]   fp16, compressed: a call's
  torch_train.py train --data OUT.npz... --arch 16/128 (--steps N | --seconds S) --out M.safetensors [--init-from F]
  torch_train.py forward --data OUT.npz --model M.safetensors --scene 0 --out out.npy   (parity with core)

Supported: flat and multi-scale networks, `full` features, with or without autoexposure (as the export was made:
its colour planes and targets are already scaled), the l1-log (the paper's) and l1-log+ssim losses and the relMSE
term. Not: demodulation, a prior, input skip, dilations, the low-band and edge terms; refused by name.
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from safetensors_meta import read_tensors, write_tensors  # noqa: E402

DTYPES = {"F32": "<f4", "F16": "<f2"}


def read_safetensors(path):
    """A file's tensors as NumPy arrays and its metadata."""
    meta, raw = read_tensors(path)
    tensors = {}
    for name, (dtype, shape, data) in raw.items():
        if dtype not in DTYPES:
            sys.exit(f"torch_train: {path}: tensor {name} has dtype {dtype}; expected F32 or F16")
        tensors[name] = np.frombuffer(data, DTYPES[dtype]).reshape(shape)
    return tensors, meta


def write_safetensors(path, tensors, meta):
    write_tensors(path, meta, {k: ("F32", v.shape, np.ascontiguousarray(v, "<f4").tobytes())
                               for k, v in tensors.items()})


# ---------------------------------------------------------------- pack: an export as a compact NumPy archive
def pack(args):
    if os.path.exists(args.out) and not args.force:
        sys.exit(f"torch_train: {args.out} exists; pass --force to replace it")
    tensors, meta = read_safetensors(args.export)
    if meta.get("features") != "full":
        sys.exit(f"torch_train: {args.export}: features {meta.get('features')}; only 'full' is supported")
    k, n = (int(v) for v in args.part.split("/"))
    out = {"meta": np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)}
    for split in ("train", "val"):
        names = json.loads(meta.get(split + ".scenes", "[]"))
        if split == "val" and args.no_val:
            continue
        halves = [0] if split == "val" else [0, 1] if args.half is None else [args.half]
        inputs, targets, noise, exposure = [], [], [], []
        for i in range(len(names)):
            if split == "train" and i % n != k:
                continue
            for h in halves:
                key = f"{split}/{i}/input{h}"
                if key not in tensors:
                    continue
                if inputs and tensors[key].shape != inputs[0].shape:
                    sys.exit(f"torch_train: {args.export}: scene {names[i]} is {tensors[key].shape[1]} x "
                             f"{tensors[key].shape[0]}, the first {inputs[0].shape[1]} x {inputs[0].shape[0]}: "
                             "a packed file holds scenes of one size (pack other sizes apart)")
                inputs.append(tensors[key].astype(np.float16))
                targets.append(tensors[f"{split}/{i}/target{h}"].astype(np.float16))
                noise.append(tensors[f"{split}/{i}/noise"][:, :, 0].astype(np.float16))
                exposure.append(tensors[f"{split}/{i}/exposure{h}"][0])
        if not inputs:
            continue
        out[split + "_inputs"] = np.stack(inputs)      # S x H x W x C
        out[split + "_targets"] = np.stack(targets)    # S x H x W x 3
        out[split + "_noise"] = np.stack(noise)        # S x H x W: what patches are drawn by
        out[split + "_exposure"] = np.array(exposure, np.float32)  # S: the colour and targets are scaled by it
    np.savez_compressed(args.out, **out)
    print(f"torch_train: wrote {args.out}: {out['train_inputs'].shape[0]} training images, "
          f"{out.get('val_inputs', np.zeros((0,))).shape[0]} validation, {os.path.getsize(args.out) / 2**20:.1f} MiB")


# ---------------------------------------------------------------- the network (torch_network.cpp's, by name)
def build(torch, arch_text, in_channels):
    nn = torch.nn

    def conv(i, o, bias, d=1):
        return nn.Conv2d(i, o, 3, padding=d, dilation=d, bias=bias)

    class ResBlock(nn.Module):
        def __init__(self, w):
            super().__init__()
            self.conv1, self.bn1, self.prelu = conv(w, w, False), nn.BatchNorm2d(w), nn.PReLU(w)
            self.conv2, self.bn2 = conv(w, w, False), nn.BatchNorm2d(w)

        def forward(self, x):
            return x + self.bn2(self.conv2(self.prelu(self.bn1(self.conv1(x)))))

    class ConvBnPRelu(nn.Module):
        def __init__(self, i, o):
            super().__init__()
            self.conv, self.bn, self.prelu = conv(i, o, False), nn.BatchNorm2d(o), nn.PReLU(o)

        def forward(self, x):
            return self.prelu(self.bn(self.conv(x)))

    class Level(nn.Module):
        def __init__(self, widths, blocks, l):
            super().__init__()
            w = widths[l]
            self.enc = nn.ModuleList([ResBlock(w) for _ in range(blocks[l])])
            if l + 1 < len(blocks):
                self.down = ConvBnPRelu(w, widths[l + 1])
                self.up = ConvBnPRelu(widths[l + 1] + w, w)
                self.dec = nn.ModuleList([ResBlock(w) for _ in range(blocks[l])])

    class Net(nn.Module):
        def __init__(self):
            super().__init__()
            b, w = arch_text.split("/")
            self.blocks_n = [int(v) for v in b.split(",")]
            self.widths = [int(v) for v in w.split(",")]
            w0 = self.widths[0]
            self.head = nn.Module()
            self.head.conv, self.head.prelu = conv(in_channels, w0, True), nn.PReLU(w0)
            if len(self.blocks_n) == 1:
                self.blocks = nn.ModuleList([ResBlock(w0) for _ in range(self.blocks_n[0])])
            else:
                self.levels = nn.ModuleList([Level(self.widths, self.blocks_n, l) for l in range(len(self.blocks_n))])
            self.tail = nn.Module()
            self.tail.conv, self.tail.bn = conv(w0, w0, False), nn.BatchNorm2d(w0)
            self.out = nn.Module()
            self.out.conv = conv(w0, 3, True)

        def forward(self, x):
            h = self.head.prelu(self.head.conv(x))
            y = h
            if len(self.blocks_n) == 1:
                for m in self.blocks:
                    y = m(y)
            else:
                skips, L = [], len(self.levels)
                for l, level in enumerate(self.levels):
                    for m in level.enc:
                        y = m(y)
                    if l + 1 == L:
                        break
                    skips.append(y)
                    y = level.down(torch.nn.functional.max_pool2d(y, 2, 2))
                for l in range(L - 2, -1, -1):
                    level = self.levels[l]
                    up = torch.nn.functional.interpolate(y, scale_factor=2, mode="nearest")
                    y = level.up(torch.cat([up, skips[l]], 1))
                    for m in level.dec:
                        y = m(y)
            y = self.tail.bn(self.tail.conv(y)) + h
            return self.out.conv(y)

    net = Net()
    for m in net.modules():  # He initialisation for PReLU (a = 0.25), zero biases: torch_network.cpp's initialise()
        if isinstance(m, nn.Conv2d):
            nn.init.kaiming_normal_(m.weight, a=0.25, mode="fan_in", nonlinearity="leaky_relu")
            if m.bias is not None:
                nn.init.zeros_(m.bias)
    return net


def check_exposure(meta, path, autoexposure, key):
    """Refuses a model file whose autoexposure or exposure key differs from the data's (the export's metadata)."""
    if (meta.get("residue.autoexposure", "0") == "1") != autoexposure or \
            (autoexposure and meta.get("residue.exposure_key") != key):
        sys.exit(f"torch_train: {path} has autoexposure {meta.get('residue.autoexposure', '0')} "
                 f"(key {meta.get('residue.exposure_key')}), the data {int(autoexposure)} (key {key}): "
                 "export the data with the model's --autoexposure and --exposure-key")


def architecture_of(meta):
    """BLOCKS/WIDTH text of a model file, refusing the variants this port lacks."""
    for key, ok in (("residue.features", "full"), ("residue.demodulate", "0"),
                    ("residue.input_skip", "0"), ("residue.prior", "")):
        if meta.get(key, ok) != ok:
            sys.exit(f"torch_train: the model's {key} is {meta[key]!r}; this port supports {ok!r} only")
    if meta.get("residue.dilations", "") not in ("", "1"):
        sys.exit("torch_train: dilated models are not supported")
    if "residue.levels" in meta:
        return meta["residue.levels"] + "/" + meta["residue.widths"]
    return meta["residue.blocks"] + "/" + meta["residue.width"]


def load_weights(torch, net, tensors, path):
    """Copies a model file's tensors (read_safetensors of path) into net, refusing any that do not fit."""
    state = net.state_dict()
    for name, value in tensors.items():
        if name not in state:
            sys.exit(f"torch_train: {path}: tensor {name} has no place in this network")
        if tuple(state[name].shape) != value.shape:
            sys.exit(f"torch_train: {path}: tensor {name} is {value.shape}, expected {tuple(state[name].shape)}")
        state[name] = torch.from_numpy(value.copy())
    missing = [k for k in state if k not in tensors and "num_batches_tracked" not in k]
    if missing:
        sys.exit(f"torch_train: {path}: no tensor {missing[0]} (and {len(missing) - 1} more)")
    net.load_state_dict(state)


# ---------------------------------------------------------------- data on the device, sampled as training_set.cpp
class Data:
    """Packed files (their training images concatenated; the first one's validation images) on the device."""

    def __init__(self, torch, paths, device):
        self.torch, self.device = torch, device
        for p in paths:
            if not os.path.isfile(p):
                sys.exit(f"torch_train: {p}: no such file (expected a file torch_train.py pack wrote)")
        parts = [np.load(p) for p in paths]
        metas = [json.loads(bytes(z["meta"]).decode()) for z in parts]
        for p, m in zip(paths[1:], metas[1:]):
            for key in ("feature_planes", "patch", "autoexposure", "exposure_key"):
                if m.get(key) != metas[0].get(key):
                    sys.exit(f"torch_train: {p}: {key} is {m.get(key)}, {paths[0]}'s {metas[0].get(key)}")
        self.planes = json.loads(metas[0]["feature_planes"])
        self.normal_plane = int(metas[0]["normal_plane"])
        self.autoexposure = metas[0].get("autoexposure", "0") == "1"
        self.exposure_key = metas[0].get("exposure_key")
        self.sources = sorted({d for m in metas for d in json.loads(m["data"])})

        sizes = {p: z["train_inputs"].shape[1:] for p, z in zip(paths, parts)}
        if len(set(sizes.values())) > 1:
            sys.exit(f"torch_train: the packed files hold scenes of different sizes: {sizes}")

        def cat(key, dtype=None):
            a = np.concatenate([z[key] for z in parts])
            return torch.from_numpy(a if dtype is None else a.astype(dtype)).to(device)
        self.inputs, self.targets = cat("train_inputs"), cat("train_targets")       # S x H x W x C, fp16
        self.noise = cat("train_noise", np.float32)                                 # S x H x W
        self.set_patch(int(metas[0]["patch"]))
        self.val = None
        if "val_inputs" in parts[0]:
            self.val = (torch.from_numpy(parts[0]["val_inputs"]).to(device),
                        torch.from_numpy(parts[0]["val_targets"]).to(device),
                        torch.from_numpy(parts[0]["val_exposure"]).to(device))

    def set_patch(self, patch):
        """training_set.cpp's patch weights for this patch size: corners every 8 px, each weighted by the mean
        relative noise under the patch plus a floor of a quarter of the mean weight, so flat regions still appear."""
        torch = self.torch
        self.patch = patch
        S, H, W = self.noise.shape
        if H < patch or W < patch:
            sys.exit(f"torch_train: --patch {patch} is larger than the scenes ({W} x {H})")
        sat = torch.zeros((S, H + 1, W + 1), dtype=torch.float64, device=self.device)
        sat[:, 1:, 1:] = self.noise.double().cumsum(1).cumsum(2)
        ys, xs = torch.arange(0, H - patch + 1, 8, device=self.device), torch.arange(0, W - patch + 1, 8,
                                                                                      device=self.device)
        y, x = torch.meshgrid(ys, xs, indexing="ij")
        y, x = y.reshape(-1), x.reshape(-1)
        w = (sat[:, y + patch, x + patch] - sat[:, y, x + patch] - sat[:, y + patch, x] + sat[:, y, x]) / patch ** 2
        self.weights = (w + 0.25 * w.mean(1, keepdim=True) + 1e-6).float()    # S x N
        self.corners = torch.stack([x, y], 1)                                   # N x 2: x, y

    def sample(self, batch, gen, details=False):
        torch, P = self.torch, self.patch
        S = self.inputs.shape[0]
        s = torch.randint(0, S, (batch,), device=self.device, generator=gen)
        c = torch.multinomial(self.weights[s], 1, generator=gen)[:, 0]
        xy = self.corners[c]                                      # B x 2
        r = torch.arange(P, device=self.device)
        ys = (xy[:, 1, None] + r)[:, :, None]
        xs = (xy[:, 0, None] + r)[:, None, :]
        x = self.inputs[s[:, None, None], ys, xs].float()          # B x P x P x C
        y = self.targets[s[:, None, None], ys, xs].float()
        x, y = x.permute(0, 3, 1, 2), y.permute(0, 3, 1, 2)
        # One of the 8 flips/transposes per patch (core/image/dihedral.h); the normals turn with the image.
        t = torch.randint(0, 8, (batch,), device=self.device, generator=gen)
        fx, fy, tr = (t & 1).bool(), (t & 2).bool(), (t & 4).bool()
        x = torch.where(fx[:, None, None, None], x.flip(3), x)
        y = torch.where(fx[:, None, None, None], y.flip(3), y)
        x = torch.where(fy[:, None, None, None], x.flip(2), x)
        y = torch.where(fy[:, None, None, None], y.flip(2), y)
        x = torch.where(tr[:, None, None, None], x.transpose(2, 3), x)
        y = torch.where(tr[:, None, None, None], y.transpose(2, 3), y)
        if self.normal_plane >= 0:
            n = self.normal_plane
            u, v = x[:, n], -x[:, n + 1]                              # image axes: (x, -y)
            u = torch.where(fx[:, None, None], -u, u)
            v = torch.where(fy[:, None, None], -v, v)
            u, v = torch.where(tr[:, None, None], v, u), torch.where(tr[:, None, None], u, v)
            x = torch.cat([x[:, :n], u[:, None], -v[:, None], x[:, n + 2:]], 1)
        x = x.contiguous(memory_format=torch.channels_last)
        return (x, y, (s, xy, t)) if details else (x, y)


def tonemap_filmic_srgb(torch, linear):
    """The SSIM metric's tonemap (training_loss.cpp): Hable's curve normalised at 11.2, then the sRGB OETF."""
    def hable(x):
        A, B, C, D, E, F = 0.15, 0.50, 0.10, 0.20, 0.02, 0.30
        return (x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F) - E / F
    t = (hable(linear.clamp(0.0, 11.2)) / hable(torch.tensor(11.2, dtype=torch.float64)).item()).clamp(0.0, 1.0)
    power = 1.055 * t.clamp_min(0.0031308).pow(1.0 / 2.4) - 0.055  # finite gradient near 0
    return torch.where(t < 0.0031308, 12.92 * t, power)


def ssim_map(torch, x, y):
    """SSIM on valid 11 x 11 Gaussian windows (sigma 1.5), population statistics: core's metric."""
    d = torch.arange(-5, 6, dtype=torch.float64)
    g = torch.exp(-0.5 * d * d / 2.25)
    g = (g / g.sum()).to(x)
    c = x.shape[1]
    m = torch.cat([x, y, x * x, y * y, x * y], 1)
    m = torch.nn.functional.conv2d(m, g.view(1, 1, 1, 11).expand(5 * c, 1, 1, 11).contiguous(), groups=5 * c)
    m = torch.nn.functional.conv2d(m, g.view(1, 1, 11, 1).expand(5 * c, 1, 11, 1).contiguous(), groups=5 * c)
    mx, my = m[:, :c], m[:, c:2 * c]
    vx, vy, cxy = m[:, 2 * c:3 * c] - mx * mx, m[:, 3 * c:4 * c] - my * my, m[:, 4 * c:] - mx * my
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    return ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))


def training_loss(torch, kind, pred, target, ssim_weight):
    """training_loss.cpp's l1-log and l1-log+ssim (SSIM averaged over full, half and quarter resolution)."""
    loss = (pred - target).abs().mean()
    if kind == "l1-log+ssim":
        a = tonemap_filmic_srgb(torch, torch.expm1(pred.clamp_max(20.0)))
        b = tonemap_filmic_srgb(torch, torch.expm1(target))
        total, used = ssim_map(torch, a, b).mean(), 1
        for _ in range(2):
            a, b = torch.nn.functional.avg_pool2d(a, 2), torch.nn.functional.avg_pool2d(b, 2)
            if min(a.shape[2:]) < 11:
                break
            total, used = total + ssim_map(torch, a, b).mean(), used + 1
        loss = loss + ssim_weight * (1.0 - total / used)
    return loss


def relmse(torch, pred_log, target_log, exposure=1.0):
    """Core's relMSE (eps 0.01) on linear colour, per image, from log(1 + c x exposure) planes."""
    out = torch.expm1(pred_log.float().clamp(0, 20)) / exposure  # core's expand_color: negatives are 0
    ref = torch.expm1(target_log.float()) / exposure
    return ((out - ref) ** 2 / (ref ** 2 + 0.01)).mean(dim=(1, 2, 3))


def validate(torch, net, data, autocast):
    if data.val is None:
        return float("nan")
    net.eval()
    scores = []
    with torch.no_grad(), autocast():
        for i in range(data.val[0].shape[0]):
            x = data.val[0][i : i + 1].float().permute(0, 3, 1, 2).contiguous(memory_format=torch.channels_last)
            scores.append(relmse(torch, net(x), data.val[1][i : i + 1].permute(0, 3, 1, 2), data.val[2][i]).item())
    net.train()
    return float(np.mean(scores))


def precise_bn(torch, net, data, batch, batches, gen):
    """recalibrate_batch_norm: each BN's statistics as the plain mean over `batches` batches."""
    norms = [m for m in net.modules() if isinstance(m, torch.nn.BatchNorm2d)]
    for m in norms:
        m.reset_running_stats()
        m.momentum = None
    net.train()
    with torch.no_grad():
        for _ in range(batches):
            net(data.sample(batch, gen)[0])
    for m in norms:
        m.momentum = 0.1


LOSSES = {"l1-log": "L1 on log(1+c)",
          "l1-log+ssim": "L1 on log(1+c) + w * (1 - SSIM averaged over 3 scales) on the metric's filmic-sRGB tonemap"}


def train(args):
    if os.path.exists(args.out) and not args.force:
        sys.exit(f"torch_train: {args.out} exists; pass --force to replace it")
    import torch
    device = torch.device(args.device)
    torch.backends.cudnn.benchmark = True  # fixed shapes: let cuDNN pick its fastest convolutions once
    torch.manual_seed(args.seed)
    gen = torch.Generator(device=device)
    gen.manual_seed(args.seed)
    tensors_in, meta_in, arch = {}, {}, args.arch
    if args.init_from:
        tensors_in, meta_in = read_safetensors(args.init_from)
        arch = architecture_of(meta_in)
    data = Data(torch, args.data, device)
    if args.patch:
        data.set_patch(args.patch)
    if args.init_from:
        check_exposure(meta_in, args.init_from, data.autoexposure, data.exposure_key)
    net = build(torch, arch, len(data.planes))
    if args.init_from:
        load_weights(torch, net, tensors_in, args.init_from)
    net = net.to(device).to(memory_format=torch.channels_last)
    opt = torch.optim.Adam(net.parameters(), lr=args.lr, betas=(0.9, 0.999))
    norms = [m for m in net.modules() if isinstance(m, torch.nn.BatchNorm2d)]

    def autocast():
        return torch.autocast(device_type=device.type, dtype=torch.bfloat16, enabled=args.bf16)

    def sync():
        if device.type == "cuda":
            torch.cuda.synchronize()

    log = open(args.log, "w") if args.log else None
    if log:
        log.write("step,seconds,loss,lr,ms_per_step,val_relmse\n")
    # residue-train's schedule (cosine from lr to lr/100 after 100 warm-up steps; BN statistics fixed, by precise
    # BN, at --freeze-bn-after), over --steps, or over --seconds of wall time: a lease's minutes are known in
    # advance, its speed is not, and a run cut before its end would end un-annealed.
    t0 = time.time()
    t_last, loss_sum, loss_n, frozen, step = t0, 0.0, 0, False, 0

    def progress():
        return (time.time() - t0) / args.seconds if args.seconds else step / args.steps

    net.train()
    while progress() < 1:
        p = progress()
        lr = args.lr * (0.01 + 0.99 * 0.5 * (1 + math.cos(math.pi * p)))
        if step < 100:
            lr *= (step + 1) / 100
        for g in opt.param_groups:
            g["lr"] = lr
        if not frozen and args.freeze_bn_after < 1 and p >= args.freeze_bn_after:
            if args.precise_bn:
                precise_bn(torch, net, data, args.batch, args.precise_bn, gen)
            frozen = True
        if frozen:
            for m in norms:
                m.eval()
        x, y = data.sample(args.batch, gen)
        with autocast():
            pred = net(x).float()
        loss = training_loss(torch, args.loss, pred, y, args.ssim_weight)
        if args.relmse_weight > 0:  # training_loss.cpp's relative_mse, on the exposed values as there
            p, t = torch.expm1(pred.clamp_max(20.0)), torch.expm1(y)
            loss = loss + args.relmse_weight * ((p - t) ** 2 / (t ** 2 + 0.01)).mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        opt.step()
        step += 1
        if step % min(50, args.val_every) == 0:  # reading the loss waits for the GPU: not at every step
            loss_sum, loss_n = loss_sum + loss.item(), loss_n + 1
        if step % args.val_every == 0:
            sync()
            ms = (time.time() - t_last) / args.val_every * 1000
            val = validate(torch, net, data, autocast)
            print(f"step {step:7d}  loss {loss_sum / max(loss_n, 1):.5f}  lr {lr:.2e}  {ms:.2f} ms/step  "
                  f"val relMSE {val:.6f}  ({time.time() - t0:.0f} s)", flush=True)
            if log:
                log.write(f"{step},{time.time() - t0:.1f},{loss_sum / max(loss_n, 1)},{lr},{ms},{val}\n")
                log.flush()
            loss_sum, loss_n, t_last = 0.0, 0, time.time()
    sync()
    wall = time.time() - t0
    if args.precise_bn and not frozen:
        precise_bn(torch, net, data, args.batch, args.precise_bn, gen)
    net.eval()
    val = validate(torch, net, data, autocast)
    gpu = torch.cuda.get_device_name(0) if device.type == "cuda" else "cpu"
    training = {"data": data.sources, "train_images": int(data.inputs.shape[0]), "steps": step, "batch": args.batch,
                "patch": data.patch, "lr": args.lr,
                "schedule": "cosine to lr/100, 100 warm-up, over " +
                            (f"{args.seconds:.0f} s" if args.seconds else f"{args.steps} steps"),
                "loss": LOSSES[args.loss], "optimizer": "Adam(0.9, 0.999), grad clip 1.0", "seed": args.seed,
                "wall_s": wall, "precision": "bf16 autocast" if args.bf16 else "fp32", "features": "full",
                "precise_bn_batches": args.precise_bn, "freeze_bn_after": args.freeze_bn_after,
                "trainer": f"tools/models/torch_train.py (PyTorch {torch.__version__}) on {gpu}"}
    if args.loss == "l1-log+ssim":
        training["ssim_weight"] = args.ssim_weight
    if args.relmse_weight > 0:
        training["relmse_weight"] = args.relmse_weight
        training["loss"] += " + w * relMSE (eps 0.01)"
    if args.init_from:
        training["init_from"] = meta_in.get("name", args.init_from)
    meta = {k: v for k, v in meta_in.items() if k.startswith("residue.") and k != "residue.blend_tau"}
    if not meta:
        b, w = arch.split("/")
        meta = {"residue.format": "1", "residue.features": "full", "residue.bn_eps": "1e-05"}
        if "," in b:
            meta.update({"residue.levels": b, "residue.widths": w, "residue.blocks": b.split(",")[0],
                         "residue.width": w.split(",")[0]})
        else:
            meta.update({"residue.blocks": b, "residue.width": w})
        if data.autoexposure:
            meta.update({"residue.autoexposure": "1", "residue.exposure_key": data.exposure_key})
    meta.update({"name": args.name or os.path.basename(args.out).split(".")[0], "training": json.dumps(training),
                 "validation": json.dumps({"scenes": int(data.val[0].shape[0]) if data.val else 0,
                                           "relmse": val, "by": "tools/models/torch_train.py, no post-steps"})})
    tensors = {k: v.detach().float().cpu().numpy() for k, v in net.state_dict().items()
               if "num_batches_tracked" not in k}
    write_safetensors(args.out, tensors, meta)
    print(f"torch_train: wrote {args.out} ({step} steps, {wall:.0f} s, val relMSE {val:.6f})", flush=True)


def forward(args):
    """The network on one scene's first noisy half, as core runs it without post-steps: exp(y) - 1 (negatives 0),
    divided by the exposure the planes were scaled by."""
    weights, meta = read_safetensors(args.model)
    if args.data.endswith(".safetensors"):  # the export itself: float32, exactly what core computes from
        tensors, data_meta = read_safetensors(args.data)
        planes = tensors[f"{args.split}/{args.scene}/input0"]
        exposure = float(tensors[f"{args.split}/{args.scene}/exposure0"][0])
    else:
        z = np.load(args.data)
        data_meta = json.loads(bytes(z["meta"]).decode())
        planes, exposure = z[args.split + "_inputs"][args.scene], float(z[args.split + "_exposure"][args.scene])
    check_exposure(meta, args.model, data_meta.get("autoexposure", "0") == "1", data_meta.get("exposure_key"))
    import torch  # after the checks, which need none of it
    net = build(torch, architecture_of(meta), planes.shape[-1])
    load_weights(torch, net, weights, args.model)
    net.eval()
    x = torch.from_numpy(planes.astype(np.float32)).permute(2, 0, 1)[None]
    with torch.no_grad():
        y = torch.expm1(net(x).clamp(min=0))[0].permute(1, 2, 0).numpy() / exposure
    np.save(args.out, y)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("pack")
    a.add_argument("export")
    a.add_argument("out")
    a.add_argument("--half", type=int, choices=(0, 1), help="keep only this noisy half of each training scene "
                   "(a data set cut in two for two device calls; default: both)")
    a.add_argument("--no-val", action="store_true", help="leave the validation scenes out")
    a.add_argument("-f", "--force", action="store_true", help="replace OUT if it exists")
    a.add_argument("--part", default="0/1", help="K/N: keep training scenes K, K + N, K + 2N, ... (a data set cut "
                   "into N parts for N device calls; default: all)")
    a = sub.add_parser("train")
    a.add_argument("--data", required=True, nargs="+", help="packed files (torch_train.py pack)")
    a.add_argument("--arch", default="16/128")
    a.add_argument("--init-from")
    a.add_argument("--steps", type=int, default=3000)
    a.add_argument("--seconds", type=float, default=0, help="train for this long instead of --steps (schedule by time)")
    a.add_argument("--batch", type=int, default=8)
    a.add_argument("--patch", type=int, default=0, help="default: the export's")
    a.add_argument("--lr", type=float, default=1e-3)
    a.add_argument("--loss", default="l1-log", choices=sorted(LOSSES))
    a.add_argument("--ssim-weight", type=float, default=1.0)
    a.add_argument("--relmse-weight", type=float, default=0.0, help="adds this weight x relMSE (eps 0.01)")
    a.add_argument("--val-every", type=int, default=500)
    a.add_argument("--precise-bn", type=int, default=100)
    a.add_argument("--freeze-bn-after", type=float, default=0.9)
    a.add_argument("--bf16", action="store_true")
    a.add_argument("--device", default="cuda")
    a.add_argument("--seed", type=int, default=1)
    a.add_argument("--name")
    a.add_argument("--log")
    a.add_argument("--out", required=True)
    a.add_argument("-f", "--force", action="store_true", help="replace --out if it exists")
    a = sub.add_parser("forward")
    a.add_argument("--data", required=True)
    a.add_argument("--model", required=True)
    a.add_argument("--split", default="val")
    a.add_argument("--scene", type=int, default=0)
    a.add_argument("--out", required=True)
    args = p.parse_args()
    {"pack": pack, "train": train, "forward": forward}[args.cmd](args)


if __name__ == "__main__":
    main()
