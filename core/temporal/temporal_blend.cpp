#include "core/temporal/temporal_blend.h"

#include <cmath>
#include <string>

#include <tbb/parallel_for.h>

#include "core/temporal/frame_window.h"
#include "core/util/error.h"

namespace residue {

Image temporal_blend(const Image& denoised, const std::vector<WarpedNeighbour>& neighbours,
                     const TemporalBlendOptions& options) {
  const int64_t W = denoised.width(), H = denoised.height();
  if (denoised.channels() != 3) throw Error(ErrorKind::Usage, "temporal blend: the denoised image is RGB");
  for (const WarpedNeighbour& n : neighbours)
    if (n.color.width() != W || n.color.height() != H || n.color.channels() != 3 || n.valid.width() != W ||
        n.valid.height() != H)
      throw Error(ErrorKind::Usage, "temporal blend: neighbour " + std::to_string(n.offset) + " is not on the frame's grid");
  if (!(options.tolerance > 0)) throw Error(ErrorKind::Usage, "temporal blend: the tolerance must be positive");
  Image out(W, H, 3);
  tbb::parallel_for(int64_t{0}, H, [&](int64_t y) {
    for (int64_t x = 0; x < W; ++x) {
      double sum[3], weight = 1;
      for (int c = 0; c < 3; ++c) sum[c] = denoised.at(x, y, c);
      const double level_t = std::abs(sum[0]) + std::abs(sum[1]) + std::abs(sum[2]);
      for (const WarpedNeighbour& n : neighbours) {
        if (!(n.valid.at(x, y) > 0.5f)) continue;
        double difference = 0, level = level_t;
        bool finite = true;
        for (int c = 0; c < 3; ++c) {
          const double v = n.color.at(x, y, c);
          finite = finite && std::isfinite(v);
          difference += std::abs(v - denoised.at(x, y, c));
          level += std::abs(v);
        }
        if (!finite) continue;
        // A small floor keeps black pixels (the environment off, a shadow) from dividing by 0.
        const double d = difference / (level + 1e-3) / options.tolerance;
        const double w = d < 1 ? 1 - d * d : 0;
        if (w <= 0) continue;
        for (int c = 0; c < 3; ++c) sum[c] += w * n.color.at(x, y, c);
        weight += w;
      }
      for (int c = 0; c < 3; ++c) out.at(x, y, c) = static_cast<float>(sum[c] / weight);
    }
  });
  return out;
}

Image temporal_blend_frames(const AovStack& frame, const Image& denoised,
                            const std::function<DenoisedFrame(int offset)>& neighbour,
                            const TemporalBlendOptions& options) {
  std::vector<WarpedNeighbour> warped;
  for (const int offset : {-1, 1}) {
    const DenoisedFrame other = neighbour(offset);
    if (!other.stack || !other.denoised) continue;
    std::optional<WarpedNeighbour> w = warp_to_frame(
        frame, offset, [&](int o) { return o == offset ? other.stack : nullptr; }, *other.denoised, denoised);
    if (w) warped.push_back(std::move(*w));
  }
  return temporal_blend(denoised, warped, options);
}

}  // namespace residue
