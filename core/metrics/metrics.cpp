#include "core/metrics/metrics.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "core/metrics/tonemap.h"
#include "core/util/error.h"

namespace residue::metrics {
namespace {

// SSIM constants (Wang et al. 2004; scikit-image with gaussian_weights=True).
constexpr int kRadius = 5;  // 11-tap window: scipy's radius int(3.5 * 1.5 + 0.5)
constexpr int kTaps = 2 * kRadius + 1;
constexpr double kSigma = 1.5;
constexpr double kK1 = 0.01;
constexpr double kK2 = 0.03;
constexpr double kDataRange = 1.0;
constexpr double kC1 = (kK1 * kDataRange) * (kK1 * kDataRange);
constexpr double kC2 = (kK2 * kDataRange) * (kK2 * kDataRange);

// Work is split into fixed tiles of the region (never dependent on the thread count, so sums are deterministic).
// Per tile, SSIM needs the tile plus a 5 px halo: with 64 x 512 tiles the scratch is about 3 MiB per thread.
constexpr int64_t kTileRows = 64;
constexpr int64_t kTileCols = 512;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The normalised 1-D Gaussian; the 2-D window is its outer product (sums to 1 up to rounding).
std::array<double, kTaps> gaussian_taps() {
  std::array<double, kTaps> g{};
  double sum = 0.0;
  for (int i = 0; i < kTaps; ++i) {
    const double d = i - kRadius;
    g[static_cast<size_t>(i)] = std::exp(-0.5 * d * d / (kSigma * kSigma));
    sum += g[static_cast<size_t>(i)];
  }
  for (double& v : g) v /= sum;
  return g;
}

const std::array<double, kTaps>& taps() {
  static const std::array<double, kTaps> g = gaussian_taps();
  return g;
}

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

bool finite_rgb(const float* p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

// double -> float for map values; values beyond float's range (squared fireflies) become +-inf explicitly.
float to_float(double v) {
  constexpr double kMax = std::numeric_limits<float>::max();
  if (v > kMax) return std::numeric_limits<float>::infinity();
  if (v < -kMax) return -std::numeric_limits<float>::infinity();
  return static_cast<float>(v);
}

double to_space(float v, SsimSpace space) {
  return space == SsimSpace::Tonemapped ? tonemap_filmic_srgb_f64(static_cast<double>(v))
                                        : static_cast<double>(v);
}

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

// Per-thread scratch for one tile, reused from tile to tile (no allocation once warm).
struct Scratch {
  // Source window (tile + halo, cut at the image border): mask and SSIM-space values, zero where excluded.
  std::vector<double> mask;
  std::array<std::vector<double>, 3> x;
  std::array<std::vector<double>, 3> y;
  // Horizontal pass, (source rows) x (tile columns): sums of g*m, g*x, g*y, g*x^2, g*y^2, g*x*y.
  std::array<std::vector<double>, 6> h;
  // Vertical pass accumulators for one output row.
  std::array<std::vector<double>, 6> v;
  // Sum over channels of the SSIM map, (tile rows) x (tile columns).
  std::vector<double> ssim;
};

void grow(std::vector<double>& buffer, size_t n) {
  if (buffer.size() < n) buffer.resize(n);
}

class Evaluator {
 public:
  // `test` and `reference` hold rows [row0, row0 + their height) of an image `height` rows tall (a band of a
  // larger image: ScoreAccumulator), or the whole image (row0 0).
  Evaluator(const Image& test, const Image& reference, const Options& options, const Rect& region,
            Image* ssim_map, int64_t row0 = 0, int64_t height = -1)
      : test_(test), ref_(reference), options_(options), region_(region), map_(ssim_map), row0_(row0),
        height_(height < 0 ? test.height() : height) {}

  Scores run() { return finish(sum()); }

  // The sums of the region's tiles (fixed 64 x 512 tiles from its corner), added in tile order.
  TileSums sum() {
    const int64_t tiles_x = (region_.width + kTileCols - 1) / kTileCols;
    const int64_t tiles_y = (region_.height + kTileRows - 1) / kTileRows;
    const int64_t tiles = tiles_x * tiles_y;
    std::vector<TileSums> sums(static_cast<size_t>(tiles));
    tbb::enumerable_thread_specific<Scratch> scratch;
    tbb::parallel_for(tbb::blocked_range<int64_t>(0, tiles, 1), [&](const tbb::blocked_range<int64_t>& range) {
      Scratch& s = scratch.local();
      for (int64_t t = range.begin(); t != range.end(); ++t) {
        const int64_t x0 = region_.x + (t % tiles_x) * kTileCols;
        const int64_t y0 = region_.y + (t / tiles_x) * kTileRows;
        const int64_t x1 = std::min(x0 + kTileCols, region_.x + region_.width);
        const int64_t y1 = std::min(y0 + kTileRows, region_.y + region_.height);
        sums[static_cast<size_t>(t)] = tile(s, x0, x1, y0, y1);
      }
    });

    TileSums total;
    for (const TileSums& t : sums) add(total, t);  // fixed order: deterministic
    return total;
  }

  static void add(TileSums& total, const TileSums& t) {
    total.se += t.se;
    total.rse += t.rse;
    total.se_space += t.se_space;
    total.ssim_interior += t.ssim_interior;
    total.ssim_all += t.ssim_all;
    total.pixels += t.pixels;
    total.interior += t.interior;
    total.excluded_test += t.excluded_test;
    total.excluded_reference += t.excluded_reference;
  }

  static Scores finish(const TileSums& total) {
    Scores scores;
    scores.pixels = total.pixels;
    scores.excluded_test = total.excluded_test;
    scores.excluded_reference = total.excluded_reference;
    if (total.pixels == 0) {
      scores.mse = scores.relmse = scores.psnr = scores.ssim = kNaN;
      return scores;
    }
    const double values = 3.0 * static_cast<double>(total.pixels);
    scores.mse = total.se / values;
    scores.relmse = total.rse / values;
    const double mse_space = total.se_space / values;
    scores.psnr = mse_space == 0.0 ? std::numeric_limits<double>::infinity()
                                   : 10.0 * std::log10(kDataRange * kDataRange / mse_space);
    scores.ssim = total.interior > 0 ? total.ssim_interior / static_cast<double>(total.interior)
                                     : total.ssim_all / static_cast<double>(total.pixels);
    return scores;
  }

 private:
  // Output pixels [x0, x1) x [y0, y1) in image coordinates.
  TileSums tile(Scratch& s, int64_t x0, int64_t x1, int64_t y0, int64_t y1) const {
    const int64_t width = test_.width();
    const int64_t height = height_;
    // The source window: every pixel any output pixel's window touches.
    const int64_t sx0 = std::max<int64_t>(0, x0 - kRadius);
    const int64_t sx1 = std::min(width, x1 + kRadius);
    const int64_t sy0 = std::max<int64_t>(0, y0 - kRadius);
    const int64_t sy1 = std::min(height, y1 + kRadius);
    const int64_t sw = sx1 - sx0;
    const int64_t sh = sy1 - sy0;
    const int64_t tw = x1 - x0;
    const int64_t th = y1 - y0;
    const size_t src_n = static_cast<size_t>(sw * sh);
    grow(s.mask, src_n);
    for (int c = 0; c < 3; ++c) {
      grow(s.x[static_cast<size_t>(c)], src_n);
      grow(s.y[static_cast<size_t>(c)], src_n);
    }
    for (auto& b : s.h) grow(b, static_cast<size_t>(sh * tw));
    for (auto& b : s.v) grow(b, static_cast<size_t>(tw));
    grow(s.ssim, static_cast<size_t>(th * tw));

    // 1. Source values in the SSIM space, and the mask.
    const int tc = test_.channels();
    const int rc = ref_.channels();
    for (int64_t r = sy0; r < sy1; ++r) {
      const float* trow = test_.row(r - row0_).data();
      const float* rrow = ref_.row(r - row0_).data();
      const int64_t base = (r - sy0) * sw - sx0;
      for (int64_t px = sx0; px < sx1; ++px) {
        const float* pt = trow + px * tc;
        const float* pr = rrow + px * rc;
        const size_t i = static_cast<size_t>(base + px);
        const bool valid = finite_rgb(pt) && finite_rgb(pr);
        s.mask[i] = valid ? 1.0 : 0.0;
        for (size_t c = 0; c < 3; ++c) {
          s.x[c][i] = valid ? to_space(pt[c], options_.ssim_space) : 0.0;
          s.y[c][i] = valid ? to_space(pr[c], options_.ssim_space) : 0.0;
        }
      }
    }

    // 2. Point metrics over the tile's own pixels.
    TileSums sums;
    for (int64_t r = y0; r < y1; ++r) {
      const float* trow = test_.row(r - row0_).data();
      const float* rrow = ref_.row(r - row0_).data();
      for (int64_t px = x0; px < x1; ++px) {
        const float* pt = trow + px * tc;
        const float* pr = rrow + px * rc;
        if (!finite_rgb(pr)) {
          ++sums.excluded_reference;
          continue;
        }
        if (!finite_rgb(pt)) {
          ++sums.excluded_test;
          continue;
        }
        ++sums.pixels;
        const size_t i = static_cast<size_t>((r - sy0) * sw + (px - sx0));
        for (size_t c = 0; c < 3; ++c) {
          const double xr = static_cast<double>(pr[c]);
          const double d = static_cast<double>(pt[c]) - xr;
          sums.se += d * d;
          sums.rse += d * d / (xr * xr + options_.eps);
          const double ds = s.x[c][i] - s.y[c][i];
          sums.se_space += ds * ds;
        }
      }
    }

    // 3. SSIM: separable weighted moments, channel by channel.
    const auto& g = taps();
    std::fill_n(s.ssim.begin(), th * tw, 0.0);
    const Span span{sx0, sw, sh, x0, x1};
    horizontal_mask(s.mask.data(), s.h[0].data(), span);
    for (size_t c = 0; c < 3; ++c) {
      horizontal_moments(s.x[c].data(), s.y[c].data(), s.h, span);
      for (int64_t r = y0; r < y1; ++r) {
        for (auto& b : s.v) std::fill_n(b.begin(), tw, 0.0);
        const int64_t dy0 = std::max<int64_t>(-kRadius, -r);
        const int64_t dy1 = std::min<int64_t>(kRadius, height - 1 - r);
        for (int64_t dy = dy0; dy <= dy1; ++dy) {
          const double w = g[static_cast<size_t>(dy + kRadius)];
          const size_t hrow = static_cast<size_t>((r + dy - sy0) * tw);
          for (size_t k = 0; k < 6; ++k) {
            double* acc = s.v[k].data();
            const double* src = s.h[k].data() + hrow;
            for (int64_t i = 0; i < tw; ++i) acc[i] += w * src[i];
          }
        }
        double* out = s.ssim.data() + (r - y0) * tw;
        const double* mrow = s.mask.data() + (r - sy0) * sw + (x0 - sx0);
        for (int64_t i = 0; i < tw; ++i) {
          if (mrow[i] == 0.0) continue;
          const size_t k = static_cast<size_t>(i);
          const double wsum = s.v[0][k];
          const double mx = s.v[1][k] / wsum;
          const double my = s.v[2][k] / wsum;
          const double vx = s.v[3][k] / wsum - mx * mx;
          const double vy = s.v[4][k] / wsum - my * my;
          const double cxy = s.v[5][k] / wsum - mx * my;
          out[i] += ((2.0 * mx * my + kC1) * (2.0 * cxy + kC2)) / ((mx * mx + my * my + kC1) * (vx + vy + kC2));
        }
      }
    }

    // 4. The map (mean over RGB) and the SSIM sums.
    for (int64_t r = y0; r < y1; ++r) {
      const double* in = s.ssim.data() + (r - y0) * tw;
      const double* mrow = s.mask.data() + (r - sy0) * sw + (x0 - sx0);
      const bool row_interior = r >= kRadius && r < height - kRadius;
      float* map_row = map_ ? map_->row(r - region_.y).data() + (x0 - region_.x) : nullptr;
      for (int64_t i = 0; i < tw; ++i) {
        if (mrow[i] == 0.0) {
          if (map_row) map_row[i] = std::numeric_limits<float>::quiet_NaN();
          continue;
        }
        const double value = in[i] / 3.0;
        if (map_row) map_row[i] = to_float(value);
        sums.ssim_all += value;
        const int64_t px = x0 + i;
        if (row_interior && px >= kRadius && px < width - kRadius) {
          sums.ssim_interior += value;
          ++sums.interior;
        }
      }
    }
    return sums;
  }

  // Horizontal Gaussian passes over the source rows, for output columns [x0, x1): out[r][x] = sum over dx of
  // g(dx) * value(x + dx, r). Taps falling outside the image are skipped (the window is cut there; the mask
  // sum renormalises it). The first sums the mask; the second a, b, a^2, b^2 and a*b of one channel.
  struct Span {
    int64_t sx0, sw, sh, x0, x1;
  };

  void horizontal_mask(const double* m, double* o, const Span& sp) const {
    const int64_t tw = sp.x1 - sp.x0;
    for (int64_t r = 0; r < sp.sh; ++r) {
      std::fill_n(o + r * tw, tw, 0.0);
      for (int64_t dx = -kRadius; dx <= kRadius; ++dx) {
        const double w = taps()[static_cast<size_t>(dx + kRadius)];
        const int64_t lo = std::max(sp.x0, -dx);
        const int64_t n = std::min(sp.x1, test_.width() - dx) - lo;
        const double* in = m + r * sp.sw + (lo + dx - sp.sx0);
        double* out = o + r * tw + (lo - sp.x0);
        for (int64_t i = 0; i < n; ++i) out[i] += w * in[i];
      }
    }
  }

  void horizontal_moments(const double* a, const double* b, std::array<std::vector<double>, 6>& h,
                          const Span& sp) const {
    const int64_t tw = sp.x1 - sp.x0;
    for (int64_t r = 0; r < sp.sh; ++r) {
      for (size_t k = 1; k < 6; ++k) std::fill_n(h[k].data() + r * tw, tw, 0.0);
      for (int64_t dx = -kRadius; dx <= kRadius; ++dx) {
        const double w = taps()[static_cast<size_t>(dx + kRadius)];
        const int64_t lo = std::max(sp.x0, -dx);
        const int64_t n = std::min(sp.x1, test_.width() - dx) - lo;
        const int64_t in_at = r * sp.sw + (lo + dx - sp.sx0);
        const int64_t out_at = r * tw + (lo - sp.x0);
        const double* pa = a + in_at;
        const double* pb = b + in_at;
        double* o1 = h[1].data() + out_at;
        double* o2 = h[2].data() + out_at;
        double* o3 = h[3].data() + out_at;
        double* o4 = h[4].data() + out_at;
        double* o5 = h[5].data() + out_at;
        for (int64_t i = 0; i < n; ++i) {
          const double va = pa[i];
          const double vb = pb[i];
          o1[i] += w * va;
          o2[i] += w * vb;
          o3[i] += w * (va * va);
          o4[i] += w * (vb * vb);
          o5[i] += w * (va * vb);
        }
      }
    }
  }

  const Image& test_;
  const Image& ref_;
  const Options& options_;
  Rect region_;
  Image* map_;
  int64_t row0_, height_;
};

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
  return Evaluator(test, reference, options, region, nullptr).run();
}

struct ScoreAccumulator::Sums : TileSums {};

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
  Evaluator e(test, reference, options_, band, nullptr, rows_y0, height_);
  Evaluator::add(*sums_, e.sum());
  next_ = y1;
}

Scores ScoreAccumulator::scores() const {
  if (next_ != region_.y + region_.height)
    throw Error(ErrorKind::Usage, "metrics: rows " + std::to_string(next_) + "-" +
                                      std::to_string(region_.y + region_.height) + " were never added");
  return Evaluator::finish(*sums_);
}

Image error_map(const Image& test, const Image& reference, MapKind kind, const Options& options) {
  const Rect region = checked_region(test, reference, options);
  if (kind != MapKind::Ssim) return point_map(test, reference, kind, options, region);
  Image map(region.width, region.height, 1);
  Evaluator(test, reference, options, region, &map).run();
  return map;
}

const char* to_string(MapKind kind) {
  switch (kind) {
    case MapKind::AbsoluteError: return "abs";
    case MapKind::SquaredError: return "se";
    case MapKind::RelativeSquaredError: return "rse";
    case MapKind::Ssim: return "ssim";
  }
  return "unknown";
}

std::optional<MapKind> map_kind_from_string(const std::string& name) {
  for (MapKind kind : {MapKind::AbsoluteError, MapKind::SquaredError, MapKind::RelativeSquaredError, MapKind::Ssim})
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
