#include "core/metrics/temporal.h"

#include <cmath>
#include <limits>
#include <string>

#include "core/util/error.h"

namespace residue::metrics {

TemporalRelMse::TemporalRelMse(double eps, std::optional<Rect> roi) : eps_(eps), roi_(roi) {
  if (!(eps > 0 && std::isfinite(eps))) throw Error(ErrorKind::Usage, "eps must be a positive finite number");
}

void TemporalRelMse::add(const Image& frame, const Image& reference) {
  if (frame.width() != reference.width() || frame.height() != reference.height() || frame.channels() < 3 ||
      reference.channels() < 3)
    throw Error(ErrorKind::Usage, "temporal relMSE: a frame and its reference differ in size or lack RGB");
  if (prev_frame_.size() > 0) {
    if (frame.width() != prev_frame_.width() || frame.height() != prev_frame_.height())
      throw Error(ErrorKind::Usage, "temporal relMSE: the frames of a sequence must share one size (" +
                                        std::to_string(prev_frame_.width()) + "x" + std::to_string(prev_frame_.height()) +
                                        ", then " + std::to_string(frame.width()) + "x" + std::to_string(frame.height()) + ")");
    const Rect r = roi_.value_or(frame.bounds());
    if (!frame.bounds().contains(r)) throw Error(ErrorKind::Usage, "temporal relMSE: the ROI is not inside the frames");
    for (int64_t y = r.y; y < r.y + r.height; ++y)
      for (int64_t x = r.x; x < r.x + r.width; ++x) {
        double term = 0, symmetric = 0;
        bool finite = true;
        for (int c = 0; c < 3; ++c) {
          const double xt = frame.at(x, y, c), xp = prev_frame_.at(x, y, c);
          const double rt = reference.at(x, y, c), rp = prev_reference_.at(x, y, c);
          finite = finite && std::isfinite(xt) && std::isfinite(xp) && std::isfinite(rt) && std::isfinite(rp);
          const double d = (xt - xp) - (rt - rp);
          term += d * d / (rt * rt + eps_);
          symmetric += d * d / (0.5 * (rt * rt + rp * rp) + eps_);
        }
        if (!finite) {
          ++excluded_;
          continue;
        }
        sum_ += term / 3.0;
        sum_symmetric_ += symmetric / 3.0;
        ++pixels_;
      }
    ++pairs_;
  }
  prev_frame_ = frame;
  prev_reference_ = reference;
}

double TemporalRelMse::value() const {
  return pixels_ > 0 ? sum_ / static_cast<double>(pixels_) : std::numeric_limits<double>::quiet_NaN();
}

double TemporalRelMse::value_symmetric() const {
  return pixels_ > 0 ? sum_symmetric_ / static_cast<double>(pixels_) : std::numeric_limits<double>::quiet_NaN();
}

Image compensated_temporal_map(const Image& frame, const Image& reference, const Image& previous_error_warped,
                               const Image& previous_reference_warped, const Image& valid, double eps) {
  for (const Image* im : {&reference, &previous_error_warped, &previous_reference_warped, &valid})
    if (im->width() != frame.width() || im->height() != frame.height())
      throw Error(ErrorKind::Usage, "compensated temporal relMSE: the images of a pair differ in size");
  Image map(frame.width(), frame.height(), 1);
  for (int64_t y = 0; y < frame.height(); ++y)
    for (int64_t x = 0; x < frame.width(); ++x) {
      float& out = map.at(x, y);
      out = std::numeric_limits<float>::quiet_NaN();
      if (valid.at(x, y) == 0.0f) continue;
      double term = 0;
      bool finite = true;
      for (int c = 0; c < 3; ++c) {
        const double rt = reference.at(x, y, c), rp = previous_reference_warped.at(x, y, c);
        const double d = (double{frame.at(x, y, c)} - rt) - previous_error_warped.at(x, y, c);
        finite = finite && std::isfinite(d) && std::isfinite(rt) && std::isfinite(rp);
        term += d * d / (0.5 * (rt * rt + rp * rp) + eps);
      }
      if (finite) out = static_cast<float>(term / 3.0);
    }
  return map;
}

void CompensatedTemporalRelMse::add_pair(const Image& frame, const Image& reference, const Image& previous_error_warped,
                                         const Image& previous_reference_warped, const Image& valid) {
  add_map(compensated_temporal_map(frame, reference, previous_error_warped, previous_reference_warped, valid, eps_));
}

void CompensatedTemporalRelMse::add_map(const Image& map) {
  for (size_t i = 0; i < map.size(); ++i)
    if (const float v = map.data()[i]; std::isfinite(v)) {
      sum_ += v;
      ++pixels_;
    }
}

double CompensatedTemporalRelMse::value() const {
  return pixels_ > 0 ? sum_ / static_cast<double>(pixels_) : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace residue::metrics
