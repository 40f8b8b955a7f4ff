"""The project's metrics in Python, one definition for every tool: EXR reading, the filmic tonemap, relMSE, MSE
and PSNR as residue-cli eval computes them (tests/tools/test_exr_metrics.py pins them to its numbers), the
metrics stored in scene.json and the box mean that splits an image into spatial frequency bands (numpy +
OpenImageIO only). SSIM and the temporal metrics are core's alone: call `residue-cli eval --json`.

Used by make_scene.py (inside Blender, whose Python on Debian is the system Python 3.11 and sees the system's
numpy and OpenImageIO), render_dataset.py, contact_sheet.py and the studies under tools/research
(/usr/bin/python3).

relMSE here is the project's definition (docs/METRICS.md, residue-cli eval): mean over pixels and RGB channels
of (x - r)^2 / (r^2 + eps) with eps = 0.01, on linear values; pixels where the test or the reference is NaN or
infinite in any RGB channel are left out.
"""
import math

import numpy as np
import OpenImageIO as oiio

EPS = 0.01
COMBINED = "ViewLayer.Combined"


def read_exr(path):
    """Returns {"pixels": HxWxC float32, "channels": [...], "types": [...], "attrs": {...}}."""
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise IOError(f"cannot open {path}: {oiio.geterror()}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, "float")
        if pixels is None:
            raise IOError(f"cannot read {path}: {inp.geterror()}")
        pixels = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
        channels = list(spec.channelnames)
        types = [str(spec.channelformat(i)) for i in range(spec.nchannels)]
        attrs = {}
        for a in spec.extra_attribs:
            try:
                attrs[a.name] = a.value
            except Exception:  # noqa: BLE001 - exotic attribute types are irrelevant here
                pass
    finally:
        inp.close()
    return {"pixels": pixels, "channels": channels, "types": types, "attrs": attrs}


def layer_rgb(img, layer=COMBINED):
    """A layer's RGB as float64; layer None for plain R, G, B channels (residue-cli denoise's output)."""
    idx = [img["channels"].index(c if layer is None else f"{layer}.{c}") for c in "RGB"]
    return img["pixels"][:, :, idx].astype(np.float64)


def finite_pixels(x, r):
    """The pixels that enter every metric: test and reference finite in all three RGB channels."""
    return np.isfinite(x[..., :3]).all(axis=2) & np.isfinite(r[..., :3]).all(axis=2)


def relmse(x, r, eps=EPS):
    """relMSE as residue-cli eval scores it (linear RGB; non-finite pixels left out)."""
    ok = finite_pixels(x, r)
    x, r = x[..., :3].astype(np.float64), r[..., :3].astype(np.float64)
    with np.errstate(invalid="ignore", over="ignore"):  # the left-out pixels' inf - inf
        return float(np.mean(((x - r) ** 2 / (r * r + eps))[ok]))


def mse(x, r):
    """MSE on linear RGB, as residue-cli eval's "mse"."""
    ok = finite_pixels(x, r)
    with np.errstate(invalid="ignore", over="ignore"):
        return float(np.mean(((x[..., :3].astype(np.float64) - r[..., :3]) ** 2)[ok]))


def psnr(x, r):
    """PSNR in dB on tonemapped values (tonemap() at exposure 1), as residue-cli eval's "psnr"."""
    ok = finite_pixels(x, r)
    e = np.mean(((tonemap(x[..., :3].astype(np.float64)) - tonemap(r[..., :3].astype(np.float64))) ** 2)[ok])
    return float("inf") if e == 0 else float(10.0 * math.log10(1.0 / e))


def box_mean(e, w):
    """The W x W box mean of each channel of e (H x W x C), the border reflected."""
    p = np.pad(e, ((w // 2, w - 1 - w // 2), (w // 2, w - 1 - w // 2), (0, 0)), mode="reflect")
    c = np.pad(p.cumsum(0).cumsum(1), ((1, 0), (1, 0), (0, 0)))
    h, wd = e.shape[:2]
    return (c[w:w + h, w:w + wd] - c[:h, w:w + wd] - c[w:w + h, :wd] + c[:h, :wd]) / (w * w)


def luminance(rgb):
    return 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]


def _hable(x):
    a, b, c, d, e, f = 0.15, 0.50, 0.10, 0.20, 0.02, 0.30
    return (x * (a * x + c * b) + d * e) / (x * (a * x + b) + d * f) - e / f


def tonemap(rgb, exposure=1.0):
    """Hable/Uncharted-2 filmic curve normalised so linear 11.2 maps to 1, then the sRGB OETF (as eval's SSIM)."""
    x = np.nan_to_num(np.maximum(rgb * exposure, 0.0), nan=0.0, posinf=1e4)
    y = np.clip(_hable(x) / _hable(11.2), 0.0, 1.0)
    return np.where(y < 0.0031308, 12.92 * y, 1.055 * np.power(y, 1.0 / 2.4) - 0.055)


def log_average_luminance(rgb, delta=1e-4):
    lum = luminance(np.nan_to_num(rgb, nan=0.0, posinf=0.0))
    return float(math.exp(np.mean(np.log(np.maximum(lum, 0.0) + delta))))


def scene_metrics(noisy_a, noisy_b, reference, eps=EPS):
    """noisy_a/noisy_b/reference: read_exr() results (noisy_b may be None). Returns the scene.json metrics."""
    a = layer_rgb(noisy_a)
    r = layer_rgb(reference)
    m = {"eps": eps, "formula": "relMSE = mean over pixels and RGB of (x-r)^2/(r^2+eps), linear values"}
    m["relmse_noisy_a"] = relmse(a, r, eps)
    if noisy_b is not None:
        b = layer_rgb(noisy_b)
        m["relmse_noisy_b"] = relmse(b, r, eps)
        m["relmse_mean_ab"] = relmse(0.5 * (a + b), r, eps)
        ok = np.isfinite(a).all(axis=2) & np.isfinite(b).all(axis=2) & np.isfinite(r).all(axis=2)
        m["relmse_split_estimate_mean_ab"] = float(np.mean((((a - b) ** 2 / 4.0) / (r * r + eps))[ok]))
    rf = np.nan_to_num(r, nan=0.0, posinf=65504.0)
    lum = luminance(rf)
    m["ref_mean_rgb"] = [float(v) for v in rf.reshape(-1, 3).mean(axis=0)]
    m["ref_lum_mean"] = float(lum.mean())
    m["ref_lum_median"] = float(np.median(lum))
    m["ref_lum_p99"] = float(np.percentile(lum, 99))
    m["ref_lum_max"] = float(lum.max())
    m["ref_log_average_lum"] = log_average_luminance(rf)
    m["ref_frac_lum_below_0.01"] = float(np.mean(lum < 0.01))
    m["ref_frac_lum_above_4"] = float(np.mean(lum > 4.0))
    m["ref_tonemapped_mean"] = float(tonemap(rf).mean())
    m["noisy_a_mean_rgb"] = [float(v) for v in np.nan_to_num(a).reshape(-1, 3).mean(axis=0)]
    images = [noisy_a, reference] + ([noisy_b] if noisy_b is not None else [])
    m["all_finite"] = bool(all(np.isfinite(img["pixels"]).all() for img in images))
    m["ref_half_overflow_px"] = int((~np.isfinite(r)).any(axis=2).sum())
    return m
