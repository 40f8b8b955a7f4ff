#include "core/denoise/strength.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/util/error.h"

namespace residue {

void check_strength(float strength) {
  if (!(strength >= 0.0f && strength <= 1.0f))
    throw Error(ErrorKind::Usage, "strength " + std::to_string(strength) + " is outside [0, 1] (0: the noisy input, "
                                  "1: the denoised output)");
}

void apply_strength(const Image& noisy, int64_t noisy_y0, Image& out, int64_t out_y0, const Rect& region, int64_t y0,
                    int64_t rows, float strength) {
  check_strength(strength);
  if (strength == 1.0f) return;
  const int64_t r0 = std::max(y0, region.y), r1 = std::min(y0 + rows, region.y + region.height);
  const int channels = std::min(noisy.channels(), out.channels());
  for (int64_t y = r0; y < r1; ++y)
    for (int64_t x = region.x; x < region.x + region.width; ++x)
      for (int c = 0; c < channels; ++c) {
        const float n = noisy.at(x, y - noisy_y0, c);
        float& o = out.at(x, y - out_y0, c);
        if (std::isfinite(n)) o = strength * o + (1.0f - strength) * n;
      }
}

Image with_strength(const Image& noisy, const Image& denoised, float strength) {
  if (noisy.width() != denoised.width() || noisy.height() != denoised.height())
    throw Error(ErrorKind::Usage, "strength: the noisy and denoised images differ in size");
  Image out = denoised;
  apply_strength(noisy, 0, out, 0, out.bounds(), 0, out.height(), strength);
  return out;
}

}  // namespace residue
