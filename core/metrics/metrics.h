// Image quality metrics of a test image against a reference: MSE, relMSE, PSNR, SSIM, and per-pixel maps.
//
// Conventions (printed with every report, see formula_text()):
//  - relMSE = mean over pixels and RGB channels of (x - r)^2 / (r^2 + eps), eps = 0.01 by default.
//  - MSE = mean over pixels and RGB of (x - r)^2, on linear values.
//  - SSIM: Gaussian window 11x11, sigma 1.5, K1 = 0.01, K2 = 0.03, data range 1, computed per channel and
//    averaged; on tonemapped values (tonemap.h) by default, on linear values on request. The score is the mean
//    of the SSIM map over pixels whose whole window lies inside the image (as Wang et al. and scikit-image);
//    images smaller than the window use every pixel, with the window cut at the border and renormalised.
//  - PSNR = 10 log10(1 / MSE') where MSE' is the MSE on the same values SSIM uses (tonemapped by default).
//  - A pixel whose test or reference value is NaN or Inf in any channel is excluded from every metric and
//    counted; it never propagates into a score. Its map value is NaN.
// All sums are accumulated in double, rows in parallel with oneTBB, in a fixed order (deterministic).
#pragma once

#include <optional>
#include <string>

#include "core/image/image.h"

namespace residue::metrics {

enum class SsimSpace { Tonemapped, Linear };

struct Options {
  double eps = 0.01;                            // relMSE denominator offset
  SsimSpace ssim_space = SsimSpace::Tonemapped;  // also the space of PSNR
  std::optional<Rect> roi;                      // whole image when empty
};

struct Scores {
  double mse = 0;     // linear
  double relmse = 0;  // linear, with Options::eps
  double psnr = 0;    // dB, on the SSIM space; +inf for identical images
  double ssim = 0;
  int64_t pixels = 0;                 // pixels that entered the scores
  int64_t excluded_test = 0;          // pixels excluded because the test image is not finite there
  int64_t excluded_reference = 0;     // ... because the reference is not finite there (counted first)
};

// Compares the first three channels of `test` against `reference` (same size, >= 3 channels).
// Throws residue::Error(Usage) on size mismatch or an ROI outside the image.
Scores compare(const Image& test, const Image& reference, const Options& options = {});

enum class MapKind {
  AbsoluteError,         // mean over RGB of |x - r|
  SquaredError,          // mean over RGB of (x - r)^2
  RelativeSquaredError,  // mean over RGB of (x - r)^2 / (r^2 + eps): its mean is relMSE
  Ssim,                  // mean over RGB of the SSIM map: its mean (interior) is SSIM
};
const char* to_string(MapKind kind);             // "abs", "se", "rse", "ssim"
std::optional<MapKind> map_kind_from_string(const std::string& name);

// A one-channel per-pixel map of the ROI (whole image by default); NaN where a pixel is excluded.
Image error_map(const Image& test, const Image& reference, MapKind kind, const Options& options = {});

// The formulas and conventions above, as one human-readable paragraph with the eps in use.
std::string formula_text(const Options& options);

}  // namespace residue::metrics
