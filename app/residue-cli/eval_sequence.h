// `residue-cli eval shot.####.exr -r ref.####.exr [--denoised den.####.exr] [--frames SPEC]`: every frame scored
// against its reference (relMSE, SSIM), their means, and the flicker of the sequence: the temporal relMSE
// (core/metrics/temporal.h) of the noisy and the denoised frames, and their ratio.
#pragma once

#include <optional>
#include <string>

#include "cli_common.h"

namespace residue::cli {

struct EvalSequenceOptions {
  InputOptions input;       // inputs[0] and reference are frame patterns
  std::string denoised;     // a frame pattern, or empty
  std::string frames;       // a frame spec, or empty: every frame whose input exists
  double eps = 0.01;
  std::optional<Rect> roi;
  bool json = false;
  std::string metrics_out;  // a .json file, or empty
  bool force = false;
};

int run_eval_sequence(const EvalSequenceOptions& options);

}  // namespace residue::cli
