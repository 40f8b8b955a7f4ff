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
//    counted; it never propagates into a score. Its map value is NaN. For SSIM the exclusion is a weight mask:
//    every local moment is a sum with weights gauss * mask normalised by the sum of those weights, so windows
//    cut by the image border or by excluded pixels are renormalised; where the whole window is inside the
//    image and holds no excluded pixel this is exactly the standard SSIM.
//  - With an ROI, scores and maps cover the ROI's pixels only, but SSIM windows reach outside the ROI into the
//    image, and "interior" (5 px from the border) still refers to the image border: the SSIM score is the mean
//    of the map over the ROI's interior pixels, or over all its pixels when none of them is interior.
//  - When no pixel enters (every pixel excluded, or an empty image) the scores are NaN and pixels is 0.
// All sums are accumulated in double, in parallel with oneTBB over fixed tiles whose partial sums are added
// in a fixed order (deterministic: the same bits for any thread count). SSIM is separable and works in strips
// of rows, so memory stays bounded (a few MiB per thread) whatever the image size.
#pragma once

#include <memory>
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
// Throws residue::Error(Usage) on size mismatch, fewer than 3 channels, an empty ROI or one outside the image,
// or an eps that is not a positive finite number.
Scores compare(const Image& test, const Image& reference, const Options& options = {});

// compare() band by band, for images too large to hold (a streamed denoise scored against its reference): the
// same scores, bit for bit. add() takes the rows [y0, y1) of the region, with test and reference holding rows
// [rows_y0, rows_y0 + their height) of the full image, which must cover SSIM's window: [y0 - 5, y1 + 5] within
// the image. Bands come in order from the region's top, each a multiple of kRowMultiple rows but the last.
class ScoreAccumulator {
 public:
  static constexpr int64_t kHalo = 5;
  static constexpr int64_t kRowMultiple = 64;

  ScoreAccumulator(int64_t width, int64_t height, const Options& options = {});
  ~ScoreAccumulator();
  void add(const Image& test, const Image& reference, int64_t rows_y0, int64_t y0, int64_t y1);
  Scores scores() const;  // once every row of the region was added
  Rect region() const { return region_; }

 private:
  struct Sums;
  int64_t width_, height_;
  Options options_;
  Rect region_;
  int64_t next_ = 0;
  std::unique_ptr<Sums> sums_;
};

enum class MapKind {
  AbsoluteError,         // mean over RGB of |x - r|
  SquaredError,          // mean over RGB of (x - r)^2
  RelativeSquaredError,  // mean over RGB of (x - r)^2 / (r^2 + eps): its mean is relMSE
  Ssim,                  // mean over RGB of the SSIM map: its mean (interior) is SSIM
  SignedDifference,      // mean over RGB of x - r: where the test is brighter (> 0) or darker (< 0), its bias
};
const char* to_string(MapKind kind);             // "abs", "se", "rse", "ssim", "diff"
std::optional<MapKind> map_kind_from_string(const std::string& name);

// A one-channel per-pixel map of the ROI (whole image by default); NaN where a pixel is excluded. Map values
// beyond float's range (squared fireflies) are +inf. Throws like compare().
Image error_map(const Image& test, const Image& reference, MapKind kind, const Options& options = {});

// The formulas and conventions above, as one human-readable paragraph with the eps in use.
std::string formula_text(const Options& options);

}  // namespace residue::metrics
