// The shipped models, as the speed-versus-accuracy control lists them: one entry per model family (tiny,
// small, base, paper, and OIDN's for comparison; the -albedo-normal / -color variants are picked per render by core::find_model_for),
// with the architecture, its cost, and the validation numbers and benchmarks stored in the model files.
#pragma once

#include <QString>
#include <optional>
#include <vector>

namespace residue::ui {

struct ModelEntry {
  QString name;                   // family name, what find_model_for takes; "bilateral" for the baseline,
                                  // "oidn" / "oidn-cleanaux" for Open Image Denoise's networks
  QString path;                   // the full-feature file (empty for the baseline)
  int blocks = 0, width = 0;
  QString architecture;           // "8/32", "OIDN UNet"
  double gflop_per_mp = 0;        // network cost per megapixel
  std::optional<double> val_relmse, val_ssim, noisy_relmse;  // from the "validation" metadata
  std::optional<double> s_per_mp_fp32, s_per_mp_bf16;        // from the "benchmark" metadata
  QString benchmark_machine;
  QString variants;               // e.g. "full, color+albedo+normal, color"
  bool baseline() const { return path.isEmpty(); }
};

// Scans $RESIDUE_MODEL_PATH and the shipped models folders (core/util/resources.h); unreadable files are
// skipped with a warning in `problems`. Sorted by cost, the cross-bilateral baseline first; Open Image
// Denoise's networks (when installed in a models folder's oidn/) last, as the yardstick.
std::vector<ModelEntry> scan_models(QStringList* problems = nullptr);

}  // namespace residue::ui
