// The network and its backends against an independent float64 implementation.
#include <cmath>

#include <gtest/gtest.h>

#include "core/nn/backend.h"
#include "support/reference_network.h"
#include "support/test_support.h"

namespace residue {
namespace {

using nn::Architecture;

TEST(NnArchitecture, PaperModelCounts) {
  Architecture paper{16, 128, FeatureSet::Full};
  EXPECT_EQ(paper.conv_layers(), 35);
  EXPECT_EQ(paper.in_channels(), 9);
  // 9.76 TFLOP per megapixel (the brief's figure).
  EXPECT_NEAR(paper.flops_per_pixel() * 1e6 / 1e12, 9.76, 0.01);
}

TEST(NnBatchNorm, FoldingEqualsExplicitBatchNorm) {
  nn::Network net = nn::random_network({1, 8, FeatureSet::ColorOnly}, 3);
  nn::BatchNorm bn;
  for (int o = 0; o < 8; ++o) {
    bn.gamma.push_back(0.5f + 0.1f * static_cast<float>(o));
    bn.beta.push_back(-0.2f + 0.05f * static_cast<float>(o));
    bn.mean.push_back(0.3f * static_cast<float>(o % 3));
    bn.var.push_back(0.5f + static_cast<float>(o));
  }
  const Image x = testing::random_image(5, 4, 8, 9, -1.0f, 1.0f);
  const testing::Tensor64 raw = testing::naive_conv3x3(testing::to_tensor(x), net.tail);
  const testing::Tensor64 folded = testing::naive_conv3x3(testing::to_tensor(x), nn::fold_batch_norm(net.tail, bn));
  for (size_t i = 0; i < raw.v.size(); ++i) {
    const size_t o = i % 8;
    const double expect = (raw.v[i] - bn.mean[o]) / std::sqrt(static_cast<double>(bn.var[o]) + bn.eps) * bn.gamma[o] + bn.beta[o];
    EXPECT_NEAR(folded.v[i], expect, 1e-5) << i;
  }
}

struct BackendCase {
  std::string backend;
  nn::Precision precision;
  double tolerance;
};

class NnBackend : public ::testing::TestWithParam<BackendCase> {};

TEST_P(NnBackend, WholeNetworkMatchesFloat64Reference) {
  const auto& p = GetParam();
  for (const auto& [arch, w, h] : std::vector<std::tuple<Architecture, int, int>>{
           {{2, 16, FeatureSet::Full}, 13, 9}, {{3, 32, FeatureSet::ColorOnly}, 1, 1},
           {{1, 8, FeatureSet::ColorAlbedoNormal}, 3, 5}, {{2, 16, FeatureSet::Full}, 40, 2}}) {
    const nn::Network net = nn::random_network(arch, 42);
    const Image x = testing::random_image(w, h, arch.in_channels(), 7, -1.0f, 2.0f);
    auto backend = nn::make_backend(p.backend, net, {p.precision});
    Image out;
    backend->run(x, out);
    ASSERT_EQ(out.width(), w);
    ASSERT_EQ(out.height(), h);
    ASSERT_EQ(out.channels(), 3);
    const double err = testing::max_relative_error(out, testing::naive_forward(net, x));
    EXPECT_LT(err, p.tolerance) << backend->description() << " " << arch.to_string() << " " << w << "x" << h;
  }
}

TEST_P(NnBackend, WideImageMatchesReference) {
  // 1000 x 7: many GEMM strips, one row of tiles.
  const auto& p = GetParam();
  const nn::Network net = nn::random_network({1, 8, FeatureSet::Full}, 5);
  const Image x = testing::random_image(1000, 7, 9, 11, 0.0f, 1.0f);
  auto backend = nn::make_backend(p.backend, net, {p.precision});
  Image out;
  backend->run(x, out);
  EXPECT_LT(testing::max_relative_error(out, testing::naive_forward(net, x)), p.tolerance);
}

std::vector<BackendCase> backend_cases() {
  std::vector<BackendCase> cases = {{"eigen", nn::Precision::FP32, 1e-5}};
  for (const auto& b : nn::available_backends())
    if (b == "onednn") {
      cases.push_back({"onednn", nn::Precision::FP32, 1e-5});
      cases.push_back({"onednn", nn::Precision::BF16, 2e-2});
    }
  return cases;
}

INSTANTIATE_TEST_SUITE_P(All, NnBackend, ::testing::ValuesIn(backend_cases()),
                         [](const auto& param_info) { return param_info.param.backend + "_" + nn::to_string(param_info.param.precision); });

}  // namespace
}  // namespace residue
