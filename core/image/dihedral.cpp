#include "core/image/dihedral.h"

#include <algorithm>
#include <cstdlib>

#include <tbb/parallel_for.h>

namespace residue {

Rect Dihedral::map(const Rect& r, int64_t w, int64_t h) const {
  // Source pixel s lands where the inverse element, reading the output, finds it.
  const auto [ow, oh] = size(w, h);
  const Dihedral inv = inverse();
  const auto [ax, ay] = inv.source(r.x, r.y, ow, oh);
  const auto [bx, by] = inv.source(r.x + r.width - 1, r.y + r.height - 1, ow, oh);
  return {std::min(ax, bx), std::min(ay, by), std::abs(bx - ax) + 1, std::abs(by - ay) + 1};
}

Image apply(const Image& src, const Dihedral& d, int normal_plane) {
  const int64_t w = src.width(), h = src.height();
  const int channels = src.channels();
  const std::pair<int64_t, int64_t> size = d.size(w, h);
  const int64_t ow = size.first, oh = size.second;  // not a structured binding: the lambda below captures them
  Image out(ow, oh, channels);
  tbb::parallel_for(int64_t{0}, oh, [&](int64_t v) {
    for (int64_t u = 0; u < ow; ++u) {
      const auto [x, y] = d.source(u, v, w, h);
      const float* s = src.data() + src.offset(x, y);
      float* o = &out.at(u, v, 0);
      for (int c = 0; c < channels; ++c) o[c] = s[c];
      if (normal_plane >= 0) {
        const auto [nx, ny] = d.turn_normal(s[normal_plane], s[normal_plane + 1]);
        o[normal_plane] = nx;
        o[normal_plane + 1] = ny;
      }
    }
  });
  return out;
}

}  // namespace residue
