#include "core/denoise/output_guard.h"

#include <algorithm>
#include <atomic>
#include <limits>
#include <vector>

#include <tbb/parallel_for.h>

namespace residue {
namespace {

constexpr float kNone = -std::numeric_limits<float>::infinity();  // outside the features: no bound from there
constexpr int64_t kStrip = 128;  // output columns per task: the scratch stays small whatever the tile

// Sliding maximum over windows of k = 2r + 1 elements (van Herk / Gil-Werman: three comparisons per value
// whatever r): out[j] = max(a[j], ..., a[j + 2r]) for j + 2r < n. An element is `len` floats (channels, or a
// whole row of them) maxed independently. g and h are scratch of a's size.
void sliding_max(const float* a, int64_t n, int64_t len, int64_t r, float* out, float* g, float* h) {
  const int64_t k = 2 * r + 1;
  for (int64_t i = 0; i < n; ++i) {  // g: running max from the start of each block of k
    const float* ai = a + i * len;
    float* gi = g + i * len;
    if (i % k == 0) {
      std::copy(ai, ai + len, gi);
    } else {
      for (int64_t e = 0; e < len; ++e) gi[e] = std::max(gi[e - len], ai[e]);
    }
  }
  for (int64_t i = n - 1; i >= 0; --i) {  // h: running max to the end of each block
    const float* ai = a + i * len;
    float* hi = h + i * len;
    if (i == n - 1 || (i + 1) % k == 0) {
      std::copy(ai, ai + len, hi);
    } else {
      for (int64_t e = 0; e < len; ++e) hi[e] = std::max(hi[e + len], ai[e]);
    }
  }
  for (int64_t j = 0; j + k - 1 < n; ++j)  // a window spans the end of one block and the start of the next
    for (int64_t e = 0; e < len; ++e) out[j * len + e] = std::max(h[j * len + e], g[(j + k - 1) * len + e]);
}

}  // namespace

int64_t guard_output(const Image& features, const Rect& tile, int64_t radius, Image& output) {
  const int64_t r = radius, rows = tile.height + 2 * r;  // rows of the window's reach, padded with kNone
  const int64_t strips = (tile.width + kStrip - 1) / kStrip;
  std::atomic<int64_t> clamped{0};
  tbb::parallel_for(int64_t{0}, strips, [&](int64_t s) {
    const int64_t x0 = tile.x + s * kStrip, w = std::min(kStrip, tile.x + tile.width - x0);
    const int64_t line_len = w + 2 * r;
    std::vector<float> line(static_cast<size_t>(line_len * 3)), lg(line.size()), lh(line.size());
    std::vector<float> row_max(static_cast<size_t>(rows * w * 3)), g(row_max.size()), h(row_max.size());
    // Rows: the max over each row's window, per channel.
    for (int64_t i = 0; i < rows; ++i) {
      const int64_t y = tile.y - r + i;
      float* out = &row_max[static_cast<size_t>(i * w * 3)];
      if (y < 0 || y >= features.height()) {
        std::fill(out, out + w * 3, kNone);
        continue;
      }
      for (int64_t j = 0; j < line_len; ++j) {
        const int64_t x = x0 - r + j;
        for (int c = 0; c < 3; ++c)
          line[static_cast<size_t>(j * 3 + c)] = x >= 0 && x < features.width() ? features.at(x, y, c) : kNone;
      }
      sliding_max(line.data(), line_len, 3, r, out, lg.data(), lh.data());
    }
    // Columns: the max over the rows' maxima, whole rows at a time; then the clamp.
    std::vector<float> window_max(static_cast<size_t>(tile.height * w * 3));
    sliding_max(row_max.data(), rows, w * 3, r, window_max.data(), g.data(), h.data());
    int64_t n = 0;
    for (int64_t y = 0; y < tile.height; ++y)
      for (int64_t x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) {
          float& v = output.at(x0 + x, tile.y + y, c);
          const float m = window_max[static_cast<size_t>((y * w + x) * 3 + c)];
          if (!(v > m)) continue;  // within the brightest input (most values): no bound to compute; NaN stays NaN
          const float bound = OutputGuard::bound(m);
          if (v > bound) {
            v = bound;
            ++n;
          }
        }
    clamped += n;
  });
  return clamped;
}

}  // namespace residue
