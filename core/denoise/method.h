// A denoising method: what a denoise runs for one model (Residue's residual networks, Open Image Denoise's
// filter with its prefilters) or for none (the cross-bilateral filter). A method decides which network passes
// run, on which images, with which post-steps; the tile engine (core/denoise/engine/) runs each pass and never
// asks which method it serves. Methods are made by the registry (method_registry.h); the entry points that run
// them, with threads, timing and progress, are in denoiser.h.
//
// Progress is a work amount over every pass (a network's FLOPs per pixel times the pixels it covers; a filter's
// taps), so that the bar of a prefiltered or post-corrected run moves once from 0 to 100 %.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "core/aov/aov_loader.h"
#include "core/aov/aov_stack.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/engine/network_pass.h"
#include "core/io/exr_writer.h"

namespace residue {

class Method {
 public:
  virtual ~Method() = default;

  virtual std::string name() const = 0;          // the model's name, or the filter's ("bilateral")
  virtual std::string architecture() const = 0;  // "8/32 full", "OIDN UNet (rt_hdr_alb_nrm)", "cross-bilateral filter"
  virtual FeatureSet features() const = 0;       // the AOVs it reads
  // The model its main pass runs, or null for a filter (the viewer sizes its tiles from the graph).
  virtual const nn::Model* model() const { return nullptr; }

  // The neighbouring frames it reads each side (stack.neighbours, core/temporal/frame_window.h): 0 for a
  // still's method; k for a temporal one, which a sequence run feeds frames t-k..t+k.
  virtual int frame_radius() const { return 0; }

  // Error(Input) naming the AOV `stack` lacks.
  virtual void check_inputs(const AovStack& stack) const = 0;
  // The work of a whole denoise of a `width` x `height` image with `options`, every pass included.
  virtual int64_t work(int64_t width, int64_t height, const DenoiseOptions& options) const = 0;
  // The denoised colour, the stack's size. Tiles are reported through `on_tile` with `work` updated.
  virtual Image denoise(const AovStack& stack, const DenoiseOptions& options, const TileCallback& on_tile,
                        DenoiseStats& stats, WorkCounter& work) const = 0;

  // Whether it can run band by band from the files (denoise_to_exr): only a method whose passes need no whole
  // image first. The others throw Error(Usage) from denoise_to_exr, saying why.
  virtual bool streams() const { return false; }
  virtual DenoiseStats denoise_to_exr(const AovReader& reader, const DenoiseOptions& options,
                                      const std::filesystem::path& output, io::ExrWriteOptions exr,
                                      const TileCallback& on_tile, WorkCounter& work) const;

  // The variance blend's tau a denoise with `options` uses where the stack has variance; 0: it does not blend.
  virtual float variance_blend_tau(const DenoiseOptions&) const { return 0.0f; }
};

// The options of a pass that runs on the whole image before the main one (a prefilter, a prior): no region,
// full strength, no self-ensemble (it runs as it was trained).
DenoiseOptions whole_image_options(const DenoiseOptions& options);

// The tile callback of a pass that runs before the result's (a prefilter, a prior): its events say that their
// pixels are not the result (TileEvent::result false), so a viewer does not draw them.
TileCallback preliminary(const TileCallback& on_tile);

// Pixels of the region a denoise with `options` covers (the ROI, else the image).
int64_t region_pixels(int64_t width, int64_t height, const DenoiseOptions& options);

// The self-ensemble's size for a model: the option, else the model's (residue.ensemble); Error(Usage) unless
// 1, 2, 4 or 8.
int ensemble_members(const DenoiseOptions& options, const nn::Model& model);

}  // namespace residue
