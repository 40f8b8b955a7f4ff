// AOV stack -> the network's input planes, and the network's output -> linear colour.
// The one place this mapping lives: inference and training both call it (no second copy anywhere).
//
// Planes, in order (FeatureSet says which are present):
//   colour  log(1 + c)                       c sanitised: NaN/Inf/negative -> 0
//   depth   log(1 + d / depth scale)         background (0) stays 0; the scale is the median hit depth rounded
//                                            to 1/8 octave, per image, so units do not matter
//   normal  view-space x, y                  world-space normals rotated by the camera when it is known;
//                                            non-finite -> 0, clamped to [-1, 1]
//   albedo  log(1 + a)                       a sanitised like colour; log keeps emissive albedo (> 1) bounded
//   noise   log(1 + sqrt(mean_RGB var))      (full+variance only) var: the per-pixel variance of the colour
//                                            estimate, from the variance AOV (for a data set's scenes: from the two
//                                            halves, load_dataset_scene);
//                                            the standard deviation in the colour's units, log-compressed alike
//   prior   log(1 + p)                       (post-correction models only, after the set's planes) p: the prior
//                                            model's denoised colour (stack.prior), sanitised like colour
//   t-k..   log(1 + n), valid                (temporal models only, last; per neighbour -k..-1, +1..+k) n: the
//                                            neighbour's noisy colour warped to this frame (stack.neighbours),
//                                            sanitised like colour and exposed like it; valid 1 or 0. A neighbour
//                                            the stack lacks (the shot's first or last frames) reads as this
//                                            frame's colour with valid 0, as a disoccluded pixel does
// Output: c = exp(y) - 1, clamped to [0, FLT_MAX], NaN -> 0: always finite and non-negative.
// Autoexposed models (Architecture::autoexposure) see c (noise, p) times the image's exposure (FeatureStats) in
// place of c, and their output is divided by it: scaling a render's colour scales their output alike.
// Demodulated models (Architecture::demodulate, issue 16's lever 4) see the colour divided by the albedo,
// log(1 + c / (a + 0.01)) per channel (a sanitised like colour), and their output is multiplied back by (a + 0.01):
// texture comes back from the albedo by construction; 0.01 bounds the gain where the albedo is black.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/aov/aov_stack.h"
#include "core/features/feature_set.h"

namespace residue {

// Whole-image statistics the features need, computed once so that every tile sees the same normalisation.
struct FeatureStats {
  double depth_scale = 1.0;  // median depth of hits, rounded to 1/8 octave (1 when none)
  bool rotate_normals = false;  // world-space normals and a known camera
  std::array<double, 9> normal_rotation{1, 0, 0, 0, 1, 0, 0, 0, 1};  // world -> camera, row-major 3x3
  // Not statistics: the model's encoding, set by the caller from its Architecture.
  bool demodulate = false;  // colour (and prior) divided by the albedo
  // Colour, noise and prior multiplied by this before the log, the output divided by it: 1, or for models with
  // Architecture::autoexposure the image's autoexposure (the model's key / the log-average luminance; OIDN's
  // key is 0.18: Architecture::exposure).
  float exposure = 1.0f;
  bool prior = false;       // 3 more planes: the prior model's colour (stack.prior)
  int temporal = 0;         // 4 more planes per neighbour of this radius (stack.neighbours)
};

FeatureStats compute_feature_stats(const AovStack& stack);

// The depth scale is the median of a sample of the depth plane: every stride-th pixel in row-major order
// (at most about 2^20 of them), so a whole stack and the same render read band by band get the same scale.
class DepthScaleSampler {
 public:
  explicit DepthScaleSampler(int64_t pixel_count);
  // The depth of consecutive pixels, the first being pixel `first` of the image (row-major).
  void add(const float* depth, int64_t count, int64_t first);
  double scale();  // the median of the hits, rounded to 1/8 octave; 1 when none

 private:
  int64_t stride_;
  std::vector<float> samples_;
};

// The richest feature set the stack can feed without inventing data. The sets nest: full+variance needs
// everything full needs plus variance; full > color+albedo+normal > color.
FeatureSet feature_set_for(const AovStack& stack);


// Throws Error(Input) naming what is missing when `stack` cannot feed `set`.
void check_features_available(const AovStack& stack, FeatureSet set);

// Fills `out` with the feature planes of `rect` (inside the stack): rect.width x rect.height x channels (+ 3 with
// stats.prior, + 8 x stats.temporal).
void make_features(const AovStack& stack, FeatureSet set, const FeatureStats& stats, const Rect& rect, Image& out);

// Colour transform and its inverse, exposed for training and tests.
float compress_color(float linear);
float expand_color(float network_output);
// What a demodulated model's colour is divided by, and its output multiplied by: sanitised albedo + 0.01.
float demodulation_factor(float albedo);
// A colour value times the exposure, kept finite: a finite value that overflows becomes FLT_MAX (NaN, Inf and
// negatives stay as they are, for compress_color to sanitise).
float exposed(float linear, float exposure);

}  // namespace residue
