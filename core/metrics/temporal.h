// Flicker: how much a denoised sequence changes from frame to frame beyond what the references change.
//
//   temporal relMSE = mean over frame pairs (t-1, t), pixels and RGB channels of
//                     ((x_t - x_{t-1}) - (r_t - r_{t-1}))^2 / (r_t^2 + eps)
//
// the relMSE of the sequence's frame-to-frame differences against the references' own differences (eps as in
// relMSE, 0.01). With a static camera and one reference for every frame it is the mean squared frame-to-frame
// change, relative: pure flicker. Per-frame denoising that leaves residual noise or low-frequency blotches that
// move with the sampling seed raises it; a temporally stable result has it far below the noisy input's. It is
// the evaluation counterpart of the temporal term of Chaitanya et al. 2017 ("Interactive reconstruction of Monte
// Carlo image sequences using a recurrent denoising autoencoder"), whose loss compares the temporal derivatives
// of output and target. Pixels non-finite in any of the four images are excluded and counted; with an ROI only
// the ROI is scored.
//
// The symmetric form divides by (r_t^2 + r_{t-1}^2) / 2 + eps instead: on a shot where a highlight moves (bright
// at t-1, dark at t) the r_t form is dominated by the pixels it has just left (per-frame multiscale measured
// 7-11x its own relMSE that way, 1.6-1.8x in the symmetric form: issue 51), so both are reported.
#pragma once

#include <optional>

#include "core/image/image.h"

namespace residue::metrics {

class TemporalRelMse {
 public:
  explicit TemporalRelMse(double eps = 0.01, std::optional<Rect> roi = std::nullopt);
  // The next frame of the sequence and its reference (the sizes of the first frame; Error(Usage) otherwise).
  void add(const Image& frame, const Image& reference);
  // The next frame added does not follow the last one (a frame between them is missing): no pair across the gap.
  void gap() { prev_frame_ = Image(), prev_reference_ = Image(); }
  double value() const;            // NaN before two frames
  double value_symmetric() const;  // the same with (r_t^2 + r_{t-1}^2) / 2 + eps below
  int64_t pairs() const { return pairs_; }
  int64_t pixels() const { return pixels_; }      // pixel x pair terms that entered
  int64_t excluded() const { return excluded_; }  // ... left out as not finite

 private:
  double eps_;
  std::optional<Rect> roi_;
  Image prev_frame_, prev_reference_;
  double sum_ = 0, sum_symmetric_ = 0;
  int64_t pairs_ = 0, pixels_ = 0, excluded_ = 0;
};

// The motion-compensated form (issue 51): frame t's error e_t = x_t - r_t against frame t-1's error brought to
// frame t along the motion, over the pixels where frame t-1 shows the same surface:
//
//   mean over those pixels and RGB of (e_t - W e_{t-1})^2 / ((r_t^2 + (W r_{t-1})^2) / 2 + eps)
//
// where W warps frame t-1 to t (core/temporal/reprojection.h). On a moving camera the fixed-pixel forms above also
// count the error's own motion; this one counts only how the error on a surface changes. The caller warps; this
// adds one pair. Error(Usage) when the sizes differ.
class CompensatedTemporalRelMse {
 public:
  explicit CompensatedTemporalRelMse(double eps = 0.01) : eps_(eps) {}
  void add_pair(const Image& frame, const Image& reference, const Image& previous_error_warped,
                const Image& previous_reference_warped, const Image& valid);
  void add_map(const Image& map);  // a pair's compensated_temporal_map(): its finite pixels
  double value() const;  // NaN before a pair with a valid pixel
  int64_t pixels() const { return pixels_; }

 private:
  double eps_;
  double sum_ = 0;
  int64_t pixels_ = 0;
};

// One pair's terms per pixel (1 channel): the mean over RGB of the term above where frame t-1 shows the same
// surface and every value is finite, NaN elsewhere. The mean of its finite pixels is the pair's value; the viewer's
// temporal error map. Error(Usage) when the sizes differ.
Image compensated_temporal_map(const Image& frame, const Image& reference, const Image& previous_error_warped,
                               const Image& previous_reference_warped, const Image& valid, double eps = 0.01);

}  // namespace residue::metrics
