#include "core/temporal/warped_error.h"

#include "core/metrics/temporal.h"
#include "core/util/error.h"

namespace residue {

WarpedError warp_previous_error(const AovStack& t, const AovStack& previous, const Image& previous_result) {
  if (!t.motion) throw Error(ErrorKind::Usage, "the temporal error along the motion needs frame t's motion AOV");
  if (!t.reference || !previous.reference)
    throw Error(ErrorKind::Usage, "the temporal error along the motion needs both frames' references");
  const Image& r = previous.reference->image;
  if (previous_result.width() != r.width() || previous_result.height() != r.height() ||
      previous.width() != t.width() || previous.height() != t.height())
    throw Error(ErrorKind::Usage, "the temporal error along the motion: the frames differ in size");
  Image both(r.width(), r.height(), 6);  // error and reference, warped together in one pass
  for (int64_t y = 0; y < r.height(); ++y)
    for (int64_t x = 0; x < r.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        both.at(x, y, c) = previous_result.at(x, y, c) - r.at(x, y, c);
        both.at(x, y, 3 + c) = r.at(x, y, c);
      }
  auto img = [](const std::optional<Aov>& a) { return a ? &a->image : nullptr; };
  Reprojected w = reproject(both, t.motion->image, MotionStep::Previous, img(t.depth), img(previous.depth),
                            img(t.normal), img(previous.normal));
  WarpedError out{Image(r.width(), r.height(), 3), Image(r.width(), r.height(), 3), std::move(w.valid)};
  for (int64_t y = 0; y < r.height(); ++y)
    for (int64_t x = 0; x < r.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        out.error.at(x, y, c) = w.image.at(x, y, c);
        out.reference.at(x, y, c) = w.image.at(x, y, 3 + c);
      }
  return out;
}

Image compensated_temporal_map(const AovStack& t, const Image& x, const AovStack& previous,
                               const Image& previous_result, double eps) {
  const WarpedError w = warp_previous_error(t, previous, previous_result);
  return metrics::compensated_temporal_map(x, t.reference->image, w.error, w.reference, w.valid, eps);
}

}  // namespace residue
