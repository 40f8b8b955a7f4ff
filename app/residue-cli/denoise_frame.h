// One render denoised into one EXR: what `residue-cli denoise` does for a single render and for every frame of
// a sequence (denoise_sequence.h). The output is checked before any work, the render read, denoised in memory or
// (when larger than --max-memory) streamed band by band, written atomically, and scored when a reference is
// known.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.h"
#include "core/denoise/denoiser.h"
#include "core/nn/model_cache.h"
#include "core/io/exr_writer.h"
#include "core/io/metrics_report.h"
#include "interrupt.h"

namespace residue::cli {

struct DenoiseCliOptions {
  InputOptions input;
  std::string output;
  std::string model = nn::kDefaultModel;
  std::string backend;
  std::string precision = "fp32";
  int64_t tile = 0;
  int threads = 0;
  std::string roi;
  size_t max_memory_mib = 4096;
  bool no_skip = false;
  bool no_energy_correction = false;
  bool no_variance_blend = false;
  bool float_output = false;
  float strength = 1.0f;
  int ensemble = 0;  // 0: the model's
  std::string compression = "zip";
  bool force = false;
  // Sequences (denoise_sequence.h)
  std::string frames;
  bool skip_existing = false;
  bool fail_fast = false;
  std::string summary;

  DenoiseOptions denoise_options() const;
  io::ExrWriteOptions write_options() const;  // without the per-render header
};

// What the frames of one process share: the models, loaded once, and their backends, planned once.
struct FrameContext {
  const DenoiseCliOptions& options;
  const InterruptScope& interrupt;
  bool show_progress = true;  // a progress bar (single renders) or nothing (sequences print a line per frame)
  nn::ModelCache models;  // before the backends, which are keyed by the models: they go first
  BackendCache backends;
};

struct FrameResult {
  std::string output;
  std::string model, architecture;
  DenoiseStats stats;
  double megapixels = 0;
  double read_s = -1, write_s = -1;  // in-memory runs
  bool streamed = false;
  std::optional<io::MetricsReport> metrics;  // noisy and denoised rows, when the render has a reference
  std::vector<std::string> notes;            // the loader's
};

// Throws residue::Error (nothing written), or Cancelled when interrupted before the output was complete.
FrameResult denoise_frame(FrameContext& context, const std::vector<std::filesystem::path>& inputs,
                          const LoadOptions& load, const std::string& output);

}  // namespace residue::cli
