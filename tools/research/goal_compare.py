#!/usr/bin/python3
"""Two of tools/research/goal_check.py's JSON files, scene by scene: on how many validation scenes does B's model have the
lower relMSE, and the higher SSIM, than A's; and the means and the Cornell box side by side. The ship rule of
issue 16's fine-tunes is "better than the start on most scenes", not only in the mean, which a few scenes can carry.

  /usr/bin/python3 tools/research/goal_compare.py A.json B.json
"""
import argparse, json, sys


def compare(a, b):
    """Per-scene counts and means of B's model against A's; refuses files scored on different scenes."""
    names_a, names_b = [s["scene"] for s in a["scenes"]], [s["scene"] for s in b["scenes"]]
    if names_a != names_b:
        raise ValueError(f"the two files score different scenes ({len(names_a)} and {len(names_b)})")
    pairs = [(x["model"], y["model"]) for x, y in zip(a["scenes"], b["scenes"])]
    n = len(pairs)
    return {
        "scenes": n,
        "relmse_lower": sum(y["relmse"] < x["relmse"] for x, y in pairs),
        "ssim_higher": sum(y["ssim"] > x["ssim"] for x, y in pairs),
        "mean": {k: (sum(x[k] for x, _ in pairs) / n, sum(y[k] for _, y in pairs) / n) for k in ("relmse", "ssim")},
        "cornell": {k: (a["cornell"]["model"][k], b["cornell"]["model"][k]) for k in ("relmse", "ssim")},
    }


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("a")
    p.add_argument("b")
    args = p.parse_args()
    try:
        c = compare(json.load(open(args.a)), json.load(open(args.b)))
    except (OSError, ValueError, KeyError) as e:
        print(f"goal_compare.py: {e}", file=sys.stderr)
        return 2
    print(f"B ({args.b}) against A ({args.a}), {c['scenes']} validation scenes:")
    print(f"  relMSE lower on {c['relmse_lower']}, SSIM higher on {c['ssim_higher']}")
    for k, digits in (("relmse", 6), ("ssim", 5)):
        (ma, mb), (ca, cb) = c["mean"][k], c["cornell"][k]
        print(f"  {k:6}  mean A {ma:.{digits}f}  B {mb:.{digits}f}   Cornell A {ca:.{digits}f}  B {cb:.{digits}f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
