// The training losses. Predictions and targets are log(1 + c) of linear colour (N x 3 x H x W, float).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <torch/torch.h>

namespace residue::train {

// The main loss (--loss). The terms --relmse-weight, --lowband-weight, ... add are separate functions below.
enum class Loss { L1Log, L1LogMean, L1LogSsim, L1PuSsim };

struct LossKind {
  Loss loss;
  const char* name;         // what --loss takes
  const char* description;  // the model file's training metadata
  bool ssim_term;           // has the (1 - SSIM) term --ssim-weight weighs
  // The loss of log(1 + c) predictions against targets.
  torch::Tensor (*function)(const torch::Tensor& prediction, const torch::Tensor& target, double ssim_weight);
};
// Every loss, in the order --help lists them:
//   l1-log       the paper's L1 on log colour;
//   l1-log+mean  adds the L1 of the log patch means (see the .cpp);
//   l1-log+ssim  adds ssim_weight * (1 - multi-scale SSIM) on the tonemap the SSIM metric uses;
//   l1-pu+ssim   the same SSIM term, the L1 on pu_transfer of the linear colour instead of on log(1 + c).
const std::vector<LossKind>& losses();
const LossKind& loss_kind(Loss loss);
std::optional<Loss> loss_from_name(const std::string& name);

torch::Tensor training_loss(Loss loss, const torch::Tensor& prediction, const torch::Tensor& target,
                            double ssim_weight = 1.0);

// The learning rate at `step` of `steps`: cosine decay from `peak` to peak / 100, after 100 steps of linear warm-up.
double cosine_learning_rate(double peak, int step, int steps);

// The relMSE metric (core/metrics) on the linear values of log(1 + c) predictions and targets: the mean of
// (p - t)^2 / (t^2 + eps) over pixels and channels. --relmse-weight adds it to any loss.
torch::Tensor relative_mse(const torch::Tensor& prediction, const torch::Tensor& target, double eps = 0.01);

// relMSE of the `width` x `width` box means (non-overlapping; a remainder at the right and bottom is left out): the
// error's low band only, the wall blotches that the per-pixel terms weigh as little as fine noise (issue 16).
// --lowband-weight adds it to any loss. H and W must be at least `width`.
torch::Tensor low_band_relative_mse(const torch::Tensor& prediction, const torch::Tensor& target, int width,
                                    double eps = 0.01);

// Pixels on an edge of the albedo or the normal (issue 16: a third of x1's SSIM deficit indoors is there), from
// the network's input planes: 1 where log(1 + albedo) in any channel differs from a 4-neighbour's by more than
// kAlbedoEdge, or the view-space normal's x or y by more than kNormalEdge; else 0. albedo_planes N x 3 x H x W,
// normal_planes N x 2 x H x W; the result N x 1 x H x W, without gradient. A step marks the pixels on both sides.
constexpr double kAlbedoEdge = 0.1;
constexpr double kNormalEdge = 0.25;
torch::Tensor aov_edge_mask(const torch::Tensor& albedo_planes, const torch::Tensor& normal_planes);

// The edge pixels' share of 1 - SSIM (full resolution, the metric's tonemap and window): the sum of
// edges x (1 - SSIM map averaged over RGB) over the pixels whose window is inside the patch, divided by their
// count, so that it is exactly that class's contribution to the patch's 1 - SSIM (tools/research/error_bands.py's
// "1-SSIM albedo/normal edge"). --edge-ssim-weight adds it to any loss. H and W must be at least 11.
torch::Tensor edge_ssim_loss(const torch::Tensor& prediction, const torch::Tensor& target,
                             const torch::Tensor& edges);

// A demodulated network's output, log(1 + c / f), back to log(1 + c): f = a + 0.01 as core multiplies back
// (core/features/features.h), the albedo a recovered from its input planes log(1 + a). Products below -0.99 (a
// negative prediction times an emissive albedo) are clamped there, so the log stays finite.
torch::Tensor remodulate(const torch::Tensor& prediction, const torch::Tensor& albedo_planes);

// Linear colour -> the metric's display values: Hable's filmic curve normalised at 11.2, clamped, then the
// sRGB OETF (core/metrics/tonemap.h), differentiable (the OETF's power is taken above its linear segment only).
torch::Tensor tonemap_filmic_srgb(const torch::Tensor& linear);

// OIDN's PU transfer (core/denoise/pu_curve.h) of kPuExposure x the linear colour, divided by its log branch's
// slope E so that above the knee it is log(y + F) + const, as log(1 + c) is above 1: the two L1 terms then weigh
// bright pixels alike. kPuExposure puts the trainer's autoexposed colour (key 1) at OIDN's key, 0.18. Differentiable
// everywhere; below 0 the linear piece continues.
constexpr double kPuExposure = 0.18;
torch::Tensor pu_transfer(const torch::Tensor& linear);

// SSIM per pixel and channel, N x C x (H - 10) x (W - 10): the pixels whose whole window is inside.
torch::Tensor ssim_map(const torch::Tensor& x, const torch::Tensor& y);

// Mean SSIM of two N x C x H x W images in [0, 1]: core's metric (11x11 Gaussian, sigma 1.5, K1 0.01, K2 0.03,
// population (co)variances, per channel, averaged over the pixels whose whole window is inside: a "valid"
// convolution). H and W must be at least 11.
torch::Tensor ssim(const torch::Tensor& x, const torch::Tensor& y);

// The mean of SSIM over `scales` resolutions (each a 2x2 average of the one before); scales whose image is
// smaller than the window are left out.
torch::Tensor multiscale_ssim(const torch::Tensor& x, const torch::Tensor& y, int scales = 3);

}  // namespace residue::train
