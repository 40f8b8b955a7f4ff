"""One model's mean relMSE and SSIM over a data set's scenes, by `residue-cli evaluate-set`: what the fitting tools
(fit_blend_tau.py, fit_exposure_key.py) compare their candidates by, and the candidates they choose among."""
import json, os, subprocess, tempfile


def mean_scores(cli, dataset, model, scenes=("--split", "validation"), options=()):
    """(mean relMSE, mean SSIM) of the model file on the scenes (evaluate-set's selection options), post-steps as
    evaluate-set runs them unless options say otherwise."""
    label = os.path.splitext(os.path.basename(model))[0]
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "eval.json")
        subprocess.run([cli, "evaluate-set", dataset, *scenes, "--models", model, *options, "--json", out, "--force"],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        row = next(r for r in json.load(open(out))["summary"] if r["label"] == label)
    return row["mean_relmse"], row["mean_ssim"]


def near_best(sweep, max_ssim_loss, relmse_tolerance):
    """Of a sweep of (mean relMSE, candidate, mean SSIM): those within max_ssim_loss of the best SSIM whose relMSE is
    within relmse_tolerance (relative) of the lowest among them; with that lowest relMSE and the best SSIM. Each
    fit picks one of them by its own rule."""
    best_ssim = max(s for _, _, s in sweep)
    eligible = [r for r in sweep if r[2] >= best_ssim - max_ssim_loss]
    lowest = min(r[0] for r in eligible)
    return [r for r in eligible if r[0] <= lowest * (1 + relmse_tolerance)], lowest, best_ssim
