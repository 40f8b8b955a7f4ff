#!/usr/bin/python3
"""tools/models/model_card.py on a shipped model and a hand-made evaluation whose answers are known: the per-scene table
with the noisy input, the bilateral filter and the --compare columns (matched with or without the precision), their
means, and the checks' counts against each compared column; an unknown column is refused by name.

  test_model_card.py REPO RESIDUE_CLI
"""
import json, os, subprocess, sys, tempfile

repo, cli = sys.argv[1], sys.argv[2]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from checks import check, finish  # noqa: E402


def score(relmse, ssim):
    return {"relmse": relmse, "ssim": ssim, "mean_ratio": 1.0}


with tempfile.TemporaryDirectory() as tmp:
    evaluation = os.path.join(tmp, "eval.json")
    json.dump({"dataset": "made-up", "split": "validation", "scenes": [
        {"scene": "s1", "results": {"noisy": score(0.5, 0.3), "net": score(0.01, 0.90), "bilateral": score(0.05, 0.8),
                                    "oidn fp32": score(0.02, 0.95)}},
        {"scene": "s2", "results": {"noisy": score(0.1, 0.5), "net": score(0.03, 0.85), "bilateral": score(0.04, 0.7),
                                    "oidn fp32": score(0.04, 0.78)}},
    ]}, open(evaluation, "w"))
    model = os.path.join(repo, "resources", "models", "tiny.safetensors")
    run = lambda *extra: subprocess.run(["/usr/bin/python3", os.path.join(repo, "tools", "models", "model_card.py"), model,
                                         "--eval", evaluation, "--label", "net", "--cli", cli, *extra],
                                        capture_output=True, text=True)
    out = run("--compare", "oidn")
    check(out.returncode == 0, f"exit status 0 (got {out.returncode}: {out.stderr})")
    lines = out.stdout.splitlines()
    check(any(l.startswith("| scene |") and l.endswith("| oidn relMSE | oidn SSIM |") for l in lines),
          "the compared column's header")
    check("| s1 |  | 0.5 | 0.01 | 50.0x | 0.9000 | 1.000 | 0.05 | 0.8000 | 0.02 | 0.9500 |" in lines,
          "a scene's row with the compared column")
    # Means: net 0.02 / 0.875, oidn 0.03 / 0.865; net's relMSE lower on both scenes, its SSIM higher on s2 only.
    check(any(l.startswith("| **mean** |") and l.endswith("| 0.03 | 0.8650 |") for l in lines), "the compared means")
    check("against `oidn`: mean relMSE 0.02 vs 0.03 (-33.3%; lower on 2 of 2 scenes), mean SSIM 0.8750 vs 0.8650 "
          "(higher on 1 of 2)" in out.stdout, "the check against the compared column")
    plain = run()
    check(plain.returncode == 0 and "oidn" not in plain.stdout, "no --compare, no compared column")
    bad = run("--compare", "nothing")
    check(bad.returncode != 0 and "no column 'nothing'" in bad.stderr, "an unknown column is named")
finish()
