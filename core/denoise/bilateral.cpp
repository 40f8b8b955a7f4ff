#include "core/denoise/bilateral.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <tbb/parallel_for.h>

namespace residue {
namespace {
float finite_or_zero(float v) { return std::isfinite(v) ? std::max(v, 0.0f) : 0.0f; }
}  // namespace

Image cross_bilateral(const AovStack& s, const BilateralOptions& o, std::optional<Rect> roi) {
  Image out = s.color.image;
  cross_bilateral_rect(s, o, roi.value_or(Rect{0, 0, s.width(), s.height()}), out);
  return out;
}

void cross_bilateral_rect(const AovStack& s, const BilateralOptions& o, const Rect& region, Image& out) {
  const int r = o.radius;
  std::vector<float> spatial(static_cast<size_t>((2 * r + 1) * (2 * r + 1)));
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx)
      spatial[static_cast<size_t>((dy + r) * (2 * r + 1) + dx + r)] =
          static_cast<float>(std::exp(-(dx * dx + dy * dy) / (2 * o.sigma_spatial * o.sigma_spatial)));
  const float ka = static_cast<float>(1.0 / (2 * o.sigma_albedo * o.sigma_albedo));
  const float kn = static_cast<float>(1.0 / (2 * o.sigma_normal * o.sigma_normal));
  const float kd = static_cast<float>(1.0 / (2 * o.sigma_depth * o.sigma_depth));
  const Image* alb = s.albedo ? &s.albedo->image : nullptr;
  const Image* nrm = s.normal ? &s.normal->image : nullptr;
  const Image* dep = s.depth ? &s.depth->image : nullptr;
  auto guide = [](const Image* img, int64_t x, int64_t y, int c) { return finite_or_zero(img->at(x, y, c)); };

  tbb::parallel_for(region.y, region.y + region.height, [&](int64_t y) {
    for (int64_t x = region.x; x < region.x + region.width; ++x) {
      double sum[3] = {0, 0, 0}, wsum = 0;
      const float zc = dep ? finite_or_zero(dep->at(x, y)) : 0.0f;
      for (int dy = -r; dy <= r; ++dy) {
        const int64_t qy = y + dy;
        if (qy < 0 || qy >= s.height()) continue;
        for (int dx = -r; dx <= r; ++dx) {
          const int64_t qx = x + dx;
          if (qx < 0 || qx >= s.width()) continue;
          float e = 0;
          if (alb)
            for (int c = 0; c < 3; ++c) {
              const float d = guide(alb, qx, qy, c) - guide(alb, x, y, c);
              e += ka * d * d;
            }
          if (nrm)
            for (int c = 0; c < 3; ++c) {
              const float nq = nrm->at(qx, qy, c), np = nrm->at(x, y, c);
              const float d = (std::isfinite(nq) ? nq : 0.0f) - (std::isfinite(np) ? np : 0.0f);
              e += kn * d * d;
            }
          if (dep && zc > 0) {
            const float d = (finite_or_zero(dep->at(qx, qy)) - zc) / zc;
            e += kd * d * d;
          }
          const double w = spatial[static_cast<size_t>((dy + r) * (2 * r + 1) + dx + r)] * std::exp(-e);
          for (int c = 0; c < 3; ++c) sum[c] += w * finite_or_zero(s.color.image.at(qx, qy, c));
          wsum += w;
        }
      }
      for (int c = 0; c < 3; ++c) out.at(x, y, c) = static_cast<float>(std::min(sum[c] / wsum, 3.0e38));
    }
  });
}

}  // namespace residue
