#include "core/denoise/oidn_filter.h"

#include <algorithm>
#include <cfloat>
#include <cmath>

#include "core/denoise/pu_curve.h"

namespace residue {
namespace {

// PU, unnormalised (core/denoise/pu_curve.h).
float pu(float y) {
  using namespace pu_curve;
  if (y <= Y0) return A * y;
  if (y <= Y1) return B * std::pow(y, C) + D;
  return E * std::log(y + F) + G;
}

float pu_inv(float x) {
  using namespace pu_curve;
  if (x <= X0) return x / A;
  if (x <= X1) return std::pow((x - D) / B, 1.0f / C);
  return std::exp((x - G) / E) - F;
}

const float kPuNorm = 1.0f / pu(pu_curve::kHdrMax);

float srgb(float y) { return y <= 0.0031308f ? 12.92f * y : 1.055f * std::pow(y, 1.0f / 2.4f) - 0.055f; }
float srgb_inv(float x) { return x <= 0.04045f ? x / 12.92f : std::pow((x + 0.055f) / 1.055f, 2.4f); }

float sanitise(float v, float lo, float hi) { return std::isnan(v) ? std::clamp(0.0f, lo, hi) : std::clamp(v, lo, hi); }

float luminance(float r, float g, float b) { return 0.212671f * r + 0.715160f * g + 0.072169f * b; }

}  // namespace

float oidn_pu_forward(float y) { return pu(y) * kPuNorm; }
float oidn_pu_inverse(float x) { return pu_inv(x / kPuNorm); }

OidnAutoexposure::OidnAutoexposure(int64_t width, int64_t height)
    : w_(width), h_(height), bins_x_((width + 15) / 16), bins_y_((height + 15) / 16) {
  // Bin j covers [j * W / bins, (j + 1) * W / bins), as OIDN cuts them.
  bin_of_x_.resize(static_cast<size_t>(std::max<int64_t>(w_, 0)));
  bin_of_y_.resize(static_cast<size_t>(std::max<int64_t>(h_, 0)));
  for (int64_t j = 0; j < bins_x_; ++j)
    for (int64_t x = j * w_ / bins_x_; x < (j + 1) * w_ / bins_x_; ++x) bin_of_x_[static_cast<size_t>(x)] = j;
  for (int64_t i = 0; i < bins_y_; ++i)
    for (int64_t y = i * h_ / bins_y_; y < (i + 1) * h_ / bins_y_; ++y) bin_of_y_[static_cast<size_t>(y)] = i;
  sum_.assign(static_cast<size_t>(bins_x_ * bins_y_), 0.0);
}

void OidnAutoexposure::add(const Image& colour, int64_t y0) {
  for (int64_t y = 0; y < colour.height(); ++y) {
    const int64_t row = bin_of_y_[static_cast<size_t>(y0 + y)] * bins_x_;
    for (int64_t x = 0; x < colour.width(); ++x) {
      const float* p = colour.row(y).data() + x * colour.channels();
      sum_[static_cast<size_t>(row + bin_of_x_[static_cast<size_t>(x)])] +=
          luminance(sanitise(p[0], 0, FLT_MAX), sanitise(p[1], 0, FLT_MAX), sanitise(p[2], 0, FLT_MAX));
    }
  }
}

float OidnAutoexposure::scale() const {
  std::vector<double> mean(sum_.size());
  double brightest = 0;
  for (int64_t i = 0; i < bins_y_; ++i)
    for (int64_t j = 0; j < bins_x_; ++j) {
      const int64_t pixels = ((i + 1) * h_ / bins_y_ - i * h_ / bins_y_) * ((j + 1) * w_ / bins_x_ - j * w_ / bins_x_);
      const size_t b = static_cast<size_t>(i * bins_x_ + j);
      mean[b] = sum_[b] / static_cast<double>(pixels);
      brightest = std::max(brightest, mean[b]);
    }
  constexpr double kOidnFloor = 1e-8;
  const double black = std::min(kOidnFloor, 1e-5 * brightest);
  double log_sum = 0;
  int64_t count = 0;
  for (const double l : mean)
    if (l > black) {
      log_sum += std::log2(l);
      ++count;
    }
  if (count == 0) return 1.0f;
  return static_cast<float>(std::min(1e38, 0.18 / std::exp2(log_sum / static_cast<double>(count))));
}

float oidn_autoexposure(const Image& colour) {
  OidnAutoexposure a(colour.width(), colour.height());
  a.add(colour, 0);
  return a.scale();
}

OidnTransform::OidnTransform(const nn::OidnInputs& inputs, float input_scale) : in_(inputs), scale_(input_scale) {
  if (!in_.color && in_.normal) tf_ = Transfer::Linear;  // a normal prefilter
  else if (in_.hdr) tf_ = Transfer::Pu;
  else tf_ = Transfer::Srgb;
}

int OidnTransform::channels() const { return 3 * (int{in_.color} + int{in_.albedo} + int{in_.normal}); }

float OidnTransform::forward(float v) const {
  switch (tf_) {
    case Transfer::Pu: return oidn_pu_forward(v);
    case Transfer::Srgb: return srgb(v);
    case Transfer::Linear: return v;
  }
  return v;
}

void OidnTransform::input(const AovStack& stack, const Rect& r, Image& planes) const {
  const int c = channels();
  if (planes.width() != r.width || planes.height() != r.height || planes.channels() != c) planes = Image(r.width, r.height, c);
  const bool alone = !in_.color;  // a prefilter: its image takes the colour's scale and transfer
  for (int64_t y = 0; y < r.height; ++y)
    for (int64_t x = 0; x < r.width; ++x) {
      float* out = &planes.at(x, y, 0);
      int k = 0;
      if (in_.color) {
        const float* p = stack.color.image.row(r.y + y).data() + (r.x + x) * stack.color.image.channels();
        for (int i = 0; i < 3; ++i) out[k++] = forward(sanitise(p[i] * scale_, 0.0f, in_.hdr ? FLT_MAX : 1.0f));
      }
      if (in_.albedo) {
        const float* p = stack.albedo->image.row(r.y + y).data() + (r.x + x) * stack.albedo->image.channels();
        for (int i = 0; i < 3; ++i) {
          const float v = sanitise(alone ? p[i] * scale_ : p[i], 0.0f, 1.0f);
          out[k++] = alone ? forward(v) : v;
        }
      }
      if (in_.normal) {
        const float* p = stack.normal->image.row(r.y + y).data() + (r.x + x) * stack.normal->image.channels();
        for (int i = 0; i < 3; ++i) out[k++] = sanitise(alone ? p[i] * scale_ : p[i], -1.0f, 1.0f) * 0.5f + 0.5f;
      }
    }
}

float OidnTransform::output(float v) const {
  v = sanitise(v, 0.0f, FLT_MAX);
  switch (tf_) {
    case Transfer::Pu: v = oidn_pu_inverse(v); break;
    case Transfer::Srgb: v = srgb_inv(v); break;
    case Transfer::Linear: break;
  }
  const bool snorm = !in_.color && in_.normal;
  if (snorm) v = std::max(v * 2.0f - 1.0f, -1.0f);
  if (!in_.hdr) v = std::min(v, 1.0f);
  // Finite always: the inverse transfer of a large network output, or a tiny autoexposure's inverse, overflows.
  // (0 times the Inf inverse of a denormal autoexposure is 0.)
  const float linear = v * (scale_ != 0.0f ? 1.0f / scale_ : 0.0f);
  return std::isnan(linear) ? 0.0f : std::min(linear, FLT_MAX);
}

}  // namespace residue
