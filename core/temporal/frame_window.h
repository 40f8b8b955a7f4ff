// Frame t of a shot with its neighbours: each neighbouring frame's noisy colour brought to frame t along the
// motion (reprojection.h), with where that is the same surface. These are what a temporal model reads besides
// frame t's own AOVs (AovStack::neighbours; core/features/features.h has the planes).
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include "core/aov/aov_stack.h"
#include "core/temporal/reprojection.h"

namespace residue {

// Frame t + offset's stack, or null where the shot has no such frame (before its first, after its last, or
// missing on disk).
using ShotFrames = std::function<const AovStack*(int offset)>;

// `image` (RGB, on the grid of frame t + offset) brought to frame t along the motion, in |offset| steps through the
// frames between, with where that is the same surface; `fill`'s pixel (RGB, frame t's grid) where it is not. Null
// when the shot lacks a frame on the way. The warp of attach_neighbours, for any image of a neighbour (its noisy
// colour, its denoised colour).
std::optional<WarpedNeighbour> warp_to_frame(const AovStack& frame, int offset, const ShotFrames& shot,
                                             const Image& image, const Image& fill,
                                             const ReprojectionOptions& options = {});

// Sets frame.neighbours to the warped colour of every neighbour of offsets -radius..-1, +1..+radius that `shot`
// has, and returns the offsets it lacks (a temporal model reads those as not valid). A neighbour two frames away
// is warped in two steps, through the frame between (whose motion it needs); a pixel is valid where every step
// is. Throws Error(Input) naming the file when a frame that must be warped through has no motion AOV, or when a
// neighbour's size differs from frame t's.
std::vector<int> attach_neighbours(AovStack& frame, int radius, const ShotFrames& shot,
                                   const ReprojectionOptions& options = {});

}  // namespace residue
