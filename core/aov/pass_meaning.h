// What a pass's values mean beyond its role: the space of its normals, the kind of its depth, and the
// conversions the loader applies to them. A convention's rule states it (PassRule, conventions.h), recognition
// carries it to the AOV it found (RecognisedAov, channel_naming.h) and the loader reads by it: one struct, passed
// whole, so a new kind of meaning is one field here.
#pragma once

#include "core/aov/aov_stack.h"

namespace residue {

struct PassMeaning {
  NormalSpace normal_space = NormalSpace::Unknown;
  bool flip_normal_z = false;  // the renderer's camera space has +z along the view direction
  DepthKind depth_kind = DepthKind::Unknown;
  // Depth read as the z of a camera-space position pass (pbrt-v4's P): right only while that pass, which shares
  // the normals' space, is in camera space.
  bool depth_from_position = false;
  // The pass is the variance of the samples (pbrt-v4's Variance), not of the pixel's estimate: read divided by the
  // header's samplesPerPixel, and left out when the header does not say it.
  bool samples_variance = false;
  // The motion is Cycles' Vector pass (its own convention), turned into Residue's (core/temporal/reprojection.h).
  bool cycles_vector = false;
};

}  // namespace residue
