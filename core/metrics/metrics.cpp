#include "core/metrics/metrics.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/metrics/tile_scores.h"
#include "core/util/error.h"

namespace residue::metrics {
namespace {

using detail::finite_rgb;
using detail::to_float;

std::string size_text(const Image& image) {
  return std::to_string(image.width()) + "x" + std::to_string(image.height());
}

// Validates the inputs; returns the region to evaluate (the ROI or the whole image).
Rect checked_region(const Image& test, const Image& reference, const Options& options) {
  if (test.width() != reference.width() || test.height() != reference.height())
    throw Error(ErrorKind::Usage, "metrics: the test image is " + size_text(test) + " but the reference is " +
                                      size_text(reference) + "; both must have the same size");
  if (test.channels() < 3 || reference.channels() < 3)
    throw Error(ErrorKind::Usage, "metrics: the test image has " + std::to_string(test.channels()) +
                                      " channel(s) and the reference " + std::to_string(reference.channels()) +
                                      "; both need at least 3 (RGB)");
  if (!(options.eps > 0.0) || !std::isfinite(options.eps)) {
    std::ostringstream text;
    text << "metrics: eps must be a positive finite number, not " << options.eps;
    throw Error(ErrorKind::Usage, text.str());
  }
  if (!options.roi) return test.bounds();
  const Rect& roi = *options.roi;
  if (roi.empty())
    throw Error(ErrorKind::Usage, "metrics: the region of interest " + roi.to_string() + " (x,y,w,h) is empty");
  if (!test.bounds().contains(roi))
    throw Error(ErrorKind::Usage, "metrics: the region of interest " + roi.to_string() +
                                      " (x,y,w,h) is not inside the " + size_text(test) + " image");
  return roi;
}

// Per-pixel point maps (abs, se, rse), row-parallel.
Image point_map(const Image& test, const Image& reference, MapKind kind, const Options& options,
                const Rect& region) {
  Image map(region.width, region.height, 1);
  const int tc = test.channels();
  const int rc = reference.channels();
  const double eps = options.eps;
  tbb::parallel_for(tbb::blocked_range<int64_t>(0, region.height), [&](const tbb::blocked_range<int64_t>& rows) {
    for (int64_t r = rows.begin(); r != rows.end(); ++r) {
      const float* trow = test.row(region.y + r).data();
      const float* rrow = reference.row(region.y + r).data();
      float* out = map.row(r).data();
      for (int64_t i = 0; i < region.width; ++i) {
        const float* pt = trow + (region.x + i) * tc;
        const float* pr = rrow + (region.x + i) * rc;
        if (!finite_rgb(pt) || !finite_rgb(pr)) {
          out[i] = std::numeric_limits<float>::quiet_NaN();
          continue;
        }
        double sum = 0.0;
        for (size_t c = 0; c < 3; ++c) {
          const double xr = static_cast<double>(pr[c]);
          const double d = static_cast<double>(pt[c]) - xr;
          switch (kind) {
            case MapKind::AbsoluteError: sum += std::abs(d); break;
            case MapKind::SquaredError: sum += d * d; break;
            case MapKind::RelativeSquaredError: sum += d * d / (xr * xr + eps); break;
            case MapKind::SignedDifference: sum += d; break;
            case MapKind::Ssim: break;  // not a point map
          }
        }
        out[i] = to_float(sum / 3.0);
      }
    }
  });
  return map;
}

}  // namespace

Scores compare(const Image& test, const Image& reference, const Options& options) {
  const Rect region = checked_region(test, reference, options);
  return detail::scores_of(detail::region_sums(test, reference, options, region));
}

struct ScoreAccumulator::Sums : detail::TileSums {};

ScoreAccumulator::ScoreAccumulator(int64_t width, int64_t height, const Options& options)
    : width_(width), height_(height), options_(options), sums_(std::make_unique<Sums>()) {
  if (!(options.eps > 0.0) || !std::isfinite(options.eps))
    throw Error(ErrorKind::Usage, "metrics: eps must be a positive finite number, not " + std::to_string(options.eps));
  region_ = options.roi.value_or(Rect{0, 0, width, height});
  if (region_.empty() || !Rect{0, 0, width, height}.contains(region_))
    throw Error(ErrorKind::Usage, "metrics: the region of interest " + region_.to_string() + " (x,y,w,h) is not inside the " +
                                      std::to_string(width) + "x" + std::to_string(height) + " image");
  next_ = region_.y;
}

ScoreAccumulator::~ScoreAccumulator() = default;

void ScoreAccumulator::add(const Image& test, const Image& reference, int64_t rows_y0, int64_t y0, int64_t y1) {
  if (y0 != next_ || y1 <= y0 || y1 > region_.y + region_.height ||
      (y1 != region_.y + region_.height && (y1 - region_.y) % kRowMultiple != 0))
    throw Error(ErrorKind::Usage, "metrics: bands must follow each other from the region's top in multiples of " +
                                      std::to_string(kRowMultiple) + " rows (expected rows from " + std::to_string(next_) +
                                      ", got " + std::to_string(y0) + "-" + std::to_string(y1) + ")");
  const int64_t need0 = std::max<int64_t>(0, y0 - kHalo), need1 = std::min(height_, y1 + kHalo);
  if (test.width() != width_ || reference.width() != width_ || test.height() != reference.height() ||
      rows_y0 > need0 || rows_y0 + test.height() < need1 || test.channels() < 3 || reference.channels() < 3)
    throw Error(ErrorKind::Usage, "metrics: a band of rows " + std::to_string(y0) + "-" + std::to_string(y1) +
                                      " needs rows " + std::to_string(need0) + "-" + std::to_string(need1) + " of both "
                                      "images, " + std::to_string(width_) + " wide, with RGB");
  const Rect band{region_.x, y0, region_.width, y1 - y0};
  detail::add(*sums_, detail::region_sums(test, reference, options_, band, nullptr, rows_y0, height_));
  next_ = y1;
}

Scores ScoreAccumulator::scores() const {
  if (next_ != region_.y + region_.height)
    throw Error(ErrorKind::Usage, "metrics: rows " + std::to_string(next_) + "-" +
                                      std::to_string(region_.y + region_.height) + " were never added");
  return detail::scores_of(*sums_);
}

Image error_map(const Image& test, const Image& reference, MapKind kind, const Options& options) {
  const Rect region = checked_region(test, reference, options);
  if (kind != MapKind::Ssim) return point_map(test, reference, kind, options, region);
  Image map(region.width, region.height, 1);
  detail::region_sums(test, reference, options, region, &map);
  return map;
}

const char* to_string(MapKind kind) {
  switch (kind) {
    case MapKind::AbsoluteError: return "abs";
    case MapKind::SquaredError: return "se";
    case MapKind::RelativeSquaredError: return "rse";
    case MapKind::Ssim: return "ssim";
    case MapKind::SignedDifference: return "diff";
  }
  return "unknown";
}

std::optional<MapKind> map_kind_from_string(const std::string& name) {
  for (MapKind kind : {MapKind::AbsoluteError, MapKind::SquaredError, MapKind::RelativeSquaredError, MapKind::Ssim,
                       MapKind::SignedDifference})
    if (name == to_string(kind)) return kind;
  return std::nullopt;
}

std::string formula_text(const Options& options) {
  const bool tonemapped = options.ssim_space == SsimSpace::Tonemapped;
  const char* space = tonemapped
                          ? "tonemapped values (Hable/Uncharted-2 filmic curve normalised so that linear 11.2 maps "
                            "to 1, clamped to [0, 1], then the sRGB OETF; no exposure scale)"
                          : "linear values";
  std::ostringstream text;
  text << "MSE = mean over pixels and RGB channels of (x - r)^2 and relMSE = mean over pixels and RGB channels of "
          "(x - r)^2 / (r^2 + eps) with eps = "
       << options.eps
       << ", both on linear values (x the test image, r the reference); SSIM (Wang et al. 2004) with an 11x11 "
          "Gaussian window (sigma 1.5), K1 = 0.01, K2 = 0.03, data range 1 and population (co)variances, "
          "computed per RGB channel and averaged, on "
       << space
       << ", averaged over the pixels whose whole window lies inside the image (at least 5 pixels from its "
          "border; all pixels when there are none), windows cut by the border or by excluded pixels being "
          "renormalised; PSNR = 10 log10(1 / MSE') in dB, MSE' being the MSE of the "
       << (tonemapped ? "tonemapped" : "linear")
       << " values SSIM uses (+inf when they are identical); pixels whose test or reference value is NaN or "
          "infinite in any RGB channel are excluded from every metric and counted";
  if (options.roi) text << "; scores cover the region of interest " << options.roi->to_string() << " (x,y,w,h)";
  text << ".";
  return text.str();
}

}  // namespace residue::metrics
