#include "core/denoise/output_guard.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace residue {

int64_t guard_output(const Image& features, const Rect& tile, int64_t radius, Image& output) {
  // Separable max: rows first (over every feature row a tile pixel's window reaches), then columns.
  const int64_t y0 = std::max<int64_t>(0, tile.y - radius);
  const int64_t y1 = std::min(features.height(), tile.y + tile.height + radius);
  const int64_t rows = y1 - y0;
  std::vector<float> row_max(static_cast<size_t>(rows * tile.width * 3));
  for (int64_t y = y0; y < y1; ++y)
    for (int64_t x = 0; x < tile.width; ++x) {
      const int64_t cx = tile.x + x;
      const int64_t a = std::max<int64_t>(0, cx - radius), b = std::min(features.width() - 1, cx + radius);
      for (int c = 0; c < 3; ++c) {
        float m = -INFINITY;
        for (int64_t sx = a; sx <= b; ++sx) m = std::max(m, features.at(sx, y, c));
        row_max[static_cast<size_t>(((y - y0) * tile.width + x) * 3 + c)] = m;
      }
    }
  int64_t clamped = 0;
  for (int64_t y = 0; y < tile.height; ++y) {
    const int64_t cy = tile.y + y;
    const int64_t a = std::max(y0, cy - radius), b = std::min(y1 - 1, cy + radius);
    for (int64_t x = 0; x < tile.width; ++x)
      for (int c = 0; c < 3; ++c) {
        float m = -INFINITY;
        for (int64_t sy = a; sy <= b; ++sy) m = std::max(m, row_max[static_cast<size_t>(((sy - y0) * tile.width + x) * 3 + c)]);
        float& v = output.at(tile.x + x, cy, c);
        const float bound = m + OutputGuard::kMargin;
        if (v > bound) {  // NaN stays NaN: expand_color maps it to 0
          v = bound;
          ++clamped;
        }
      }
  }
  return clamped;
}

}  // namespace residue
