// Running a denoise: the options, the progress events, the statistics, and the entry points that run a method
// (method.h) on a stack in memory or band by band from the files to an EXR, on the calling thread.
//
// The image (or the ROI) is cut into square tiles (engine/tiling.h); each tile is extended by a halo equal to the
// network's receptive field, run through the backend, and only its centre is kept, so tiled output equals
// untiled output; the guard bounds it by the brightest input within that halo. Tiles run one after another,
// each using every allowed thread; where the render has a variance AOV each tile is blended back towards its
// clean input pixels. Then, unless turned off, the energy correction rescales the region to the noisy input's
// local mean, and a strength below 1 blends the result back towards the noisy colour.
#pragma once

#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>

#include "core/aov/aov_loader.h"
#include "core/aov/aov_stack.h"
#include "core/denoise/engine/tiling.h"
#include "core/io/exr_writer.h"
#include "core/nn/backend.h"
#include "core/nn/model_file.h"
#include "core/util/cancel.h"

namespace residue {

class Method;

// Backends kept from one denoise to the next (the frames of a sequence, a viewer's runs): each keeps the tile
// sizes it planned (oneDNN's primitives), so only the first frame pays for them. Keyed by the model object: keep
// the models alive while the cache is used. One denoise at a time.
class BackendCache {
 public:
  nn::Backend& get(const nn::Model& model, const std::string& backend, nn::Precision precision);

 private:
  std::map<std::tuple<const nn::Model*, std::string, nn::Precision>, std::unique_ptr<nn::Backend>> backends_;
};

struct DenoiseOptions {
  std::string backend;                          // empty: nn::default_backend(precision)
  nn::Precision precision = nn::Precision::FP32;
  int64_t tile = 0;                             // tile edge without halo; 0: the largest that fits max_memory
  size_t max_memory = size_t{4} << 30;          // bytes for tiles, backend scratch and the output
  int threads = 0;                              // 0: every core
  std::optional<Rect> roi;                      // denoise only this rectangle; elsewhere the noisy colour
  bool skip_empty_tiles = true;                 // pass through tiles whose colour (with halo) is all zero
  bool output_guard = true;                     // clamp overshoots to the receptive field's max (output_guard.h)
  bool energy_correction = true;                // rescale to the noisy input's local mean (energy_correction.h)
  bool variance_blend = true;                   // with a variance AOV: keep clean input pixels (variance_blend.h)
  float blend_tau = 0;                          // the blend's tau; 0: the model's (residue.blend_tau) or the default
  float strength = 1.0f;                        // 1: the output; 0: the noisy input; between: blend (strength.h)
  // With a variance AOV: keep the noisy colour where its relative variance is at most this, and run the method
  // only on rectangles covering the rest (converged_regions.h). 0: off.
  float skip_converged = 0;
  // The self-ensemble: the network runs on each tile under the first 1, 2, 4 or 8 flips and transposes
  // (core/image/dihedral.h; normals turned with the image) and the mean of its outputs, turned back, is kept:
  // that many times the network's work for a lower error (measured in docs/MODELS.md). 0: the model's.
  int ensemble = 0;
  const CancelToken* cancel = nullptr;          // raised: stop within one network layer, throwing Cancelled
  BackendCache* backends = nullptr;             // reuse backends across calls; null: made for this call
};

struct TileEvent {
  Rect rect;          // the tile's pixels in the output
  bool skipped = false;
  int64_t done = 0;   // tiles of this pass finished so far, this one included
  int64_t total = 0;  // tiles of this pass
  // Work of the whole denoise, every pass (a prefilter's, a prior's) included: the fraction to show.
  int64_t work_done = 0, work_total = 0;
  bool result = true;  // the pixels are the denoise's result (false: a prefilter's albedo, a prior's colour)
};

struct DenoiseStats {
  int64_t tiles = 0;
  int64_t skipped = 0;
  int64_t tile_size = 0;
  int ensemble = 1;  // members of the self-ensemble
  double seconds = 0;
  std::string backend;  // the backend's description
  FeatureSet features = FeatureSet::Full;
  bool energy_corrected = false;
  bool variance_blended = false;  // the option was on and the render has variance
  int64_t guarded_values = 0;     // output values the guard clamped (channels, not pixels)
  int64_t clamped_to_half = 0;    // denoise_to_exr into half: finite values beyond 65504 written as 65504
  float strength = 1.0f;          // the blend towards the noisy colour applied last (strength.h)
  // skip_converged: its threshold (0: off), the pixels kept as the noisy colour, the rectangles the method
  // ran on (1: the region), and the pixels those computed, halos included (what the time follows).
  float skip_converged = 0;
  int64_t converged_pixels = 0;
  int64_t regions = 1;
  int64_t network_pixels = 0;
};

// Called after every tile with its denoised pixels (before the energy correction and the strength, which run per
// band of tiles); return false to cancel (stops after that tile; a CancelToken in the options stops sooner).
using TileCallback = std::function<bool(const TileEvent&, const Image& output)>;

// The denoised colour, the stack's size: `method` run with `options` (threads, timing, progress). Throws Error
// (Input when the stack lacks the method's AOVs, Usage for bad options), or Cancelled.
Image denoise(const AovStack& stack, const Method& method, const DenoiseOptions& options,
              const TileCallback& on_tile = {}, DenoiseStats* stats = nullptr);
// The same with the method that runs `model` (method_registry.h).
Image denoise(const AovStack& stack, const nn::Model& model, const DenoiseOptions& options,
              const TileCallback& on_tile = {}, DenoiseStats* stats = nullptr);

// The variance blend's tau a denoise with these options uses (when the stack has variance); 0 when the blend is
// off: unasked, a model that keeps its whole output (residue.blend_tau 0), or not a Residue network (OIDN's
// networks have their own post-processing; a post-correction's prior is cleaner than the input it would keep).
float variance_blend_tau(const DenoiseOptions& options, const nn::Model& model);

// The same denoise, streamed: the render is read band by band (rows of tiles with their halos) and the EXR is
// written band by band, so memory stays within options.max_memory whatever the image size (a 16K x 16K render
// in 4 GiB). `exr` says how to write (its data/display windows and metadata are taken from the reader when
// unset). Cancelling leaves no file. Both run the same tile engine (bands of tiles pulled from a source: the
// stack in memory, or the files), so the output equals denoise()'s. Error(Usage) for a method that needs the
// whole image first (Method::streams()).
DenoiseStats denoise_to_exr(const AovReader& reader, const Method& method, const DenoiseOptions& options,
                            const std::filesystem::path& output, io::ExrWriteOptions exr, const TileCallback& on_tile = {});
DenoiseStats denoise_to_exr(const AovReader& reader, const nn::Model& model, const DenoiseOptions& options,
                            const std::filesystem::path& output, io::ExrWriteOptions exr, const TileCallback& on_tile = {});

}  // namespace residue
