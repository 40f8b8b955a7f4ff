#include "core/temporal/frame_window.h"

#include <string>

#include "core/util/error.h"

namespace residue {
namespace {

void check_motion(const AovStack& s) {
  if (!s.motion)
    throw Error(ErrorKind::Input, "'" + s.color.source.file + "' has no motion vectors (the motion AOV: Cycles' "
                                  "Vector pass, or --map motion=...): a temporal model warps the neighbouring frames "
                                  "to it along them");
}

void check_grid(const AovStack& frame, const AovStack& other) {
  if (other.width() != frame.width() || other.height() != frame.height())
    throw Error(ErrorKind::Input, "'" + other.color.source.file + "' is " + std::to_string(other.width()) + "x" +
                                      std::to_string(other.height()) + ", but the frame it neighbours, '" +
                                      frame.color.source.file + "', is " + std::to_string(frame.width()) + "x" +
                                      std::to_string(frame.height()));
}

const Image* image_of(const std::optional<Aov>& a) { return a ? &a->image : nullptr; }

// `carried` (colour + a validity channel, on `from`'s grid) brought one frame along, to the grid of `to`, a
// neighbour of `from` by one frame: `to`'s motion towards `from` says where each of its pixels was.
Image step(const Image& carried, const AovStack& to, const AovStack& from, MotionStep direction,
           const ReprojectionOptions& options) {
  const Reprojected r = reproject(carried, to.motion->image, direction, image_of(to.depth), image_of(from.depth),
                                  image_of(to.normal), image_of(from.normal), options);
  Image out = r.image;
  // Valid where this step's taps are and every tap carried a valid pixel (a bilinear mix of validity is 1 only then).
  for (int64_t y = 0; y < out.height(); ++y)
    for (int64_t x = 0; x < out.width(); ++x)
      out.at(x, y, 3) = r.valid.at(x, y) > 0.5f && out.at(x, y, 3) > 0.999f ? 1.0f : 0.0f;
  return out;
}

}  // namespace

std::vector<int> attach_neighbours(AovStack& frame, int radius, const ShotFrames& shot,
                                   const ReprojectionOptions& options) {
  frame.neighbours.clear();
  std::vector<int> missing;
  const std::vector<int> offsets = neighbour_offsets(radius);
  for (int d : offsets) {
    // The frames from t to t + d; all must exist to carry t + d's colour to t.
    const int sign = d < 0 ? -1 : 1;
    std::vector<const AovStack*> path = {&frame};
    for (int i = sign; i != d + sign; i += sign) path.push_back(shot(i));
    bool complete = true;
    for (const AovStack* s : path) complete = complete && s;
    if (!complete) {
      missing.push_back(d);
      continue;
    }
    for (size_t i = 1; i < path.size(); ++i) check_grid(frame, *path[i]);
    const AovStack& far = *path.back();
    Image carried(frame.width(), frame.height(), 4);
    for (int64_t y = 0; y < frame.height(); ++y)
      for (int64_t x = 0; x < frame.width(); ++x) {
        for (int c = 0; c < 3; ++c) carried.at(x, y, c) = far.color.image.at(x, y, c);
        carried.at(x, y, 3) = 1.0f;
      }
    // From t + d towards t: each frame on the way looks up where its pixels were in the one beyond it.
    const MotionStep direction = d < 0 ? MotionStep::Previous : MotionStep::Next;
    for (size_t i = path.size() - 1; i > 0; --i) {
      check_motion(*path[i - 1]);
      carried = step(carried, *path[i - 1], *path[i], direction, options);
    }
    WarpedNeighbour n{d, Image(frame.width(), frame.height(), 3), Image(frame.width(), frame.height(), 1)};
    for (int64_t y = 0; y < frame.height(); ++y)
      for (int64_t x = 0; x < frame.width(); ++x) {
        const bool valid = carried.at(x, y, 3) > 0.5f;
        for (int c = 0; c < 3; ++c) n.color.at(x, y, c) = valid ? carried.at(x, y, c) : frame.color.image.at(x, y, c);
        n.valid.at(x, y) = valid ? 1.0f : 0.0f;
      }
    frame.neighbours.push_back(std::move(n));
  }
  return missing;
}

}  // namespace residue
