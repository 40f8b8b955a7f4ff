// The trainer's libtorch network and core's inference agree on the same weights: export, load, compare.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <algorithm>
#include <fstream>

#include <nlohmann/json.hpp>

#include "core/features/features.h"
#include "core/nn/backend.h"
#include "core/nn/model_file.h"
#include "core/nn/model_registry.h"
#include "core/nn/safetensors.h"
#include "core/util/error.h"
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

  // Odd sizes for the flat networks; whole multiples of the pooling for the multi-scale one (20 x 12 at 4 px).
  const int64_t W = arch.multiscale() ? 24 : 21, H = arch.multiscale() ? 16 : 13;  // multiscale: multiples of 8
  const Image x = testing::random_image(W, H, 9, 4, -0.5f, 1.5f);
  // libtorch: NCHW.
  torch::Tensor t = torch::empty({1, 9, H, W});
  for (int c = 0; c < 9; ++c)
    for (int64_t y = 0; y < H; ++y)
      for (int64_t xx = 0; xx < W; ++xx) t[0][c][y][xx] = x.at(xx, y, c);
  torch::Tensor expect;
  {
    torch::NoGradGuard no_grad;
    expect = net->forward(t);
  }
  // The trainer's layout (channels-last weights and inputs) computes the same and exports the same file.
  {
    train::ResidueNet nhwc(arch);
    {
      torch::NoGradGuard no_grad;
      const auto from = net->named_parameters(), to = nhwc->named_parameters();
      for (const auto& p : from) to[p.key()].copy_(p.value());
      const auto from_buffers = net->named_buffers(), to_buffers = nhwc->named_buffers();
      for (const auto& b : from_buffers) to_buffers[b.key()].copy_(b.value());
    }
    train::use_channels_last(nhwc);
    nhwc->eval();
    ASSERT_TRUE(nhwc->head->conv->weight.is_contiguous(at::MemoryFormat::ChannelsLast));
    torch::NoGradGuard no_grad;
    const torch::Tensor out = nhwc->forward(train::to_channels_last(t));
    EXPECT_LT((out - expect).abs().max().item<double>(), 1e-5 * std::max(1.0, expect.abs().max().item<double>()));
    const nn::SafetensorsFile a = train::export_model(net, {}), b = train::export_model(nhwc, {});
    ASSERT_EQ(a.tensors.size(), b.tensors.size());
    for (const auto& [name, tensor] : a.tensors) {
      ASSERT_TRUE(b.tensors.count(name)) << name;
      EXPECT_EQ(tensor.shape, b.tensors.at(name).shape) << name;
      EXPECT_EQ(tensor.values, b.tensors.at(name).values) << name << ": the export must not depend on the layout";
    }
  }
  for (const auto& backend : nn::available_backends()) {
    auto b = nn::make_backend(backend, model.graph, {});
    Image out;
    b->run(x, out);
    double scale = 1e-3, err = 0;
    for (int c = 0; c < 3; ++c)
      for (int64_t y = 0; y < H; ++y)
        for (int64_t xx = 0; xx < W; ++xx) {
          const double e = expect[0][c][y][xx].item<double>();
          scale = std::max(scale, std::abs(e));
          err = std::max(err, std::abs(e - out.at(xx, y, c)));
        }
    EXPECT_LT(err / scale, 1e-4) << backend << " " << arch.to_string();
  }
}

// The paper's network, one with dilated blocks (taps 3 px apart reach past the 13-px-high input), one with the
// input skip, and a three-level multi-scale network.
INSTANTIATE_TEST_SUITE_P(Architectures, TrainParity,
                         ::testing::Values(nn::Architecture{3, 16, FeatureSet::Full},
                                           nn::Architecture{3, 16, FeatureSet::Full, {1, 3}},
                                           nn::Architecture{2, 16, FeatureSet::Full, {}, true},
                                           nn::Architecture{1, 8, FeatureSet::Full, {}, false, {1, 2, 1}, {8, 16, 12}},
                                           // Four levels, as the studies at OIDN's cost: a tile of 3 x 2 pixels at
                                           // the bottom, borders on every side at every level.
                                           nn::Architecture{1, 8, FeatureSet::Full, {}, false, {1, 1, 1, 1}, {8, 12, 16, 20}}),
                         [](const auto& info) {
                           return (info.param.multiscale() ? "multiscale" + std::to_string(info.param.levels.size())
                                                           : std::string(info.param.max_dilation() > 1 ? "dilated" : "paper")) +
                                  (info.param.input_skip ? "_input_skip" : "");
                         });

// --init-from: a variant for another feature set starts as its source network with the planes it lacks set
// to zero (depth dropped, the noise plane new), for every variant; a source of another size is refused.
TEST(TrainInitFrom, AVariantStartsAsItsSourceWithTheMissingPlanesZero) {
  torch::manual_seed(9);
  train::ResidueNet source(nn::Architecture{2, 8, FeatureSet::Full});
  train::initialise(source);
  {
    torch::NoGradGuard no_grad;
    for (auto& p : source->named_parameters())
      if (p.key().find("bn") != std::string::npos || p.key().find("bias") != std::string::npos) p.value().uniform_(0.5, 1.5);
    source->train();
    for (int i = 0; i < 3; ++i) source->forward(torch::randn({4, 9, 12, 12}));
  }
  source->eval();
  testing::TempDir tmp;
  const auto file = tmp / "source.safetensors";
  nn::write_safetensors(file, train::export_model(source, {{"name", "src"}}), false);
  const nn::SafetensorsFile read = nn::read_safetensors(file);
  const std::vector<std::string> source_planes = feature_planes(FeatureSet::Full);

  for (FeatureSet set : {FeatureSet::ColorAlbedoNormal, FeatureSet::ColorOnly, FeatureSet::FullVariance}) {
    train::ResidueNet variant(nn::Architecture{2, 8, set});
    train::initialise(variant);
    train::initialise_from(variant, read, file);
    variant->eval();
    const std::vector<std::string> planes = feature_planes(set);
    const torch::Tensor x = torch::randn({2, static_cast<int64_t>(planes.size()), 12, 12});
    torch::Tensor x_source = torch::zeros({2, 9, 12, 12});
    int shared = 0;
    for (size_t c = 0; c < planes.size(); ++c) {
      const auto it = std::find(source_planes.begin(), source_planes.end(), planes[c]);
      if (it == source_planes.end()) continue;
      x_source.select(1, it - source_planes.begin()).copy_(x.select(1, static_cast<int64_t>(c)));
      ++shared;
    }
    EXPECT_EQ(shared, set == FeatureSet::FullVariance ? 9 : static_cast<int>(planes.size())) << to_string(set);
    torch::NoGradGuard no_grad;
    const torch::Tensor expect = source->forward(x_source), got = variant->forward(x);
    EXPECT_TRUE(torch::allclose(got, expect, 1e-5, 1e-5))
        << to_string(set) << ": max difference " << (got - expect).abs().max().item<float>();
  }

  train::ResidueNet deeper(nn::Architecture{3, 8, FeatureSet::Full});
  try {
    train::initialise_from(deeper, read, file);
    ADD_FAILURE() << "a 2/8 file initialised a 3/8 network";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("2/8"), std::string::npos) << e.what();
  }
}

// A network with non-trivial BN and PReLU parameters and real BN statistics, in inference mode, written to `file`
// and read back: the source of the warm-start tests below.
train::ResidueNet trained_source(const nn::Architecture& arch, const std::filesystem::path& file, nn::SafetensorsFile& read) {
  train::ResidueNet source(arch);
  train::initialise(source);
  {
    torch::NoGradGuard no_grad;
    for (auto& p : source->named_parameters())
      if (p.key().find("bn") != std::string::npos || p.key().find("prelu") != std::string::npos)
        p.value().uniform_(0.5, 1.5);
    source->train();
    for (int i = 0; i < 3; ++i) source->forward(torch::randn({4, 9, 32, 32}) * 0.7 + 0.2);
  }
  source->eval();
  nn::write_safetensors(file, train::export_model(source, {{"name", "src"}}), false);
  read = nn::read_safetensors(file);
  return source;
}

// The largest difference of two libtorch outputs relative to the largest of `expect` (at least 1e-3), as
// core_difference measures core's: outputs reach a few hundred, where fp32 rounding alone differs by 1e-4 between
// oneDNN's AVX2 and AVX-512 kernels.
double torch_difference(const torch::Tensor& got, const torch::Tensor& expect) {
  const double scale = std::max(1e-3, expect.abs().max().item<double>());
  return (got - expect).abs().max().item<double>() / scale;
}

// Core's outputs for two model files on one random 48 x 32 input: the largest difference relative to the largest
// output (at least 1e-3).
double core_difference(const std::filesystem::path& a, const std::filesystem::path& b) {
  const Image in = testing::random_image(48, 32, 9, 5, -0.5f, 1.5f);
  Image out_a, out_b;
  nn::make_backend("eigen", nn::load_model(a).graph, {})->run(in, out_a);
  nn::make_backend("eigen", nn::load_model(b).graph, {})->run(in, out_b);
  double err = 0, scale = 1e-3;
  for (int64_t y = 0; y < 32; ++y)
    for (int64_t xx = 0; xx < 48; ++xx)
      for (int c = 0; c < 3; ++c) {
        scale = std::max(scale, static_cast<double>(std::abs(out_a.at(xx, y, c))));
        err = std::max(err, static_cast<double>(std::abs(out_a.at(xx, y, c) - out_b.at(xx, y, c))));
      }
  return err / scale;
}

// --grow-from: a multi-scale network grown by one level computes what its source computes (in libtorch and in
// core, from the exported file), while the new level gets a gradient; a source of other widths is refused.
TEST(TrainGrowFrom, AGrownNetworkStartsAsItsSourceAndItsNewLevelLearns) {
  torch::manual_seed(11);
  const nn::Architecture small{1, 8, FeatureSet::Full, {}, false, {1, 2, 1}, {8, 12, 16}};
  testing::TempDir tmp;
  const auto file = tmp / "source.safetensors";
  nn::SafetensorsFile read;
  train::ResidueNet source = trained_source(small, file, read);

  train::ResidueNet grown(nn::Architecture{1, 8, FeatureSet::Full, {}, false, {1, 2, 1, 2}, {8, 12, 16, 24}});
  train::initialise(grown);
  int batches = 0;
  train::grow_from(grown, read, file, [&] { ++batches; return torch::randn({2, 9, 32, 32}); }, 4);
  EXPECT_EQ(batches, 4);
  grown->eval();
  const torch::Tensor x = torch::randn({2, 9, 32, 48}) * 0.7 + 0.2;
  {
    torch::NoGradGuard no_grad;
    const torch::Tensor expect = source->forward(x), got = grown->forward(x);
    EXPECT_LT(torch_difference(got, expect), 1e-5);
  }
  // The new bottom's batch norms were measured (not left at mean 0, variance 1); the new level is not dead.
  auto* bottom = grown->levels[3]->as<train::ScaleLevel>();
  auto* enc = bottom->enc[0]->as<train::ResBlock>();
  EXPECT_GT(enc->bn1->running_mean.abs().sum().item<float>(), 0.f);
  grown->train();
  train::freeze_batch_norm(grown);
  grown->forward(x).abs().mean().backward();
  auto* above = grown->levels[2]->as<train::ScaleLevel>();
  EXPECT_GT(above->up->conv->weight.grad().slice(1, 0, 24).abs().sum().item<float>(), 0.f)
      << "the upsampled channels of the old bottom's up step must get a gradient";
  EXPECT_GT(above->dec[0]->as<train::ResBlock>()->bn2->weight.grad().abs().sum().item<float>(), 0.f);

  // Core runs the exported grown network as it runs the source.
  grown->eval();
  const auto grown_file = tmp / "grown.safetensors";
  nn::write_safetensors(grown_file, train::export_model(grown, {{"name", "grown"}}), false);
  EXPECT_LT(core_difference(file, grown_file), 1e-5);

  train::ResidueNet other(nn::Architecture{1, 8, FeatureSet::Full, {}, false, {1, 2, 1, 2}, {8, 12, 20, 24}});
  const std::string message = testing::error_message(
      [&] { train::grow_from(other, read, file, [] { return torch::randn({2, 9, 32, 32}); }, 1); }, ErrorKind::Input);
  EXPECT_NE(message.find(file.string()), std::string::npos) << "an 8,12,16 network grew into 8,12,20,24: " << message;
  EXPECT_NE(message.find("8,12,16"), std::string::npos) << message;
}

// --widen-from: every level wider (the full-resolution one most), the source's function exactly, the new channels
// measured and learning; core runs the export as it runs the source; a network of another shape is refused.
TEST(TrainWidenFrom, AWidenedNetworkStartsAsItsSourceAndItsNewChannelsLearn) {
  torch::manual_seed(13);
  const nn::Architecture narrow{1, 8, FeatureSet::Full, {}, false, {1, 2, 1}, {8, 12, 16}};
  testing::TempDir tmp;
  const auto file = tmp / "source.safetensors";
  nn::SafetensorsFile read;
  train::ResidueNet source = trained_source(narrow, file, read);

  train::ResidueNet wide(nn::Architecture{1, 12, FeatureSet::Full, {}, false, {1, 2, 1}, {12, 12, 20}});  // width: the first level's, as parsed
  train::initialise(wide);
  int batches = 0;
  train::widen_from(wide, read, file, [&] { ++batches; return torch::randn({2, 9, 32, 32}); }, 4);
  EXPECT_EQ(batches, 4);
  wide->eval();
  const torch::Tensor x = torch::randn({2, 9, 32, 48}) * 0.7 + 0.2;
  {
    torch::NoGradGuard no_grad;
    const torch::Tensor expect = source->forward(x), got = wide->forward(x);
    EXPECT_LT(torch_difference(got, expect), 1e-5);
  }
  // The old channels keep the source's statistics; the new ones were measured.
  auto* top = wide->levels[0]->as<train::ScaleLevel>();
  auto* block = top->enc[0]->as<train::ResBlock>();
  EXPECT_TRUE(torch::equal(block->bn1->running_var.slice(0, 0, 8),
                           torch::tensor(read.tensors.at("levels.0.enc.0.bn1.running_var").values)));
  EXPECT_NE(block->bn1->running_var.slice(0, 8, 12).sub(1).abs().sum().item<float>(), 0.f);
  // The new channels reach the output through weights that start at zero: those get a gradient at once.
  wide->train();
  train::freeze_batch_norm(wide);
  wide->forward(x).abs().mean().backward();
  EXPECT_GT(wide->out->conv->weight.grad().slice(1, 8, 12).abs().sum().item<float>(), 0.f);
  auto* middle = wide->levels[1]->as<train::ScaleLevel>();
  EXPECT_GT(middle->up->conv->weight.grad().slice(1, 16, 20).abs().sum().item<float>(), 0.f)
      << "the upsampled bottom's new channels sit after its old ones, before the skip";

  wide->eval();
  const auto wide_file = tmp / "wide.safetensors";
  nn::write_safetensors(wide_file, train::export_model(wide, {{"name", "wide"}}), false);
  EXPECT_LT(core_difference(file, wide_file), 1e-5);

  for (const auto& other : std::vector<nn::Architecture>{nn::Architecture{1, 8, FeatureSet::Full, {}, false, {1, 2, 1}, {12, 8, 20}},
                            nn::Architecture{1, 8, FeatureSet::Full, {}, false, {1, 1, 1}, {12, 12, 20}},
                            nn::Architecture{1, 8, FeatureSet::ColorOnly, {}, false, {1, 2, 1}, {12, 12, 20}}}) {
    train::ResidueNet net(other);
    const std::string message = testing::error_message(
        [&] { train::widen_from(net, read, file, [] { return torch::randn({2, 9, 32, 32}); }, 1); }, ErrorKind::Input);
    EXPECT_NE(message.find(file.string()), std::string::npos) << "an 8,12,16 network widened into " << other.to_string();
    EXPECT_NE(message.find("8,12,16"), std::string::npos) << message;
  }
}

// A fresh post-correction network is the identity on its prior's planes (its output conv starts at zero), and it
// still learns: the output conv gets a gradient.
TEST(TrainPlanes, NormalAndAlbedoPlanesFollowTheFeatureSet) {
  EXPECT_EQ(train::normal_plane(FeatureSet::Full), 4);
  EXPECT_EQ(train::normal_plane(FeatureSet::FullVariance), 4);
  EXPECT_EQ(train::normal_plane(FeatureSet::ColorAlbedoNormal), 3);
  EXPECT_EQ(train::normal_plane(FeatureSet::ColorOnly), -1);
  EXPECT_EQ(train::albedo_plane(FeatureSet::Full), 6);
  EXPECT_EQ(train::albedo_plane(FeatureSet::FullVariance), 6);
  EXPECT_EQ(train::albedo_plane(FeatureSet::ColorAlbedoNormal), 5);
  EXPECT_EQ(train::albedo_plane(FeatureSet::ColorOnly), -1);
}

TEST(TrainInit, PostCorrectionStartsAsItsPrior) {
  torch::manual_seed(2);
  nn::Architecture arch{2, 8, FeatureSet::Full};
  arch.prior = "oidn";
  arch.input_skip = true;
  train::ResidueNet net(arch);
  train::initialise(net);
  net->train();
  const auto x = torch::randn({2, 12, 16, 16});
  const auto y = net->forward(x);
  EXPECT_TRUE(torch::equal(y, x.slice(1, 9, 12)));
  (y - 1.0).abs().mean().backward();
  EXPECT_GT(net->out->conv->weight.grad().abs().sum().item<double>(), 0.0);
  nn::Architecture plain{2, 8, FeatureSet::Full};
  plain.input_skip = true;
  train::ResidueNet other(plain);
  train::initialise(other);
  EXPECT_GT(other->out->conv->weight.abs().sum().item<double>(), 0.0) << "only post-correction starts at zero";
}

TEST(TrainAugmentation, TurnsNormalsWithTheImage) {
  // A scene-free check of the dihedral transforms: build a TrainingSet on the starter data when present.
  const auto dir = testing::shared_dataset("cycles-starter");
  RESIDUE_REQUIRE_SHARED(dir);
  const train::TrainingSet set({dir / "s100"}, nn::Architecture{1, 8, FeatureSet::Full}, 64);
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

// Distillation on a real scene: each half's target is (1 - w) log(1 + reference) + w log(1 + the teacher's output on
// that half). The teacher's output here comes from residue-cli, run on each half's own file as a user would
// (`-m multiscale --ensemble 2`, float EXR), not from the trainer's code path; the reference from the file too.
TEST(TrainDistillation, TargetsMoveTowardsTheTeachersOutputOnEachHalfByItsWeight) {
  const auto dir = testing::shared_dataset("cycles-starter/s101");
  RESIDUE_REQUIRE_SHARED(dir);
  testing::TempDir tmp;
  std::vector<Image> taught;
  for (const char* half : {"noisy_a", "noisy_b"}) {
    const auto out = tmp / (std::string(half) + "_multiscale.exr");
    std::string text;
    ASSERT_EQ(testing::run_cli({"denoise", (dir / (std::string(half) + ".exr")).string(), "-m", "multiscale",
                                "--ensemble", "2", "--float", "-o", out.string()},
                               &text),
              0)
        << text;
    taught.push_back(testing::read_exr_float(out));
  }
  const Image reference = testing::read_exr_float(dir / "reference.exr");
  const nn::Model teacher = nn::load_model(nn::find_model_for("multiscale", FeatureSet::Full));
  const nn::Architecture arch{1, 8, FeatureSet::Full};  // no autoexposure: the targets' exposure is 1
  for (const float w : {0.25f, 1.0f}) {
    const train::TrainingSet set({dir}, arch, 64, nullptr, {&teacher, w, 2});
    const auto& targets = set.scenes().at(0).targets;
    ASSERT_EQ(targets.size(), 2u);
    double worst = 0, moved = 0;
    for (size_t h = 0; h < 2; ++h)
      for (int64_t y = 0; y < reference.height(); ++y)
        for (int64_t x = 0; x < reference.width(); ++x)
          for (int c = 0; c < 3; ++c) {
            const double r = std::log1p(std::max(0.0, static_cast<double>(reference.at(x, y, c))));
            const double t = std::log1p(std::max(0.0, static_cast<double>(taught[h].at(x, y, c))));
            worst = std::max(worst, std::abs(targets[h].at(x, y, c) - ((1 - w) * r + w * t)));
            moved = std::max(moved, std::abs(targets[h].at(x, y, c) - r));
          }
    EXPECT_LT(worst, 1e-5) << "weight " << w;
    EXPECT_GT(moved, 0.01) << "weight " << w << ": the targets must differ from the reference's";
  }
  // Without a teacher the targets are the reference's, whatever the weight.
  const train::TrainingSet plain({dir}, arch, 64, nullptr, {nullptr, 1.0f, 2});
  EXPECT_FLOAT_EQ(plain.scenes().at(0).targets[1].at(7, 9, 1),
                  static_cast<float>(std::log1p(std::max(0.0f, reference.at(7, 9, 1)))));
  EXPECT_NE(testing::error_message([&] { train::TrainingSet({dir}, arch, 64, nullptr, {&teacher, 0.0f, 2}); },
                                   ErrorKind::Usage)
                .find("weight must be in (0, 1]"),
            std::string::npos);
}

// The trainer end to end on three real scenes: a dilated model trains 10 steps, a second run with --steps 20
// resumes from the checkpoint (not from scratch), the log goes on, the training time adds up, and core loads
// the exported file.
// Precise BN: the running statistics become the plain mean of the batches' statistics, computed here by hand
// for the first BatchNorm (blocks.0.bn1, fed by blocks.0.conv1 of the head's output).
TEST(TrainBatchNorm, RecalibrationAveragesTheBatchesStatistics) {
  torch::manual_seed(5);
  train::ResidueNet net(nn::Architecture{2, 8, FeatureSet::Full});
  train::initialise(net);
  std::vector<torch::Tensor> batches;
  for (int i = 0; i < 6; ++i) batches.push_back(torch::randn({3, 9, 12, 12}) * (0.5 + i) + 0.1 * i);
  size_t next = 0;
  train::recalibrate_batch_norm(net, [&] { return batches[next++]; }, 6);
  ASSERT_EQ(next, 6u);
  auto* block = net->blocks[0]->as<train::ResBlock>();
  torch::Tensor mean = torch::zeros({8}), var = torch::zeros({8});
  {
    torch::NoGradGuard no_grad;
    for (const auto& x : batches) {
      const auto h = block->conv1(net->head->prelu(net->head->conv(x)));
      mean += h.mean({0, 2, 3}) / 6.0;
      var += h.var({0, 2, 3}, /*unbiased=*/true) / 6.0;
    }
  }
  EXPECT_TRUE(torch::allclose(block->bn1->running_mean, mean, 1e-4, 1e-5)) << block->bn1->running_mean << mean;
  EXPECT_TRUE(torch::allclose(block->bn1->running_var, var, 1e-4, 1e-5)) << block->bn1->running_var << var;
  EXPECT_TRUE(net->is_training()) << "the mode is restored";
  EXPECT_EQ(block->bn1->options.momentum().value(), 0.1) << "and the momentum";
}

// Frozen BN: training steps leave the statistics alone and the training forward is the inference forward.
TEST(TrainBatchNorm, FrozenStatisticsTrainAsInferenceRuns) {
  torch::manual_seed(6);
  train::ResidueNet net(nn::Architecture{2, 8, FeatureSet::Full});
  train::initialise(net);
  net->train();
  {
    torch::NoGradGuard no_grad;
    for (int i = 0; i < 3; ++i) net->forward(torch::randn({4, 9, 12, 12}));
  }
  const torch::Tensor stats = net->blocks[1]->as<train::ResBlock>()->bn2->running_var.clone();
  const torch::Tensor x = torch::randn({2, 9, 12, 12}) * 3;
  net->train();
  train::freeze_batch_norm(net);
  const torch::Tensor trained = net->forward(x);
  trained.abs().mean().backward();  // gradients still reach the BN's affine parameters
  EXPECT_TRUE(net->blocks[1]->as<train::ResBlock>()->bn2->weight.grad().defined());
  EXPECT_TRUE(torch::equal(net->blocks[1]->as<train::ResBlock>()->bn2->running_var, stats));
  net->eval();
  torch::NoGradGuard no_grad;
  EXPECT_TRUE(torch::allclose(trained.detach(), net->forward(x), 1e-5, 1e-6));
  net->train();
  EXPECT_FALSE(torch::allclose(net->forward(x), trained.detach(), 1e-3, 1e-3)) << "unfrozen, batch statistics differ";
}

// A patch within the network's reach is refused before any data is read, naming the reach and a patch that works;
// one past the reach trains (a note says the interior needs twice the reach).
TEST(TrainCli, RefusesAPatchWithinTheNetworksReach) {
  testing::TempDir tmp;
  std::string text;
  // 4 levels of 1 block: reach 75 px, rounded to the 8-px pooling grid: 80.
  const int rc = testing::run_program(RESIDUE_TRAIN_PATH,
                                      {"--data", tmp.path().string(), "--arch", "1,1,1,1/8,8,8,8", "--patch", "64",
                                       "--steps", "1", "-o", (tmp / "m.safetensors").string()},
                                      &text);
  EXPECT_NE(rc, 0) << text;
  EXPECT_NE(text.find("--patch 64 is within the reach"), std::string::npos) << text;
  EXPECT_NE(text.find("(80 px each side)"), std::string::npos) << text;
  EXPECT_NE(text.find("use --patch 88"), std::string::npos) << text;
  EXPECT_FALSE(std::filesystem::exists(tmp / "m.safetensors"));

  // An exposure key means nothing without --autoexposure: refused rather than silently ignored.
  EXPECT_NE(testing::run_program(RESIDUE_TRAIN_PATH,
                                 {"--data", tmp.path().string(), "--exposure-key", "1", "-o",
                                  (tmp / "m.safetensors").string()},
                                 &text),
            0);
  EXPECT_NE(text.find("--exposure-key needs --autoexposure"), std::string::npos) << text;

  // The edge term finds edges in the albedo and normal planes: refused for a feature set without them.
  EXPECT_NE(testing::run_program(RESIDUE_TRAIN_PATH,
                                 {"--data", tmp.path().string(), "--features", "color", "--edge-ssim-weight", "1",
                                  "-o", (tmp / "m.safetensors").string()},
                                 &text),
            0);
  EXPECT_NE(text.find("--edge-ssim-weight needs a feature set with the albedo and the normal, not \"color\""),
            std::string::npos)
      << text;

  // A teacher at weight 0 would change nothing: refused, naming the option.
  EXPECT_NE(testing::run_program(RESIDUE_TRAIN_PATH,
                                 {"--data", tmp.path().string(), "--arch", "1/8", "--teacher", "multiscale",
                                  "--teacher-weight", "0", "-o", (tmp / "m.safetensors").string()},
                                 &text),
            0);
  EXPECT_NE(text.find("--teacher-weight must be above 0 with --teacher"), std::string::npos) << text;
}

TEST(TrainCli, ResumesFromItsCheckpointAndExportsAModelCoreLoads) {
  const auto starter = testing::shared_dataset("cycles-starter");
  RESIDUE_REQUIRE_SHARED(starter);
  testing::TempDir tmp;
  std::filesystem::create_directories(tmp / "data");
  for (const char* s : {"s100", "s101", "s102"}) std::filesystem::create_directory_symlink(starter / s, tmp / "data" / s);
  const std::string out = (tmp / "m.safetensors").string(), csv = (tmp / "m.csv").string();
  auto train = [&](int steps, std::string* text) {
    return testing::run_program(RESIDUE_TRAIN_PATH,
                                {"--data", (tmp / "data").string(), "--val", "1", "--arch", "2/8", "--dilations", "1,2",
                                 "--patch", "32", "--batch", "2", "--steps", std::to_string(steps), "--val-every", "10",
                                 "--checkpoint-every", "5", "--threads", "1", "--precise-bn", "3", "--freeze-bn-after", "0.75",
                                 "-o", out, "--log", csv, "--force"},
                                text);
  };
  std::string first, second;
  ASSERT_EQ(train(10, &first), 0) << first;
  ASSERT_EQ(train(20, &second), 0) << second;
  EXPECT_NE(second.find("resumed from"), std::string::npos) << second;
  EXPECT_NE(second.find("at step 10"), std::string::npos) << second;
  EXPECT_EQ(second.find("step     10 "), std::string::npos) << "the second run starts after step 10";

  std::ifstream log(csv);
  std::string line, last;
  int rows = 0;
  while (std::getline(log, line)) {
    ++rows;
    last = line;
  }
  EXPECT_EQ(rows, 1 + 4) << "header, steps 5 and 10 (first run; a line per checkpoint), 15 and 20 (second run)";
  EXPECT_EQ(last.rfind("20,", 0), 0u) << last;
  // Each validation per scene: steps 10 (first run) and 20 (the resumed run appends).
  std::ifstream scene_log(csv + ".scenes.jsonl");
  std::vector<int> validated_steps;
  while (std::getline(scene_log, line)) {
    const auto v = nlohmann::json::parse(line);
    validated_steps.push_back(v.at("step").get<int>());
    ASSERT_EQ(v.at("per_scene").size(), 1u) << line;
    EXPECT_EQ(v.at("per_scene")[0].at("scene"), "s102") << line;
  }
  EXPECT_EQ(validated_steps, (std::vector<int>{10, 20}));

  const nn::Model model = nn::load_model(out);
  EXPECT_EQ(model.network.arch.dilations, (std::vector<int>{1, 2}));
  const auto training = nlohmann::json::parse(model.metadata.at("training"));
  EXPECT_EQ(training.at("steps"), 20);
  EXPECT_EQ(training.at("precise_bn_batches"), 3);
  EXPECT_EQ(training.at("freeze_bn_after"), 0.75);
  EXPECT_GT(training.at("wall_s").get<double>(), training.at("wall_s_this_run").get<double>())
      << "the first run's time is counted";
  const auto validation = nlohmann::json::parse(model.metadata.at("validation"));
  EXPECT_EQ(validation.at("scenes"), 1);
  EXPECT_GT(validation.at("relmse").get<double>(), 0.0);

  // A colour-only variant fine-tuned from it: a fresh run (its own checkpoint) that starts from the file and
  // records where it started.
  std::string third;
  const std::string variant = (tmp / "m-color.safetensors").string();
  ASSERT_EQ(testing::run_program(RESIDUE_TRAIN_PATH,
                                 {"--data", (tmp / "data").string(), "--val", "1", "--arch", "2/8", "--dilations", "1,2",
                                  "--features", "color", "--init-from", out, "--lr", "3e-4", "--patch", "32", "--batch",
                                  "2", "--steps", "3", "--threads", "1", "--name", "m-color", "-o", variant},
                                 &third),
            0)
      << third;
  EXPECT_NE(third.find("initialised from"), std::string::npos) << third;
  EXPECT_EQ(third.find("resumed from"), std::string::npos) << third;
  const nn::Model color = nn::load_model(variant);
  EXPECT_EQ(color.network.arch.features, FeatureSet::ColorOnly);
  EXPECT_EQ(nlohmann::json::parse(color.metadata.at("training")).at("init_from"), "m");
}

}  // namespace
}  // namespace residue
