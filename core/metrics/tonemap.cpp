#include "core/metrics/tonemap.h"

#include <cmath>

namespace residue {
namespace {

constexpr double kA = 0.15;
constexpr double kB = 0.50;
constexpr double kC = 0.10;
constexpr double kD = 0.20;
constexpr double kE = 0.02;
constexpr double kF = 0.30;
constexpr double kWhite = 11.2;

constexpr double hable(double x) {
  return (x * (kA * x + kC * kB) + kD * kE) / (x * (kA * x + kB) + kD * kF) - kE / kF;
}

constexpr double kWhiteScale = hable(kWhite);

// sRGB OETF for t already known to be a number; clamps to [0, 1].
double srgb_oetf_f64(double t) {
  if (!(t > 0.0)) return 0.0;  // also NaN
  if (t >= 1.0) t = 1.0;
  const double v = t < 0.0031308 ? 12.92 * t : 1.055 * std::pow(t, 1.0 / 2.4) - 0.055;
  return v < 0.0 ? 0.0 : (v > 1.0 ? 1.0 : v);
}

}  // namespace

double tonemap_filmic_srgb_f64(double linear) {
  if (!(linear > 0.0)) return 0.0;  // negatives, -Inf and NaN
  // f is increasing, so everything at or above the white point clamps to 1; this also keeps x*x from
  // overflowing for huge inputs (+Inf, FLT_MAX fireflies).
  const double t = linear >= kWhite ? 1.0 : hable(linear) / kWhiteScale;
  return srgb_oetf_f64(t);
}

float tonemap_filmic_srgb(float linear) {
  return static_cast<float>(tonemap_filmic_srgb_f64(static_cast<double>(linear)));
}

float srgb_oetf(float linear) { return static_cast<float>(srgb_oetf_f64(static_cast<double>(linear))); }

}  // namespace residue
