// Output guard: bounds the network's output by the brightest input it could see.
//
// A network extrapolates badly on inputs brighter than its training patches held: a base model at 4000
// steps turned a small emitter of (57, 69, 81) into (765, 0, 517292), a log-space overshoot of 9 in one
// channel, and 25 such pixels made a validation scene's relMSE 306. Denoising averages; it cannot make a
// pixel brighter than everything in its receptive field. So each output channel is clamped to twice the
// maximum of the same input channel over the receptive field (the tile's halo), in linear (exposed) terms:
// a bound that scales with the input, so that over black the output is black (never a network's bias, which
// would depend on the tiling, as empty tiles are skipped) and a dim image is bounded like a bright one. In
// the network's log space log(1 + x): log(1 + 2 (e^max - 1)). The bound is far from anything a good output
// needs (on the validation scenes it clamps nothing with a healthy model) and costs a sliding max filter per
// tile (van Herk / Gil-Werman: 3 comparisons per value whatever the radius; 0.02 s/MP on one thread).
#pragma once

#include <cmath>
#include <cstdint>

#include "core/image/image.h"

namespace residue {

struct OutputGuard {
  static constexpr float kFactor = 2.0f;  // linear output <= kFactor x the brightest input
  // The bound in log space for a window maximum `m` (log space); 0 for m <= 0 (black).
  static float bound(float m) { return m > 0.0f ? std::log1p(kFactor * std::expm1(m)) : 0.0f; }
};

// Clamps `output`'s first three channels (log space) inside `tile` (in `output`'s and `features`'s
// coordinates, which are the same rectangle) to the max of `features`'s first three channels (the log colour)
// within `radius` pixels, clipped to `features`, plus the margin. Returns how many values it clamped.
int64_t guard_output(const Image& features, const Rect& tile, int64_t radius, Image& output);

}  // namespace residue
