#!/usr/bin/python3
"""tools/research/goal_compare.py on a real goal_check.py file (docs/research/models): a file against itself wins nowhere; against a
copy with one scene's relMSE lowered and two others' SSIM raised it counts exactly those; the means and Cornell
values are the files' own; files scored on different scenes are refused, by the function and by the command.

  test_goal_compare.py REPO
"""
import copy, json, os, subprocess, sys, tempfile

repo = sys.argv[1]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(repo, "tools", "research"))
from checks import check, finish  # noqa: E402
from goal_compare import compare  # noqa: E402

a = json.load(open(os.path.join(repo, "docs", "research", "models", "goal_s13_full_soup_x1.json")))
n = len(a["scenes"])
same = compare(a, a)
check(same["scenes"] == n == 30 and same["relmse_lower"] == 0 and same["ssim_higher"] == 0, f"against itself: {same}")

b = copy.deepcopy(a)
b["scenes"][3]["model"]["relmse"] *= 0.99
b["scenes"][7]["model"]["ssim"] += 1e-4
b["scenes"][8]["model"]["ssim"] += 1e-4
b["scenes"][9]["model"]["relmse"] *= 1.5  # worse: not counted
b["cornell"]["model"]["ssim"] = 0.5
c = compare(a, b)
check(c["relmse_lower"] == 1 and c["ssim_higher"] == 2, f"one lower, two higher: {c}")
mean_a = sum(s["model"]["relmse"] for s in a["scenes"]) / n
mean_b = sum(s["model"]["relmse"] for s in b["scenes"]) / n
check(abs(c["mean"]["relmse"][0] - mean_a) < 1e-15 and abs(c["mean"]["relmse"][1] - mean_b) < 1e-15, f"means: {c}")
check(c["cornell"]["ssim"] == (a["cornell"]["model"]["ssim"], 0.5), f"Cornell: {c['cornell']}")
back = compare(b, a)
check(back["relmse_lower"] == 1 and back["ssim_higher"] == 0, f"the other way round: {back}")

short = copy.deepcopy(a)
del short["scenes"][5]
try:
    compare(a, short)
    check(False, "files with different scenes were compared")
except ValueError as e:
    check("different scenes" in str(e), f"refusal names the cause: {e}")
with tempfile.TemporaryDirectory() as tmp:
    paths = []
    for name, doc in (("a.json", a), ("short.json", short)):
        paths.append(os.path.join(tmp, name))
        json.dump(doc, open(paths[-1], "w"))
    run = subprocess.run([sys.executable, os.path.join(repo, "tools", "research", "goal_compare.py"), *paths],
                         capture_output=True, text=True)
    check(run.returncode == 2 and "different scenes" in run.stderr, f"the command refuses: {run.returncode} {run.stderr}")
    run = subprocess.run([sys.executable, os.path.join(repo, "tools", "research", "goal_compare.py"), paths[0], paths[0]],
                         capture_output=True, text=True)
    check(run.returncode == 0 and "relMSE lower on 0, SSIM higher on 0" in run.stdout, f"the command: {run.stdout}")
finish()
