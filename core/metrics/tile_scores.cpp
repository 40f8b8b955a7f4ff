#include "core/metrics/tile_scores.h"

#include <algorithm>
#include <array>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "core/metrics/tonemap.h"

namespace residue::metrics::detail {
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

double to_space(float v, SsimSpace space) {
  return space == SsimSpace::Tonemapped ? tonemap_filmic_srgb_f64(static_cast<double>(v))
                                        : static_cast<double>(v);
}

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

}  // namespace

TileSums region_sums(const Image& test, const Image& reference, const Options& options, const Rect& region,
                     Image* ssim_map, int64_t row0, int64_t height) {
  return Evaluator(test, reference, options, region, ssim_map, row0, height).sum();
}

void add(TileSums& total, const TileSums& t) { Evaluator::add(total, t); }

Scores scores_of(const TileSums& total) { return Evaluator::finish(total); }

}  // namespace residue::metrics::detail
