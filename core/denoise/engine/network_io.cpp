#include "core/denoise/engine/network_io.h"

#include <algorithm>
#include <vector>

#include "core/denoise/oidn_filter.h"

namespace residue {

WholeImageStats measure_whole_image(RowSource& source, bool exposure, bool depth, int64_t band,
                                    const CancelToken* cancel) {
  WholeImageStats s;
  if (const AovStack* stack = source.whole()) {
    s.features = compute_feature_stats(*stack);
    if (exposure) s.exposure = oidn_autoexposure(stack->color.image);
    return s;
  }
  const AovStack& layout = source.layout();
  const int64_t W = layout.data_window.width, H = layout.data_window.height;
  s.features = compute_feature_stats(layout);  // the layout holds no pixels: the normals' rotation only
  depth = depth && layout.depth;
  if (!depth && !exposure) return s;
  OidnAutoexposure autoexposure(W, H);
  DepthScaleSampler sampler(W * H);  // the same sample compute_feature_stats draws from a whole stack
  std::vector<AovRole> roles;        // only what the statistics read
  if (exposure) roles.push_back(AovRole::Color);
  if (depth) roles.push_back(AovRole::Depth);
  for (int64_t y0 = 0; y0 < H; y0 += band) {
    throw_if_cancelled(cancel);
    const auto rows = source.rows(y0, std::min(H, y0 + band), roles);
    if (exposure) autoexposure.add(rows.stack->color.image, y0);
    if (depth) sampler.add(rows.stack->depth->image.data(), rows.stack->depth->image.pixel_count(), y0 * W);
  }
  if (depth) s.features.depth_scale = sampler.scale();
  if (exposure) s.exposure = autoexposure.scale();
  return s;
}

}  // namespace residue
