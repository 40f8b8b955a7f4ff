// A plain cross-bilateral filter guided by the same AOVs the network reads: the baseline the trained models
// must beat, and a fast preview. Each pixel's colour becomes a weighted mean of its neighbours' colours,
// weights falling off with distance and with differences in albedo, normal and relative depth. Guides the
// stack lacks are left out. Non-finite colour counts as 0; the output is finite and non-negative.
#pragma once

#include <optional>

#include "core/aov/aov_stack.h"

namespace residue {

struct BilateralOptions {
  int radius = 7;               // window (2r+1)^2
  double sigma_spatial = 4.0;   // pixels
  double sigma_albedo = 0.1;    // per-channel albedo difference
  double sigma_normal = 0.25;   // normal vector difference
  double sigma_depth = 0.05;    // depth difference relative to the centre's depth
};

// The filtered colour, the stack's size; outside `roi` (when given) the noisy colour stays.
Image cross_bilateral(const AovStack& stack, const BilateralOptions& options = {}, std::optional<Rect> roi = {});

// The filtered colour of the pixels of `rect` into `out` (the stack's size): each pixel depends on the stack
// only, so a region filtered piece by piece equals the region filtered at once.
void cross_bilateral_rect(const AovStack& stack, const BilateralOptions& options, const Rect& rect, Image& out);

}  // namespace residue
