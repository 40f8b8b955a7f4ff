// The metrics' sums over a region, in fixed tiles of 64 x 512 pixels summed in tile order (the same bits for any
// thread count): the squared errors, and SSIM, separable in strips of rows with its 5-px halo. Internal to
// core/metrics: compare(), ScoreAccumulator and the SSIM map (metrics.h) are its users.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>

#include "core/image/image.h"
#include "core/metrics/metrics.h"

namespace residue::metrics::detail {

// Partial sums of one tile, added over tiles in tile order.
struct TileSums {
  double se = 0.0;        // sum over pixels and RGB of (x - r)^2, linear
  double rse = 0.0;       // ... of (x - r)^2 / (r^2 + eps)
  double se_space = 0.0;  // ... of (x' - r')^2 in the SSIM space
  double ssim_interior = 0.0;
  double ssim_all = 0.0;
  int64_t pixels = 0;
  int64_t interior = 0;
  int64_t excluded_test = 0;
  int64_t excluded_reference = 0;
};

// The sums of `region` of `test` against `reference`, writing the SSIM map of the region into `ssim_map` when
// given. `test` and `reference` hold rows [row0, row0 + their height) of an image `height` rows tall (a band of
// a larger image: ScoreAccumulator), or the whole image (row0 0, height -1).
TileSums region_sums(const Image& test, const Image& reference, const Options& options, const Rect& region,
                     Image* ssim_map = nullptr, int64_t row0 = 0, int64_t height = -1);
void add(TileSums& total, const TileSums& t);
// The scores the sums give (NaN when no pixel entered).
Scores scores_of(const TileSums& total);

inline bool finite_rgb(const float* p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

// double -> float for map values; values beyond float's range (squared fireflies) become +-inf explicitly.
inline float to_float(double v) {
  constexpr double kMax = std::numeric_limits<float>::max();
  if (v > kMax) return std::numeric_limits<float>::infinity();
  if (v < -kMax) return -std::numeric_limits<float>::infinity();
  return static_cast<float>(v);
}

}  // namespace residue::metrics::detail
