// Open Image Denoise's RT filter around its network, as OIDN 2.4 does it, so that `-m oidn` is OIDN's result
// (a baseline to compare with), not an approximation of it:
//   - autoexposure (HDR): 0.18 / the geometric mean of the mean luminance of bins of at most 16 x 16 pixels
//     (bins with luminance <= 1e-8 left out); the input is scaled by it and the output by its inverse;
//   - colour: NaN -> 0, clamped to [0, FLT_MAX] (HDR) or [0, 1] (LDR), then the transfer function: PU (a fit of
//     the perceptually uniform curve, normalised so that 65504 maps to 1) for HDR, sRGB for LDR;
//   - albedo clamped to [0, 1]; normal clamped to [-1, 1] and mapped to [0, 1]; input planes in that order;
//   - output: NaN -> 0, clamped to >= 0, inverse transfer, scaled back.
// An albedo or normal prefilter (OIDN's clean-aux mode) takes that image alone: albedo through sRGB, normal
// linear and signed.
#pragma once

#include <cstdint>
#include <vector>

#include "core/aov/aov_stack.h"
#include "core/image/image.h"
#include "core/nn/model_file.h"

namespace residue {

// OIDN's transfer functions (PU normalised, sRGB, linear).
float oidn_pu_forward(float y);
float oidn_pu_inverse(float x);

// The autoexposure over a whole image, fed band by band (for streamed renders) or at once.
class OidnAutoexposure {
 public:
  OidnAutoexposure(int64_t width, int64_t height);
  // Rows [y0, y0 + colour.height()) of the image's colour.
  void add(const Image& colour, int64_t y0);
  // The input scale (at most 1e38); 1 when every bin is black. Bins below 1e-8 are left out of the mean as
  // black, as OIDN does, in any image whose brightest bin reaches 1e-3; in a dimmer one, bins below 1e-5 x its
  // brightest, so that it is exposed like the same image at any brightness (OIDN leaves an image whose every
  // bin is below 1e-8, e.g. a render scaled by 1e-10, unexposed, and its network then adds its bias as light).
  float scale() const;

 private:
  int64_t w_, h_, bins_x_, bins_y_;
  std::vector<int64_t> bin_of_x_, bin_of_y_;
  std::vector<double> sum_;
};
float oidn_autoexposure(const Image& colour);

// How one OIDN network is fed and read.
class OidnTransform {
 public:
  // `input_scale`: the autoexposure for HDR colour, else 1.
  OidnTransform(const nn::OidnInputs& inputs, float input_scale);
  int channels() const;
  // The input planes of rectangle r of `stack` (stack coordinates): colour, albedo, normal as the network takes.
  // A prefilter reads the stack's albedo or normal.
  void input(const AovStack& stack, const Rect& r, Image& planes) const;
  // The linear value of one raw output value.
  float output(float v) const;

 private:
  nn::OidnInputs in_;
  float scale_;
  enum class Transfer { Linear, Srgb, Pu } tf_;
  float forward(float v) const;
};

}  // namespace residue
