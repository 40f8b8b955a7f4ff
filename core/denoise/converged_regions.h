// Work only where the scene needs it: where a render has already converged (an adaptive sampler stopped early,
// a flat sky, a lit wall at many samples) the noisy colour is kept as it is, and the network runs on a few
// rectangles that cover the rest (DenoiseOptions::skip_converged).
//
// A pixel is converged when its relative variance over the variance blend's 7 x 7 box (variance_blend.h:
// rv = box(var) / (box(lum)^2 + eps)) is at most the threshold: rv is the relMSE the pixel has as it is, so a
// threshold below the model's own error keeps pixels that the network would not improve. The image is judged
// in blocks of kBlock px: a block needs the network when any pixel of it is not converged (or not finite).
// Around those blocks the result fades from the denoised colour to the noisy one over kFeather px, so no seam
// shows where they meet; the rectangles cover the blocks with that border.
//
// The rectangles are chosen for what they cost the network: each one computes its area grown by the network's
// halo on every side (as a tile does, tiling.h), so two rectangles beat their bounding box only when the gap
// between them is worth more than the halos they add. Two searches run and the cheaper plan is kept: cutting the
// covered blocks' bounding box in two at the cut that lowers that cost most, again in each part, until no cut
// lowers it; and merging the rows' runs of covered blocks two at a time while a merge lowers it (which finds
// what no single cut opens, such as noise all round a converged middle). Rectangles may overlap.
#pragma once

#include <cstdint>
#include <vector>

#include "core/aov/aov_stack.h"
#include "core/image/image.h"

namespace residue {

struct ConvergedPlan {
  static constexpr int64_t kBlock = 16;
  static constexpr int64_t kFeather = 16;

  std::vector<Rect> regions;  // where the network runs (inside the region planned); none: all converged
  Image weight;               // one channel, the region's size: 1 the denoised colour, 0 the noisy, between: a fade
  int64_t kept_pixels = 0;    // pixels of the region whose weight is 0 (the noisy colour as it is)
  int64_t network_pixels = 0; // pixels the regions' networks compute, halos included (the cost minimised)
};

// The plan for `region` (image pixels) of `stack`, which must have a variance AOV; `halo`: the network's
// receptive field (0 for a filter). A region with nothing converged gives one rectangle, the region itself.
ConvergedPlan plan_converged(const AovStack& stack, const Rect& region, float threshold, int64_t halo);

// The pixels of `regions` grown by `halo` on every side, cut to `bounds`: what their networks compute.
int64_t network_pixels(const std::vector<Rect>& regions, int64_t halo, const Rect& bounds);

}  // namespace residue
