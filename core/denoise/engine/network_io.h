// How a network is fed and read: AOVs -> input planes, raw output -> linear values; and the whole-image
// statistics an input transform needs before any tile runs.
#pragma once

#include <cstdint>

#include "core/aov/aov_stack.h"
#include "core/denoise/engine/row_source.h"
#include "core/features/features.h"
#include "core/util/cancel.h"

namespace residue {

class NetworkIO {
 public:
  virtual ~NetworkIO() = default;
  // The input planes of rectangle r of `src` (its pixel coordinates).
  virtual void input(const AovStack& src, const Rect& r, Image& planes) const = 0;
  // The linear value of raw output `raw` at pixel (x, y), channel c of `src`.
  virtual float output(float raw, const AovStack& src, int64_t x, int64_t y, int c) const = 0;
};

// What a transform may need of the whole image: the depth scale and the normals' rotation (Residue's features)
// and OIDN's autoexposure of the colour.
struct WholeImageStats {
  FeatureStats features;
  float exposure = 1.0f;  // OIDN's autoexposure; 1 when not asked for
};

// From the stack in memory, or from one pass over the files' bands of `band` rows (only the colour and depth
// are read). `exposure`, `depth`: which of the two to measure.
WholeImageStats measure_whole_image(RowSource& source, bool exposure, bool depth, int64_t band,
                                    const CancelToken* cancel);

}  // namespace residue
