#include "core/denoise/energy_correction.h"

#include <algorithm>
#include <cfloat>
#include <cmath>

#include <tbb/parallel_for.h>

namespace residue {
namespace {

// Where a pixel falls between block centres: blocks lo and hi = lo + 1, weight f of hi. Within half a block of
// the region's edge, beyond the outermost centres, the two outermost blocks extrapolate (f < 0 or f > 1):
// holding the edge block's value there would flatten a gradient at the border.
struct Lerp {
  int64_t lo = 0, hi = 0;
  float f = 0;
};

Lerp lerp_at(int64_t pixel, int64_t blocks) {
  if (blocks < 2) return {0, 0, 0};
  const double u = (static_cast<double>(pixel) + 0.5) / EnergyCorrection::kBlock - 0.5;
  const int64_t lo = std::clamp<int64_t>(static_cast<int64_t>(std::floor(u)), 0, blocks - 2);
  return {lo, lo + 1, static_cast<float>(u - static_cast<double>(lo))};
}

float luminance(const float* p) { return 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2]; }

// A block sums its values divided by its pixel count (a power of two: exact), so that a block of values near
// the float range (legal in a float EXR) sums to a finite value instead of Inf, whose ratio would be NaN. Noisy
// and output sums are scaled alike, so the ratios are the same bits as unscaled sums would give.
constexpr float kPerPixel = 1.0f / static_cast<float>(EnergyCorrection::kBlock * EnergyCorrection::kBlock);
static_assert(EnergyCorrection::kBlock == 8, "kPerPixel must stay a power of two");

}  // namespace

EnergyCorrection::EnergyCorrection(const Rect& region) : region_(region) {
  grid_w_ = (region.width + kBlock - 1) / kBlock;
  grid_h_ = (region.height + kBlock - 1) / kBlock;
  blocks_.resize(static_cast<size_t>(std::max<int64_t>(0, grid_w_ * grid_h_)));
  for (int d = 0; d <= kRadiusBlocks; ++d) weights_.push_back(std::exp(-0.5 * d * d / (kSigmaBlocks * kSigmaBlocks)));
}

void EnergyCorrection::accumulate(const Image& noisy, int64_t noisy_y0, const Image& denoised, int64_t denoised_y0,
                                  int64_t y0, int64_t rows) {
  const int64_t first = std::max(y0, region_.y), end = std::min(y0 + rows, region_.y + region_.height);
  if (end <= first) return;
  const int64_t by_first = (first - region_.y) / kBlock, by_end = (end - 1 - region_.y) / kBlock + 1;
  // One task per block row: no two tasks touch the same block.
  tbb::parallel_for(by_first, by_end, [&](int64_t by) {
    const int64_t y_begin = std::max(first, region_.y + by * kBlock);
    const int64_t y_stop = std::min(end, region_.y + (by + 1) * kBlock);
    for (int64_t y = y_begin; y < y_stop; ++y)
      for (int64_t x = region_.x; x < region_.x + region_.width; ++x) {
        const float* d = denoised.data() + denoised.offset(x, y - denoised_y0);
        const float* n = noisy.data() + noisy.offset(x, y - noisy_y0);
        if (!std::isfinite(d[0]) || !std::isfinite(d[1]) || !std::isfinite(d[2])) continue;
        Sums& s = block((x - region_.x) / kBlock, by);
        for (int c = 0; c < 3; ++c) s.output[c] += d[c] * kPerPixel;
        s.output_count += 1;
        if (!std::isfinite(n[0]) || !std::isfinite(n[1]) || !std::isfinite(n[2])) continue;
        const float limit = kFireflyClamp * std::max(luminance(d), 1e-6f);  // may be Inf: n is finite
        for (int c = 0; c < 3; ++c) s.noisy[c] += std::clamp(n[c], -limit, limit) * kPerPixel;
        s.noisy_count += 1;
      }
  });
}

int64_t EnergyCorrection::rows_required(int64_t y_end) const {
  if (y_end <= region_.y || grid_h_ == 0) return region_.y;
  const int64_t last = std::min(y_end, region_.y + region_.height) - 1 - region_.y;
  const int64_t block_row = std::min(grid_h_ - 1, lerp_at(last, grid_h_).hi + kRadiusBlocks);
  return region_.y + std::min(region_.height, (block_row + 1) * kBlock);
}

std::vector<float> EnergyCorrection::ratios(int64_t by0, int64_t by1) const {
  constexpr int kFields = 8;  // noisy rgb, output rgb, noisy count, output count
  auto fields = [](const Sums& s, double* f) {
    for (int c = 0; c < 3; ++c) {
      f[c] = s.noisy[c];
      f[3 + c] = s.output[c];
    }
    f[6] = s.noisy_count;
    f[7] = s.output_count;
  };
  // Horizontal blur of the block rows the vertical blur reaches.
  const int64_t hy0 = std::max<int64_t>(0, by0 - kRadiusBlocks), hy1 = std::min(grid_h_, by1 + kRadiusBlocks);
  std::vector<double> horizontal(static_cast<size_t>((hy1 - hy0) * grid_w_ * kFields), 0.0);
  for (int64_t by = hy0; by < hy1; ++by)
    for (int64_t bx = 0; bx < grid_w_; ++bx) {
      double* h = &horizontal[static_cast<size_t>(((by - hy0) * grid_w_ + bx) * kFields)];
      for (int64_t k = std::max<int64_t>(0, bx - kRadiusBlocks); k <= std::min(grid_w_ - 1, bx + kRadiusBlocks); ++k) {
        double f[kFields];
        fields(blocks_[static_cast<size_t>(by * grid_w_ + k)], f);
        const double w = weights_[static_cast<size_t>(std::abs(k - bx))];
        for (int i = 0; i < kFields; ++i) h[i] += w * f[i];
      }
    }
  std::vector<float> out(static_cast<size_t>((by1 - by0) * grid_w_ * 3), 1.0f);
  for (int64_t by = by0; by < by1; ++by)
    for (int64_t bx = 0; bx < grid_w_; ++bx) {
      double g[kFields] = {};
      for (int64_t k = std::max(hy0, by - kRadiusBlocks); k <= std::min(hy1 - 1, by + kRadiusBlocks); ++k) {
        const double* h = &horizontal[static_cast<size_t>(((k - hy0) * grid_w_ + bx) * kFields)];
        const double w = weights_[static_cast<size_t>(std::abs(k - by))];
        for (int i = 0; i < kFields; ++i) g[i] += w * h[i];
      }
      float* r = &out[static_cast<size_t>(((by - by0) * grid_w_ + bx) * 3)];
      if (g[6] <= 0 || g[7] <= 0) continue;  // nothing finite nearby: leave the output as it is
      for (int c = 0; c < 3; ++c) {
        const double noisy_mean = g[c] / g[6], output_mean = g[3 + c] / g[7];
        if (!(output_mean > 0)) continue;
        r[c] = static_cast<float>(std::clamp(noisy_mean / output_mean, 1.0 / kMaxRatio, double{kMaxRatio}));
      }
    }
  return out;
}

void EnergyCorrection::apply(Image& denoised, int64_t denoised_y0, int64_t y0, int64_t rows) const {
  const int64_t first = std::max(y0, region_.y), end = std::min(y0 + rows, region_.y + region_.height);
  if (end <= first) return;
  const int64_t by0 = lerp_at(first - region_.y, grid_h_).lo, by1 = lerp_at(end - 1 - region_.y, grid_h_).hi + 1;
  const std::vector<float> ratio = ratios(by0, by1);
  std::vector<Lerp> columns(static_cast<size_t>(region_.width));
  for (int64_t x = 0; x < region_.width; ++x) columns[static_cast<size_t>(x)] = lerp_at(x, grid_w_);
  tbb::parallel_for(first, end, [&](int64_t y) {
    const Lerp ly = lerp_at(y - region_.y, grid_h_);
    const float* row0 = &ratio[static_cast<size_t>((ly.lo - by0) * grid_w_ * 3)];
    const float* row1 = &ratio[static_cast<size_t>((ly.hi - by0) * grid_w_ * 3)];
    for (int64_t x = 0; x < region_.width; ++x) {
      const Lerp& lx = columns[static_cast<size_t>(x)];
      float* d = &denoised.at(region_.x + x, y - denoised_y0, 0);
      for (int c = 0; c < 3; ++c) {
        const float top = row0[lx.lo * 3 + c] + lx.f * (row0[lx.hi * 3 + c] - row0[lx.lo * 3 + c]);
        const float bottom = row1[lx.lo * 3 + c] + lx.f * (row1[lx.hi * 3 + c] - row1[lx.lo * 3 + c]);
        // The extrapolation stays in range, and so does the product (a value near FLT_MAX times a ratio above 1).
        d[c] = std::clamp(d[c] * std::clamp(top + ly.f * (bottom - top), 1.0f / kMaxRatio, kMaxRatio), -FLT_MAX, FLT_MAX);
      }
    }
  });
}

}  // namespace residue
