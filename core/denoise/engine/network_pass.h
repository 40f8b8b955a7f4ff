// One network run over an image: the unit a method is built from (a prefilter, a prior, the main network).
// The method decides what the tile engine does around its network; the engine never asks which method it is.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>

#include "core/aov/aov_stack.h"
#include "core/denoise/engine/network_io.h"
#include "core/nn/model_file.h"

namespace residue {

struct NetworkPass {
  const nn::Model* model = nullptr;  // its graph (what the backend runs) and its name (for messages)
  AovRole replaces = AovRole::Color;  // the image its output replaces (an OIDN prefilter: the albedo or normal)
  bool skip_empty = false;            // pass through tiles whose colour (with halo) is all zero
  bool guard = false;                 // clamp overshoots to the receptive field's brightest input (output_guard.h)
  bool energy_correction = false;     // rescale to the noisy input's local mean (energy_correction.h)
  float blend_tau = 0;                // the variance blend's tau (when the stack has variance); 0: off
  float strength = 1.0f;              // the blend towards the noisy colour, last (strength.h); colour only
  int ensemble = 1;                   // self-ensemble members (DenoiseOptions::ensemble)
  int turned_normal_plane = -1;       // the input plane the ensemble turns as a view-space normal's x, or -1
  // The transform from AOVs to the network's planes and back, made once the whole image is measured.
  bool needs_exposure = false, needs_depth = false;
  std::function<std::unique_ptr<NetworkIO>(const WholeImageStats&)> make_io;

  // Work units of one pixel of the pass (its network's FLOPs, times the ensemble): progress is a work amount
  // over every pass of a denoise, so a prefiltered run's bar moves evenly from 0 to 100 %.
  int64_t work_per_pixel() const;
};

// Progress over every pass of one denoise (tiles of this pass; work of all).
struct WorkCounter {
  int64_t done = 0, total = 0;
};

}  // namespace residue
