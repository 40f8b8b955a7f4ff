// Reprojection: a neighbouring frame's image brought to frame t along the motion vectors, with a mask of the
// pixels where that is not the same surface (issue 51: the temporal denoiser's inputs).
//
// Motion, in Residue's convention (the motion AOV, core/aov): four channels per pixel of frame t, in pixels of
// the image, x to the right and y down the rows: (0, 1) the displacement from the pixel to where its surface was
// in the previous frame, (2, 3) to where it will be in the next frame. A renderer's own convention is turned into
// this one when the AOV is loaded (Cycles' Vector pass: motion_from_cycles_vector).
#pragma once

#include <cstdint>
#include <optional>

#include "core/image/image.h"

namespace residue {

enum class MotionStep { Previous, Next };  // which neighbour of frame t a warp reads

// Cycles' Vector pass (X, Y: previous position - pixel; Z, W: pixel - next position; pixels, y up; measured by
// tools/datagen/vector_convention_check.py) in Residue's convention. Non-finite vectors become 0.
Image motion_from_cycles_vector(const Image& vector);

struct ReprojectionOptions {
  // A surface is the same when its depth in the neighbour, where the motion lands, is within this share of its
  // depth at t (a camera move changes depth by a few percent a frame; a disocclusion by far more).
  double depth_tolerance = 0.1;
  // ... and when the normals there agree: their dot product is at least this (camera-space normals turn with a
  // pan by the pan's angle per frame).
  double normal_min_dot = 0.8;
};

struct Reprojected {
  Image image;      // the neighbour's channels at frame t's pixels (0 where masked)
  Image valid;      // 1 channel: 1 where the neighbour shows the same surface, 0 where masked
  int64_t outside = 0;      // pixels whose motion leaves the neighbour's frame
  int64_t disoccluded = 0;  // pixels the depth or normal test masked (surfaces hidden or revealed)
};

// Frame t's view of `neighbour` (the previous or the next frame's image, any channels): at each pixel p of t, the
// neighbour bilinearly sampled at p + d(p), d from `motion` (frame t's, Residue's convention; channels 0-1 for
// Previous, 2-3 for Next). With the neighbour's and t's depth (1 channel) and camera-space normals (3 channels),
// each of the four bilinear taps must pass the depth and normal tests or the pixel is masked (the environment,
// depth 0 in both, passes: it has no normal). Throws
// Error(Usage) when the sizes differ or `motion` lacks 4 channels.
Reprojected reproject(const Image& neighbour, const Image& motion, MotionStep step,
                      const Image* depth_t = nullptr, const Image* depth_neighbour = nullptr,
                      const Image* normal_t = nullptr, const Image* normal_neighbour = nullptr,
                      const ReprojectionOptions& options = {});

}  // namespace residue
