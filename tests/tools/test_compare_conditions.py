#!/usr/bin/python3
"""tools/research/compare_conditions.py on two hand-made evaluations whose answers are known: the means over the scenes both
hold (a scene only one has is left out), each model's relMSE against the yardstick's, and the reference's floor
(noisy relMSE x n / (n + R)) taken off, and each model's SSIM less the yardstick's.

  test_compare_conditions.py REPO
"""
import json, os, subprocess, sys, tempfile

repo = sys.argv[1]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from checks import check, finish  # noqa: E402


def dataset(root, name, scenes, spp, ref_spp):
    """A data set folder holding only its index.json, and the evaluate-set JSON of its scenes (relMSE, SSIM)."""
    folder = os.path.join(root, name)
    os.makedirs(folder)
    json.dump({"scenes": [{"folder": s, "spp": spp[s], "ref_spp": ref_spp} for s in scenes]},
              open(os.path.join(folder, "index.json"), "w"))
    path = os.path.join(root, name + ".json")
    json.dump({"scenes": [{"scene": s, "results": {k: {"relmse": v[0], "ssim": v[1]} for k, v in r.items()}}
                          for s, r in scenes.items()]}, open(path, "w"))
    return path, folder


with tempfile.TemporaryDirectory() as tmp:
    spp = {"s1": 4, "s2": 4, "s3": 8}
    first = dataset(tmp, "clamped", {
        "s1": {"noisy": (1.0, 0.1), "net fp32": (0.02, 0.9), "oidn fp32": (0.01, 0.95)},
        "s2": {"noisy": (0.2, 0.5), "net fp32": (0.04, 0.8), "oidn fp32": (0.03, 0.85)},
        "s3": {"noisy": (9.0, 0.0), "net fp32": (9.0, 0.0), "oidn fp32": (9.0, 0.0)},  # only here: left out
    }, spp, 396)
    second = dataset(tmp, "unclamped", {
        "s1": {"noisy": (2.0, 0.1), "net": (0.06, 0.7), "oidn": (0.04, 0.9)},
        "s2": {"noisy": (0.4, 0.4), "net": (0.1, 0.6), "oidn": (0.04, 0.8)},
    }, spp, 196)
    md = os.path.join(tmp, "table.md")
    out = subprocess.run(["/usr/bin/python3", os.path.join(repo, "tools", "research", "compare_conditions.py"), *first, *second,
                          "--models", "net", "--names", "a,b", "--md", md], capture_output=True, text=True)
    check(out.returncode == 0, f"exit status 0 (got {out.returncode}: {out.stderr})")
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in out.stdout.splitlines() if line.startswith("| `")}
    check(out.stdout.startswith("2 scenes: s1, s2"), "only the scenes both files hold")
    # Floors: a: 1.0 and 0.2 x 4 / 400 -> 0.006; b: 2.0 and 0.4 x 4 / 200 -> 0.024.
    check("a 0.006000, b 0.024000" in out.stdout, "the references' floors")
    net, oidn = rows.get("`net`"), rows.get("`oidn`")
    check(net is not None and net[0] == "0.030000 / 0.8500" and net[1] == "0.080000 / 0.6500", "the means")
    check(net is not None and net[2] == "1.500" and net[3] == "2.000", "relMSE against the yardstick's")
    # Less the floor: a (0.03 - 0.006) / (0.02 - 0.006) = 1.714..., b (0.08 - 0.024) / (0.04 - 0.024) = 3.5
    check(net is not None and net[4] == "1.714" and net[5] == "3.500", "the ratios less the floor")
    # SSIM: a 0.85 - 0.9 = -0.05, b 0.65 - 0.85 = -0.2
    check(net is not None and net[6:] == ["-0.0500", "-0.2000"], "SSIM less the yardstick's")
    check(oidn is not None and oidn[2:] == ["1.000"] * 4 + ["+0.0000"] * 2, "the yardstick's own row is 1 and 0")
    check(os.path.isfile(md) and open(md).read() == out.stdout, "--md writes the printed table")
    bad = subprocess.run(["/usr/bin/python3", os.path.join(repo, "tools", "research", "compare_conditions.py"), *first, *second,
                          "--models", "nothing"], capture_output=True, text=True)
    check(bad.returncode != 0 and "no column 'nothing'" in bad.stderr, "an unknown model is named")
finish()
