// The trainer's libtorch network and core's inference agree on the same weights: export, load, compare.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include "core/features/features.h"
#include "core/nn/backend.h"
#include "core/nn/model_file.h"
#include "support/test_support.h"
#include "torch_network.h"
#include "training_set.h"

namespace residue {
namespace {

class TrainParity : public ::testing::TestWithParam<nn::Architecture> {};

TEST_P(TrainParity, ExportedModelGivesTheSameOutputInCore) {
  torch::manual_seed(3);
  const nn::Architecture arch = GetParam();
  train::ResidueNet net(arch);
  train::initialise(net);
  // Give batch norm real statistics and non-trivial affine parameters, then switch to inference.
  {
    torch::NoGradGuard no_grad;
    for (auto& p : net->named_parameters())
      if (p.key().find("bn") != std::string::npos) p.value().uniform_(0.5, 1.5);
    net->train();
    for (int i = 0; i < 5; ++i) net->forward(torch::randn({4, 9, 16, 16}) * 0.7 + 0.2);
  }
  net->eval();
  testing::TempDir tmp;
  nn::write_safetensors(tmp / "m.safetensors", train::export_model(net, {{"name", "parity"}}), false);
  const nn::Model model = nn::load_model(tmp / "m.safetensors");

  const Image x = testing::random_image(21, 13, 9, 4, -0.5f, 1.5f);
  // libtorch: NCHW.
  torch::Tensor t = torch::empty({1, 9, 13, 21});
  for (int c = 0; c < 9; ++c)
    for (int64_t y = 0; y < 13; ++y)
      for (int64_t xx = 0; xx < 21; ++xx) t[0][c][y][xx] = x.at(xx, y, c);
  torch::Tensor expect;
  {
    torch::NoGradGuard no_grad;
    expect = net->forward(t);
  }
  for (const auto& backend : nn::available_backends()) {
    auto b = nn::make_backend(backend, model.network, {});
    Image out;
    b->run(x, out);
    double scale = 1e-3, err = 0;
    for (int c = 0; c < 3; ++c)
      for (int64_t y = 0; y < 13; ++y)
        for (int64_t xx = 0; xx < 21; ++xx) {
          const double e = expect[0][c][y][xx].item<double>();
          scale = std::max(scale, std::abs(e));
          err = std::max(err, std::abs(e - out.at(xx, y, c)));
        }
    EXPECT_LT(err / scale, 1e-4) << backend << " " << arch.to_string();
  }
}

// The paper's network, and one with dilated blocks (taps 3 px apart reach past the 13-px-high input).
INSTANTIATE_TEST_SUITE_P(Architectures, TrainParity,
                         ::testing::Values(nn::Architecture{3, 16, FeatureSet::Full},
                                           nn::Architecture{3, 16, FeatureSet::Full, {1, 3}}),
                         [](const auto& info) { return info.param.max_dilation() > 1 ? "dilated" : "paper"; });

TEST(TrainAugmentation, TurnsNormalsWithTheImage) {
  // A scene-free check of the dihedral transforms: build a TrainingSet on the starter data when present.
  const auto dir = testing::shared_dataset("cycles-starter");
  RESIDUE_REQUIRE_SHARED(dir);
  const train::TrainingSet set({dir / "s100"}, FeatureSet::Full, 64);
  std::mt19937 rng(5);
  torch::Tensor x, y;
  set.sample(rng, 16, x, y);
  EXPECT_EQ(x.sizes(), (std::vector<int64_t>{16, 9, 64, 64}));
  EXPECT_EQ(y.sizes(), (std::vector<int64_t>{16, 3, 64, 64}));
  EXPECT_TRUE(torch::isfinite(x).all().item<bool>());
  // Normals stay unit-bounded and colours stay log-compressed and non-negative.
  EXPECT_LE(x.index({torch::indexing::Slice(), torch::indexing::Slice(4, 6)}).abs().max().item<float>(), 1.0f);
  EXPECT_GE(x.index({torch::indexing::Slice(), torch::indexing::Slice(0, 3)}).min().item<float>(), 0.0f);
}

}  // namespace
}  // namespace residue
