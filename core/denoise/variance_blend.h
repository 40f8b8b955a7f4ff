// Variance blend: keeps the noisy input where it is already clean.
//
// A network trained for a few hours smooths away detail that a low-noise input still has (on the clean
// validation scenes the models were worse than their input). Where the render says how noisy each pixel is
// (a variance AOV, or a data set's two halves), the output is mixed back towards the input:
//
//   out' = w out + (1 - w) noisy,   w = rv / (rv + tau),   rv = box(var) / (box(lum noisy)^2 + eps)
//
// rv is the relative variance of the colour estimate over a 7 x 7 box (var: the mean of its channels; eps =
// 0.01, relMSE's). tau stands for the network's own relative error, the other side of an inverse-variance
// mix: a pixel whose relative standard error is sqrt(tau) (3 % for the default 0.001) keeps half of the
// network's output, a noisier one nearly all of it. A better model needs a smaller tau, so a model file may
// carry its own (metadata residue.blend_tau; 0 when the blend costs it more than it gains, as for a model that
// beats the input everywhere: then none is applied). Non-finite noisy or variance values keep the output.
// Per tile, reading only the tile and 3 pixels around it, so tiled, untiled and streamed outputs agree.
#pragma once

#include <map>
#include <string>

#include "core/aov/aov_stack.h"
#include "core/image/image.h"

namespace residue {

struct VarianceBlend {
  // Measured with `small` (relMSE, two halves' variance): 0.001 lowers it 7 % on the project's validation
  // scenes and 1 % on the starter set's; 0.003 lowers the first 12 % but raises the second 1 %, 0.005 by 14 %
  // on its clean scenes.
  static constexpr float kTau = 0.001f;
  static constexpr int kRadius = 3;
  static constexpr float kEps = 0.01f;
};

// Blends the pixels of `tile` (image coordinates, inside `bounds`) in `out`, whose pixel (0, 0) is image pixel
// (out_x0, out_y0). `src` holds the image's pixels of `src_rect`, which covers the tile and kRadius pixels
// around it where `bounds` has them; it must have a variance AOV.
void blend_by_variance(const AovStack& src, const Rect& src_rect, const Rect& bounds, const Rect& tile, Image& out,
                       int64_t out_x0, int64_t out_y0, float tau = VarianceBlend::kTau);

// The model's tau (metadata residue.blend_tau; 0: no blend), else the default.
float blend_tau(const std::map<std::string, std::string>& model_metadata);

}  // namespace residue
