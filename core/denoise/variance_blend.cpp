#include "core/denoise/variance_blend.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace residue {

float blend_tau(const std::map<std::string, std::string>& md) {
  const auto it = md.find("residue.blend_tau");
  if (it == md.end()) return VarianceBlend::kTau;
  try {
    const float t = std::stof(it->second);
    if (t >= 0 && std::isfinite(t)) return t;  // 0: the model takes no blend
  } catch (const std::exception&) {
  }
  return VarianceBlend::kTau;  // a malformed value: the default rather than no denoise
}

void blend_by_variance(const AovStack& src, const Rect& src_rect, const Rect& bounds, const Rect& tile, Image& out,
                       int64_t out_x0, int64_t out_y0, float tau) {
  const Image& colour = src.color.image;
  const Image& var = src.variance->image;
  const int vc = var.channels();
  // Per-pixel inputs of the box sums, over the tile and its border (local coordinates of src).
  const int64_t r = VarianceBlend::kRadius;
  const int64_t x0 = std::max(bounds.x, tile.x - r), x1 = std::min(bounds.x + bounds.width, tile.x + tile.width + r);
  const int64_t y0 = std::max(bounds.y, tile.y - r), y1 = std::min(bounds.y + bounds.height, tile.y + tile.height + r);
  const int64_t w = x1 - x0, h = y1 - y0;
  std::vector<double> lum(static_cast<size_t>(w * h)), v(static_cast<size_t>(w * h)), ok(static_cast<size_t>(w * h));
  for (int64_t y = y0; y < y1; ++y)
    for (int64_t x = x0; x < x1; ++x) {
      const int64_t sx = x - src_rect.x, sy = y - src_rect.y;
      double l = 0, s = 0;
      for (int c = 0; c < 3; ++c) l += colour.at(sx, sy, c) / 3.0;
      for (int c = 0; c < vc; ++c) s += var.at(sx, sy, c) / static_cast<double>(vc);
      const size_t i = static_cast<size_t>((y - y0) * w + (x - x0));
      const bool finite = std::isfinite(l) && std::isfinite(s);
      lum[i] = finite ? l : 0.0;
      v[i] = finite ? std::max(s, 0.0) : 0.0;
      ok[i] = finite ? 1.0 : 0.0;
    }
  for (int64_t y = tile.y; y < tile.y + tile.height; ++y)
    for (int64_t x = tile.x; x < tile.x + tile.width; ++x) {
      double sl = 0, sv = 0, n = 0;
      for (int64_t yy = std::max(y0, y - r); yy <= std::min(y1 - 1, y + r); ++yy)
        for (int64_t xx = std::max(x0, x - r); xx <= std::min(x1 - 1, x + r); ++xx) {
          const size_t i = static_cast<size_t>((yy - y0) * w + (xx - x0));
          sl += lum[i];
          sv += v[i];
          n += ok[i];
        }
      if (ok[static_cast<size_t>((y - y0) * w + (x - x0))] == 0.0 || n == 0.0) continue;  // keep the output
      const double mean_lum = sl / n;
      const double rv = (sv / n) / (mean_lum * mean_lum + VarianceBlend::kEps);
      const float weight = static_cast<float>(rv / (rv + tau));
      for (int c = 0; c < 3; ++c) {
        float& o = out.at(x - out_x0, y - out_y0, c);
        const float noisy = colour.at(x - src_rect.x, y - src_rect.y, c);
        o = weight * o + (1.0f - weight) * noisy;
      }
    }
}

}  // namespace residue
