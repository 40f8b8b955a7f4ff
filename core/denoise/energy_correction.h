// Energy correction: puts back the brightness that networks trained with L1 on log colour take away.
//
// L1 on log colour estimates the median of the log; in very noisy dark regions that lies below the mean, and
// a 4-spp interior loses 7-8 % of its energy (docs/research/MODELS_HISTORY.md, "Studies"). The noisy input is an unbiased
// estimate of the image, and over a wide window its noise averages out, so the output is rescaled per channel
// by blur(noisy) / blur(output):
//
//   out'(p) = out(p) * G(noisy)(p) / G(out)(p),   G: Gaussian, sigma 16 px, normalised over the region
//
// computed on a grid of 8 x 8 blocks (block sums blurred with sigma two blocks, the ratio interpolated
// bilinearly between block centres): within 1 % of the full-resolution blur per pixel, at 0.5 bytes per pixel. Extremes stay local:
// noisy values are clamped to +-16 x the output's luminance at the pixel (a 1e6 firefly brightens its
// surroundings by a few percent, not a thousandfold), non-finite noisy pixels are left out, and the ratio is
// clamped to [1/4, 4]. Rows can be added and corrected band by band, so streamed denoising uses it too.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image/image.h"

namespace residue {

class EnergyCorrection {
 public:
  static constexpr int64_t kBlock = 8;          // pixels per grid block edge
  static constexpr double kSigmaBlocks = 2.0;   // blur sigma, in blocks (16 px)
  static constexpr int kRadiusBlocks = 6;       // blur support, in blocks (3 sigma)
  static constexpr size_t kBytesPerBlock = 32;  // sizeof(Sums), for memory budgets
  static constexpr float kFireflyClamp = 16.0f;
  static constexpr float kMaxRatio = 4.0f;

  // Corrects the pixels of `region` (image coordinates).
  explicit EnergyCorrection(const Rect& region);

  // Adds rows [y0, y0 + rows) of the region (clipped to it). `noisy` and `denoised` are full-width images
  // whose first rows are image rows `noisy_y0` and `denoised_y0`.
  void accumulate(const Image& noisy, int64_t noisy_y0, const Image& denoised, int64_t denoised_y0, int64_t y0,
                  int64_t rows);

  // The image row up to which rows must have been accumulated before rows [.., y_end) can be corrected.
  int64_t rows_required(int64_t y_end) const;

  // Rescales rows [y0, y0 + rows) of the region in `denoised` (a full-width image starting at image row
  // `denoised_y0`). Needs rows up to rows_required(y0 + rows) accumulated.
  void apply(Image& denoised, int64_t denoised_y0, int64_t y0, int64_t rows) const;

 private:
  struct Sums {  // one block (float: 64 values each; the blur adds them in double)
    float noisy[3] = {0, 0, 0};
    float output[3] = {0, 0, 0};
    float noisy_count = 0;
    float output_count = 0;
  };
  Sums& block(int64_t bx, int64_t by) { return blocks_[static_cast<size_t>(by * grid_w_ + bx)]; }
  // The per-channel ratio of blurred sums for block rows [by0, by1), 3 floats per block.
  std::vector<float> ratios(int64_t by0, int64_t by1) const;

  Rect region_;
  int64_t grid_w_ = 0, grid_h_ = 0;
  std::vector<Sums> blocks_;
  std::vector<double> weights_;  // Gaussian taps 0..kRadiusBlocks
  static_assert(sizeof(Sums) == kBytesPerBlock);
};

}  // namespace residue
