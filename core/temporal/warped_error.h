// A result's error on frame t-1 brought to frame t along the motion: what the motion-compensated temporal error
// (core/metrics/temporal.h) compares frame t's error with. Shared by `residue-cli eval` on a sequence and the
// viewer's temporal column and map, so that both give the same numbers.
#pragma once

#include "core/aov/aov_stack.h"
#include "core/temporal/reprojection.h"

namespace residue {

struct WarpedError {
  Image error;      // x_{t-1} - r_{t-1} at frame t's pixels (3 channels)
  Image reference;  // r_{t-1} at frame t's pixels (3 channels)
  Image valid;      // 1 channel: 1 where frame t-1 shows the same surface
};

// `previous_result` is a result x_{t-1} of frame `previous` (t-1). Throws Error(Usage) when frame t has no motion
// AOV, either frame has no reference, or the sizes differ.
WarpedError warp_previous_error(const AovStack& t, const AovStack& previous, const Image& previous_result);

// metrics::compensated_temporal_map of result `x` of frame t against result `previous_result` of frame t-1.
Image compensated_temporal_map(const AovStack& t, const Image& x, const AovStack& previous,
                               const Image& previous_result, double eps = 0.01);

}  // namespace residue
