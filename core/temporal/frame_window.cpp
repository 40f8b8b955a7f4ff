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

std::optional<WarpedNeighbour> warp_to_frame(const AovStack& frame, int offset, const ShotFrames& shot,
                                             const Image& image, const Image& fill, const ReprojectionOptions& options) {
  // The frames from t to t + offset; all must exist to carry t + offset's image to t.
  const int sign = offset < 0 ? -1 : 1;
  std::vector<const AovStack*> path = {&frame};
  for (int i = sign; i != offset + sign; i += sign) path.push_back(shot(i));
  for (const AovStack* s : path)
    if (!s) return std::nullopt;
  for (size_t i = 1; i < path.size(); ++i) check_grid(frame, *path[i]);
  if (image.width() != frame.width() || image.height() != frame.height() || image.channels() != 3 ||
      fill.width() != frame.width() || fill.height() != frame.height() || fill.channels() != 3)
    throw Error(ErrorKind::Usage, "warp_to_frame: the images are RGB on the frame's grid");
  Image carried(frame.width(), frame.height(), 4);
  for (int64_t y = 0; y < frame.height(); ++y)
    for (int64_t x = 0; x < frame.width(); ++x) {
      for (int c = 0; c < 3; ++c) carried.at(x, y, c) = image.at(x, y, c);
      carried.at(x, y, 3) = 1.0f;
    }
  // From t + offset towards t: each frame on the way looks up where its pixels were in the one beyond it.
  const MotionStep direction = offset < 0 ? MotionStep::Previous : MotionStep::Next;
  for (size_t i = path.size() - 1; i > 0; --i) {
    check_motion(*path[i - 1]);
    carried = step(carried, *path[i - 1], *path[i], direction, options);
  }
  WarpedNeighbour n{offset, Image(frame.width(), frame.height(), 3), Image(frame.width(), frame.height(), 1)};
  for (int64_t y = 0; y < frame.height(); ++y)
    for (int64_t x = 0; x < frame.width(); ++x) {
      const bool valid = carried.at(x, y, 3) > 0.5f;
      for (int c = 0; c < 3; ++c) n.color.at(x, y, c) = valid ? carried.at(x, y, c) : fill.at(x, y, c);
      n.valid.at(x, y) = valid ? 1.0f : 0.0f;
    }
  return n;
}

std::vector<int> attach_neighbours(AovStack& frame, int radius, const ShotFrames& shot,
                                   const ReprojectionOptions& options) {
  frame.neighbours.clear();
  std::vector<int> missing;
  for (int d : neighbour_offsets(radius)) {
    const AovStack* far = shot(d);
    std::optional<WarpedNeighbour> n =
        far ? warp_to_frame(frame, d, shot, far->color.image, frame.color.image, options) : std::nullopt;
    if (n) frame.neighbours.push_back(std::move(*n));
    else missing.push_back(d);
  }
  return missing;
}

}  // namespace residue
