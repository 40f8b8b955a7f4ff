// The network and its backends against an independent float64 implementation.
#include <algorithm>
#include <cmath>
#include <cstdlib>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include "core/nn/backend.h"
#include "core/util/error.h"
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
  EXPECT_EQ(paper.halo(), 35);
  // Dilated blocks: the same cost, a larger reach (d pixels per conv of dilation d).
  const Architecture dilated{8, 32, FeatureSet::Full, {1, 2, 4, 8}};
  EXPECT_EQ(dilated.halo(), 3 + 2 * 2 * (1 + 2 + 4 + 8));
  EXPECT_EQ(dilated.flops_per_pixel(), (Architecture{8, 32, FeatureSet::Full}.flops_per_pixel()));
  EXPECT_EQ(dilated.to_string(), "8/32 full dilated 1,2,4,8");
  EXPECT_EQ(nn::parse_dilations("1,2,4,8"), (std::vector<int>{1, 2, 4, 8}));
  for (const char* bad : {"", "1,,2", "0", "65", "1,x", "1, 2", "-1"}) EXPECT_FALSE(nn::parse_dilations(bad)) << bad;
}

// The rules on which settings go together, one case each, and the shipped kinds of network pass them.
TEST(NnArchitecture, SettingsThatCannotGoTogetherAreNamed) {
  const auto why = [](const nn::Architecture& a) { return a.contradiction().value_or(""); };
  nn::Architecture flat;
  EXPECT_FALSE(flat.contradiction());
  nn::Architecture ms;
  ms.levels = {2, 2, 2, 2};
  ms.widths = {24, 40, 56, 80};
  EXPECT_FALSE(ms.contradiction());
  nn::Architecture temporal = ms;
  temporal.temporal = 1;
  EXPECT_FALSE(temporal.contradiction());
  temporal.prior = "oidn";
  EXPECT_NE(why(temporal).find("temporal"), std::string::npos);
  nn::Architecture seven = ms;
  seven.levels = {1, 1, 1, 1, 1, 1, 1};
  seven.widths = {8, 8, 8, 8, 8, 8, 8};
  EXPECT_NE(why(seven).find("2 to 6 levels"), std::string::npos);
  nn::Architecture dilated = ms;
  dilated.dilations = {1, 2};
  EXPECT_NE(why(dilated).find("no dilations"), std::string::npos);
  nn::Architecture demodulated;
  demodulated.features = FeatureSet::ColorOnly;
  demodulated.demodulate = true;
  EXPECT_NE(why(demodulated).find("albedo"), std::string::npos);
  nn::Architecture prior;
  prior.features = FeatureSet::ColorAlbedoNormal;
  prior.prior = "oidn";
  EXPECT_NE(why(prior).find("full"), std::string::npos);
  nn::Architecture far = ms;
  far.temporal = 3;
  EXPECT_NE(why(far).find("1 or 2 frames"), std::string::npos);
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
  // So test logs say "onednn bf16" rather than the parameter's bytes.
  friend void PrintTo(const BackendCase& c, std::ostream* os) { *os << c.backend << " " << nn::to_string(c.precision); }
};

class NnBackend : public ::testing::TestWithParam<BackendCase> {};

TEST_P(NnBackend, WholeNetworkMatchesFloat64Reference) {
  const auto& p = GetParam();
  for (const auto& [arch, w, h] : std::vector<std::tuple<Architecture, int, int>>{
           {{2, 16, FeatureSet::Full}, 13, 9}, {{3, 32, FeatureSet::ColorOnly}, 1, 1},
           {{1, 8, FeatureSet::ColorAlbedoNormal}, 3, 5}, {{2, 16, FeatureSet::Full}, 40, 2},
           {{1, 48, FeatureSet::ColorAlbedoNormal}, 17, 3},
           // Dilated blocks, also with taps reaching past the whole tile.
           {{4, 16, FeatureSet::Full, {1, 2, 4, 8}}, 30, 21}, {{3, 32, FeatureSet::ColorOnly, {2, 5}}, 7, 4},
           // The input skip.
           {{2, 16, FeatureSet::Full, {}, true}, 11, 6}, {{1, 8, FeatureSet::FullVariance, {1, 2}, true}, 5, 9}}) {
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

TEST_P(NnBackend, RepeatedRunsWithChangingTileSizes) {
  // Backends cache per-size state (oneDNN: primitives per tile size and thread count); going back and forth
  // between sizes, and between thread limits, must give the right answer every time.
  const auto& p = GetParam();
  const nn::Network net = nn::random_network({2, 16, FeatureSet::Full}, 17);
  auto backend = nn::make_backend(p.backend, net, {p.precision});
  const std::vector<std::tuple<int, int, int>> runs = {{13, 9, 0}, {40, 2, 0}, {13, 9, 1}, {1, 1, 0},
                                                       {7, 30, 0}, {40, 2, 1}, {13, 9, 0}};
  for (const auto& [w, h, single_thread] : runs) {
    const Image x = testing::random_image(w, h, 9, static_cast<unsigned>(w * 100 + h), -1.0f, 2.0f);
    Image out;
    if (single_thread) tbb::task_arena(1).execute([&] { backend->run(x, out); });
    else backend->run(x, out);
    ASSERT_EQ(out.width(), w);
    ASSERT_EQ(out.height(), h);
    EXPECT_LT(testing::max_relative_error(out, testing::naive_forward(net, x)), p.tolerance)
        << backend->description() << " " << w << "x" << h << (single_thread ? " (1 thread)" : "");
  }
}

TEST_P(NnBackend, UniformPReluSlopes) {
  // All slopes of a layer equal: the oneDNN backend fuses them as a leaky-ReLU post-op instead of a prelu pass.
  const auto& p = GetParam();
  nn::Network net = nn::random_network({2, 16, FeatureSet::Full}, 23);
  std::fill(net.head_prelu.begin(), net.head_prelu.end(), 0.2f);
  std::fill(net.blocks[1].prelu.begin(), net.blocks[1].prelu.end(), -0.3f);
  const Image x = testing::random_image(11, 6, 9, 29, -1.0f, 2.0f);
  auto backend = nn::make_backend(p.backend, net, {p.precision});
  Image out;
  backend->run(x, out);
  EXPECT_LT(testing::max_relative_error(out, testing::naive_forward(net, x)), p.tolerance) << backend->description();
}

TEST_P(NnBackend, ScratchBytesCoverTheActivations) {
  const auto& p = GetParam();
  const nn::Network net = nn::random_network({1, 32, FeatureSet::Full}, 3);
  auto backend = nn::make_backend(p.backend, net, {p.precision});
  const size_t element = p.precision == nn::Precision::BF16 ? 2 : 4;
  const size_t small = backend->scratch_bytes(64, 32), large = backend->scratch_bytes(256, 128);
  EXPECT_GE(small, 3 * 64 * 32 * 32 * element);  // head output, block state, temporary
  EXPECT_GT(large, small);
  EXPECT_LT(large, size_t{256} * 128 * 32 * 4 * 8);  // and not absurd
}

std::vector<BackendCase> backend_cases() {
  std::vector<BackendCase> cases = {{"eigen", nn::Precision::FP32, 1e-5}};
  for (const auto& b : nn::available_backends())
    if (b == "onednn") {
      cases.push_back({"onednn", nn::Precision::FP32, 1e-5});
      if (nn::bf16_available()) cases.push_back({"onednn", nn::Precision::BF16, 2e-2});
    }
  return cases;
}

INSTANTIATE_TEST_SUITE_P(All, NnBackend, ::testing::ValuesIn(backend_cases()),
                         [](const auto& param_info) { return param_info.param.backend + "_" + nn::to_string(param_info.param.precision); });

bool have_onednn() {
  const auto names = nn::available_backends();
  return std::find(names.begin(), names.end(), "onednn") != names.end();
}

TEST(NnOneDnn, AgreesWithEigenOnPaperWidthNetwork) {
  // Width 128 as in the paper (oneDNN's real kernels, not the small-channel paths), 4 blocks, a 48 x 40 tile.
  if (!have_onednn()) GTEST_SKIP() << "built without oneDNN";
  const Architecture arch{4, 128, FeatureSet::Full};
  const nn::Network net = nn::random_network(arch, 8);
  const Image x = testing::random_image(48, 40, arch.in_channels(), 12, -1.0f, 2.0f);
  Image eigen_out, onednn_out;
  nn::make_backend("eigen", net, {nn::Precision::FP32})->run(x, eigen_out);
  auto onednn = nn::make_backend("onednn", net, {nn::Precision::FP32});
  onednn->run(x, onednn_out);
  EXPECT_LT(testing::max_relative_error(onednn_out, testing::to_tensor(eigen_out)), 1e-5) << onednn->description();
}

TEST(NnOneDnn, DescriptionNamesPrecisionAndImplementation) {
  if (!have_onednn()) GTEST_SKIP() << "built without oneDNN";
  const nn::Network net = nn::random_network({1, 16, FeatureSet::Full}, 1);
  const std::string fp32 = nn::make_backend("onednn", net, {nn::Precision::FP32})->description();
  EXPECT_EQ(fp32.rfind("onednn fp32 (", 0), 0u) << fp32;
  EXPECT_EQ(fp32.find("ref"), std::string::npos) << "the reference kernel runs: " << fp32;
  if (nn::bf16_available()) {
    const std::string bf16 = nn::make_backend("onednn", net, {nn::Precision::BF16})->description();
    EXPECT_EQ(bf16.rfind("onednn bf16 (", 0), 0u) << bf16;
  } else {  // a CPU without native bf16: refused with a reason
    const std::string why = testing::error_message([&] { nn::make_backend("onednn", net, {nn::Precision::BF16}); },
                                                   ErrorKind::Usage);
    EXPECT_NE(why.find("bf16 inference needs a CPU with AVX512_BF16 or AMX"), std::string::npos) << why;
  }
}

TEST(NnEigen, PortablePathMatchesReferenceAndTheAvx512Kernel) {
  // The im2col + Eigen GEMM path runs where AVX-512 is missing; RESIDUE_EIGEN_PORTABLE forces it here.
  setenv("RESIDUE_EIGEN_PORTABLE", "1", 1);
  const nn::Network small = nn::random_network({2, 16, FeatureSet::Full}, 42);
  const nn::Network wide = nn::random_network({4, 128, FeatureSet::Full}, 8);
  auto portable_small = nn::make_backend("eigen", small, {});
  auto portable_wide = nn::make_backend("eigen", wide, {});
  unsetenv("RESIDUE_EIGEN_PORTABLE");
  EXPECT_EQ(portable_small->description(), "eigen fp32");
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{13, 9}, {1, 1}, {40, 2}}) {
    const Image x = testing::random_image(w, h, 9, 7, -1.0f, 2.0f);
    Image out;
    portable_small->run(x, out);
    EXPECT_LT(testing::max_relative_error(out, testing::naive_forward(small, x)), 1e-5) << w << "x" << h;
  }
  const Image x = testing::random_image(48, 40, 9, 12, -1.0f, 2.0f);
  Image portable_out, default_out;
  portable_wide->run(x, portable_out);
  auto default_wide = nn::make_backend("eigen", wide, {});
  default_wide->run(x, default_out);
  EXPECT_LT(testing::max_relative_error(default_out, testing::to_tensor(portable_out)), 1e-5)
      << default_wide->description();
}

TEST(NnBackendChoice, EigenRefusesBf16AndUnknownNamesListTheAvailable) {
  const nn::Network net = nn::random_network({1, 8, FeatureSet::Full}, 1);
  EXPECT_THROW(nn::make_backend("eigen", net, {nn::Precision::BF16}), Error);
  try {
    nn::make_backend("tpu", net, {});
    FAIL() << "no error for an unknown backend";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Usage);
    EXPECT_NE(std::string(e.what()).find("eigen"), std::string::npos) << e.what();
  }
}

// The default for each precision can run it: fp32 on eigen where its AVX-512 kernel runs, else on oneDNN when it
// is built (faster than eigen's portable path); bf16 on oneDNN when it is built (the only one with bf16), so a
// caller naming no backend never gets eigen's bf16 refusal.
TEST(NnBackendChoice, TheDefaultRunsEachPrecision) {
  const nn::Network net = nn::random_network({1, 8, FeatureSet::Full}, 1);
  EXPECT_EQ(nn::default_backend(nn::Precision::FP32), nn::eigen_runs_direct_kernel() ? "eigen" : nn::available_backends().back());
  setenv("RESIDUE_EIGEN_PORTABLE", "1", 1);
  EXPECT_EQ(nn::default_backend(nn::Precision::FP32), nn::available_backends().back()) << "eigen's portable path is not the default where onednn is built";
  unsetenv("RESIDUE_EIGEN_PORTABLE");
  auto fp32 = nn::make_backend(nn::default_backend(nn::Precision::FP32), net, {nn::Precision::FP32});
  EXPECT_NE(fp32->description().find("fp32"), std::string::npos) << fp32->description();
  const auto names = nn::available_backends();
  if (std::find(names.begin(), names.end(), "onednn") == names.end()) GTEST_SKIP() << "built without oneDNN";
  if (!nn::bf16_available()) GTEST_SKIP() << "this CPU has no AVX512_BF16 or AMX: bf16 is refused (NnOneDnn.DescriptionNamesPrecisionAndImplementation)";
  auto bf16 = nn::make_backend(nn::default_backend(nn::Precision::BF16), net, {nn::Precision::BF16});
  EXPECT_NE(bf16->description().find("bf16"), std::string::npos) << bf16->description();
}

}  // namespace
}  // namespace residue
