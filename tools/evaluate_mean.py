"""One model's mean relMSE and SSIM over a data set's scenes, by `residue-cli evaluate-set`: what the fitting tools
(fit_blend_tau.py, fit_exposure_key.py) compare their candidates by."""
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
