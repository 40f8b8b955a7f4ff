// NVIDIA's FLIP image-difference evaluator (Andersson et al., HPG 2020: LDR-FLIP; EG 2021: HDR-FLIP) as its
// reference implementation computes it (NVlabs/flip v1.6): the error a viewer notices when flipping between a
// test image and its reference, per pixel in [0, 1], from a colour difference of the images filtered by the eye's
// contrast sensitivity (CSF, in YCxCz; HyAB on Hunt-adjusted L*a*b*) and a difference of their edges and points.
//   - LDR-FLIP compares display-referred linear RGB in [0, 1] (values outside are clamped).
//   - HDR-FLIP compares linear renders: both images are exposed over the reference's range (from its maximum
//     and median luminance), tone mapped with ACES and compared by LDR-FLIP at each exposure; a pixel's error is
//     the largest over the exposures.
// Viewing conditions: 67.02 pixels per degree (0.7 m from a 0.7 m wide 3840-px display), as the reference code's
// default. Borders clamp to the edge in every filter. Computed in double (the reference code uses float: the
// means agree to about 1e-6, per-pixel values to about 1e-5).
//
// Unlike the reference code, a pixel whose test or reference value is NaN or Inf in any RGB channel is read as 0
// by the filters, its map value is NaN and it is left out of the mean and counted, as every other metric here
// does (metrics.h); the exposure range is taken from the reference's finite pixels.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "core/image/image.h"

namespace residue::metrics {

inline constexpr double kFlipPixelsPerDegree = 67.0206451;

struct FlipExposures {
  double start = 0, stop = 0;  // log2 exposures, both ends included
  int count = 0;
};

struct FlipOptions {
  double pixels_per_degree = kFlipPixelsPerDegree;
  // HDR-FLIP: each given value replaces the one computed from the reference; the others are computed.
  std::optional<double> start_exposure, stop_exposure;
  std::optional<int> exposures;
};

struct FlipResult {
  Image map;           // one channel in [0, 1]; NaN where a pixel is excluded
  Image exposure_map;  // HDR-FLIP: i / (n - 1) of the first exposure that gave the pixel's error; empty for LDR
  FlipExposures exposures;  // HDR-FLIP's
  double mean = 0;     // of the map over the pixels that entered; NaN when none did
  int64_t pixels = 0;  // pixels that entered the mean
  int64_t excluded = 0;
};

// The first three channels of `test` against `reference` (same size). Throws Error(Usage) on a size mismatch,
// fewer than 3 channels, or pixels per degree that are not positive.
FlipResult ldr_flip(const Image& test, const Image& reference, const FlipOptions& options = {});
// Also throws Error(Usage) when the exposure range cannot be made (a reference without a pixel of positive
// luminance, fewer than 2 exposures asked for, a start after the stop).
FlipResult hdr_flip(const Image& test, const Image& reference, const FlipOptions& options = {});

// HDR-FLIP's exposures for `reference`: start = log2(x / max luminance), stop = log2(x / median luminance) where
// the ACES curve maps x to 0.85, count = max(2, ceil(stop - start)); the median is the element of rank N/2 (the
// upper middle one). A reference whose median luminance is not positive (half of it black) takes the median of
// its pixels of positive luminance instead, where the reference code would give an infinite stop.
FlipExposures flip_exposures(const Image& reference, const FlipOptions& options = {});

// The mean of a FLIP map over `region` (the whole map when empty), its NaN pixels left out; NaN when none is left.
double flip_mean(const Image& map, const std::optional<Rect>& region = std::nullopt);

// What HDR-FLIP computes, as one sentence with the exposures used (for reports, as formula_text).
std::string flip_formula_text(const FlipExposures& exposures);

}  // namespace residue::metrics
