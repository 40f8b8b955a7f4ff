#!/usr/bin/python3
"""Regenerates the model seeds of tests/fuzz/corpus/{fuzz_safetensors,fuzz_tza} from the shipped models, shrunk
so that the fuzzer can mutate them quickly: the real weights of resources/models/tiny.safetensors cut to a few
channels (valid Residue models of each feature set, plain and multi-scale, in F32, F16 and BF16), and OIDN's
rt_hdr_alb_nrm / rt_hdr / rt_hdr_calb_cnrm_large .tza with every width divided by 16 (32 for the large one), so
that they still load as UNet / UNetLarge. Run from anywhere; the seeds are committed."""
import os
import struct
import sys

import numpy as np

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
sys.path.insert(0, os.path.join(ROOT, "tools", "models"))
from safetensors_meta import read_tensors, write_tensors  # noqa: E402
CORPUS = os.path.join(ROOT, "tests", "fuzz", "corpus")
MODELS = os.path.join(ROOT, "resources", "models")


def read_safetensors(path):
    metadata, tensors = read_tensors(path)
    return metadata, {k: np.frombuffer(raw, dtype=np.float32).reshape(shape) for k, (_, shape, raw) in tensors.items()}


def write_safetensors(path, metadata, tensors, dtype="F32"):
    encoded = {}
    for k, a in tensors.items():
        if dtype == "F32":
            raw = a.astype("<f4").tobytes()
        elif dtype == "F16":
            raw = a.astype("<f2").tobytes()
        else:  # BF16: the top 16 bits of the float32
            raw = (a.astype("<f4").view("<u4") >> 16).astype("<u2").tobytes()
        encoded[k] = (dtype, a.shape, raw)
    write_tensors(path, metadata, encoded)


_, tiny = read_safetensors(os.path.join(MODELS, "tiny.safetensors"))  # 4 blocks, width 32, 9 input channels


def cut(name, *shape):
    """The real tensor `name` of tiny, cut to `shape` (leading slices)."""
    a = tiny[name]
    return np.ascontiguousarray(a[tuple(slice(0, s) for s in shape)]).copy()


def bn(prefix, w, src):
    return {f"{prefix}.{k}": cut(f"{src}.{k}", w) for k in ("weight", "bias", "running_mean", "running_var")}


def block(prefix, w, src="blocks.0"):
    t = {f"{prefix}.conv1.weight": cut(f"{src}.conv1.weight", w, w, 3, 3),
         f"{prefix}.conv2.weight": cut(f"{src}.conv2.weight", w, w, 3, 3),
         f"{prefix}.prelu.weight": cut(f"{src}.prelu.weight", w)}
    t.update(bn(prefix + ".bn1", w, src + ".bn1"))
    t.update(bn(prefix + ".bn2", w, src + ".bn2"))
    return t


def head_tail(cin, w, wl):
    """head at width w, tail and out at width w too (level 0); wl unused for plain networks."""
    t = {"head.conv.weight": cut("head.conv.weight", w, cin, 3, 3), "head.conv.bias": cut("head.conv.bias", w),
         "head.prelu.weight": cut("head.prelu.weight", w), "tail.conv.weight": cut("tail.conv.weight", w, w, 3, 3),
         "out.conv.weight": cut("out.conv.weight", 3, w, 3, 3), "out.conv.bias": cut("out.conv.bias", 3)}
    t.update(bn("tail.bn", w, "tail.bn"))
    return t


def plain(features, cin, blocks, w):
    t = head_tail(cin, w, w)
    for b in range(blocks):
        t.update(block(f"blocks.{b}", w, f"blocks.{b % 4}"))
    md = {"residue.format": "1", "residue.blocks": str(blocks), "residue.width": str(w),
          "residue.features": features, "residue.bn_eps": "1e-05", "name": f"seed-{features}-{blocks}x{w}"}
    return md, t


out = os.path.join(CORPUS, "fuzz_safetensors")
os.makedirs(out, exist_ok=True)
md, t = plain("full", 9, 2, 4)
write_safetensors(os.path.join(out, "tiny_cut_full_2x4.safetensors"), md, t)
md, t = plain("color", 3, 1, 3)
write_safetensors(os.path.join(out, "tiny_cut_color_1x3_f16.safetensors"), md, t, "F16")
md, t = plain("color+albedo+normal", 8, 1, 2)
md["residue.dilations"] = "1,2"
md["residue.input_skip"] = "1"
write_safetensors(os.path.join(out, "tiny_cut_can_dilated_bf16.safetensors"), md, t, "BF16")
md, t = plain("full+variance", 10, 1, 2)
t["head.conv.weight"] = np.concatenate([cut("head.conv.weight", 2, 9, 3, 3), cut("head.conv.weight", 2, 1, 3, 3)], 1)
write_safetensors(os.path.join(out, "tiny_cut_full_variance_1x2.safetensors"), md, t)
# multi-scale: levels 1,1 with widths 2,3
t = head_tail(9, 2, 2)
t.update(block("levels.0.enc.0", 2))
t.update(block("levels.0.dec.0", 2))
t.update(block("levels.1.enc.0", 3))
for p, cin, cout in (("levels.0.down", 2, 3), ("levels.0.up", 3 + 2, 2)):
    t[p + ".conv.weight"] = cut("blocks.1.conv1.weight", cout, cin, 3, 3)
    t[p + ".prelu.weight"] = cut("blocks.1.prelu.weight", cout)
    t.update(bn(p + ".bn", cout, "blocks.1.bn1"))
md = {"residue.format": "1", "residue.blocks": "1", "residue.width": "2", "residue.features": "full",
      "residue.levels": "1,1", "residue.widths": "2,3", "name": "seed-multiscale"}
write_safetensors(os.path.join(out, "tiny_cut_multiscale.safetensors"), md, t)


def read_tza(path):
    b = open(path, "rb").read()
    _, _, _, p = struct.unpack_from("<HBBQ", b, 0)
    n = struct.unpack_from("<I", b, p)[0]
    p += 4
    tensors = []
    for _ in range(n):
        ln = struct.unpack_from("<H", b, p)[0]
        p += 2
        name = b[p:p + ln].decode()
        p += ln
        nd = b[p]
        p += 1
        dims = struct.unpack_from("<%dI" % nd, b, p)
        p += 4 * nd
        layout = b[p:p + nd].decode()
        p += nd
        dt = chr(b[p])
        p += 1
        off = struct.unpack_from("<Q", b, p)[0]
        p += 8
        np_dt = {"f": "<f4", "h": "<f2"}[dt]
        count = int(np.prod(dims))
        a = np.frombuffer(b, dtype=np_dt, count=count, offset=off).reshape(dims)
        tensors.append((name, layout, a))
    return tensors


def write_tza(path, tensors, dtype="h"):
    data, entries = b"", []
    pos = 12
    for name, layout, a in tensors:
        pos = (pos + 63) // 64 * 64  # OIDN aligns each tensor to 64 bytes
        raw = a.astype({"f": "<f4", "h": "<f2", "b": "i1", "B": "u1"}[dtype]).tobytes()
        data += b"\0" * (pos - 12 - len(data)) + raw
        entries.append((name, layout, a.shape, pos))
        pos += len(raw)
    table = struct.pack("<I", len(entries))
    for name, layout, shape, off in entries:
        table += struct.pack("<H", len(name)) + name.encode() + bytes([len(shape)]) + struct.pack(
            "<%dI" % len(shape), *shape) + layout.encode() + dtype.encode() + struct.pack("<Q", off)
    with open(path, "wb") as f:
        f.write(struct.pack("<HBBQ", 0x41D7, 2, 0, 12 + len(data)) + data + table)


def shrink_tza(src, dst, div, dtype="h"):
    tensors = read_tza(os.path.join(MODELS, "oidn", src))
    cin = tensors[0][2].shape[1]  # the network's input channels (3 per image)

    def s(c):
        if c in (3, cin):
            return c
        return c // div if c % div == 0 else (c - cin) // div + cin  # the first decoder level: features + input

    out_t = []
    for name, layout, a in tensors:
        shape = tuple(s(d) if i < 2 else d for i, d in enumerate(a.shape))
        out_t.append((name, layout, np.ascontiguousarray(a[tuple(slice(0, d) for d in shape)])))
    write_tza(os.path.join(CORPUS, "fuzz_tza", dst), out_t, dtype)


os.makedirs(os.path.join(CORPUS, "fuzz_tza"), exist_ok=True)
shrink_tza("rt_hdr_alb_nrm.tza", "rt_hdr_alb_nrm_div16.tza", 16)
shrink_tza("rt_hdr.tza", "rt_hdr_div16_f32.tza", 16, "f")
shrink_tza("rt_hdr_calb_cnrm_large.tza", "rt_hdr_calb_cnrm_large_div32.tza", 32)
# int8 / uint8 tensors (not a network: the reader's other dtypes)
write_tza(os.path.join(CORPUS, "fuzz_tza", "int8_tensors.tza"),
          [("a", "x", np.arange(-4, 4, dtype=np.int8)), ("b", "oihw", np.zeros((2, 1, 1, 2), np.int8))], "b")
write_tza(os.path.join(CORPUS, "fuzz_tza", "uint8_tensor.tza"), [("c", "hw", np.arange(6, dtype=np.uint8).reshape(2, 3))],
          "B")
