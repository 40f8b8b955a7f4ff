// One render denoised into one EXR: what `residue-cli denoise` does for a single render and for every frame of
// a sequence (denoise_sequence.h). The output is checked before any work, the render read, denoised in memory or
// (when larger than --max-memory) streamed band by band, written atomically, and scored when a reference is
// known.
#pragma once

#include <filesystem>
#include <functional>
#include <future>
#include <memory>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.h"
#include "core/denoise/denoiser.h"
#include "core/nn/model_registry.h"
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
  float skip_converged = 0;  // 0: off
  int ensemble = 0;  // 0: the model's
  std::string compression = "zip";
  bool force = false;
  // Sequences (denoise_sequence.h)
  std::string frames;
  bool skip_existing = false;
  bool fail_fast = false;
  std::string summary;
  bool temporal = false;  // a temporal model (kDefaultTemporalModel unless -m names one), neighbours read
  bool temporal_blend = false;  // core/temporal/temporal_blend.h over frames t-1..t+1
  double blend_tolerance = 0.5;

  // The model -m names, or the default temporal model for --temporal without -m.
  std::string model_name() const;
  DenoiseOptions denoise_options() const;
  io::ExrWriteOptions write_options() const;  // without the per-render header
};

// A sequence's frames beside the one denoised, for a temporal method: the inputs of frame t + offset, or none
// where the sequence has no such frame (before its first, after its last, missing on disk).
using NeighbourInputs = std::function<std::optional<std::vector<std::filesystem::path>>(int offset)>;

// What the frames of one process share: the models, loaded once, and their backends, planned once.
struct FrameContext {
  const DenoiseCliOptions& options;
  const InterruptScope& interrupt;
  bool show_progress = true;  // a progress bar (single renders) or nothing (sequences print a line per frame)
  nn::ModelRegistry models;  // before the backends, which are keyed by the models: they go first
  BackendCache backends;
  // Frames read as a temporal method's neighbours, by their colour file, kept while the next frames need them.
  std::map<std::string, std::shared_ptr<const AovStack>> neighbour_frames;
  // --temporal-blend: frames denoised before the blend, by their colour file, kept while the next frames need
  // them (frame t's blend reads frames t-1 and t+1's), so that each is denoised once.
  struct Denoised {
    std::shared_ptr<const AovStack> stack;
    std::shared_ptr<const Image> image;
    DenoiseStats stats;
    std::vector<int> missing_neighbours;
  };
  std::map<std::string, Denoised> denoised_frames;
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
  int frame_radius = 0;                      // a temporal method's neighbours each side
  std::vector<int> missing_neighbours;       // offsets the sequence lacked (read as not valid)
  std::vector<int> blend_missing;            // --temporal-blend: the offsets of -1, +1 the sequence lacked
};

// A render read whole ahead of its turn (a sequence reads frame n+1 on its background thread while frame n is
// denoised). `stack` is null when two such renders would not fit in `max_memory` (the one denoised and the one
// read ahead): it is then read, or streamed, when its turn comes.
struct FrameRead {
  std::shared_ptr<const AovReader> reader;
  std::shared_ptr<AovStack> stack;
  double read_s = 0;
};
FrameRead read_frame_ahead(const std::vector<std::filesystem::path>& inputs, const LoadOptions& load, size_t max_memory);

// A render denoised in memory whose output is not written yet: write_frame() finishes it, on any thread. (A
// streamed render is written by then: `image` is empty and only the scores are left.)
struct FrameToWrite {
  FrameResult result;
  std::shared_ptr<const AovReader> reader;  // the render's: its reference scores the output
  std::optional<Image> image;
  io::ExrWriteOptions write;
  std::optional<Rect> roi;
};

// Throws residue::Error (nothing written), or Cancelled when interrupted before the output was complete.
// `neighbours`: for a sequence, where frame t's neighbours are (a temporal method reads them; a still's ignores
// them); null for a single render, which a temporal method denoises from its own frame alone. `ahead`: the render
// read by read_frame_ahead() (the same inputs and load options), or null to read it here.
FrameToWrite denoise_frame_image(FrameContext& context, const std::vector<std::filesystem::path>& inputs,
                                  const LoadOptions& load, const std::string& output,
                                  const NeighbourInputs* neighbours = nullptr, std::future<FrameRead>* ahead = nullptr);
// Writes the output (atomically) and scores it against the render's reference when it has one (left unscored
// when `cancel` comes first: the output is whole then).
FrameResult write_frame(FrameToWrite frame, const CancelToken& cancel);
// The two in turn.
FrameResult denoise_frame(FrameContext& context, const std::vector<std::filesystem::path>& inputs,
                          const LoadOptions& load, const std::string& output, const NeighbourInputs* neighbours = nullptr);

}  // namespace residue::cli
