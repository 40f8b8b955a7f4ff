// The trainer's losses: the SSIM term scores what core's SSIM metric scores (same tonemap, same window), and the
// loss stays finite with finite gradients at numerical extremes.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <limits>

#include "core/aov/dataset.h"
#include "core/denoise/oidn_filter.h"
#include "core/denoise/pu_curve.h"
#include "core/features/features.h"
#include "core/metrics/metrics.h"
#include "core/metrics/tonemap.h"
#include "support/test_support.h"
#include "training_loss.h"

namespace residue {
namespace {

// An interleaved H x W x C image as a 1 x C x H x W tensor of the given type (a copy).
torch::Tensor to_tensor(const Image& image, torch::ScalarType type) {
  const auto hwc = torch::from_blob(const_cast<float*>(image.data()),
                                    {image.height(), image.width(), image.channels()}, torch::kFloat32);
  return hwc.permute({2, 0, 1}).unsqueeze(0).to(type).contiguous();
}

TEST(TrainLoss, TonemapIsCoresCurve) {
  const std::vector<double> xs = {-5.0, 0.0, 1e-6, 1e-4, 0.0021, 0.01, 0.18, 0.5, 1.0, 3.0, 11.19, 11.2, 40.0, 1e6};
  const auto t = train::tonemap_filmic_srgb(torch::tensor(xs, torch::kFloat64));
  for (size_t i = 0; i < xs.size(); ++i)
    EXPECT_NEAR(t[static_cast<int64_t>(i)].item<double>(), tonemap_filmic_srgb_f64(xs[i]), 1e-12) << "x = " << xs[i];
}

// A real render: a noisy Cycles image (starter s158) and its 512-spp reference, with core's float64 scores of
// the pair, which the loss terms must reproduce.
class TrainLossOnARealRender : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto starter = testing::shared_dataset("cycles-starter");
    RESIDUE_REQUIRE_SHARED(starter);
    scene_ = load_dataset_scene(starter / "s158");
    scores_ = metrics::compare(noisy(), reference());
  }
  const Image& noisy() const { return scene_.color.image; }
  const Image& reference() const { return scene_.reference->image; }
  // The render's colour as a 1 x 3 x H x W tensor of the given type.
  torch::Tensor colour(const Image& image, torch::ScalarType type) const {
    return to_tensor(image, type).slice(1, 0, 3);
  }
  AovStack scene_;
  metrics::Scores scores_;
};

// The loss's single-scale SSIM is core's metric: in float64 to rounding, in float32 (as training runs it) to 1e-5.
TEST_F(TrainLossOnARealRender, SsimIsCoresMetric) {
  const double expected = scores_.ssim;
  ASSERT_LT(expected, 0.95) << "a noisy image, so that the check is not near the trivial 1";
  for (const auto type : {torch::kFloat64, torch::kFloat32}) {
    const auto x = train::tonemap_filmic_srgb(colour(noisy(), type));
    const auto y = train::tonemap_filmic_srgb(colour(reference(), type));
    EXPECT_NEAR(train::ssim(x, y).item<double>(), expected, type == torch::kFloat64 ? 1e-10 : 1e-5);
    const double ms = train::multiscale_ssim(x, y, 3).item<double>();
    EXPECT_GT(ms, expected) << "coarser scales average the noise away";
    EXPECT_LT(ms, 1.0);
  }
}

// The relMSE term is core's relMSE metric, given log(1 + c) values, and its gradient stays finite where the
// prediction is far above a black target.
TEST_F(TrainLossOnARealRender, RelativeMseIsCoresMetric) {
  const double expected = scores_.relmse;
  ASSERT_GT(expected, 0.01) << "a noisy image, so that the check is not near the trivial 0";
  const auto x = torch::log1p(colour(noisy(), torch::kFloat64));
  const auto y = torch::log1p(colour(reference(), torch::kFloat64));
  EXPECT_NEAR(train::relative_mse(x, y).item<double>(), expected, 1e-9 * expected);
  EXPECT_NEAR(train::relative_mse(y, y).item<double>(), 0.0, 1e-15);
  auto far = torch::full({1, 3, 4, 4}, 30.0, torch::dtype(torch::kFloat32).requires_grad(true));
  const auto loss = train::relative_mse(far, torch::zeros({1, 3, 4, 4}));
  loss.backward();
  EXPECT_TRUE(std::isfinite(loss.item<double>()));
  EXPECT_TRUE(torch::isfinite(far.grad()).all().item<bool>()) << "the prediction is clamped before expm1";
}

// The low-band term against a naive float64 one (the relMSE of each box's per-channel linear means, boxes that do
// not fit left out); a checkerboard finer than the box does not reach it, a constant relative bias does.
TEST_F(TrainLossOnARealRender, LowBandRelativeMseIsTheBoxMeansRelMse) {
  const Image& n = noisy();
  const Image& r = reference();
  const auto x = torch::log1p(colour(n, torch::kFloat64));
  const auto y = torch::log1p(colour(r, torch::kFloat64));
  for (const int w : {8, 16, 24}) {
    double sum = 0;
    int64_t count = 0;
    for (int by = 0; by + w <= n.height(); by += w)
      for (int bx = 0; bx + w <= n.width(); bx += w)
        for (int c = 0; c < 3; ++c) {
          double mp = 0, mt = 0;
          for (int yy = by; yy < by + w; ++yy)
            for (int xx = bx; xx < bx + w; ++xx) {
              mp += n.data()[(static_cast<size_t>(yy) * n.width() + xx) * n.channels() + c];
              mt += r.data()[(static_cast<size_t>(yy) * r.width() + xx) * r.channels() + c];
            }
          mp /= w * w;
          mt /= w * w;
          sum += (mp - mt) * (mp - mt) / (mt * mt + 0.01);
          ++count;
        }
    const double expected = sum / static_cast<double>(count);
    EXPECT_NEAR(train::low_band_relative_mse(x, y, w).item<double>(), expected, 1e-9 * expected) << "box " << w;
  }
  const double all = train::relative_mse(x, y).item<double>();
  const double low = train::low_band_relative_mse(x, y, 16).item<double>();
  EXPECT_LT(low, 0.1 * all) << "the noise averages out in a 16-px box";

  const auto t = torch::expm1(y);
  const auto checker = (torch::arange(t.size(2)).view({-1, 1}) + torch::arange(t.size(3)).view({1, -1})).remainder(2) * 2 - 1;
  const auto biased = torch::log1p(1.1 * t);
  const auto biased_and_noisy = torch::log1p(1.1 * t + 0.05 * checker.to(torch::kFloat64));
  const double bias_alone = train::low_band_relative_mse(biased, y, 16).item<double>();
  EXPECT_GT(bias_alone, 1e-4);
  EXPECT_NEAR(train::low_band_relative_mse(biased_and_noisy, y, 16).item<double>(), bias_alone, 1e-12);
  EXPECT_GT(train::relative_mse(biased_and_noisy, y).item<double>(), 2 * train::relative_mse(biased, y).item<double>())
      << "the per-pixel term does see the checkerboard";
  EXPECT_THROW(train::low_band_relative_mse(y, y, n.width() + 1), std::invalid_argument);
}

// The edge term against a naive one: the mask from the scene's real feature planes in plain loops (a step of
// log(1 + albedo) above 0.1 or of the normal's x, y above 0.25 to the right or below marks both pixels), core's
// float64 SSIM map, and the masked sum of 1 - SSIM over the pixels whose window is inside, divided by their count.
TEST_F(TrainLossOnARealRender, EdgeSsimTermIsTheEdgePixelsShareOfOneMinusSsim) {
  Image features;
  const Rect all{0, 0, scene_.width(), scene_.height()};
  make_features(scene_, FeatureSet::Full, compute_feature_stats(scene_), all, features);
  const int albedo = first_plane(FeatureSet::Full, AovRole::Albedo), normal = first_plane(FeatureSet::Full, AovRole::Normal);
  const int64_t w = features.width(), h = features.height();
  std::vector<uint8_t> edge(static_cast<size_t>(w * h), 0);
  const auto step = [&](int64_t x0, int64_t y0, int64_t x1, int64_t y1) {
    bool big = false;
    for (int c = 0; c < 3; ++c)
      big |= std::abs(features.at(x1, y1, albedo + c) - features.at(x0, y0, albedo + c)) > train::kAlbedoEdge;
    for (int c = 0; c < 2; ++c)
      big |= std::abs(features.at(x1, y1, normal + c) - features.at(x0, y0, normal + c)) > train::kNormalEdge;
    if (big) edge[static_cast<size_t>(y0 * w + x0)] = edge[static_cast<size_t>(y1 * w + x1)] = 1;
  };
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x) {
      if (x + 1 < w) step(x, y, x + 1, y);
      if (y + 1 < h) step(x, y, x, y + 1);
    }
  const Image map = metrics::error_map(noisy(), reference(), metrics::MapKind::Ssim);
  double sum = 0;
  int64_t inner = 0, edges_inside = 0;
  for (int64_t y = 5; y < h - 5; ++y)
    for (int64_t x = 5; x < w - 5; ++x, ++inner)
      if (edge[static_cast<size_t>(y * w + x)]) {
        sum += 1.0 - map.at(x, y, 0);
        ++edges_inside;
      }
  ASSERT_GT(edges_inside, inner / 50) << "the scene has edges";
  ASSERT_LT(edges_inside, inner / 2) << "and flat parts";
  const double expected = sum / static_cast<double>(inner);
  ASSERT_GT(expected, 0.01);

  const auto planes = to_tensor(features, torch::kFloat64);
  const auto mask = train::aov_edge_mask(planes.slice(1, albedo, albedo + 3), planes.slice(1, normal, normal + 2));
  ASSERT_EQ(mask.sizes(), (std::vector<int64_t>{1, 1, h, w}));
  const auto marked = mask.contiguous();
  int64_t differ = 0;
  for (size_t i = 0; i < edge.size(); ++i) differ += (marked.data_ptr<double>()[i] != 0) != (edge[i] != 0);
  EXPECT_EQ(differ, 0);
  const auto x = torch::log1p(colour(noisy(), torch::kFloat64));
  const auto t = torch::log1p(colour(reference(), torch::kFloat64));
  EXPECT_NEAR(train::edge_ssim_loss(x, t, mask).item<double>(), expected, 1e-9);
  EXPECT_NEAR(train::edge_ssim_loss(x, t, torch::ones_like(mask)).item<double>(), 1.0 - scores_.ssim, 1e-9)
      << "every pixel an edge: the image's 1 - SSIM";
  EXPECT_EQ(train::edge_ssim_loss(x, t, torch::zeros_like(mask)).item<double>(), 0.0);
  EXPECT_NEAR(train::edge_ssim_loss(t, t, mask).item<double>(), 0.0, 1e-12);
}

TEST(TrainLoss, SsimTermIsZeroAtTheTargetAndGrowsWithTheError) {
  torch::manual_seed(5);
  const auto target = torch::log1p(torch::rand({2, 3, 64, 64}) * 4.0);
  EXPECT_NEAR(train::training_loss(train::Loss::L1LogSsim, target, target).item<double>(), 0.0, 1e-6);
  const auto slightly = target + 0.02 * torch::randn_like(target);
  const auto more = target + 0.2 * torch::randn_like(target);
  const double l1_slight = train::training_loss(train::Loss::L1Log, slightly, target).item<double>();
  const double ssim_slight = train::training_loss(train::Loss::L1LogSsim, slightly, target).item<double>() - l1_slight;
  const double l1_more = train::training_loss(train::Loss::L1Log, more, target).item<double>();
  const double ssim_more = train::training_loss(train::Loss::L1LogSsim, more, target).item<double>() - l1_more;
  EXPECT_GT(ssim_slight, 0.0);
  EXPECT_GT(ssim_more, 2.0 * ssim_slight);
  EXPECT_NEAR(train::training_loss(train::Loss::L1LogSsim, more, target, 3.0).item<double>(), l1_more + 3.0 * ssim_more, 1e-5)
      << "the weight scales the SSIM term only";
  EXPECT_FALSE(train::loss_from_name("l2"));
  EXPECT_EQ(train::loss_from_name("l1-log+ssim"), train::Loss::L1LogSsim);
  for (const auto& k : train::losses()) EXPECT_EQ(train::loss_from_name(k.name), k.loss) << k.name;
}

// A demodulated network's output goes back to log colour as core multiplies it back: log(1 + c / f) -> log(1 + c)
// with f = a + 0.01 and a from the albedo planes log(1 + a).
TEST(TrainLoss, RemodulationUndoesTheDemodulation) {
  const auto colour = torch::tensor({0.0, 0.3, 2.0, 150.0}, torch::kFloat64).reshape({1, 1, 2, 2}).expand({1, 3, 2, 2});
  const auto albedo = torch::tensor({0.0, 0.5, 0.02, 30.0}, torch::kFloat64).reshape({1, 1, 2, 2}).expand({1, 3, 2, 2});
  const auto demodulated = torch::log1p(colour / (albedo + 0.01));
  const auto back = train::remodulate(demodulated, torch::log1p(albedo));
  EXPECT_LT((back - torch::log1p(colour)).abs().max().item<double>(), 1e-12);
  auto negative = torch::full({1, 3, 2, 2}, -3.0, torch::requires_grad());
  const auto clamped = train::remodulate(negative, torch::log1p(albedo));
  EXPECT_TRUE(torch::isfinite(clamped).all().item<bool>()) << "a negative prediction times an emissive albedo";
}

// Black patches, values at and far beyond the tonemap's white point, a prediction far outside the data: the loss
// and every gradient stay finite (a NaN here would poison the weights on the first such patch).
TEST(TrainLoss, FiniteWithFiniteGradientsAtExtremes) {
  auto target = torch::zeros({1, 3, 32, 32}, torch::kFloat32);
  target.index_put_({0, 0}, std::log1p(1e4f));  // a light in one channel
  target.index_put_({0, 1, torch::indexing::Slice(0, 16)}, std::log1p(11.2f));
  for (const train::Loss kind : {train::Loss::L1LogSsim, train::Loss::L1PuSsim}) {
    for (const float fill : {0.0f, 1e-7f, 2.5f, 40.0f, -3.0f}) {
      auto prediction = torch::full({1, 3, 32, 32}, fill, torch::requires_grad());
      const auto loss = train::training_loss(kind, prediction, target);
      loss.backward();
      EXPECT_TRUE(std::isfinite(loss.item<double>())) << train::loss_kind(kind).name << ", prediction " << fill;
      EXPECT_TRUE(torch::isfinite(prediction.grad()).all().item<bool>()) << train::loss_kind(kind).name << ", prediction " << fill;
    }
  }
}

// The trainer's PU is core's (the OIDN filter's oidn_pu_forward, normalised to 1 at 65504), at 0.18 x the colour
// and in units of its log slope: differences of the two agree at points in each of the three pieces, and across
// the breaks.
TEST(TrainLoss, PuTransferIsCoresCurve) {
  const std::vector<double> colour = {-1e-6, 0.0, 1e-6, 8.7e-6, 1e-4, 0.01, 0.17, 0.179, 0.18, 0.2, 1.0, 30.0, 1e4};
  const auto pu = train::pu_transfer(torch::tensor(colour, torch::kFloat64));
  // Core's curve is normalised, pu(y) / pu(65504), and 65504 is on the log piece.
  const double pu_max = pu_curve::E * std::log(static_cast<double>(pu_curve::kHdrMax) + pu_curve::F) + pu_curve::G;
  for (size_t i = 1; i < colour.size(); ++i) {
    const double ours = pu[i].item<double>() - pu[0].item<double>();
    const double cores = (static_cast<double>(oidn_pu_forward(static_cast<float>(0.18 * colour[i]))) -
                          oidn_pu_forward(static_cast<float>(0.18 * colour[0]))) * pu_max / pu_curve::E;
    EXPECT_NEAR(ours, cores, 1e-5 * std::max(1.0, std::abs(cores))) << "colour " << colour[i];
  }
  // Above the knee it is the log of the colour, as log(1 + c) is above 1: equal steps for equal ratios.
  EXPECT_NEAR(pu[11].item<double>() - pu[10].item<double>(), std::log((0.18 * 30 + pu_curve::F) / (0.18 + pu_curve::F)),
              1e-9);
}

TEST(TrainLoss, PuLossIsTheL1OfThePuTransferPlusTheSsimTerm) {
  torch::manual_seed(6);
  const auto target = torch::log1p(torch::rand({2, 3, 64, 64}, torch::kFloat64) * 4.0);
  EXPECT_NEAR(train::training_loss(train::Loss::L1PuSsim, target, target).item<double>(), 0.0, 1e-9);
  const auto prediction = target + 0.1 * torch::randn_like(target);
  const double ssim_term = train::training_loss(train::Loss::L1LogSsim, prediction, target).item<double>() -
                           train::training_loss(train::Loss::L1Log, prediction, target).item<double>();
  const double l1_pu =
      (train::pu_transfer(torch::expm1(prediction)) - train::pu_transfer(torch::expm1(target))).abs().mean().item<double>();
  EXPECT_NEAR(train::training_loss(train::Loss::L1PuSsim, prediction, target).item<double>(), l1_pu + ssim_term, 1e-9);
  EXPECT_NEAR(train::training_loss(train::Loss::L1PuSsim, prediction, target, 0.0).item<double>(), l1_pu, 1e-9);
  // Dark pixels weigh more than in log(1 + c): the same relative error costs PU's L1 more at c = 0.3 than log's.
  const auto dark = torch::full({1, 3, 16, 16}, std::log1p(0.3), torch::kFloat64);
  const auto dark_off = torch::full({1, 3, 16, 16}, std::log1p(0.33), torch::kFloat64);
  EXPECT_GT(train::training_loss(train::Loss::L1PuSsim, dark_off, dark, 0.0).item<double>(),
            2.0 * train::training_loss(train::Loss::L1Log, dark_off, dark).item<double>());
}

}  // namespace
}  // namespace residue
