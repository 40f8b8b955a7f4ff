// Features, model files, tiled inference and the job API.
#include <cfloat>
#include <chrono>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <thread>

#include <gtest/gtest.h>
#include <OpenImageIO/imagebuf.h>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoise_job.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/oidn_filter.h"
#include "core/features/features.h"
#include "core/metrics/metrics.h"
#include "core/io/exr_writer.h"
#include "core/nn/model_card.h"
#include "core/nn/model_file.h"
#include "core/nn/model_registry.h"
#include "core/util/error.h"
#include "support/reference_network.h"
#include "support/test_support.h"

namespace residue {
namespace {

using testing::random_image;
using testing::random_stack;
using testing::TempDir;

const float kNan = std::numeric_limits<float>::quiet_NaN();
const float kInf = std::numeric_limits<float>::infinity();

nn::Model small_model(FeatureSet set = FeatureSet::Full, int blocks = 2, int width = 8, uint32_t seed = 1) {
  return nn::model_from_network(nn::random_network({blocks, width, set}, seed), "test");
}

double max_rel_diff(const Image& a, const Image& b) {
  double scale = 1e-6, err = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    scale = std::max(scale, static_cast<double>(std::abs(b.data()[i])));
    err = std::max(err, static_cast<double>(std::abs(a.data()[i] - b.data()[i])));
  }
  return err / scale;
}

// Feature planes 0-2 are log(1 + value(x, y, c, colour)), colour being the render's, negatives as 0.
void expect_colour_planes(const Image& f, const AovStack& s,
                          const std::function<double(int64_t, int64_t, int, double)>& value) {
  for (int64_t y = 0; y < f.height(); ++y)
    for (int64_t x = 0; x < f.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        const double colour = std::max(0.0, static_cast<double>(s.color.image.at(x, y, c)));
        EXPECT_NEAR(f.at(x, y, c), std::log1p(value(x, y, c, colour)), 2e-6 * (1 + f.at(x, y, c))) << x << "," << y;
      }
}

bool all_finite_nonnegative(const Image& img) {
  for (size_t i = 0; i < img.size(); ++i)
    if (!std::isfinite(img.data()[i]) || img.data()[i] < 0) return false;
  return true;
}

// The network's output as it is: these tests check the tiling and the backends (the energy correction and
// the output guard have their own tests, and the streamed test below runs with both).
DenoiseOptions eigen_options(int64_t tile) {
  DenoiseOptions o;
  o.backend = "eigen";
  o.tile = tile;
  o.skip_empty_tiles = false;
  o.energy_correction = false;
  o.output_guard = false;
  return o;
}

// --- features --------------------------------------------------------------------------------------------

TEST(Features, ColourTransformAndInverse) {
  for (float c : {0.0f, 1e-6f, 0.5f, 1.0f, 100.0f, 1e4f, 1e8f})
    EXPECT_NEAR(expand_color(compress_color(c)), c, 1e-5 * std::max(1.0f, c)) << c;
  EXPECT_EQ(compress_color(kNan), 0.0f);
  EXPECT_EQ(compress_color(kInf), 0.0f);
  EXPECT_EQ(compress_color(-3.0f), 0.0f);
  EXPECT_FLOAT_EQ(compress_color(FLT_MAX), std::log1p(FLT_MAX));
  EXPECT_EQ(expand_color(-5.0f), 0.0f);
  EXPECT_EQ(expand_color(kNan), 0.0f);
  EXPECT_TRUE(std::isfinite(expand_color(1e30f)));
  EXPECT_TRUE(std::isfinite(expand_color(kInf)));
}

TEST(Features, PlanesInPaperOrder) {
  AovStack s = random_stack(4, 3, 5);
  s.depth->image.at(1, 1) = 0.0f;  // background
  const FeatureStats stats = compute_feature_stats(s);
  std::vector<float> hits;
  for (size_t i = 0; i < s.depth->image.size(); ++i)
    if (s.depth->image.data()[i] > 0) hits.push_back(s.depth->image.data()[i]);
  std::sort(hits.begin(), hits.end());
  const double median = hits[hits.size() / 2];
  EXPECT_NEAR(std::log2(stats.depth_scale), std::log2(median), 1.0 / 16 + 1e-12) << "within 1/16 octave of the median";
  EXPECT_DOUBLE_EQ(std::log2(stats.depth_scale) * 8, std::round(std::log2(stats.depth_scale) * 8));
  Image f;
  make_features(s, FeatureSet::Full, stats, {1, 0, 3, 3}, f);
  ASSERT_EQ(f.channels(), 9);
  // Pixel (0,1) of the feature image is (1,1) of the stack.
  EXPECT_FLOAT_EQ(f.at(0, 1, 0), std::log1p(s.color.image.at(1, 1, 0)));
  EXPECT_EQ(f.at(0, 1, 3), 0.0f) << "background depth stays 0";
  EXPECT_FLOAT_EQ(f.at(1, 1, 3), static_cast<float>(std::log1p(s.depth->image.at(2, 1) / stats.depth_scale)));
  EXPECT_FLOAT_EQ(f.at(1, 2, 4), s.normal->image.at(2, 2, 0));
  EXPECT_FLOAT_EQ(f.at(1, 2, 5), s.normal->image.at(2, 2, 1));
  EXPECT_FLOAT_EQ(f.at(2, 0, 8), std::log1p(s.albedo->image.at(3, 0, 2)));
  make_features(s, FeatureSet::ColorAlbedoNormal, stats, {0, 0, 4, 3}, f);
  EXPECT_EQ(f.channels(), 8);
  EXPECT_FLOAT_EQ(f.at(2, 2, 3), s.normal->image.at(2, 2, 0));
}

TEST(Features, WorldNormalsRotatedByTheCamera) {
  AovStack s = random_stack(1, 1, 2);
  s.normal_space = NormalSpace::World;
  // A camera rotated 90 degrees about world z: world +x maps to camera +y.
  s.world_to_camera = std::array<double, 16>{0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  s.normal->image.at(0, 0, 0) = 1;
  s.normal->image.at(0, 0, 1) = 0;
  s.normal->image.at(0, 0, 2) = 0;
  const FeatureStats stats = compute_feature_stats(s);
  EXPECT_TRUE(stats.rotate_normals);
  Image f;
  make_features(s, FeatureSet::Full, stats, {0, 0, 1, 1}, f);
  EXPECT_NEAR(f.at(0, 0, 4), 0.0f, 1e-7);
  EXPECT_NEAR(f.at(0, 0, 5), 1.0f, 1e-7);
}

TEST(Features, NoiseLevelPlaneIsTheLogStandardDeviation) {
  AovStack s = random_stack(3, 2, 4);
  EXPECT_EQ(feature_set_for(s), FeatureSet::Full);
  EXPECT_THROW(check_features_available(s, FeatureSet::FullVariance), Error);
  s.variance = Aov{random_image(3, 2, 3, 9, 0.0f, 2.0f), {}, {}, 0};
  s.variance->image.at(2, 1, 0) = std::numeric_limits<float>::quiet_NaN();  // counts as 0
  EXPECT_EQ(feature_set_for(s), FeatureSet::FullVariance);
  Image f;
  make_features(s, FeatureSet::FullVariance, compute_feature_stats(s), {0, 0, 3, 2}, f);
  ASSERT_EQ(f.channels(), 10);
  for (int64_t y = 0; y < 2; ++y)
    for (int64_t x = 0; x < 3; ++x) {
      double sum = 0;
      for (int c = 0; c < 3; ++c) {
        const double v = s.variance->image.at(x, y, c);
        sum += std::isfinite(v) ? v : 0.0;
      }
      EXPECT_NEAR(f.at(x, y, 9), std::log1p(std::sqrt(sum / 3)), 1e-6);
    }
  // The first nine planes are the full set's.
  Image full;
  make_features(s, FeatureSet::Full, compute_feature_stats(s), {0, 0, 3, 2}, full);
  for (int c = 0; c < 9; ++c) EXPECT_EQ(f.at(1, 1, c), full.at(1, 1, c));
  // A one-channel variance AOV is used as is.
  s.variance = Aov{Image(3, 2, 1, 4.0f), {}, {}, 0};
  make_features(s, FeatureSet::FullVariance, compute_feature_stats(s), {0, 0, 3, 2}, f);
  EXPECT_FLOAT_EQ(f.at(0, 0, 9), std::log1p(2.0f));
}

TEST(Features, MissingAovNamesWhatIsMissing) {
  AovStack s = random_stack(2, 2, 1);
  s.depth.reset();
  EXPECT_EQ(feature_set_for(s), FeatureSet::ColorAlbedoNormal);
  try {
    check_features_available(s, FeatureSet::Full);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Input);
    EXPECT_NE(std::string(e.what()).find("depth"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("color+albedo+normal"), std::string::npos) << e.what();
  }
  s.albedo.reset();
  EXPECT_EQ(feature_set_for(s), FeatureSet::ColorOnly);
}

// --- model files -------------------------------------------------------------------------------------------

TEST(ModelFile, RoundTripKeepsEveryWeight) {
  TempDir tmp;
  const nn::Network net = nn::random_network({3, 16, FeatureSet::ColorAlbedoNormal}, 9);
  nn::write_safetensors(tmp / "m.safetensors", nn::to_safetensors(net, {{"name", "tiny-test"}}), false);
  const nn::Model m = nn::load_model(tmp / "m.safetensors");
  EXPECT_EQ(m.name, "tiny-test");
  EXPECT_EQ(m.network.arch.blocks, 3);
  EXPECT_EQ(m.network.arch.features, FeatureSet::ColorAlbedoNormal);
  EXPECT_EQ(m.network.head.weight, net.head.weight);
  EXPECT_EQ(m.network.blocks[2].conv2.weight, net.blocks[2].conv2.weight);
  EXPECT_EQ(m.network.blocks[1].conv1.bias, net.blocks[1].conv1.bias);
  EXPECT_EQ(m.network.tail.bias, net.tail.bias);
  EXPECT_EQ(m.network.out.weight, net.out.weight);
  EXPECT_TRUE(m.network.arch.dilations.empty());
  // And it refuses to overwrite.
  EXPECT_THROW(nn::write_safetensors(tmp / "m.safetensors", nn::to_safetensors(net), false), Error);
  // Dilations travel in the metadata; a bad list is refused with the key named.
  const nn::Network dilated = nn::random_network({4, 8, FeatureSet::Full, {1, 3}}, 2);
  nn::write_safetensors(tmp / "d.safetensors", nn::to_safetensors(dilated), false);
  EXPECT_EQ(nn::load_model(tmp / "d.safetensors").network.arch.dilations, (std::vector<int>{1, 3}));
  EXPECT_EQ(nn::load_model(tmp / "d.safetensors").network.arch.halo(), 3 + 2 * (1 + 3 + 1 + 3));
  EXPECT_FALSE(nn::load_model(tmp / "d.safetensors").network.arch.input_skip);
  nn::write_safetensors(tmp / "s.safetensors", nn::to_safetensors(nn::random_network({1, 8, FeatureSet::Full, {}, true}, 2)), false);
  EXPECT_TRUE(nn::load_model(tmp / "s.safetensors").network.arch.input_skip);
  auto f = nn::to_safetensors(dilated);
  f.metadata["residue.dilations"] = "1,0";
  nn::write_safetensors(tmp / "bad.safetensors", f, false);
  try {
    nn::load_model(tmp / "bad.safetensors");
    ADD_FAILURE() << "a dilation of 0 loaded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("residue.dilations"), std::string::npos) << e.what();
  }
}

TEST(ModelFile, BatchNormIsFoldedOnLoad) {
  TempDir tmp;
  const nn::Network net = nn::random_network({1, 4, FeatureSet::ColorOnly}, 4);
  nn::SafetensorsFile f = nn::to_safetensors(net);
  f.metadata["residue.bn_eps"] = "0.001";
  f.tensors["tail.bn.weight"].values = {2.0f, 0.5f, 1.0f, 3.0f};
  f.tensors["tail.bn.running_mean"].values = {0.1f, -0.2f, 0.3f, 0.0f};
  f.tensors["tail.bn.running_var"].values = {4.0f, 1.0f, 0.25f, 9.0f};
  nn::write_safetensors(tmp / "bn.safetensors", f, false);
  const nn::Model m = nn::load_model(tmp / "bn.safetensors");
  const Image x = random_image(3, 3, 4, 1, -1, 1);
  const auto folded = testing::naive_conv3x3(testing::to_tensor(x), m.network.tail);
  const auto raw = testing::naive_conv3x3(testing::to_tensor(x), net.tail);  // includes bias (= beta here)
  for (size_t i = 0; i < raw.v.size(); ++i) {
    const size_t o = i % 4;
    const double conv = raw.v[i] - net.tail.bias[o];
    const double expect = (conv - f.tensors["tail.bn.running_mean"].values[o]) /
                              std::sqrt(f.tensors["tail.bn.running_var"].values[o] + 0.001) *
                              f.tensors["tail.bn.weight"].values[o] + net.tail.bias[o];
    EXPECT_NEAR(folded.v[i], expect, 1e-5);
  }
}

std::string load_error(const std::filesystem::path& p) {
  try {
    nn::load_model(p);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(ModelFile, ErrorsNameTheFileAndTheTensor) {
  TempDir tmp;
  const nn::Network net = nn::random_network({1, 4, FeatureSet::Full}, 2);
  {
    auto f = nn::to_safetensors(net);
    f.tensors["blocks.0.conv9.weight"] = f.tensors["blocks.0.conv1.weight"];
    f.tensors.erase("blocks.0.conv1.weight");
    nn::write_safetensors(tmp / "name.safetensors", f, false);
    const std::string e = load_error(tmp / "name.safetensors");
    EXPECT_NE(e.find("blocks.0.conv1.weight"), std::string::npos) << e;
    EXPECT_NE(e.find("name.safetensors"), std::string::npos) << e;
  }
  {
    auto f = nn::to_safetensors(net);
    f.tensors["head.conv.weight"].shape = {4, 3, 3, 3};
    f.tensors["head.conv.weight"].values.resize(4 * 3 * 9);
    nn::write_safetensors(tmp / "shape.safetensors", f, false);
    const std::string e = load_error(tmp / "shape.safetensors");
    EXPECT_NE(e.find("[4, 3, 3, 3]"), std::string::npos) << e;
    EXPECT_NE(e.find("[4, 9, 3, 3]"), std::string::npos) << e;
  }
  {
    auto f = nn::to_safetensors(net);
    f.tensors["extra.weight"] = nn::Tensor{"F32", {1}, {1.0f}};
    nn::write_safetensors(tmp / "extra.safetensors", f, false);
    EXPECT_NE(load_error(tmp / "extra.safetensors").find("unexpected tensor \"extra.weight\""), std::string::npos);
  }
  {
    auto f = nn::to_safetensors(net);
    f.metadata["residue.features"] = "color";  // the head expects 9 inputs: a wrong feature set
    nn::write_safetensors(tmp / "features.safetensors", f, false);
    EXPECT_NE(load_error(tmp / "features.safetensors").find("head.conv.weight"), std::string::npos);
  }
  {
    // A shape whose element count overflows int64 (2^62 x 4): refused with the tensor named, no signed overflow.
    const std::string header = R"({"x":{"dtype":"F32","shape":[4611686018427387904,4],"data_offsets":[0,16]}})";
    std::ofstream out(tmp / "huge.safetensors", std::ios::binary);
    const uint64_t n = header.size();
    out.write(reinterpret_cast<const char*>(&n), 8);
    out << header << std::string(16, '\0');
    out.close();
    const std::string e = load_error(tmp / "huge.safetensors");
    EXPECT_NE(e.find("tensor \"x\" has shape [4611686018427387904, 4]"), std::string::npos) << e;
  }
  {
    nn::write_safetensors(tmp / "full.safetensors", nn::to_safetensors(net), false);
    const auto size = std::filesystem::file_size(tmp / "full.safetensors");
    std::filesystem::copy_file(tmp / "full.safetensors", tmp / "cut.safetensors");
    std::filesystem::resize_file(tmp / "cut.safetensors", size - 100);
    EXPECT_NE(load_error(tmp / "cut.safetensors").find("truncated"), std::string::npos) << load_error(tmp / "cut.safetensors");
  }
  {
    // A dtype Residue does not read: rewrite one tensor's dtype in the header by hand.
    nn::write_safetensors(tmp / "d.safetensors", nn::to_safetensors(net), false);
    std::fstream file(tmp / "d.safetensors", std::ios::in | std::ios::out | std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
    const auto pos = bytes.find("\"F32\"");
    ASSERT_NE(pos, std::string::npos);
    file.seekp(static_cast<std::streamoff>(pos));
    file.write("\"I32\"", 5);
    file.close();
    EXPECT_NE(load_error(tmp / "d.safetensors").find("dtype I32"), std::string::npos) << load_error(tmp / "d.safetensors");
  }
  std::ofstream(tmp / "junk.safetensors") << "nonsense";
  EXPECT_FALSE(load_error(tmp / "junk.safetensors").empty());
  EXPECT_NE(load_error(tmp / "missing.safetensors").find("missing.safetensors"), std::string::npos);
}

// --- tiled inference ---------------------------------------------------------------------------------------

TEST(Denoise, TiledEqualsUntiled) {
  // halo 3 + 2 * (1 + 4 + 1) = 15: tiles need the dilated reach as their halo
  const nn::Model dilated = nn::model_from_network(nn::random_network({3, 8, FeatureSet::Full, {1, 4}}, 6));
  for (const nn::Model& model : {small_model(), dilated})
    for (auto [w, h] : std::vector<std::pair<int64_t, int64_t>>{{1, 1}, {3, 5}, {40, 33}, {1000, 7}}) {
      const AovStack s = random_stack(w, h, 3);
      const Image whole = denoise(s, model, eigen_options(std::max(w, h)));
      for (int64_t tile : {16, 23}) {
        DenoiseStats stats;
        const Image tiled = denoise(s, model, eigen_options(tile), {}, &stats);
        EXPECT_LT(max_rel_diff(tiled, whole), 1e-5) << model.network.arch.to_string() << " " << w << "x" << h << " tile " << tile;
        EXPECT_EQ(stats.tiles, ((w + tile - 1) / tile) * ((h + tile - 1) / tile));
      }
    }
}

TEST(Denoise, MatchesTheFloat64ReferenceThroughFeatures) {
  const nn::Model model = small_model(FeatureSet::Full, 1, 8, 3);
  const AovStack s = random_stack(9, 7, 8);
  const Image out = denoise(s, model, eigen_options(4));
  Image f;
  make_features(s, FeatureSet::Full, compute_feature_stats(s), {0, 0, 9, 7}, f);
  const auto ref = testing::naive_forward(model.network, f);
  for (size_t i = 0; i < ref.v.size(); ++i)
    EXPECT_NEAR(out.data()[i], expand_color(static_cast<float>(ref.v[i])), 1e-5 * std::max(1.0f, out.data()[i]));
}

// A demodulated model (issue 16, lever 4): the colour planes are log(1 + c / (a + 0.01)) and the output is the
// network's times (a + 0.01), checked against the float64 network with the division and product done here, on
// albedo that is black, NaN, negative and emissive (30) somewhere; tiled equals untiled; the flag travels in the
// model file and a colour-only demodulated model is refused.
TEST(Denoise, DemodulatedModelDividesByTheAlbedoAndMultipliesBack) {
  nn::Architecture arch{1, 8, FeatureSet::Full};
  arch.demodulate = true;
  const nn::Model model = nn::model_from_network(nn::random_network(arch, 3), "demod");
  AovStack s = random_stack(9, 7, 8);
  Image& albedo = s.albedo->image;
  albedo.at(1, 1, 0) = 0.0f;
  albedo.at(2, 3, 1) = std::numeric_limits<float>::quiet_NaN();
  albedo.at(4, 2, 2) = -0.5f;
  albedo.at(5, 5, 0) = 30.0f;
  const auto factor = [&](int64_t x, int64_t y, int c) {
    const double a = albedo.at(x, y, c);
    return (std::isfinite(a) && a > 0 ? a : 0.0) + static_cast<double>(0.01f);
  };
  FeatureStats stats = compute_feature_stats(s);
  stats.demodulate = true;
  Image f;
  make_features(s, FeatureSet::Full, stats, {0, 0, 9, 7}, f);
  expect_colour_planes(f, s, [&](int64_t x, int64_t y, int c, double colour) { return colour / factor(x, y, c); });
  const Image out = denoise(s, model, eigen_options(9));
  const auto ref = testing::naive_forward(model.network, f);
  for (int64_t y = 0; y < 7; ++y)
    for (int64_t x = 0; x < 9; ++x)
      for (int c = 0; c < 3; ++c) {
        const double expected = std::expm1(std::max(0.0, ref.at(y, x, c))) * factor(x, y, c);
        EXPECT_NEAR(out.at(x, y, c), expected, 1e-5 * std::max(1.0, expected)) << x << "," << y << "," << c;
      }
  EXPECT_LT(max_rel_diff(denoise(s, model, eigen_options(4)), out), 1e-5) << "tiled equals untiled";

  TempDir tmp;
  nn::write_safetensors(tmp / "d.safetensors", nn::to_safetensors(model.network), false);
  EXPECT_TRUE(nn::load_model(tmp / "d.safetensors").network.arch.demodulate);
  EXPECT_NE(nn::load_model(tmp / "d.safetensors").architecture().find("demodulated"), std::string::npos);
  auto colour_only = nn::to_safetensors(nn::random_network({1, 8, FeatureSet::ColorOnly}, 2));
  colour_only.metadata["residue.demodulate"] = "1";
  nn::write_safetensors(tmp / "c.safetensors", colour_only, false);
  EXPECT_NE(testing::error_message([&] { nn::load_model(tmp / "c.safetensors"); }, ErrorKind::Input).find("albedo"),
            std::string::npos);
}

// An autoexposed model (issue 16): its colour planes are log(1 + c e) with e the image's autoexposure and its
// output the network's divided by e, against the float64 network; so a render 8x brighter or 16x dimmer gives
// the same image scaled alike (the same weights without the flag do not: the test can tell), with the energy
// correction and the guard on; tiled equals untiled; the flag travels in the model file and a bad value is refused.
TEST(Denoise, AutoexposedModelScalesWithTheRender) {
  nn::Architecture arch{1, 8, FeatureSet::Full};
  arch.autoexposure = true;
  arch.exposure_key = 0.5f;  // the log-average luminance goes to 0.5 instead of OIDN's 0.18
  const nn::Network network = nn::random_network(arch, 5);
  const nn::Model model = nn::model_from_network(network, "ae");
  const AovStack s = random_stack(21, 13, 8);
  const float e = oidn_autoexposure(s.color.image) * 0.5f / 0.18f;
  ASSERT_TRUE(std::isfinite(e) && e > 0 && std::abs(e - 1.0f) > 0.1f) << e;  // the scale does something here
  FeatureStats stats = compute_feature_stats(s);
  stats.exposure = e;
  Image f;
  make_features(s, FeatureSet::Full, stats, {0, 0, 21, 13}, f);
  expect_colour_planes(f, s, [&](int64_t, int64_t, int, double colour) { return colour * e; });
  const Image out = denoise(s, model, eigen_options(21));
  const auto ref = testing::naive_forward(model.network, f);
  for (int64_t y = 0; y < 13; ++y)
    for (int64_t x = 0; x < 21; ++x)
      for (int c = 0; c < 3; ++c) {
        const double expected = std::expm1(std::max(0.0, ref.at(y, x, c))) / e;
        EXPECT_NEAR(out.at(x, y, c), expected, 1e-5 * std::max(1.0, expected)) << x << "," << y << "," << c;
      }
  EXPECT_LT(max_rel_diff(denoise(s, model, eigen_options(8)), out), 1e-5) << "tiled equals untiled";

  nn::Network plain_network = network;
  plain_network.arch.autoexposure = false;
  const nn::Model plain = nn::model_from_network(plain_network, "plain");
  DenoiseOptions o = eigen_options(8);
  o.energy_correction = true;
  o.output_guard = true;
  for (float k : {8.0f, 1.0f / 16}) {
    AovStack scaled = s;
    for (int64_t i = 0; i < scaled.color.image.pixel_count() * 3; ++i) scaled.color.image.data()[i] *= k;
    Image expected = denoise(s, model, o);
    for (int64_t i = 0; i < expected.pixel_count() * 3; ++i) expected.data()[i] *= k;
    EXPECT_LT(max_rel_diff(denoise(scaled, model, o), expected), 1e-4) << "x" << k;
    Image plain_expected = denoise(s, plain, o);
    for (int64_t i = 0; i < plain_expected.pixel_count() * 3; ++i) plain_expected.data()[i] *= k;
    EXPECT_GT(max_rel_diff(denoise(scaled, plain, o), plain_expected), 1e-2) << "x" << k << " without the flag";
  }

  TempDir tmp;
  auto file = nn::to_safetensors(model.network);
  nn::write_safetensors(tmp / "ae.safetensors", file, false);
  const nn::Model loaded = nn::load_model(tmp / "ae.safetensors");
  EXPECT_TRUE(loaded.network.arch.autoexposure);
  EXPECT_EQ(loaded.network.arch.exposure_key, 0.5f);
  EXPECT_NE(loaded.architecture().find("autoexposure 0.5"), std::string::npos) << loaded.architecture();
  for (const auto& [key, value] : {std::pair<std::string, std::string>{"residue.autoexposure", "yes"},
                                   {"residue.exposure_key", "-1"}, {"residue.exposure_key", "0.5x"}}) {
    auto bad = file;
    bad.metadata[key] = value;
    nn::write_safetensors(tmp / "bad.safetensors", bad, true);
    EXPECT_NE(testing::error_message([&] { nn::load_model(tmp / "bad.safetensors"); }, ErrorKind::Input).find(key),
              std::string::npos) << key << "=" << value;
  }
}

// A post-correction model (issue 16, lever 6) refines OIDN's denoise: OIDN runs first, its log colour comes in
// as planes 9-11, and input_skip adds those. With a zero output convolution the model returns OIDN's image (up to
// the log/exp round trip); with random weights it equals the float64 network on those 12 planes. The file records
// the prior and loads it; the streamed path refuses (OIDN needs the whole render first).
TEST(Denoise, PostCorrectionRefinesOidnsOutput) {
  const nn::Model oidn = nn::load_model(testing::oidn_dir() / "rt_hdr_alb_nrm.tza");
  nn::Architecture arch{1, 8, FeatureSet::Full};
  arch.prior = "oidn";
  arch.input_skip = true;
  ASSERT_EQ(arch.in_channels(), 12);
  nn::Network net = nn::random_network(arch, 5);
  const AovStack s = random_stack(21, 18, 4);
  DenoiseOptions o = eigen_options(64);
  o.output_guard = false;
  const Image by_oidn = denoise(s, oidn, o);

  nn::Network zero = net;
  std::fill(zero.out.weight.begin(), zero.out.weight.end(), 0.0f);
  std::fill(zero.out.bias.begin(), zero.out.bias.end(), 0.0f);
  nn::Model identity = nn::model_from_network(zero, "zero-correction");
  identity.prior = std::make_shared<const nn::Model>(oidn);
  EXPECT_LT(max_rel_diff(denoise(s, identity, o), by_oidn), 1e-5);

  nn::Model model = nn::model_from_network(net, "post");
  model.prior = identity.prior;
  const Image out = denoise(s, model, o);
  AovStack with = s;
  with.prior = Aov{by_oidn, {}, {}, 0};
  FeatureStats stats = compute_feature_stats(s);
  stats.prior = true;
  Image f;
  make_features(with, FeatureSet::Full, stats, {0, 0, 21, 18}, f);
  ASSERT_EQ(f.channels(), 12);
  EXPECT_NEAR(f.at(3, 4, 10), std::log1p(by_oidn.at(3, 4, 1)), 1e-6);
  const auto ref = testing::naive_forward(model.network, f);
  for (size_t i = 0; i < ref.v.size(); ++i)
    EXPECT_NEAR(out.data()[i], expand_color(static_cast<float>(ref.v[i])), 1e-4 * std::max(1.0f, out.data()[i]));
  EXPECT_LT(max_rel_diff(denoise(s, model, eigen_options(16)), denoise(s, model, eigen_options(64))), 1e-5)
      << "tiled equals untiled (OIDN's pass and the correction both tiled)";
  {  // the variance blend does not apply to a post-correction model (its prior is cleaner than the noisy input)
    AovStack v = s;
    v.variance = Aov{Image(21, 18, 3, 0.0f), {}, {}, 0};  // zero variance: the blend would keep every input pixel
    DenoiseOptions blend = o;
    blend.variance_blend = true;
    DenoiseStats run;
    EXPECT_LT(max_rel_diff(denoise(v, model, blend, {}, &run), out), 1e-6);
    EXPECT_FALSE(run.variance_blended);
  }

  TempDir tmp;
  nn::write_safetensors(tmp / "p.safetensors", nn::to_safetensors(net), false);
  const nn::Model loaded = nn::load_model(tmp / "p.safetensors");
  ASSERT_TRUE(loaded.prior);
  EXPECT_EQ(loaded.prior->name, "rt_hdr_alb_nrm");
  EXPECT_NE(loaded.architecture().find("refines oidn"), std::string::npos) << loaded.architecture();
  auto bad = nn::to_safetensors(net);
  bad.metadata["residue.prior"] = "bilateral";
  nn::write_safetensors(tmp / "bad.safetensors", bad, false);
  EXPECT_NE(testing::error_message([&] { nn::load_model(tmp / "bad.safetensors"); }, ErrorKind::Input).find("residue.prior"),
            std::string::npos);
  const auto dir = testing::shared_dataset("cycles-starter/s104");
  if (!dir.empty()) {
    const AovReader reader({dir / "noisy_a.exr"});
    EXPECT_NE(testing::error_message([&] { denoise_to_exr(reader, loaded, o, tmp / "s.exr", {}); }, ErrorKind::Usage)
                  .find("in memory"),
              std::string::npos);
    EXPECT_FALSE(std::filesystem::exists(tmp / "s.exr"));
  }
}

TEST(Denoise, RegionOfInterestOnly) {
  const nn::Model model = small_model();
  const AovStack s = random_stack(30, 20, 4);
  const Image full = denoise(s, model, eigen_options(32));
  DenoiseOptions o = eigen_options(8);
  o.roi = Rect{5, 4, 12, 9};
  const Image part = denoise(s, model, o);
  for (int64_t y = 0; y < 20; ++y)
    for (int64_t x = 0; x < 30; ++x)
      for (int c = 0; c < 3; ++c) {
        const bool inside = o.roi->contains({x, y, 1, 1});
        if (inside) {
          EXPECT_NEAR(part.at(x, y, c), full.at(x, y, c), 1e-5 * std::max(1.0f, full.at(x, y, c)));
        } else {
          EXPECT_EQ(part.at(x, y, c), s.color.image.at(x, y, c)) << "outside the ROI the noisy colour stays";
        }
      }
  o.roi = Rect{25, 0, 10, 5};
  EXPECT_THROW(denoise(s, model, o), Error);
}

TEST(Denoise, EmptyTilesArePassedThrough) {
  const nn::Model model = small_model(FeatureSet::Full, 1, 8);  // halo 5
  AovStack s = random_stack(64, 16, 6);
  for (int64_t y = 0; y < 16; ++y)
    for (int64_t x = 0; x < 40; ++x)
      for (int c = 0; c < 3; ++c) s.color.image.at(x, y, c) = 0.0f;
  DenoiseOptions o = eigen_options(16);
  o.skip_empty_tiles = true;
  DenoiseStats stats;
  const Image skipped = denoise(s, model, o, {}, &stats);
  EXPECT_EQ(stats.skipped, 2) << "tiles at x 0-15 and 16-31 see only black within their halo";
  const Image full = denoise(s, model, eigen_options(16));
  for (int64_t y = 0; y < 16; ++y) {
    EXPECT_EQ(skipped.at(3, y, 0), 0.0f);
    EXPECT_EQ(skipped.at(50, y, 1), full.at(50, y, 1)) << "tiles with content are denoised as usual";
  }
}

TEST(Denoise, ExtremeInputsGiveFiniteOutputAndStayLocal) {
  const nn::Model model = small_model(FeatureSet::Full, 1, 8, 7);  // halo 5
  const AovStack clean = random_stack(40, 40, 12);
  const Image clean_out = denoise(clean, model, eigen_options(64));
  struct Case {
    const char* name;
    std::function<void(AovStack&)> spoil;
  };
  const std::vector<Case> cases = {
      {"firefly 1e4", [](AovStack& s) { s.color.image.at(20, 20, 0) = 1e4f; }},
      {"firefly 1e8", [](AovStack& s) { s.color.image.at(20, 20, 1) = 1e8f; }},
      {"firefly FLT_MAX", [](AovStack& s) { s.color.image.at(20, 20, 2) = FLT_MAX; }},
      {"NaN colour", [](AovStack& s) { s.color.image.at(20, 20, 0) = kNan; }},
      {"Inf colour", [](AovStack& s) { s.color.image.at(20, 20, 1) = kInf; }},
      {"negative colour", [](AovStack& s) { s.color.image.at(20, 20, 2) = -50.0f; }},
      {"NaN albedo", [](AovStack& s) { s.albedo->image.at(20, 20, 0) = kNan; }},
      {"Inf albedo", [](AovStack& s) { s.albedo->image.at(20, 20, 1) = kInf; }},
      {"NaN normal", [](AovStack& s) { s.normal->image.at(20, 20, 0) = kNan; }},
      {"zero-length normal", [](AovStack& s) { for (int c = 0; c < 3; ++c) s.normal->image.at(20, 20, c) = 0; }},
      {"NaN depth", [](AovStack& s) { s.depth->image.at(20, 20) = kNan; }},
      {"Inf depth", [](AovStack& s) { s.depth->image.at(20, 20) = kInf; }},
      {"denormal colour", [](AovStack& s) { s.color.image.at(20, 20, 0) = 1e-42f; }},
  };
  for (const auto& c : cases) {
    AovStack s = random_stack(40, 40, 12);
    c.spoil(s);
    const Image out = denoise(s, model, eigen_options(64));
    EXPECT_TRUE(all_finite_nonnegative(out)) << c.name;
    const int64_t halo = model.network.arch.halo();
    for (int64_t y = 0; y < 40; ++y)
      for (int64_t x = 0; x < 40; ++x)
        if (std::abs(x - 20) > halo || std::abs(y - 20) > halo) {
          for (int ch = 0; ch < 3; ++ch) {
            ASSERT_NEAR(out.at(x, y, ch), clean_out.at(x, y, ch), 1e-6f * std::max(1.0f, clean_out.at(x, y, ch)))
                << c.name << " changed (" << x << "," << y << "), outside the receptive field";
          }
        }
  }
  // All black, and a fully non-finite image.
  AovStack black = random_stack(20, 20, 3);
  for (size_t i = 0; i < black.color.image.size(); ++i) black.color.image.data()[i] = 0;
  EXPECT_TRUE(all_finite_nonnegative(denoise(black, model, eigen_options(8))));
  // A colour with no finite value at all is refused (it was once denoised to black and reported as success).
  AovStack nan = random_stack(20, 20, 3);
  for (size_t i = 0; i < nan.color.image.size(); ++i) nan.color.image.data()[i] = kNan;
  EXPECT_NE(testing::error_message([&] { denoise(nan, model, eigen_options(8)); }, ErrorKind::Input)
                .find("no finite value (1200 NaN"),
            std::string::npos);
}

// A model file with a NaN weight is refused when loaded, naming the tensor; one whose weights overflow fp32
// (1e30) stops the denoise with an error instead of writing Inf or black.
TEST(Denoise, NonFiniteWeightsAndOutputsAreErrors) {
  testing::TempDir tmp;
  nn::Network n = nn::random_network({2, 8, FeatureSet::Full}, 3);
  n.blocks[1].conv1.weight[5] = kNan;
  nn::write_safetensors(tmp / "nan.safetensors", nn::to_safetensors(n), false);
  EXPECT_NE(testing::error_message([&] { nn::load_model(tmp / "nan.safetensors"); }, ErrorKind::Input)
                .find("blocks.1.conv1.weight\" has 1 non-finite"),
            std::string::npos);
  // A batch-norm epsilon that is not a number is an input error naming the key, not "internal error: stof".
  int k = 0;
  for (const char* eps : {"abc", "1e999", "-1", ""}) {
    nn::SafetensorsFile f = nn::to_safetensors(nn::random_network({2, 8, FeatureSet::Full}, 3));
    f.metadata["residue.bn_eps"] = eps;
    const auto file = tmp / ("eps" + std::to_string(k++) + ".safetensors");
    nn::write_safetensors(file, f, true);
    EXPECT_NE(testing::error_message([&] { nn::load_model(file); }, ErrorKind::Input).find("residue.bn_eps"),
              std::string::npos)
        << eps;
  }
  nn::Network huge = nn::random_network({2, 8, FeatureSet::Full}, 3);
  for (float& w : huge.head.weight) w = 1e30f;
  for (float& w : huge.blocks[0].conv1.weight) w = 1e30f;
  DenoiseOptions o = eigen_options(16);
  o.output_guard = false;  // the guard would clamp +Inf (not NaN) back into range
  EXPECT_NE(testing::error_message([&] { denoise(random_stack(24, 24, 5), nn::model_from_network(huge, "huge"), o); },
                                    ErrorKind::Input)
                .find("non-finite output values"),
            std::string::npos);
}

TEST(Denoise, MemoryBoundChoosesTheTile) {
  const nn::Model model = small_model(FeatureSet::Full, 4, 32);
  auto backend = nn::make_backend("eigen", model.network, {});
  const int64_t big = tile_for_memory(*backend, model.graph, size_t{1} << 30);
  const int64_t small = tile_for_memory(*backend, model.graph, size_t{8} << 20);
  EXPECT_GT(big, small);
  EXPECT_GT(small, 0);
  EXPECT_EQ(tile_for_memory(*backend, model.graph, 1024), 0);
  const AovStack s = random_stack(50, 50, 1);
  DenoiseOptions o;
  o.backend = "eigen";
  o.max_memory = 4096;
  EXPECT_THROW(denoise(s, model, o), Error);
}

// The viewer's automatic tile for the shipped models at their benchmarked speed: about half a second of work
// per tile with its halo, never below 8 halos, on the network's alignment grid.
TEST(Denoise, InteractiveTileTakesAboutHalfASecondAndKeepsTheHaloSmall) {
  for (const char* name : {"tiny", "small", "base", "paper"}) {
    SCOPED_TRACE(name);
    const nn::Model model = nn::load_model(nn::find_model_for(name, FeatureSet::Full));
    const auto s_per_mp = nn::model_card(model, name).seconds_per_mp(nn::Precision::FP32);
    ASSERT_TRUE(s_per_mp) << "the shipped model has its benchmark";
    const int64_t tile = interactive_tile(model.graph, *s_per_mp);
    const int64_t halo = model.graph.halo();
    EXPECT_EQ(tile % model.graph.alignment(), 0);
    EXPECT_GE(tile, 8 * halo);
    EXPECT_LE(tile, 1024);
    const double seconds = std::pow(static_cast<double>(tile + 2 * halo), 2) * *s_per_mp / 1e6;
    if (tile > 8 * halo + model.graph.alignment()) {  // not held up by the halo bound: near the target
      EXPECT_LE(seconds, 0.5);
      EXPECT_GT(std::pow(static_cast<double>(tile + 2 * halo + 2 * model.graph.alignment()), 2) * *s_per_mp / 1e6, 0.5);
    }
  }
  // The paper's 16/128 network is slow: the halo bound wins (a 0.5 s tile would be 2 px).
  const nn::Model paper = nn::load_model(nn::find_model_for("paper", FeatureSet::Full));
  EXPECT_EQ(interactive_tile(paper.graph, 26.0), 8 * paper.graph.halo());
  EXPECT_EQ(interactive_tile(paper.graph, 0.0), 1024);  // no speed known: the largest
}

TEST(Denoise, RealStarterSceneTiledEqualsUntiled) {
  const auto dir = testing::shared_dataset("cycles-starter/s105");
  RESIDUE_REQUIRE_SHARED(dir);
  const AovStack s = load_aov_stack({dir / "noisy_a.exr"});
  const nn::Model model = small_model(FeatureSet::Full, 2, 16, 5);
  DenoiseStats stats;
  const Image tiled = denoise(s, model, eigen_options(100), {}, &stats);
  const Image whole = denoise(s, model, eigen_options(256));
  EXPECT_EQ(stats.tiles, 9);
  EXPECT_LT(max_rel_diff(tiled, whole), 1e-5);
  EXPECT_TRUE(all_finite_nonnegative(tiled));
}

// --- the job API -------------------------------------------------------------------------------------------

TEST(DenoiseJob, RunsOnAWorkerAndReportsEveryTile) {
  auto stack = std::make_shared<AovStack>(random_stack(48, 32, 2));
  auto model = std::make_shared<nn::Model>(small_model());
  std::mutex m;
  Image assembled(48, 32, 3, -1.0f);
  DenoiseJob job(stack, model, eigen_options(16), [&](const Rect& r, const Image& px) {
    std::lock_guard lock(m);
    for (int64_t y = 0; y < r.height; ++y)
      for (int64_t x = 0; x < r.width; ++x)
        for (int c = 0; c < 3; ++c) assembled.at(r.x + x, r.y + y, c) = px.at(x, y, c);
  });
  job.wait();
  ASSERT_EQ(job.status(), DenoiseJob::Status::Done) << job.error();
  EXPECT_EQ(job.progress().done, 6);
  EXPECT_EQ(job.progress().total, 6);
  ASSERT_TRUE(job.result().has_value());
  const Image direct = denoise(*stack, *model, eigen_options(16));
  EXPECT_EQ(max_rel_diff(*job.result(), direct), 0.0);
  EXPECT_EQ(max_rel_diff(assembled, direct), 0.0) << "the tiles handed out add up to the result";
}

TEST(DenoiseJob, CancelStopsAfterTheTileInFlight) {
  auto stack = std::make_shared<AovStack>(random_stack(256, 256, 2));
  auto model = std::make_shared<nn::Model>(small_model(FeatureSet::Full, 4, 32));
  std::atomic<int> tiles_seen{0};
  std::atomic<DenoiseJob*> self{nullptr};
  DenoiseJob job(stack, model, eigen_options(16), [&](const Rect&, const Image&) {
    while (!self.load()) std::this_thread::yield();  // the worker may start before `job` is known here
    if (++tiles_seen == 2) self.load()->cancel();
  });
  self = &job;
  ASSERT_TRUE(job.wait_for(std::chrono::seconds(30)));
  EXPECT_EQ(job.status(), DenoiseJob::Status::Cancelled);
  EXPECT_FALSE(job.result().has_value());
  EXPECT_EQ(job.progress().done, 2) << "of 256 tiles: cancelled during the second tile's report";
}

TEST(DenoiseJob, ErrorsAreValues) {
  AovStack s = random_stack(8, 8, 1);
  s.depth.reset();
  DenoiseJob job(std::make_shared<AovStack>(std::move(s)), std::make_shared<nn::Model>(small_model()), eigen_options(8));
  job.wait();
  EXPECT_EQ(job.status(), DenoiseJob::Status::Failed);
  EXPECT_EQ(job.error_kind(), ErrorKind::Input);
  EXPECT_NE(job.error().find("depth"), std::string::npos) << job.error();
}

// --- streamed denoise (band by band, bounded memory) ------------------------------------------------------

 TEST(DenoiseStreamed, EqualsTheInMemoryDenoise) {
  const auto dir = testing::shared_dataset("cycles-starter/s104");
  RESIDUE_REQUIRE_SHARED(dir);
  const nn::Model model = small_model(FeatureSet::Full, 2, 8, 9);
  const AovReader reader({dir / "noisy_a.exr"});
  const AovStack whole = load_aov_stack({dir / "noisy_a.exr"});
  TempDir tmp;
  // With the energy correction the streamed denoise runs bands ahead of the one it writes (3 with 24-px tiles).
  struct Case {
    int64_t tile;
    bool energy;
    std::optional<Rect> roi;
    const char* file;
  };
  for (const Case& c : {Case{64, false, {}, "all.exr"}, Case{64, false, Rect{30, 50, 100, 77}, "roi.exr"},
                        Case{64, true, {}, "energy.exr"}, Case{24, true, Rect{30, 50, 100, 77}, "energy_roi.exr"}}) {
    DenoiseOptions o = eigen_options(c.tile);
    o.roi = c.roi;
    o.energy_correction = c.energy;
    o.output_guard = true;  // the streamed path guards each tile as the in-memory one does
    const Image in_memory = denoise(whole, model, o);
    io::ExrWriteOptions exr;
    exr.pixel_type = io::PixelType::Float;
    const DenoiseStats stats = denoise_to_exr(reader, model, o, tmp / c.file, exr);
    EXPECT_EQ(stats.tile_size, c.tile);
    EXPECT_EQ(stats.energy_corrected, c.energy);
    const Image streamed = testing::read_exr_float(tmp / c.file);
    EXPECT_LT(max_rel_diff(streamed, in_memory), 1e-5) << c.file;
  }
  // Variants that read more than the tile's colour: a demodulated model the albedo of the rows it multiplies
  // back, band by band; an autoexposed one its exposure, from a pass over the colour's bands.
  for (const bool demodulate : {true, false}) {
    nn::Architecture arch{2, 8, FeatureSet::Full};
    arch.demodulate = demodulate;
    arch.autoexposure = !demodulate;
    const nn::Model variant = nn::model_from_network(nn::random_network(arch, 4), "variant");
    DenoiseOptions o = eigen_options(24);
    o.energy_correction = true;
    io::ExrWriteOptions exr;
    exr.pixel_type = io::PixelType::Float;
    const auto file = tmp / (demodulate ? "demod.exr" : "autoexposed.exr");
    denoise_to_exr(reader, variant, o, file, exr);
    EXPECT_LT(max_rel_diff(testing::read_exr_float(file), denoise(whole, variant, o)), 1e-5)
        << arch.to_string();
  }
  // The written file keeps the source's metadata and says which backend ran.
  OIIO::ImageBuf img((tmp / "all.exr").string());
  ASSERT_TRUE(img.read());
  EXPECT_NE(img.spec().get_string_attribute("residue:backend").find("eigen"), std::string::npos);
  EXPECT_FALSE(img.spec().get_string_attribute("Note").empty());
}

TEST(DenoiseStreamed, MemoryBoundPicksTheTileAndCancelLeavesNoFile) {
  const std::filesystem::path ex = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";
  const AovReader reader({ex / "noisy.exr"});
  const nn::Model model = small_model(FeatureSet::Full, 2, 16, 3);
  TempDir tmp;
  DenoiseOptions o;
  o.backend = "eigen";
  o.max_memory = size_t{6} << 20;  // 6 MiB: room for bands of small tiles only
  const DenoiseStats stats = denoise_to_exr(reader, model, o, tmp / "a.exr", {});
  EXPECT_GT(stats.tile_size, 0);
  EXPECT_LT(stats.tile_size, 192) << "the bound forces bands narrower than the image";
  o.max_memory = 1 << 16;
  EXPECT_THROW(denoise_to_exr(reader, model, o, tmp / "b.exr", {}), Error);
  o.max_memory = size_t{6} << 20;
  EXPECT_THROW(denoise_to_exr(reader, model, o, tmp / "c.exr", {}, [](const TileEvent& e, const Image&) { return e.done < 2; }),
               Cancelled);
  EXPECT_FALSE(std::filesystem::exists(tmp / "c.exr"));
  int files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(tmp.path())) ++files;
  EXPECT_EQ(files, 1) << "only a.exr: no temporary file left behind";
}

// On both of eigen's paths (the portable one is what runs on CPUs without AVX-512: its im2col strips count in the
// budget too).
TEST(CliDenoise, LargeRendersAreStreamedWithinMaxMemory) {
  TempDir tmp;
  nn::write_safetensors(tmp / "m.safetensors", nn::to_safetensors(nn::random_network({1, 8, FeatureSet::Full}, 1)), false);
  const std::filesystem::path ex = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";
  for (const bool portable : {false, true}) {
    SCOPED_TRACE(portable ? "portable" : "default");
    if (portable) setenv("RESIDUE_EIGEN_PORTABLE", "1", 1);
    const auto out = tmp / (portable ? "portable.exr" : "default.exr");
    std::string text;
    const int rc = testing::run_cli({"denoise", (ex / "noisy.exr").string(), "-r", (ex / "reference.exr").string(), "-o",
                                     out.string(), "-m", (tmp / "m.safetensors").string(), "--backend", "eigen",
                                     "--max-memory", "1"},
                                    &text);
    unsetenv("RESIDUE_EIGEN_PORTABLE");
    ASSERT_EQ(rc, 0) << text;
    EXPECT_NE(text.find("streamed band by band"), std::string::npos) << text;
    EXPECT_NE(text.find("denoised"), std::string::npos) << text;
    EXPECT_EQ(testing::read_exr_float(out).width(), 192);
  }
}

// --- the shipped models ---------------------------------------------------------------------------------

class ShippedModels : public ::testing::TestWithParam<std::string> {};

TEST_P(ShippedModels, DenoiseTheBundledExample) {
  const std::filesystem::path res = RESIDUE_SOURCE_RESOURCES;
  const nn::Model model = nn::load_model(res / ("models/" + GetParam() + ".safetensors"));
  EXPECT_EQ(model.name, GetParam());
  EXPECT_EQ(model.network.arch.features, FeatureSet::Full);
  LoadOptions lo;
  lo.reference = res / "examples/room/reference.exr";
  const AovStack s = load_aov_stack({res / "examples/room/noisy.exr"}, lo);
  const Image out = denoise(s, model, {});
  const double noisy = metrics::compare(s.color.image, s.reference->image).relmse;
  const double denoised = metrics::compare(out, s.reference->image).relmse;
  // Measured when shipped: 0.0595 -> 0.0074 (tiny, 8x), 0.0033 (small, 18x), 0.0021 (base, 28x, with the
  // post-steps), 0.0019 (paper, 32x). A broken loader, feature or backend change shows here.
  EXPECT_LT(denoised, noisy / 4) << "noisy " << noisy << " denoised " << denoised;
  EXPECT_TRUE(all_finite_nonnegative(out));
  // The mean brightness is kept (no energy lost to the log-space L1 loss on this scene).
  double sum_out = 0, sum_ref = 0;
  for (size_t i = 0; i < out.size(); ++i) {
    sum_out += out.data()[i];
    sum_ref += s.reference->image.data()[i];
  }
  EXPECT_NEAR(sum_out / sum_ref, 1.0, 0.1);
}

INSTANTIATE_TEST_SUITE_P(Zoo, ShippedModels, ::testing::Values("tiny", "small", "base", "paper"));

// The shipped model file the family name picks for a render with these AOVs (resources/models only).
std::filesystem::path shipped_model_for(const std::string& family, FeatureSet available) {
  setenv("RESIDUE_MODEL_PATH", (std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "models").c_str(), 1);
  const auto path = nn::find_model_for(family, available);
  unsetenv("RESIDUE_MODEL_PATH");
  return path;
}

// base's variants serve renders that lack AOVs: the family name picks them, and they denoise the example with
// only the AOVs they read (the others dropped from the loaded stack, as a render without them would load).
TEST(ShippedModels, BaseVariantsServeRendersWithoutDepthOrAovs) {
  const std::filesystem::path res = RESIDUE_SOURCE_RESOURCES;
  LoadOptions lo;
  lo.reference = res / "examples/room/reference.exr";
  const AovStack full = load_aov_stack({res / "examples/room/noisy.exr"}, lo);
  const double noisy = metrics::compare(full.color.image, full.reference->image).relmse;
  struct Case {
    const char* variant;
    FeatureSet set;
  };
  for (const Case& c : {Case{"base-albedo-normal", FeatureSet::ColorAlbedoNormal}, Case{"base-color", FeatureSet::ColorOnly}}) {
    AovStack s = full;
    s.depth.reset();
    s.variance.reset();
    if (c.set == FeatureSet::ColorOnly) {
      s.albedo.reset();
      s.normal.reset();
    }
    ASSERT_EQ(feature_set_for(s), c.set);
    const auto path = shipped_model_for("base", feature_set_for(s));
    EXPECT_EQ(path.filename(), std::string(c.variant) + ".safetensors");
    const nn::Model model = nn::load_model(path);
    EXPECT_EQ(model.network.arch.features, c.set);
    const Image out = denoise(s, model, {});
    const double denoised = metrics::compare(out, s.reference->image).relmse;
    EXPECT_TRUE(all_finite_nonnegative(out)) << c.variant;
    // Measured when shipped: 0.0595 -> 0.00207 (base-albedo-normal), 0.00246 (base-color); base 0.00209.
    EXPECT_LT(denoised, noisy / 4) << c.variant << ": noisy " << noisy << " denoised " << denoised;
  }
}

// With a variance AOV (Tungsten's colorVariance), the family name picks the noise-level variant.
TEST(ShippedModels, BaseVariancePicksTheNoiseLevelVariantForARenderWithVariance) {
  const auto dir = testing::shared_dataset("tungsten-example/cornell-box");
  RESIDUE_REQUIRE_SHARED(dir);
  const AovStack s = load_aov_stack({dir}, {});
  ASSERT_TRUE(s.reference.has_value());
  ASSERT_EQ(feature_set_for(s), FeatureSet::FullVariance);
  const auto path = shipped_model_for("base", feature_set_for(s));
  EXPECT_EQ(path.filename(), "base-variance.safetensors");
  const nn::Model model = nn::load_model(path);
  EXPECT_EQ(model.network.arch.features, FeatureSet::FullVariance);
  const Image out = denoise(s, model, {});
  const double noisy = metrics::compare(s.color.image, s.reference->image).relmse;
  const double denoised = metrics::compare(out, s.reference->image).relmse;
  // Measured when shipped: 0.0084 -> 0.00060 (base, without the noise level: 0.00058).
  EXPECT_LT(denoised, noisy / 4) << "noisy " << noisy << " denoised " << denoised;
  EXPECT_TRUE(all_finite_nonnegative(out));
}

// --- residue-cli denoise ----------------------------------------------------------------------------------

TEST(CliDenoise, WritesAnExrWithProvenanceAndNeverOverwrites) {
  TempDir tmp;
  const auto model_path = tmp / "random.safetensors";
  nn::write_safetensors(model_path, nn::to_safetensors(nn::random_network({2, 8, FeatureSet::Full}, 1), {{"name", "random-2x8"}}), false);
  const std::filesystem::path ex = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";
  const auto out = tmp / "denoised.exr";
  std::vector<std::string> args = {"denoise", (ex / "noisy.exr").string(), "-r", (ex / "reference.exr").string(),
                                   "-o", out.string(), "--model", model_path.string(), "--backend", "eigen", "--tile", "64"};
  std::string text;
  ASSERT_EQ(testing::run_cli(args, &text), 0) << text;
  EXPECT_NE(text.find("per megapixel"), std::string::npos) << text;
  EXPECT_NE(text.find("denoised"), std::string::npos) << "metrics against the reference: " << text;
  OIIO::ImageBuf img(out.string());
  ASSERT_TRUE(img.read());
  EXPECT_EQ(img.spec().width, 192);
  EXPECT_EQ(img.spec().nchannels, 3);
  EXPECT_EQ(img.spec().get_string_attribute("residue:model"), "random-2x8");
  EXPECT_NE(img.spec().get_string_attribute("residue:backend").find("eigen"), std::string::npos);
  EXPECT_FALSE(img.spec().get_string_attribute("Note").empty()) << "the source's metadata is kept";
  const auto before = std::filesystem::last_write_time(out);
  EXPECT_EQ(testing::run_cli(args, &text), 4) << text;
  EXPECT_EQ(std::filesystem::last_write_time(out), before);
  args.push_back("--force");
  EXPECT_EQ(testing::run_cli(args, &text), 0) << text;
  // A model that reads AOVs the input lacks: a clear input error.
  nn::write_safetensors(tmp / "m.safetensors", nn::to_safetensors(nn::random_network({1, 4, FeatureSet::Full}, 1)), false);
  EXPECT_EQ(testing::run_cli({"denoise", (ex / "reference.exr").string(), "-o", (tmp / "x.exr").string(), "-m",
                              (tmp / "m.safetensors").string()},
                             &text),
            3)
      << text;
  EXPECT_FALSE(std::filesystem::exists(tmp / "x.exr"));
  EXPECT_EQ(testing::run_cli({"denoise", (ex / "noisy.exr").string(), "-o", (tmp / "y.exr").string(), "-m", "no-such-model"}, &text), 3) << text;
}

// The header records the post-steps that ran, as core decided them, in memory and streamed: Tungsten's file
// set has a variance AOV (so the blend runs unless switched off), the bundled room has none; and the
// self-ensemble's size.
TEST(CliDenoise, HeaderSaysWhichPostStepsRan) {
  const auto tungsten = testing::shared_dataset("tungsten-example/cornell-box");
  RESIDUE_REQUIRE_SHARED(tungsten);
  TempDir tmp;
  const auto model = tmp / "random.safetensors";
  nn::write_safetensors(model, nn::to_safetensors(nn::random_network({2, 8, FeatureSet::Full}, 1)), false);
  const std::string room = (std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room/noisy.exr").string();
  struct Case {
    std::string input;
    std::vector<std::string> flags;
    int energy, blend;
    int ensemble = 1;
  };
  int n = 0;
  for (const Case& c : {Case{tungsten.string(), {}, 1, 1}, Case{tungsten.string(), {"--no-variance-blend"}, 1, 0},
                        Case{tungsten.string(), {"--no-energy-correction"}, 0, 1}, Case{room, {}, 1, 0},
                        Case{room, {"--ensemble", "4"}, 1, 0, 4}}) {
    for (const char* memory : {"4096", "2"}) {  // 2 MiB: the 384x384 Tungsten render is streamed band by band
      const auto out = tmp / ("out" + std::to_string(n++) + ".exr");
      std::vector<std::string> args = {"denoise", c.input, "-o", out.string(), "--model", model.string(),
                                       "--backend", "eigen", "--max-memory", memory};
      args.insert(args.end(), c.flags.begin(), c.flags.end());
      std::string text;
      ASSERT_EQ(testing::run_cli(args, &text), 0) << text;
      OIIO::ImageBuf img(out.string());
      ASSERT_TRUE(img.read());
      const std::string what = c.input + " " + memory + " MiB " + (c.flags.empty() ? "" : c.flags[0]);
      EXPECT_EQ(img.spec().get_int_attribute("residue:energy_correction", -1), c.energy) << what;
      EXPECT_EQ(img.spec().get_int_attribute("residue:variance_blend", -1), c.blend) << what;
      EXPECT_EQ(img.spec().get_int_attribute("residue:ensemble", -1), c.ensemble) << what;
    }
  }
}

// With a reference, the scores are taken band by band from the written file (the render never whole in memory,
// as for the streamed denoise itself): they are core's scores of the whole images, in memory or streamed.
TEST(CliDenoise, ScoresFromTheWrittenFileBandByBand) {
  TempDir tmp;
  const std::filesystem::path ex = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";
  const AovStack stack = load_aov_stack({ex / "noisy.exr"}, {.reference = ex / "reference.exr"});
  for (const char* memory : {"4096", "2"}) {
    SCOPED_TRACE(memory);
    const auto out = tmp / (std::string("out") + memory + ".exr");
    std::string text;
    ASSERT_EQ(testing::run_cli({"denoise", (ex / "noisy.exr").string(), "-r", (ex / "reference.exr").string(), "-o",
                                out.string(), "-m", "tiny", "--max-memory", memory, "--roi", "10,20,150,140"},
                               &text),
              0)
        << text;
    LoadOptions lo;
    lo.load_reference = false;
    const Image denoised = load_aov_stack({out}, lo).color.image;
    metrics::Options m;
    m.roi = Rect{10, 20, 150, 140};
    for (const auto& [name, img] : {std::pair<std::string, const Image*>{"noisy", &stack.color.image},
                                    std::pair<std::string, const Image*>{"denoised", &denoised}}) {
      const metrics::Scores e = metrics::compare(*img, stack.reference->image, m);
      char relmse[32], ssim[32];
      std::snprintf(relmse, sizeof relmse, "%g", e.relmse);
      std::snprintf(ssim, sizeof ssim, "%.5f", e.ssim);
      const auto line = text.substr(text.find("\n" + name + " ") + 1);
      const std::string row = line.substr(0, line.find('\n'));
      EXPECT_NE(row.find(relmse), std::string::npos) << row << " / " << relmse;
      EXPECT_NE(row.find(ssim), std::string::npos) << row << " / " << ssim;
    }
  }
}

TEST(CliDenoise, ModelNamePicksTheVariantForTheAovsPresent) {
  TempDir tmp;
  nn::write_safetensors(tmp / "fam.safetensors",
                        nn::to_safetensors(nn::random_network({1, 4, FeatureSet::Full}, 1), {{"name", "fam"}}), false);
  nn::write_safetensors(tmp / "fam-color.safetensors",
                        nn::to_safetensors(nn::random_network({1, 4, FeatureSet::ColorOnly}, 2), {{"name", "fam-color"}}),
                        false);
  EXPECT_EQ(nn::find_model_for((tmp / "fam.safetensors").string(), FeatureSet::ColorOnly), tmp / "fam.safetensors")
      << "a path is taken as is";
  setenv("RESIDUE_MODEL_PATH", tmp.path().c_str(), 1);
  EXPECT_EQ(nn::find_model_for("fam", FeatureSet::Full), tmp / "fam.safetensors");
  EXPECT_EQ(nn::find_model_for("fam", FeatureSet::ColorAlbedoNormal), tmp / "fam-color.safetensors")
      << "no albedo-normal variant: the colour-only one, never zeros for depth";
  EXPECT_THROW(nn::find_model_for("other", FeatureSet::Full), Error);
  // With a variance AOV, the noise-level variant when there is one, else the full model.
  EXPECT_EQ(nn::find_model_for("fam", FeatureSet::FullVariance), tmp / "fam.safetensors");
  nn::write_safetensors(tmp / "fam-variance.safetensors",
                        nn::to_safetensors(nn::random_network({1, 4, FeatureSet::FullVariance}, 3)), false);
  EXPECT_EQ(nn::find_model_for("fam", FeatureSet::FullVariance), tmp / "fam-variance.safetensors");
  EXPECT_EQ(nn::find_model_for("fam", FeatureSet::Full), tmp / "fam.safetensors");
  const std::filesystem::path ex = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";
  std::string text;
  // The reference file has only colour: the colour-only variant runs.
  ASSERT_EQ(testing::run_cli({"denoise", (ex / "reference.exr").string(), "-o", (tmp / "c.exr").string(), "-m", "fam",
                              "--backend", "eigen"},
                             &text),
            0)
      << text;
  OIIO::ImageBuf img((tmp / "c.exr").string());
  ASSERT_TRUE(img.read());
  EXPECT_EQ(img.spec().get_string_attribute("residue:model"), "fam-color");
  unsetenv("RESIDUE_MODEL_PATH");
}

}  // namespace
}  // namespace residue
