#include "training_loss.h"

#include <cmath>
#include <stdexcept>

#include "core/denoise/pu_curve.h"

namespace residue::train {
namespace {

constexpr int kRadius = 5;  // core/metrics: an 11-tap Gaussian of sigma 1.5
constexpr double kSigma = 1.5;
constexpr double kC1 = 0.01 * 0.01;
constexpr double kC2 = 0.03 * 0.03;

// The 11 x 11 window is the outer product of an 11-tap Gaussian with itself, so it is applied as two depthwise
// passes (1 x 11, then 11 x 1) for `channels` channels: 22 multiply-adds a pixel and channel instead of 121.
struct SeparableWindow {
  torch::Tensor across, down;  // C x 1 x 1 x 11, C x 1 x 11 x 1
};

SeparableWindow gaussian_window(int64_t channels, const torch::TensorOptions& options) {
  auto d = torch::arange(-kRadius, kRadius + 1, torch::TensorOptions().dtype(torch::kFloat64));
  auto g = torch::exp(-0.5 * d * d / (kSigma * kSigma));
  g = (g / g.sum()).to(options);
  const int64_t taps = 2 * kRadius + 1;
  return {g.view({1, 1, 1, taps}).expand({channels, 1, 1, taps}).contiguous(),
          g.view({1, 1, taps, 1}).expand({channels, 1, taps, 1}).contiguous()};
}

torch::Tensor blur(const torch::Tensor& x, const SeparableWindow& window) {
  namespace F = torch::nn::functional;
  const auto depthwise = F::Conv2dFuncOptions().groups(x.size(1));  // "valid"
  return F::conv2d(F::conv2d(x, window.across, depthwise), window.down, depthwise);
}

// Hable's curve, f(x) = (x (A x + C B) + D E) / (x (A x + B) + D F) - E / F.
torch::Tensor hable(const torch::Tensor& x) {
  constexpr double A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30;
  return (x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F) - E / F;
}

double hable(double x) {
  constexpr double A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30;
  return (x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F) - E / F;
}

// The relMSE formula on linear values, (p - t)^2 / (t^2 + eps) averaged: the per-pixel and the low-band terms.
torch::Tensor relmse_of_linear(const torch::Tensor& p, const torch::Tensor& t, double eps) {
  return ((p - t).square() / (t.square() + eps)).mean();
}

// Where a plane differs from its right or lower neighbour by more than `threshold`, both pixels are marked.
torch::Tensor steps_above(const torch::Tensor& planes, double threshold) {
  const int64_t h = planes.size(2), w = planes.size(3);
  const auto across = (planes.slice(3, 1, w) - planes.slice(3, 0, w - 1)).abs().amax(1, true) > threshold;
  const auto down = (planes.slice(2, 1, h) - planes.slice(2, 0, h - 1)).abs().amax(1, true) > threshold;
  auto mask = torch::zeros({planes.size(0), 1, h, w}, planes.options().dtype(torch::kBool));
  mask.slice(3, 1, w).logical_or_(across);
  mask.slice(3, 0, w - 1).logical_or_(across);
  mask.slice(2, 1, h).logical_or_(down);
  mask.slice(2, 0, h - 1).logical_or_(down);
  return mask;
}

}  // namespace

torch::Tensor remodulate(const torch::Tensor& prediction, const torch::Tensor& albedo_planes) {
  const auto factor = torch::expm1(albedo_planes).clamp_min(0.0) + 0.01;
  return torch::log1p((torch::expm1(prediction.clamp_max(20.0)) * factor).clamp_min(-0.99));
}

torch::Tensor tonemap_filmic_srgb(const torch::Tensor& linear) {
  constexpr double kWhite = 11.2;
  const auto x = linear.clamp(0.0, kWhite);
  const auto t = (hable(x) / hable(kWhite)).clamp(0.0, 1.0);
  // The OETF's power branch sees t >= its threshold only, so that its gradient stays finite near 0.
  const auto power = 1.055 * t.clamp_min(0.0031308).pow(1.0 / 2.4) - 0.055;
  return torch::where(t < 0.0031308, 12.92 * t, power);
}

torch::Tensor pu_transfer(const torch::Tensor& linear) {
  using namespace pu_curve;
  const auto y = linear * kPuExposure;
  // Each branch sees only values inside its own piece (clamped), so that no gradient is infinite or NaN: the power
  // at 0, the log below -F. The linear piece continues below 0, so a negative prediction is pulled back up.
  const auto power = B * y.clamp_min(Y0).pow(C) + D;
  const auto log = E * torch::log(y.clamp_min(Y1) + F) + G;
  return torch::where(y <= Y0, A * y, torch::where(y <= Y1, power, log)) / E;
}

torch::Tensor ssim_map(const torch::Tensor& x, const torch::Tensor& y) {
  if (x.size(2) < 2 * kRadius + 1 || x.size(3) < 2 * kRadius + 1)
    throw std::invalid_argument("ssim: images must be at least 11 x 11");
  // The five local means in one blur: of x, y, x^2, y^2 and x y.
  const int64_t c = x.size(1);
  const auto m = blur(torch::cat({x, y, x * x, y * y, x * y}, 1), gaussian_window(5 * c, x.options()));
  const auto mx = m.slice(1, 0, c), my = m.slice(1, c, 2 * c);
  const auto vx = m.slice(1, 2 * c, 3 * c) - mx * mx;
  const auto vy = m.slice(1, 3 * c, 4 * c) - my * my;
  const auto cxy = m.slice(1, 4 * c, 5 * c) - mx * my;
  return ((2 * mx * my + kC1) * (2 * cxy + kC2)) / ((mx * mx + my * my + kC1) * (vx + vy + kC2));
}

torch::Tensor ssim(const torch::Tensor& x, const torch::Tensor& y) { return ssim_map(x, y).mean(); }

torch::Tensor multiscale_ssim(const torch::Tensor& x, const torch::Tensor& y, int scales) {
  torch::Tensor sum = ssim(x, y);
  int used = 1;
  torch::Tensor a = x, b = y;
  for (int s = 1; s < scales; ++s) {
    a = torch::avg_pool2d(a, 2);
    b = torch::avg_pool2d(b, 2);
    if (a.size(2) < 2 * kRadius + 1 || a.size(3) < 2 * kRadius + 1) break;
    sum = sum + ssim(a, b);
    ++used;
  }
  return sum / used;
}

// "l1-log" is the paper's L1. L1 on log values estimates the median of the noisy target's log, which for very
// noisy dark pixels lies below the mean: the output comes out darker. "l1-log+mean" adds, per patch and channel,
// the L1 distance between the logs of the patch's linear means, |log(1 + mean(exp(p) - 1)) - log(1 + mean(exp(t) -
// 1))|: a mean-matching term in the same log units as the per-pixel term (a first version used the patches'
// relative mean error, which dark patches dominated: validation relMSE 0.075 against 0.027 at 2000 steps).
// "l1-log+ssim" adds the structural term production denoisers train with (issue 16, lever 1), on the very values
// the SSIM metric scores, at full, half and quarter resolution (coarse scales weigh the low-frequency blotches).
// "l1-pu+ssim" is the same with the L1 measured in the PU transfer OIDN trains in (lever 1's transfer): log(1 + c)
// weighs an error relatively only above c ~ 1 (the image's log-average, autoexposed), PU above c ~ 0.2 and as a
// power (0.43) below it: nearer relMSE, which is relative down to c ~ 0.1.
namespace {

torch::Tensor l1_log(const torch::Tensor& prediction, const torch::Tensor& target, double) {
  return torch::l1_loss(prediction, target);
}

torch::Tensor l1_log_mean(const torch::Tensor& prediction, const torch::Tensor& target, double) {
  const auto mp = torch::log1p(torch::expm1(prediction.clamp_max(20.0)).mean({2, 3}).clamp_min(0.0));
  const auto mt = torch::log1p(torch::expm1(target).mean({2, 3}));
  return torch::l1_loss(prediction, target) + (mp - mt).abs().mean();
}

torch::Tensor ssim_term(const torch::Tensor& p, const torch::Tensor& t, double ssim_weight) {
  return ssim_weight * (1.0 - multiscale_ssim(tonemap_filmic_srgb(p), tonemap_filmic_srgb(t), 3));
}

torch::Tensor l1_log_ssim(const torch::Tensor& prediction, const torch::Tensor& target, double ssim_weight) {
  return torch::l1_loss(prediction, target) +
         ssim_term(torch::expm1(prediction.clamp_max(20.0)), torch::expm1(target), ssim_weight);
}

torch::Tensor l1_pu_ssim(const torch::Tensor& prediction, const torch::Tensor& target, double ssim_weight) {
  const auto p = torch::expm1(prediction.clamp_max(20.0));
  const auto t = torch::expm1(target);
  return torch::l1_loss(pu_transfer(p), pu_transfer(t)) + ssim_term(p, t, ssim_weight);
}

}  // namespace

const std::vector<LossKind>& losses() {
  static const std::vector<LossKind> table = {
      {Loss::L1Log, "l1-log", "L1 on log(1+c)", false, l1_log},
      {Loss::L1LogMean, "l1-log+mean", "L1 on log(1+c) + L1 of the log patch means", false, l1_log_mean},
      {Loss::L1LogSsim, "l1-log+ssim",
       "L1 on log(1+c) + w * (1 - SSIM averaged over 3 scales) on the metric's filmic-sRGB tonemap", true, l1_log_ssim},
      {Loss::L1PuSsim, "l1-pu+ssim",
       "L1 on OIDN's PU transfer of 0.18 c (in units of its log slope) + w * (1 - SSIM averaged over 3 scales) on the "
       "metric's filmic-sRGB tonemap",
       true, l1_pu_ssim},
  };
  return table;
}

const LossKind& loss_kind(Loss loss) {
  for (const LossKind& k : losses())
    if (k.loss == loss) return k;
  throw std::invalid_argument("a loss without an entry in losses()");
}

std::optional<Loss> loss_from_name(const std::string& name) {
  for (const LossKind& k : losses())
    if (name == k.name) return k.loss;
  return std::nullopt;
}

torch::Tensor training_loss(Loss loss, const torch::Tensor& prediction, const torch::Tensor& target,
                            double ssim_weight) {
  return loss_kind(loss).function(prediction, target, ssim_weight);
}

// The metric the goal is scored on, as a loss term (issue 16, lever 1): L1 on log colour weighs a relative error
// the same everywhere, while relMSE squares it, so that the few large errors of very noisy dark interiors (where
// the mean relMSE is decided) pull harder than many small ones.
torch::Tensor relative_mse(const torch::Tensor& prediction, const torch::Tensor& target, double eps) {
  return relmse_of_linear(torch::expm1(prediction.clamp_max(20.0)), torch::expm1(target), eps);
}

// A 2% bias over a 48-px patch of wall costs the per-pixel terms as much as 2% of noise, which they leave behind
// everywhere; averaged over a box the noise cancels and the bias stays, so this term weighs blotches alone.
torch::Tensor low_band_relative_mse(const torch::Tensor& prediction, const torch::Tensor& target, int width,
                                    double eps) {
  if (width < 1 || prediction.size(2) < width || prediction.size(3) < width)
    throw std::invalid_argument("low_band_relative_mse: the box (" + std::to_string(width) +
                                " px) must fit the patch");
  return relmse_of_linear(torch::avg_pool2d(torch::expm1(prediction.clamp_max(20.0)), width),
                          torch::avg_pool2d(torch::expm1(target), width), eps);
}

torch::Tensor aov_edge_mask(const torch::Tensor& albedo_planes, const torch::Tensor& normal_planes) {
  torch::NoGradGuard no_grad;
  const auto edges = steps_above(albedo_planes, kAlbedoEdge).logical_or(steps_above(normal_planes, kNormalEdge));
  return edges.to(albedo_planes.scalar_type());
}

// The per-pixel SSIM term averages over every pixel, and most pixels of a patch are flat: an edge smeared by a
// pixel costs it little. This term counts the full-resolution SSIM loss again on the edge pixels alone, with its
// own weight.
torch::Tensor edge_ssim_loss(const torch::Tensor& prediction, const torch::Tensor& target, const torch::Tensor& edges) {
  const auto p = tonemap_filmic_srgb(torch::expm1(prediction.clamp_max(20.0)));
  const auto t = tonemap_filmic_srgb(torch::expm1(target));
  const auto loss = 1.0 - ssim_map(p, t).mean(1, true);
  const int64_t h = edges.size(2), w = edges.size(3);
  return (loss * edges.slice(2, kRadius, h - kRadius).slice(3, kRadius, w - kRadius)).mean();
}

double cosine_learning_rate(double peak, int step, int steps) {
  const double progress = static_cast<double>(step) / steps;
  double lr = peak * (0.01 + 0.99 * 0.5 * (1 + std::cos(M_PI * progress)));
  if (step < 100) lr *= (step + 1) / 100.0;
  return lr;
}

}  // namespace residue::train
