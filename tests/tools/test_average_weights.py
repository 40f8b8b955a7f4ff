#!/usr/bin/python3
"""tools/models/average_weights.py on the real shipped multiscale file: the weighted mean is exact (checked in float64
against NumPy), the result loads and denoises in residue-cli, and bad inputs fail early without writing.

  test_average_weights.py REPO RESIDUE_CLI
"""
import json, os, subprocess, sys, tempfile

import numpy as np

repo, cli = sys.argv[1], sys.argv[2]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(repo, "tools", "models"))
from safetensors_meta import read_tensors, write_tensors  # noqa: E402
from checks import check, finish  # noqa: E402

tool = os.path.join(repo, "tools", "models", "average_weights.py")
model = os.path.join(repo, "resources", "models", "multiscale.safetensors")
room = os.path.join(repo, "resources", "examples", "room")
def arrays(path):
    """A file's float32 tensors as arrays, and its metadata."""
    meta, tensors = read_tensors(path)
    return {k: np.frombuffer(raw, "<f4").reshape(shape) for k, (dtype, shape, raw) in tensors.items()
            if dtype == "F32"}, meta


def run(*args):
    return subprocess.run([sys.executable, tool, *args], capture_output=True, text=True)


with tempfile.TemporaryDirectory() as tmp:
    # B: the shipped weights, each tensor scaled by its own factor (so that a mix-up of names would show).
    a, meta = arrays(model)
    b_path = os.path.join(tmp, "b.safetensors")
    write_tensors(b_path, meta, {k: ("F32", v.shape, (v * np.float32(1.0 + 0.01 * (i % 7))).astype("<f4").tobytes())
                                 for i, (k, v) in enumerate(sorted(a.items()))})
    b, _ = arrays(b_path)

    out = os.path.join(tmp, "mean.safetensors")
    r = run(out, f"{model}:1", f"{b_path}:3")
    check(r.returncode == 0, f"the average runs: {r.stderr}")
    mean, meta = arrays(out)
    check(mean.keys() == a.keys(), "every tensor is kept")
    def relative_error(k):  # float32 rounding of the float64 mean: within one unit in the last place
        expected = 0.25 * a[k].astype(np.float64) + 0.75 * b[k].astype(np.float64)
        return float(np.max(np.abs(mean[k] - expected) / np.maximum(np.abs(expected), 1e-30)))
    worst = max(relative_error(k) for k in a)
    check(worst <= 1.2e-7, f"weights 1:3 give 0.25 A + 0.75 B (largest relative difference {worst})")
    check(meta.get("name") == "multiscale", "the first file's metadata is kept")
    check([e["weight"] for e in json.loads(meta["averaged_from"])] == [0.25, 0.75], "averaged_from records the weights")

    # The shipped file averaged with itself denoises the bundled room as the shipped file does.
    same = os.path.join(tmp, "same.safetensors")
    check(run(same, model, model).returncode == 0, "a file averaged with itself")
    outputs = {}
    for name, path in (("shipped", model), ("same", same)):
        exr = os.path.join(tmp, name + ".exr")
        r = subprocess.run([cli, "denoise", os.path.join(room, "noisy.exr"), "--reference",
                            os.path.join(room, "reference.exr"), "-m", path, "-o", exr], capture_output=True, text=True)
        check(r.returncode == 0, f"residue-cli denoise with the {name} file: {r.stderr}")
        outputs[name] = next((l for l in r.stdout.splitlines() if l.startswith("denoised")), None)
    check(outputs["shipped"] is not None and outputs["shipped"] == outputs["same"],
          f"same scores: {outputs['shipped']} / {outputs['same']}")

    # Refusals: an existing output, another network shape, a bad weight; nothing written.
    r = run(out, model, b_path)
    check(r.returncode != 0 and "exists" in r.stderr, "an existing output is not replaced without --force")
    other = os.path.join(repo, "resources", "models", "multiscale-color.safetensors")
    bad = os.path.join(tmp, "bad.safetensors")
    r = run(bad, model, other)
    check(r.returncode != 0 and "tensor" in r.stderr and not os.path.exists(bad),
          f"another network shape is refused, naming the tensor: {r.stderr.strip()}")
    r = run(bad, f"{model}:-1", b_path)
    check(r.returncode != 0 and not os.path.exists(bad), "a negative weight is refused")
    r = run(bad, f"{model}:half", b_path)
    check(r.returncode != 0 and "half" in r.stderr and not os.path.exists(bad), "a weight that is no number is named")
    r = run(bad, model, os.path.join(tmp, "missing.safetensors"))
    check(r.returncode != 0 and "missing.safetensors" in r.stderr and not os.path.exists(bad),
          "a missing input is named")

finish()
