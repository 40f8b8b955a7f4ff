// The temporal blend: frame t's denoised colour averaged with the denoised colour of frames t-k..t+k brought to
// it along the motion (frame_window.h's warp_to_frame, with its mask). A denoiser's error that changes from frame
// to frame (the boiling a per-frame or a windowed network leaves) is averaged over the frames that show the same
// surface; a pixel no neighbour shows (a disocclusion, the frame's edge) keeps frame t's own colour.
//
// Motion vectors follow surfaces, not what lights them: a moving highlight or shadow does not move with the
// vectors, and averaging it would leave copies of it behind (ghosts). A neighbour's weight therefore falls with its
// difference from frame t's colour, relative to their level, and is 0 beyond `tolerance`.
#pragma once

#include <functional>
#include <vector>

#include "core/aov/aov_stack.h"

namespace residue {

struct TemporalBlendOptions {
  // The relative difference |a - b| / (a + b) (summed over RGB) at which a weight is 0; residue-cli's default.
  double tolerance = 0.5;
};

// The blend of `denoised` (frame t's, RGB) with `neighbours` (other frames' denoised colour warped to t, with their
// validity): at each pixel, sum of w_i c_i over sum of w_i, with frame t's weight 1 and a valid neighbour's
// 1 - (d / tolerance)^2 for its relative difference d from frame t's colour (0 beyond). Non-finite neighbour pixels
// weigh 0. Throws Error(Usage) when a size differs.
Image temporal_blend(const Image& denoised, const std::vector<WarpedNeighbour>& neighbours,
                     const TemporalBlendOptions& options = {});

// A neighbouring frame for the blend: its stack (whose place on the shot the warp needs) and its denoised colour;
// both null where the shot has no such frame.
struct DenoisedFrame {
  const AovStack* stack = nullptr;
  const Image* denoised = nullptr;
};

// What --temporal-blend computes for frame t: `denoised` (frame t's) blended with frames t-1 and t+1 as
// `neighbour(offset)` gives them (asked for -1, then +1), each warped to `frame` along its motion
// (frame_window.h's warp_to_frame, filled with frame t's colour). Throws as warp_to_frame and temporal_blend do.
Image temporal_blend_frames(const AovStack& frame, const Image& denoised,
                            const std::function<DenoisedFrame(int offset)>& neighbour,
                            const TemporalBlendOptions& options = {});

}  // namespace residue
